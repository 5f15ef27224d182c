"""Independent blocking, forged flag-ACKs and their combination: costs, rates and energy against
independently built chains and closed forms."""

import math
from fractions import Fraction

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names, random_system
from reference import explore_any_chain, stationary_power, traces

LAM, Z0 = 0.5, 2


def chain_reference(system, lam, z0, mu, block, gamma, cap=90):
    """(J, genuine flags sent, flags reaching the sensor) per step from the explicit chain, by
    power iteration; at the cap the mass times Tr h^tau is below 1e-12 of J for the cases used
    (a survival of at most 0.5 * 0.93 per step against a trace growth of 1.44)."""
    states, T = explore_any_chain(lam, z0, mu, block, gamma, cap)
    pi = stationary_power(T)
    taus = np.array([s[0] for s in states])
    tr = traces(system.A, system.Q, system.pbar, int(taus.max()))
    flag = np.array([1.0 if z == z0 + 1 else (mu if z == z0 else 0.0) for _, z, _ in states])
    b = np.array([block[s] for _, _, s in states])
    sent = float(pi @ flag)
    reaching = float(pi @ (flag * (1 - b))) + gamma * (1 - sent)
    return float(pi @ tr[taus]), sent, reaching


ATTACKS = [
    (fa.RandomBlocking(0.3), (0.3,), 0.0),
    (fa.RandomBlocking(0.85), (0.85,), 0.0),
    (fa.FlagInjection(0.1), (0.0,), 0.1),
    (fa.FlagInjection(0.05, fa.RandomBlocking(0.6)), (0.6,), 0.05),
    (fa.FlagInjection(0.2, fa.PeriodicBlocking(1, 3)), (1.0, 0.0, 0.0), 0.2),
    (fa.FlagInjection(0.1, fa.MaskBlocking([1, 0, 1, 1, 0])), (1.0, 0.0, 1.0, 1.0, 0.0), 0.1),
]


@pytest.mark.parametrize("attack, block, gamma", ATTACKS, ids=str)
@pytest.mark.parametrize("mu", [1.0, 0.55])
def test_cost_and_rates_against_the_explicit_chain(paper, attack, block, gamma, mu):
    j, sent, reaching = chain_reference(paper, LAM, Z0, mu, block, gamma)
    assert_allclose(fa.j_attack(paper, LAM, Z0, mu=mu, attack=attack), j, rtol=1e-9)
    rates = fa.flag_rates(LAM, Z0, attack, mu)
    assert_allclose([rates.sent, rates.delivered], [sent, reaching], rtol=1e-10)
    assert_allclose(rates.forged, gamma * (1 - sent), rtol=1e-12, atol=1e-15)
    assert_allclose(fa.high_power_rate(LAM, Z0, attack, mu), reaching, rtol=1e-10)


@pytest.mark.parametrize("seed", range(4))
def test_random_systems(seed):
    rng = np.random.default_rng(100 + seed)
    n = 1 + seed % 3
    system = fa.LinearSystem(*random_system(rng, n, unstable=False))
    lam, z0, mu = [(0.3, 2, 1.0), (0.6, 1, 0.4), (0.45, 3, 0.8), (0.7, 2, 0.0)][seed]
    for attack, block, gamma in [ATTACKS[0], ATTACKS[3]]:
        j, _, _ = chain_reference(system, lam, z0, mu, block, gamma, cap=120)
        assert_allclose(fa.j_attack(system, lam, z0, mu=mu, attack=attack), j, rtol=1e-9)


@pytest.mark.parametrize("mu", [1.0, 0.3])
def test_random_blocking_runs_from_the_online_cost_to_j_max(paper, mu):
    j = [fa.j_attack(paper, LAM, Z0, mu=mu, attack=fa.RandomBlocking(b)) for b in (0, 0.25, 0.5, 1)]
    assert_allclose(j[0], fa.j_online(paper, LAM, Z0, mu), rtol=1e-14)
    assert_allclose(j[-1], fa.j_max(paper, LAM), rtol=1e-12)
    assert all(x < y for x, y in zip(j, j[1:], strict=False))
    assert_allclose(
        fa.high_power_rate(LAM, Z0, fa.RandomBlocking(0), mu),
        fa.online_high_power_rate(LAM, Z0, mu),
        rtol=1e-14,
    )
    sweep = fa.random_blocking_sweep(paper, LAM, Z0, [0, 0.25, 0.5, 1], mu)
    assert_allclose(sweep.j_attack, j, rtol=1e-15)


def test_forging_trades_error_for_energy(paper):
    gammas = [0.0, 0.02, 0.1, 0.4]
    j = [fa.j_attack(paper, LAM, Z0, attack=fa.FlagInjection(g)) for g in gammas]
    e = [fa.energy_per_step(LAM, Z0, 3, 1, fa.FlagInjection(g)) for g in gammas]
    assert all(x > y for x, y in zip(j, j[1:], strict=False))
    assert all(x < y for x, y in zip(e, e[1:], strict=False))
    # Unattacked, the designed schedule spends exactly the budget Psi = 9/7.
    assert_allclose(e[0], 9 / 7, rtol=1e-14)
    # Forging every step: high power always, Tr P-bar.
    assert_allclose(fa.j_attack(paper, LAM, Z0, attack=fa.FlagInjection(1.0)), np.trace(paper.pbar))
    assert fa.energy_per_step(LAM, Z0, 3, 1, fa.FlagInjection(1.0)) == 3.0


def test_infinite_exactly_past_the_growth_condition():
    """J = inf iff beta (a rho^2)^z0 (mu + (1 - mu) a rho^2) >= 1: each blocked flag starts a new
    run of z0 (or z0 + 1) losses, over which Tr h^tau grows like rho^(2 tau)."""
    system = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    lam, z0, mu = 0.2, 1, 0.5
    g = (1 - lam) * 1.44
    edge = 1 / (g**z0 * (mu + (1 - mu) * g))
    assert 0 < edge < 1
    below = fa.j_attack(system, lam, z0, mu=mu, attack=fa.RandomBlocking(edge * 0.99))
    above = fa.j_attack(system, lam, z0, mu=mu, attack=fa.RandomBlocking(edge * 1.01))
    assert math.isfinite(below) and above == math.inf


def test_random_threshold(paper):
    b = fa.beta_bar_random(paper, LAM, Fraction(1, 7))
    assert 0 < b < 1
    assert_allclose(
        fa.j_attack(paper, LAM, Z0, attack=fa.RandomBlocking(b)),
        fa.j_offline(paper, LAM, Fraction(1, 7)),
        rtol=1e-12,
    )


@pytest.mark.parametrize("beta", [0.2, 0.5, 2 / 3])
def test_rate_matching_hides_from_the_flag_count(paper, beta):
    att = fa.rate_matching_attack(LAM, Z0, beta)
    assert isinstance(att, fa.FlagInjection) and att.block == fa.RandomBlocking(beta)
    assert 0 < att.gamma < 1
    assert_allclose(fa.delivered_flag_rate(LAM, Z0, att), fa.delivered_flag_rate(LAM, Z0), rtol=1e-12)
    # The attack blocks genuine flags and so still raises the error above J_on.
    assert fa.j_attack(paper, LAM, Z0, attack=att) > fa.j_online(paper, LAM, Z0)


def test_spellings():
    assert fa.attacks.as_attack("random:0.3") == fa.RandomBlocking(0.3)
    assert fa.attacks.as_attack("inject:0.1") == fa.FlagInjection(0.1)
    assert fa.attacks.as_attack("inject:0.1+random:0.3") == fa.FlagInjection(0.1, fa.RandomBlocking(0.3))
    assert fa.attacks.as_attack("inject:0.1+1/5") == fa.FlagInjection(0.1, fa.PeriodicBlocking(1, 5))
    assert fa.FlagInjection(0.1, fa.RandomBlocking(0.3)).label == "inject:0.1+random:0.3"
    assert hash(fa.RandomBlocking(0.3)) == hash(fa.RandomBlocking(0.3))


@pytest.mark.parametrize(
    "make, exc, name",
    [
        (lambda: fa.RandomBlocking(1.5), ValueError, "beta"),
        (lambda: fa.RandomBlocking(float("nan")), ValueError, "beta"),
        (lambda: fa.RandomBlocking("0.3"), TypeError, "beta"),
        (lambda: fa.RandomBlocking(fa.PeriodicBlocking(1, 5)), TypeError, "beta"),
        (lambda: fa.FlagInjection(-0.1), ValueError, "gamma"),
        (lambda: fa.FlagInjection(0.1, 0.3), TypeError, "block"),
        (lambda: fa.FlagInjection(0.1, fa.FlagInjection(0.1)), TypeError, "block"),
        (lambda: fa.attacks.as_attack("random:2"), ValueError, "beta"),
        (lambda: fa.attacks.as_attack("inject:0.1+inject:0.2"), ValueError, "attack"),
        (
            lambda: fa.high_power_rate(0.5, 2, fa.RandomBlocking(0.2), mu=fa.RandomBlocking(0.2)),
            TypeError,
            "mu",
        ),
        (lambda: fa.energy_per_step(0.5, 2, 1, 3), ValueError, "Delta"),
        (lambda: fa.rate_matching_attack(0.5, 2, fa.RandomBlocking(0.2)), TypeError, "beta"),
        (
            lambda: fa.random_blocking_sweep(fa.LinearSystem(1.2, 0.7, 0.8, 0.8), 0.5, 2, [0.1, 1.2]),
            ValueError,
            "betas",
        ),
    ],
)
def test_bad_input(make, exc, name):
    with pytest.raises(exc, match=names(name)):
        make()


def test_other_attack_results_carry_their_inputs(paper):
    """Each result echoes what it was computed for, and μ and z0 reach the core: the energy per
    step is δ + (Δ - δ) f with f the high-power rate at that μ; beta_bar_random at an explicit
    (z0, μ) differs from the designed schedule's; the sweep carries its β grid, γ, z0, μ and λ
    (kills each argument or field dropped or replaced by None)."""
    rate = fa.high_power_rate(0.5, 2, fa.RandomBlocking(0.2), mu=0.4)
    assert fa.energy_per_step(0.5, 2, 10, 3, fa.RandomBlocking(0.2), mu=0.4) == pytest.approx(
        3 + 7 * rate, rel=1e-15
    )
    assert rate != fa.high_power_rate(0.5, 2, fa.RandomBlocking(0.2))
    designed = fa.beta_bar_random(paper, 0.5, Fraction(1, 7))
    assert fa.beta_bar_random(paper, 0.5, Fraction(1, 7), z0=2, mu=1.0) == designed  # (2, 1) is the design
    assert fa.beta_bar_random(paper, 0.5, Fraction(1, 7), z0=3) != designed
    assert fa.beta_bar_random(paper, 0.5, Fraction(1, 7), z0=2, mu=0.5) != designed
    sw = fa.random_blocking_sweep(paper, 0.5, 3, [0.1, 0.2], mu=0.5, gamma=0.05)
    assert sw.beta.tolist() == [0.1, 0.2] and sw.beta.dtype == np.float64
    assert (sw.gamma, sw.z0, sw.mu, sw.lam) == (0.05, 3, 0.5, 0.5)


def test_other_attack_budgets_at_their_ends(paper):
    """Closed ranges: the rate-matching attack exists for β = 0 (nothing blocked, nothing forged)
    and β = 1; δ = 0 is a valid low power; Δ = δ is refused; a sweep given the integer budgets
    0 and 1 gives J_on and J_max (kills the closed interval opened, the bounds moved and the
    grid left in integers)."""
    sw = fa.random_blocking_sweep(paper, 0.5, 2, [0, 1])
    assert sw.beta.dtype == np.float64
    assert_allclose(sw.j_attack, [fa.j_online(paper, 0.5, 2), fa.j_max(paper, 0.5)], rtol=1e-12)
    assert fa.rate_matching_attack(0.5, 2, 0).gamma == 0.0
    assert 0 < fa.rate_matching_attack(0.5, 2, 1).gamma < 1
    f = fa.high_power_rate(0.5, 2)
    assert fa.energy_per_step(0.5, 2, 1, 0) == pytest.approx(f, rel=1e-15)
    with pytest.raises(ValueError, match=names("Delta")):
        fa.energy_per_step(0.5, 2, 3, 3)
