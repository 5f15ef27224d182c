"""One model of an attack: the attack objects, every call form, and the costs they give, checked
against independently built chains and closed forms."""

from fractions import Fraction

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from reference import explore_mask_chain, stationary_dense, traces

LAM, Z0 = 0.5, 2


def j_reference(system, lam, z0, mask, mu=1.0):
    """J from the independent (tau, zeros, sigma) chain and plain trace iteration."""
    states, T = explore_mask_chain(lam, z0, list(mask), mu)
    pi = stationary_dense(T)
    taus = np.array([s[0] for s in states])
    tr = traces(system.A, system.Q, system.pbar, int(taus.max()))
    return float(pi @ tr[taus])


def test_objects_are_frozen_hashable_and_readable():
    a, b = fa.PeriodicBlocking(1, 5), fa.PeriodicBlocking(1, 5)
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    assert repr(a) == "PeriodicBlocking(r=1, t=5)" and str(a) == "block 1 of every 5 flag-ACKs"
    assert a.beta == Fraction(1, 5) and a.mask == (True, False, False, False, False)
    m = fa.MaskBlocking([1, 0, 1, 0, 0])
    assert repr(m) == "MaskBlocking('10100')" and m.beta == Fraction(2, 5)
    assert hash(m) == hash(fa.MaskBlocking((True, False, True, False, False)))
    with pytest.raises(AttributeError):
        a.r = 2  # type: ignore[misc]
    # (2, 6) is a different attack from (1, 3): two blocked in a row.
    assert fa.PeriodicBlocking(2, 6) != fa.PeriodicBlocking(1, 3)


@pytest.mark.parametrize(
    "args, exc, name",
    [
        ((3, 3), ValueError, "r"),
        ((0, 0), ValueError, "t"),
        ((-1, 5), ValueError, "r"),
        ((1.5, 5), TypeError, "r"),
        ((True, 5), TypeError, "r"),
    ],
)
def test_periodic_rejects_bad_parameters(args, exc, name):
    with pytest.raises(exc, match=names(name)):
        fa.PeriodicBlocking(*args)


@pytest.mark.parametrize(
    "mask, exc",
    [([], ValueError), ([0, 2], ValueError), ("101", TypeError), ([[1, 0]], ValueError), (None, TypeError)],
)
def test_mask_rejects_bad_masks(mask, exc):
    with pytest.raises(exc, match="mask"):
        fa.MaskBlocking(mask)


def test_every_spelling_of_the_paper_attack_gives_one_cost(paper):
    ref = j_reference(paper, LAM, Z0, [1, 0, 0, 0, 0])
    forms = [
        fa.j_attack(paper, LAM, Z0, 1, 5),
        fa.j_attack(paper, LAM, Z0, attack=fa.PeriodicBlocking(1, 5)),
        fa.j_attack(paper, LAM, Z0, fa.PeriodicBlocking(1, 5)),
        fa.j_attack(paper, LAM, Z0, attack=(1, 5)),
        fa.j_attack(paper, LAM, Z0, attack="1/5"),
        fa.j_attack(paper, LAM, Z0, attack=fa.MaskBlocking([1, 0, 0, 0, 0])),
        fa.j_attack_pattern(paper, LAM, Z0, [1, 0, 0, 0, 0]),
    ]
    assert_allclose(forms, ref, rtol=1e-10)


@pytest.mark.parametrize(
    "mask, mu",
    [([1, 0, 1, 1, 0], 1.0), ([0, 1, 1, 0, 0, 0, 1], 0.45), ([1, 1, 0], 0.0), ([1, 0, 0, 0, 0], 0.7)],
)
def test_any_mask_and_mu_against_the_independent_chain(paper, mask, mu):
    got = fa.j_attack(paper, LAM, Z0, mu=mu, attack=fa.MaskBlocking(mask))
    assert_allclose(got, j_reference(paper, LAM, Z0, mask, mu), rtol=1e-10)


def test_attack_argument_errors(paper):
    with pytest.raises(TypeError, match="either r and t, or attack"):
        fa.j_attack(paper, LAM, Z0, 1, 5, attack=fa.PeriodicBlocking(1, 5))
    with pytest.raises(TypeError, match="attack"):
        fa.j_attack(paper, LAM, Z0)
    with pytest.raises(TypeError, match="attack"):
        fa.j_attack(paper, LAM, Z0, attack=[1, 0])
    with pytest.raises(ValueError, match="j_max"):
        fa.j_attack(paper, LAM, Z0, attack=fa.MaskBlocking([1, 1]))


def test_simulate_and_curve_accept_attack_objects(paper):
    att = fa.PeriodicBlocking(1, 5)
    a = fa.simulate(paper, LAM, fa.OnlineSchedule(Z0), 200, 512, seed=4, attack=att, progress=False)
    b = fa.simulate(paper, LAM, fa.OnlineSchedule(Z0), 200, 512, seed=4, attack=(1, 5), progress=False)
    c = fa.simulate(
        paper,
        LAM,
        fa.OnlineSchedule(Z0),
        200,
        512,
        seed=4,
        attack=fa.MaskBlocking([1, 0, 0, 0, 0]),
        progress=False,
    )
    assert a.j == b.j == c.j and a.attack == str(att)
    curve = fa.expected_trace_curve(paper, LAM, fa.OnlineSchedule(Z0), 3000, attack=att)
    assert_allclose(curve.j_k[-1], fa.j_attack(paper, LAM, Z0, attack=att), rtol=2e-3)


def test_flag_rates_are_a_function_of_the_protocol_alone():
    sent, delivered, forged = fa.flag_rates(LAM, Z0)
    assert sent == delivered == pytest.approx(1 / 7, rel=1e-14) and forged == 0
    for att, mu in [(fa.PeriodicBlocking(1, 5), 1.0), (fa.MaskBlocking([1, 0, 1, 0, 0, 0]), 0.3)]:
        sent, delivered, _ = fa.flag_rates(0.3, 3, att, mu)
        assert delivered == pytest.approx(sent * (1 - float(att.beta)), rel=1e-14)
        # Independent: the chain's probability of a flag that gets through.
        states, T = explore_mask_chain(0.3, 3, list(att.mask), mu)
        pi = stationary_dense(T)
        p_flag = np.array([1.0 if z == 4 else (mu if z == 3 else 0.0) for _, z, _ in states])
        assert_allclose(sent, pi @ p_flag, rtol=1e-10)
    # Every flag blocked: each arrival starts a walk that flags u/(1-u) times on average.
    u = 0.7**3 * (0.3 + 0.7 * 0.7)
    sent, delivered, _ = fa.flag_rates(0.3, 3, fa.MaskBlocking([1]), 0.3)
    assert sent == pytest.approx(0.3 * u / (1 - u), rel=1e-14) and delivered == 0.0


def test_threshold_functions_take_a_given_design(paper):
    ratio = Fraction(1, 7)
    # The designed schedule by default; the same when given explicitly.
    assert fa.beta_bar(paper, LAM, ratio) == fa.beta_bar(paper, LAM, ratio, z0=2, mu=1.0)
    # Another memory mix: the finite threshold is the first swept r/t whose J reaches J_off.
    bar = fa.beta_bar(paper, LAM, ratio, t_max=40, z0=2, mu=0.6)
    sw = fa.beta_sweep(paper, LAM, ratio, t_max=40, z0=2, mu=0.6)
    assert (bar.z0, bar.mu, sw.z0, sw.mu) == (2, 0.6, 2, 0.6)
    first = np.flatnonzero(sw.j_attack >= bar.j_offline)[0]
    assert bar.finite == Fraction(int(sw.r[first]), int(sw.t[first]))
    assert_allclose(sw.j_online, fa.j_online(paper, LAM, 2, 0.6), rtol=1e-14)
    # Short attacks only: the dense reference loses accuracy where a^tau Tr h^tau spans many
    # orders of magnitude.
    for i in np.flatnonzero((sw.r <= 4) & (sw.t <= 12))[::5]:
        att = fa.PeriodicBlocking(int(sw.r[i]), int(sw.t[i]))
        assert_allclose(sw.j_attack[i], j_reference(paper, LAM, 2, att.mask, 0.6), rtol=1e-9)
    assert 0 < bar.limit < 1  # this design beats the offline schedule unattacked
    assert_allclose(fa.j_attack_limit(paper, LAM, 2, bar.limit, 0.6), bar.j_offline, rtol=1e-12)
    with pytest.raises(TypeError, match="mu"):
        fa.beta_bar(paper, LAM, ratio, mu=0.5)


@pytest.mark.parametrize("mu", [1.0, 0.35])
def test_choose_schedule_against_the_regime_mix(paper, mu):
    """The decision compares J_inf(beta), the time-weighted mix of the unattacked and the
    all-blocked regimes (each regime's flags over its flag rate), with J_offline."""
    ratio, z0 = Fraction(1, 7), 2
    j_on, j_max = fa.j_online(paper, LAM, z0, mu), fa.j_max(paper, LAM)
    f_on = fa.flag_rates(LAM, z0, None, mu)[0]
    f_blk = fa.flag_rates(LAM, z0, fa.MaskBlocking([1]), mu)[0]
    j_off = fa.j_offline(paper, LAM, ratio)
    for beta in [0.05, 0.2, 0.5, 0.8]:
        mix = (beta * j_max / f_blk + (1 - beta) * j_on / f_on) / (beta / f_blk + (1 - beta) / f_on)
        d = fa.choose_schedule(paper, LAM, ratio, beta, z0=z0, mu=mu)
        assert_allclose(d.j_online_attacked, mix, rtol=1e-12)
        assert d.schedule == ("online" if mix < j_off else "offline")
        assert d.j_offline == j_off and d.mu == mu
