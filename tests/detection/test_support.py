"""The support check (test="support"): an alarm at any gap between delivered flag-ACKs shorter than
the attack-free minimum. Its alarm probability against a Monte Carlo of the protocol written from
its description; exactly 0 without attack and against every attack that never produces such a gap
(blocking, mimicry, the forger with min_gap = z0 + 1)."""

import numpy as np
import pytest

import fakeack as fa

GE_BELIEF = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)


def protocol_short_gap_rate(lam, z0, gamma, beta, n, runs, burn, seed):
    """Windows of n steps after a burn-in: the fraction with a delivered flag-ACK fewer than
    z0 + 1 steps after the previous one (which may fall before the window). The protocol: a
    high-power packet (after a delivered flag) always arrives, a low one with probability lam; a
    loss adds one to the zero count, an arrival resets it; at z0 a flag is sent and the memory
    restarts; the attacker blocks a genuine flag with probability beta and forges one with
    probability gamma on a step without a genuine flag."""
    short, _ = protocol_window_counts(lam, z0, gamma, beta, n, runs, burn, seed)
    return short.mean()


@pytest.mark.parametrize(("gamma", "beta"), [(0.05, 0.0), (0.036465, 0.2)])
def test_the_short_gap_probability_is_the_protocols(gamma, beta):
    n, runs = 30, 100_000
    attack = fa.FlagInjection(gamma, block=fa.RandomBlocking(beta)) if beta else fa.FlagInjection(gamma)
    p = fa.detection_probability(0.5, 2, attack, n, 0.01, test="support")
    sim = protocol_short_gap_rate(0.5, 2, gamma, beta, n, runs, 300, seed=7)
    assert abs(sim - p) < 4 * np.sqrt(p * (1 - p) / runs)


@pytest.mark.parametrize(
    "attack",
    [
        None,
        fa.PeriodicBlocking(1, 5),
        fa.RandomBlocking(0.3),
        fa.MimicryAttack(),
        fa.FlagInjection(0.2, min_gap=3),
    ],
    ids=str,
)
def test_attacks_without_impossible_gaps_are_never_seen_by_it(attack):
    assert fa.detection_probability(0.5, 2, attack, 1000, 0.01, test="support") == 0.0


def test_the_naive_forger_and_its_rate_matching_are_seen_almost_surely():
    """At beta = 0.2 rate matching keeps the count's mean (the count test's power stays near
    alpha) but forges on any quiet step; the careful version (min_gap = z0 + 1) is not seen."""
    naive = fa.rate_matching_attack(0.5, 2, 0.2)
    careful = fa.rate_matching_attack(0.5, 2, 0.2, min_gap=3)
    assert fa.detection_probability(0.5, 2, naive, 1000, 0.01, test="support") > 0.9999
    assert fa.detection_probability(0.5, 2, careful, 1000, 0.01, test="support") == 0.0


def test_the_attack_free_minimum_gap():
    for z0, mu in [(1, 1.0), (2, 1.0), (3, 0.5), (2, 0.0)]:
        expect = z0 + 1 if mu > 0 else z0 + 2  # mu = 0: the flag goes out at z0 + 1 losses
        assert fa.flag_process(0.5, fa.OnlineDesign(z0, mu)).min_gap == expect
    # A high-power packet that can be lost shortens it: a flag at once after a lost one (z0 = 1).
    leaky = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2, high_bad=0.5)
    assert fa.flag_process(leaky, fa.OnlineDesign(1)).min_gap == 1
    assert fa.flag_process(0.5, fa.OnlineDesign(2), fa.FlagInjection(0.1)).min_gap == 1


@pytest.mark.parametrize("beta_bar", [0.1, 0.3])
def test_the_harmful_rule_reads_the_count_of_a_window_with_a_short_gap(beta_bar):
    """A short gap triggers the fall-back under the harmful rule only in a window whose estimated
    budget exceeds beta_bar, as in the closed loop: P(short gap, estimate_beta(N) > beta_bar),
    against the protocol's windows."""
    runs = 100_000
    attack = fa.FlagInjection(0.002, block=fa.RandomBlocking(0.3))
    p = fa.detection_probability(0.5, 2, attack, 200, 0.01, test="support", beta_bar=beta_bar)
    short, count = protocol_window_counts(0.5, 2, 0.002, 0.3, 200, runs, 300, seed=5)
    estimate = np.array([fa.estimate_beta(c, 200, 0.5, 2) for c in range(201)])
    sim = np.mean(short & (estimate[count] > beta_bar))
    assert 0.01 < p < fa.detection_probability(0.5, 2, attack, 200, 0.01, test="support") - 0.01
    assert abs(sim - p) < 4 * np.sqrt(p * (1 - p) / runs), (sim, p)
    with pytest.raises(ValueError, match="beta_bar: the harmful rule is computed on the paper's"):
        fa.detection_probability(GE_BELIEF, 2, attack, 200, 0.01, test="support", beta_bar=beta_bar)


def test_the_one_shot_tests_apply_it_to_the_gaps_they_are_given():
    rng = np.random.default_rng(0)
    law = fa.flag_interval_law(0.5, 2)
    lengths = np.arange(1, len(law.pmf) + 1)
    clean = rng.choice(lengths, size=140, p=law.pmf / law.pmf.sum())
    assert clean.min() >= 3  # the attack-free law has no mass below z0 + 1
    forged = np.concatenate([clean[:-1], [1]])
    d = fa.detect_attack(len(clean), 1000, 0.5, 2, gaps=clean)
    assert d.short_gap is False and not d.attack_detected
    d = fa.detect_attack(len(forged), 1000, 0.5, 2, gaps=forged)
    assert d.short_gap is True and d.attack_detected
    assert not fa.detect_attack(len(forged), 1000, 0.5, 2, gaps=forged, support=False).attack_detected
    assert fa.detect_attack(140, 1000, 0.5, 2).short_gap is None
    assert fa.detect_intervals(forged, 1000, 0.5, 2).short_gap
    assert not fa.detect_intervals(forged, 1000, 0.5, 2, support=False).short_gap
    # mu = 0: the memory is z0 + 1, so a gap of z0 + 1 is already impossible.
    assert fa.detect_attack(10, 1000, 0.5, 2, mu=0.0, gaps=[3, 5]).short_gap
    with pytest.raises(ValueError, match="gaps must be positive integers"):
        fa.detect_attack(2, 1000, 0.5, 2, gaps=[0, 4])


def test_the_careful_rate_matching_forger_is_unseen_by_every_test():
    """min_gap = z0 + 1 keeps every gap possible and the count's mean: the count test's power
    stays at alpha, the support check's at 0, and the interval test's, from the flag process's
    bin moments (tests/detection/test_gap_bins.py), near alpha too."""
    careful = fa.rate_matching_attack(0.5, 2, 0.2, min_gap=3)
    assert fa.detection_probability(0.5, 2, careful, 1000, 0.01, test="support") == 0.0
    assert fa.detection_probability(0.5, 2, careful, 1000, 0.01) == pytest.approx(0.01, abs=0.002)
    assert fa.detection_probability(0.5, 2, careful, 1000, 0.01, "interval") == pytest.approx(0.01, abs=0.002)


def protocol_window_counts(lam, z0, gamma, beta, n, runs, burn, seed):
    """As :func:`protocol_short_gap_rate`, also returning each window's count of delivered
    flag-ACKs (forged ones included: the sensor cannot tell them apart)."""
    rng = np.random.default_rng(seed)
    high = np.ones(runs, bool)
    z = np.zeros(runs, int)
    age = np.full(runs, 10**9)
    short = np.zeros(runs, bool)
    count = np.zeros(runs, int)
    for k in range(burn + n):
        arrive = high | (rng.random(runs) < lam)
        z = np.where(arrive, 0, z + 1)
        flag = ~arrive & (z >= z0)
        z = np.where(flag, 0, z)
        deliver = (flag & (rng.random(runs) >= beta)) | (~flag & (rng.random(runs) < gamma))
        age += 1
        if k >= burn:
            short |= deliver & (age < z0 + 1)
            count += deliver
        age = np.where(deliver, 0, age)
        high = deliver
    return short, count


@pytest.mark.parametrize(
    ("gamma", "beta", "n", "alternative"),
    [(0.002, 0.0, 200, "two-sided"), (0.01, 0.2, 200, "less"), (0.0004, 0.1, 1000, "two-sided")],
)
def test_the_count_test_with_the_support_check_is_the_protocols(gamma, beta, n, alternative):
    """support=True (the default): the window alarms if either alarms, computed exactly from the
    joint law of short gaps and the count; against windows of the protocol with the count test's
    own alarm region."""
    runs = 100_000
    attack = fa.FlagInjection(gamma, block=fa.RandomBlocking(beta)) if beta else fa.FlagInjection(gamma)
    p = fa.detection_probability(0.5, 2, attack, n, 0.01, alternative=alternative)
    alone = fa.detection_probability(0.5, 2, attack, n, 0.01, alternative=alternative, support=False)
    p_s = fa.detection_probability(0.5, 2, attack, n, 0.01, test="support")
    lo, hi = fa.detection.count_alarm_bounds(0.5, 2, n, 0.01, alternative)
    short, count = protocol_window_counts(0.5, 2, gamma, beta, n, runs, 300, seed=11)
    sim = np.mean(short | (count <= lo) | (count >= hi))
    assert 0.05 < p_s < 0.95 and p > max(p_s, alone) + 0.003  # both parts matter here
    assert abs(sim - p) < 4 * np.sqrt(p * (1 - p) / runs), (sim, p)


def test_without_forgery_the_support_check_changes_nothing():
    for attack in [None, fa.PeriodicBlocking(1, 5), fa.RandomBlocking(0.3), fa.FlagInjection(0.1, min_gap=3)]:
        for test in ["count"] + (["interval"] if not isinstance(attack, fa.FlagInjection) else []):
            on = fa.detection_probability(0.5, 2, attack, 1000, 0.01, test=test)
            assert on == fa.detection_probability(0.5, 2, attack, 1000, 0.01, test=test, support=False)


def test_the_interval_test_with_the_support_check():
    """P(short gap) + P(no short gap) P_h(X² > c): between the two parts' larger and their sum, and
    sure against a forger seen surely (the protocol check is in tests/detection/test_gap_bins.py)."""
    attack = fa.FlagInjection(0.0004)
    p_s = fa.detection_probability(0.5, 2, attack, 1000, 0.01, test="support")
    p_x = fa.detection_probability(0.5, 2, attack, 1000, 0.01, test="interval", support=False)
    p = fa.detection_probability(0.5, 2, attack, 1000, 0.01, test="interval")
    assert max(p_s, p_x) < p <= p_s + p_x
    assert fa.detection_probability(0.5, 2, fa.FlagInjection(0.2), 1000, 0.01, test="interval") > 1 - 1e-9
    with pytest.raises(TypeError, match="support must be True or False"):
        fa.detection_probability(0.5, 2, attack, 1000, 0.01, support=1)


def test_the_harmful_rule_with_the_support_check():
    """P(alarm and N <= harm): at a harm bound above every count it is the plain combination, and
    it never exceeds it."""
    attack = fa.FlagInjection(0.002)
    p = fa.detection_probability(0.5, 2, attack, 200, 0.01)
    high = fa.detection_probability(0.5, 2, attack, 200, 0.01, beta_bar=-10.0)
    low = fa.detection_probability(0.5, 2, attack, 200, 0.01, beta_bar=0.5)
    assert high == pytest.approx(p, abs=1e-12)
    assert 0.0 <= low < p


# ---------------------------------------------------------------------------------------------
# The support check in the simulated windows (detection_rates, the closed-loop kernel).


@pytest.mark.parametrize(("gamma", "n"), [(0.0005, 1000), (0.002, 200), (0.002, 1000)])
def test_simulated_support_alarms_are_the_short_gap_probability(gamma, n):
    """test="support": the check alone, on stationary windows (a burn-in of three windows),
    against the flag process's exact recursion and detection_probability."""
    runs = 8000
    attack = fa.FlagInjection(gamma)
    r = fa.detection_rates(0.5, 2, attack, n, runs, seed=3, test="support", burn_in=3 * n)
    exact = fa.flag_process(0.5, fa.OnlineDesign(2), attack).short_gap_probability(n, 3)
    assert exact == pytest.approx(fa.detection_probability(0.5, 2, attack, n, 0.01, test="support"), rel=1e-9)
    assert 0.05 < exact < 0.95
    assert abs(r.detection - exact) < 4 * np.sqrt(exact * (1 - exact) / runs), (r.detection, exact)
    assert r.false_alarm == 0.0 and (r.test, r.alternative, r.support) == ("support", "two-sided", True)


def test_a_window_alarms_when_its_test_or_the_check_does():
    """Same seed, same windows: the alarms with the check are those of the test alone or of the
    check alone, window by window."""
    from fakeack.detection.rates import simulate_windows

    design, attack, n = fa.OnlineDesign(2), fa.FlagInjection(0.002), 1000
    args = (0.5, design, attack, n, 2000, 11)
    for test in ("count", "interval"):
        both, counts = simulate_windows(*args, test, 0.05, "two-sided", n)
        alone, counts_alone = simulate_windows(*args, test, 0.05, "two-sided", n, support=False)
        check, _ = simulate_windows(*args, "support", 0.05, "two-sided", n)
        assert np.array_equal(both, np.maximum(alone, check)) and np.array_equal(counts, counts_alone)
        assert 0 < alone.sum() and 0 < check.sum() and both.sum() > max(alone.sum(), check.sum())


def test_the_gap_across_the_windows_start_counts():
    """gamma = 1 delivers a flag-ACK on every step: a window of one step holds one flag-ACK, whose
    gap (1) reaches back into the previous window, or to the run's start (step 0)."""
    for burn_in in (0, 5):
        r = fa.detection_rates(0.5, 2, fa.FlagInjection(1.0), 1, 100, seed=1, test="support", burn_in=burn_in)
        assert r.detection == 1.0
        s = fa.detection_rates(0.5, 2, fa.FlagInjection(1.0), 1, 100, seed=1, burn_in=burn_in, support=False)
        assert s.detection == 0.0 and not s.support  # one flag-ACK is not below the count's bound


def test_detection_rates_arguments_for_the_check():
    with pytest.raises(ValueError, match="support: test='support' includes the support check"):
        fa.detection_rates(0.5, 2, fa.FlagInjection(0.1), 100, 10, test="support", support=False)
    with pytest.raises(ValueError, match="alternative: the support test is two-sided"):
        fa.detection_rates(0.5, 2, fa.FlagInjection(0.1), 100, 10, test="support", alternative="less")


@pytest.mark.parametrize("test", ["count", "support"])
def test_the_closed_loop_confirms_the_combined_detection_probability(test):
    """detection_rates with the check beside the count test (the defaults on both sides) against
    the exact joint law, within 4 standard errors."""
    attack, n, runs = fa.FlagInjection(0.002), 200, 20_000
    p = fa.detection_probability(0.5, 2, attack, n, 0.01, test=test)
    r = fa.detection_rates(0.5, 2, attack, n, runs, seed=9, alternative="two-sided", test=test, burn_in=3 * n)
    assert 0.05 < p < 0.95
    assert abs(r.detection - p) < 4 * np.sqrt(p * (1 - p) / runs), (r.detection, p)
