"""fakeack.flag_process: the delivered flag-ACKs as a Markov arrival process over the engine's
automaton, against renewal theory (the paper's channel), two exact identities (mimicry, and random
blocking at z0 = 1), the Monte Carlo of the protocol on bursty channels, and its own two routes
(the covariance sums and the exact count law)."""

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER

GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
THREE = fa.MarkovChannel(
    [[0.8, 0.2, 0.0], [0.1, 0.8, 0.1], [0.0, 0.3, 0.7]], [0.9, 0.5, 0.1], [1.0, 1.0, 0.6]
)


@pytest.mark.parametrize(("lam", "z0", "mu"), [(0.5, 2, 1.0), (0.3, 1, 1.0), (0.7, 3, 0.4), (0.5, 2, 0.0)])
def test_the_paper_channel_is_a_renewal_process(lam, z0, mu):
    """Gaps i.i.d. with mean m and variance v: rate 1/m, variance rate v/m^3 (renewal CLT)."""
    fp = fa.flag_process(lam, fa.OnlineDesign(z0, mu))
    m, v = fa.flag_interval_moments(lam, z0, mu)
    assert fp.rate == pytest.approx(1 / m, rel=1e-12)
    assert fp.variance_rate == pytest.approx(v / m**3, rel=1e-10)


@pytest.mark.parametrize("channel", [0.5, GE])
def test_mimicry_delivers_the_attack_free_flag_law(channel):
    design = fa.OnlineDesign(2)
    free = fa.flag_process(channel, design)
    mimic = fa.flag_process(channel, design, fa.MimicryAttack())
    assert mimic.rate == pytest.approx(free.rate, rel=1e-12)
    assert mimic.variance_rate == pytest.approx(free.variance_rate, rel=1e-10)
    a, b = free.count_law(300), mimic.count_law(300)
    n = max(len(a), len(b))
    assert np.allclose(np.pad(a, (0, n - len(a))), np.pad(b, (0, n - len(b))), atol=1e-13)


@pytest.mark.parametrize(("lam", "beta"), [(0.5, 0.2), (0.3, 0.6)])
def test_random_blocking_at_z0_1_is_a_better_channel(lam, beta):
    """With z0 = 1 a flag follows every loss; a blocked flag leaves the sensor at low power, as a
    loss would have: the deliveries are those of the unattacked lam' = 1 - (1 - lam)(1 - beta)."""
    attacked = fa.flag_process(lam, fa.OnlineDesign(1), fa.RandomBlocking(beta))
    twin = fa.flag_process(1 - (1 - lam) * (1 - beta), fa.OnlineDesign(1))
    assert attacked.rate == pytest.approx(twin.rate, rel=1e-12)
    assert attacked.variance_rate == pytest.approx(twin.variance_rate, rel=1e-10)


def test_count_moments_and_count_law_agree_and_approach_the_rates():
    fp = fa.flag_process(GE, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 3))
    for start in ("stationary", "initial"):
        m, v = fp.count_moments(400, start)
        law = fp.count_law(400, start)
        c = np.arange(len(law))
        assert law.sum() == pytest.approx(1.0, abs=1e-12)
        assert law @ c == pytest.approx(m, rel=1e-10)
        assert law @ c**2 - (law @ c) ** 2 == pytest.approx(v, rel=1e-8)
    m, v = fp.count_moments(400)
    assert m == pytest.approx(400 * fp.rate, rel=1e-12)  # stationary start: exactly n rate
    m2, v2 = fp.count_moments(8000)
    # Var N_n = n sigma^2 + O(1): the slope between two windows is the variance rate.
    assert (v2 - v) / 7600 == pytest.approx(fp.variance_rate, rel=1e-6)


@pytest.mark.parametrize(
    ("channel", "attack"),
    [
        (GE, None),
        (fa.GilbertElliott(0.2, 0.2, 1.0, 0.0), fa.PeriodicBlocking(1, 3)),
        (THREE, fa.FlagInjection(0.05)),
    ],
)
def test_the_monte_carlo_of_the_protocol_agrees(channel, attack):
    """Counts of 300-step runs from the paper's initial condition: mean and variance within 4
    standard errors of the exact ones."""
    s, design, H, R = fa.LinearSystem(**PAPER), fa.OnlineDesign(2), 300, 3000
    res = fa.simulate(s, channel, design, H, R, seed=11, attack=attack, record_runs=True, progress=False)
    x = res.delivered_per_run.astype(float)
    m, v = fa.flag_process(channel, design, attack).count_moments(H, start="initial")
    assert abs(x.mean() - m) < 4 * np.sqrt(v / R)
    assert abs(x.var(ddof=1) - v) < 4 * v * np.sqrt(2 / (R - 1))


def test_bad_arguments_name_themselves():
    fp = fa.flag_process(0.5, fa.OnlineDesign(2))
    with pytest.raises(ValueError, match="n_steps"):
        fp.count_moments(0)
    with pytest.raises(ValueError, match="start must be"):
        fp.count_law(10, start="burn-in")
    with pytest.raises(ValueError, match="n_steps = 10000000"):
        fa.flag_process(GE, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 50)).count_law(10**7)
    with pytest.raises(TypeError, match="design must be"):
        fa.flag_process(0.5, (2, 1.0))
    with pytest.raises(ValueError, match="channel must lie in"):
        fa.flag_process(1.5, fa.OnlineDesign(2))


def test_a_burn_in_of_the_mixing_time_puts_simulated_windows_in_the_stationary_regime():
    """PeriodicBlocking(8, 59): the attacker's phase mixes slowly (about 1.7e4 steps to 1e-3 in
    total variation). After that burn-in the protocol's windows match the stationary detection
    probability; after one window of burn-in they do not."""
    attack = fa.PeriodicBlocking(8, 59)
    design = fa.OnlineDesign(2)
    k = fa.flag_process(0.5, design, attack).mixing_steps()
    assert 10_000 < k < 30_000
    assert fa.flag_process(0.5, design).mixing_steps() < 100  # no attack: a few gaps
    p = fa.detection_probability(0.5, 2, attack, 1000, 0.01, support=False)
    runs = 4000
    mixed = fa.detection_rates(0.5, 2, attack, 1000, runs, alternative="two-sided", burn_in=k, seed=5)
    short = fa.detection_rates(0.5, 2, attack, 1000, runs, alternative="two-sided", burn_in=1000, seed=5)
    se = np.sqrt(p * (1 - p) / runs)
    assert abs(mixed.detection - p) < 4 * se, (mixed.detection, p)
    assert abs(short.detection - p) > 4 * se, (short.detection, p)
    with pytest.raises(ValueError, match="tol"):
        fa.flag_process(0.5, design, attack).mixing_steps(tol=1e-3, max_steps=100)


@pytest.mark.parametrize(
    "attack", [None, fa.PeriodicBlocking(1, 5), fa.FlagInjection(0.01, min_gap=3)], ids=str
)
def test_the_banded_window_recursion_is_the_full_count_law(attack):
    """Without a support check (min_gap = 1) the window's no-alarm mass is the count law's inside
    the bounds: the banded recursion over (state, age, count) against the full one over (state,
    count) of count_law."""
    process = fa.flag_process(0.5, fa.OnlineDesign(2), attack)
    law = process.count_law(3000)
    for lo, hi in [(380, 480), (300, 460), (-1, 430), (400, 3001)]:
        inside = law[max(lo + 1, 0) : min(hi, len(law))].sum()
        got = process.window_alarm_probability(3000, 1, (lo, hi))
        assert got == pytest.approx(1.0 - inside, abs=1e-13)
