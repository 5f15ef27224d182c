"""detection_probability with the sensor's belief about the channel apart from the truth:
true_channel (any channel), lam_range (an unknown lam), and a Markov channel as the belief,
against the Monte Carlo of the protocol's windows, the definition of the range test, and the
identity of random blocking at z0 = 1 with a better channel."""

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER
from fakeack.detection.count import count_alarm_bounds
from fakeack.detection.rates import simulate_windows

GE = fa.GilbertElliott(0.1, 0.1, 1.0, 0.0)


def test_the_truth_equal_to_the_belief_is_the_plain_call():
    for attack in (None, fa.PeriodicBlocking(1, 5), fa.RandomBlocking(0.2)):
        for n in (300, 1000):
            plain = fa.detection_probability(0.5, 2, attack, n, 0.01)
            assert fa.detection_probability(0.5, 2, attack, n, 0.01, true_channel=0.5) == plain


@pytest.mark.parametrize(("n", "truth"), [(1000, 0.48), (3000, 0.48), (500, 0.53)])
def test_a_wrong_lam_against_the_monte_carlo(n, truth):
    """Windows simulated on the true lam after a burn-in, counted against the bounds the sensor
    computed for lam = 0.5."""
    runs = 20000
    lo, hi = count_alarm_bounds(0.5, 2, n, 0.01, "two-sided")
    _, counts = simulate_windows(
        truth, fa.OnlineDesign(2), None, n, runs, 5, "count", 0.01, "two-sided", 2 * n
    )
    sim = np.mean((counts <= lo) | (counts >= hi))
    p = fa.detection_probability(0.5, 2, None, n, 0.01, true_channel=truth)
    assert abs(sim - p) < 4 * np.sqrt(p * (1 - p) / runs) + 1e-4


def test_an_iid_sensor_on_a_bursty_channel_against_the_monte_carlo():
    """From the paper's initial condition (fa.simulate's runs), so the law starts there too."""
    n, runs = 1000, 6000
    design = fa.OnlineDesign(2)
    res = fa.simulate(fa.LinearSystem(**PAPER), GE, design, n, runs, seed=2, record_runs=True, progress=False)
    lo, hi = count_alarm_bounds(0.5, 2, n, 0.01, "two-sided")
    counts = res.delivered_per_run
    sim = np.mean((counts <= lo) | (counts >= hi))
    law = fa.flag_process(GE, design).count_law(n, start="initial")
    c = np.arange(len(law))
    exact = float(law[(c <= lo) | (c >= hi)].sum())
    assert abs(sim - exact) < 4 * np.sqrt(exact * (1 - exact) / runs)
    # In the stationary regime the false-alarm rate of the i.i.d. sensor is far above alpha, and a
    # sensor that knows the channel keeps it at alpha.
    assert fa.detection_probability(0.5, 2, None, n, 0.01, true_channel=GE) > 0.5
    assert fa.detection_probability(GE, 2, None, n, 0.01) < 0.012


def test_a_lam_range_keeps_every_false_alarm_rate_at_most_alpha():
    span = (0.45, 0.55)
    for truth in np.linspace(*span, 5):
        p = fa.detection_probability(0.5, 2, None, 3000, 0.01, lam_range=span, true_channel=float(truth))
        assert p <= 0.01 * (1 + 1e-6) + 1e-12
    # It alarms only where the test of every lam of the range does: within each one's region.
    lo, hi = fa.detection.belief.belief_bounds(
        fa.BernoulliChannel(0.5), fa.OnlineDesign(2), 3000, 0.01, "two-sided", span
    )
    for lam in np.linspace(*span, 9):
        a, b = count_alarm_bounds(float(lam), 2, 3000, 0.01, "two-sided")
        assert lo <= a and hi >= b


def test_random_blocking_at_z0_1_cannot_be_told_from_a_better_channel():
    """At z0 = 1 RandomBlocking(beta) on lam delivers the flags of the unattacked lam' = 1 - (1 -
    lam)(1 - beta): a sensor whose range holds lam' has power at most alpha against it."""
    lam, beta = 0.5, 0.2
    twin = 1 - (1 - lam) * (1 - beta)
    p = fa.detection_probability(lam, 1, fa.RandomBlocking(beta), 3000, 0.01, lam_range=(lam, twin))
    assert p <= 0.01 * (1 + 1e-6)
    assert fa.detection_probability(lam, 1, fa.RandomBlocking(beta), 3000, 0.01) > 0.99


def test_mimicry_is_seen_only_at_the_false_alarm_rate():
    """Under a Markov channel both go through the flag process: equal. On the paper's channel the
    attack-free rate uses the renewal moments and mimicry the process's exact window moments, two
    normal approximations of the same law: equal to 0.5%."""
    free = fa.detection_probability(GE, 2, None, 1000, 0.01)
    assert fa.detection_probability(GE, 2, fa.MimicryAttack(), 1000, 0.01) == pytest.approx(free, rel=1e-9)
    free = fa.detection_probability(0.5, 2, None, 1000, 0.01)
    mimic = fa.detection_probability(0.5, 2, fa.MimicryAttack(), 1000, 0.01, true_channel=0.5)
    assert mimic == pytest.approx(free, rel=5e-3)


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match="lam_range"):
        fa.detection_probability(0.5, 2, None, 1000, 0.01, lam_range=(0.6, 0.4))
    with pytest.raises(TypeError, match="lam_range must be a pair"):
        fa.detection_probability(0.5, 2, None, 1000, 0.01, lam_range=0.5)
    with pytest.raises(ValueError, match="only the count and support tests"):
        fa.detection_probability(0.5, 2, None, 1000, 0.01, test="interval", lam_range=(0.48, 0.5))
    with pytest.raises(ValueError, match="beta_bar"):
        fa.detection_probability(GE, 2, None, 1000, 0.01, beta_bar=0.3)
    with pytest.raises(ValueError, match="true_channel"):
        fa.detection_probability(0.5, 2, None, 1000, 0.01, true_channel=1.5)
    with pytest.raises(TypeError, match="give either channel or lam"):
        fa.detection_probability(0.5, 2, None, 1000, 0.01, lam=0.5)
    assert fa.detection_probability(lam=0.5, z0=2, attack=None, n_steps=1000, alpha=0.01) == pytest.approx(
        fa.detection_probability(0.5, 2, None, 1000, 0.01)
    )


def test_detect_attack_with_a_lam_range_alarms_exactly_on_the_range_region():
    span, n = (0.45, 0.55), 3000
    lo, hi = fa.detection.belief.belief_bounds(
        fa.BernoulliChannel(0.5), fa.OnlineDesign(2), n, 0.01, "two-sided", span
    )
    for d in (lo - 3, lo, lo + 1, hi - 1, hi, hi + 3):
        det = fa.detect_attack(d, n, 0.5, 2, alternative="two-sided", lam_range=span)
        assert det.attack_detected == (d <= lo or d >= hi), d
        plain = fa.detect_attack(d, n, 0.5, 2, alternative="two-sided")
        assert det.p_value >= plain.p_value and det.z_score == plain.z_score
    with pytest.raises(ValueError, match="lam_range"):
        fa.detect_attack(400, n, 0.5, 2, lam_range=(0.55, 0.45))


def _renewal_gaps(lam, z0, n, rng):
    """The gaps of one window of n steps of the attack-free flag process, drawn from the exact
    gap law (the first gap reaches back before the window)."""
    law = fa.flag_interval_law(lam, z0)
    lengths = np.arange(1, len(law.pmf) + 1)
    draws = rng.choice(lengths, size=n, p=law.pmf / law.pmf.sum())
    return draws[: int(np.searchsorted(np.cumsum(draws), n, side="right"))]


def test_the_interval_test_over_a_lam_range_alarms_only_where_every_lam_does():
    rng = np.random.default_rng(5)
    span = (0.45, 0.55)
    grid = np.linspace(*span, 9)
    seen = set()
    for true_lam in (0.5, 0.4, 0.3):
        for _ in range(15):
            gaps = _renewal_gaps(true_lam, 2, 1000, rng)
            ranged = fa.detect_intervals(gaps, 1000, 0.5, 2, lam_range=span)
            each = [fa.detect_intervals(gaps, 1000, float(x), 2) for x in grid]
            assert ranged.attack_detected == all(d.attack_detected for d in each)
            assert ranged.p_value == pytest.approx(max(d.p_value for d in each))
            assert ranged.p_value >= fa.detect_intervals(gaps, 1000, 0.5, 2).p_value
            seen.add(ranged.attack_detected)
    assert seen == {True, False}  # both outcomes occur, so the check has teeth
    with pytest.raises(ValueError, match="lam_range"):
        fa.detect_intervals(gaps, 1000, 0.5, 2, lam_range=(0.6, 0.4))
