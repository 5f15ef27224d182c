"""The window's likelihood-ratio test: its law against a simulation of the protocol written from
its description, its mean against the renewal formula of the gap laws, mimicry at the false-alarm
rate, the Neyman-Pearson property against the count test, and the errors."""

import math

import numpy as np
import pytest

import fakeack as fa
from fakeack.detection import likelihood_ratio_law, likelihood_ratio_test

DESIGN = fa.OnlineDesign(2)
ALT = fa.RandomBlocking(0.2)


def survival_of(pmf):
    """S(y) = P(G >= y), y = 1..len, summed from the tail (no cancellation far out)."""
    return np.cumsum(pmf[::-1])[::-1]


def opening_of(y, null_pmf, alt_pmf):
    """log(P_a(y0) / P_0(y0)) with P(y0 = y) = S(y) / m: the stationary age laws of the gap walk."""
    s0, sa = survival_of(null_pmf), survival_of(alt_pmf)
    m0 = float(np.arange(1, null_pmf.size + 1) @ null_pmf)
    ma = float(np.arange(1, alt_pmf.size + 1) @ alt_pmf)
    return np.log(sa[y - 1] / ma) - np.log(s0[y - 1] / m0)


def simulate_windows(attack_of, n, runs, seed, burn_in=300):
    """The statistic of a window of n steps after a burn-in, over the protocol written from its
    description: a high-power packet (after a delivered flag) always arrives, a low one with
    probability 1/2; a loss adds one to the zero count, an arrival resets it; at z0 = 2 a flag is
    sent and the count restarts. attack_of(flag, y, rng) says which flags reach the sensor. The
    window's statistic opens with the log-likelihood ratio of the running gap's age y0 (from the
    gap walk's pmfs) and adds inc.flag or inc.quiet at each step's gap y (capped at the tables'
    length). Returns the statistics and the first window's (delivered, y0) for a spot check."""
    inc = fa.CusumTest(ALT, 1.0).increments(0.5, DESIGN)
    Y = inc.length
    pmf0, pmfa = fa.flag_interval_law(0.5, 2).pmf, fa.flag_interval_law(0.5, 2, ALT).pmf
    rng = np.random.default_rng(seed)
    high = np.ones(runs, bool)
    z = np.zeros(runs, int)
    y = np.ones(runs, int)
    stat = np.zeros(runs)
    first = []
    for k in range(burn_in + n):
        if k == burn_in:
            assert y.max() <= pmf0.size
            stat = opening_of(y, pmf0, pmfa)
            y0 = int(y[0])
        arrive = high | (rng.random(runs) < 0.5)
        z = np.where(arrive, 0, z + 1)
        flag = ~arrive & (z >= 2)
        z = np.where(flag, 0, z)
        deliver = attack_of(flag, y, rng)
        if k >= burn_in:
            step = np.where(deliver, inc.flag[np.minimum(y, Y) - 1], inc.quiet[np.minimum(y, Y) - 1])
            stat = stat + step
            first.append(bool(deliver[0]))
        y = np.where(deliver, 1, y + 1)
        high = deliver
    return stat, (np.array(first), y0)


def none():
    return lambda flag, y, rng: flag


def blocking(beta):
    return lambda flag, y, rng: flag & (rng.random(flag.size) >= beta)


def careful_forger(gamma, min_gap):
    return lambda flag, y, rng: flag | (~flag & (y >= min_gap) & (rng.random(flag.size) < gamma))


@pytest.mark.parametrize(
    ("attack", "attack_of"),
    [
        (None, none()),
        (fa.RandomBlocking(0.2), blocking(0.2)),
        (fa.FlagInjection(0.02, min_gap=3), careful_forger(0.02, 3)),
    ],
    ids=["none", "random:0.2", "careful forger"],
)
def test_the_law_is_the_protocols(attack, attack_of):
    n, runs = 150, 40_000
    stat, (delivered, y0) = simulate_windows(attack_of, n, runs, seed=7)
    law = likelihood_ratio_law(0.5, 2, n, attack)
    coarse = likelihood_ratio_law(0.5, 2, n, attack, resolution=4.0)
    assert stat.mean() == pytest.approx(law.mean, abs=4 * stat.std() / math.sqrt(runs))
    for q in (0.1, 0.5, 0.9, 0.99):
        c = float(np.quantile(stat, q))
        mc = float(np.mean(stat >= c))
        se = math.sqrt(mc * (1 - mc) / runs)
        exact, grid_error = law.tail(c), abs(law.tail(c) - coarse.tail(c))
        assert abs(mc - exact) < 4 * se + grid_error, (q, c, mc, exact, se, grid_error)
    # The test's own statistic of one simulated window is the simulation's.
    test = likelihood_ratio_test(0.5, 2, n)
    assert test.statistic(delivered, y0) == pytest.approx(stat[0], abs=1e-9)


@pytest.mark.parametrize("attack", [None, fa.RandomBlocking(0.2)], ids=str)
def test_the_mean_is_the_renewal_formula(attack):
    """E Lambda_n = E[opening] + n E[increment], both from the stationary age law S(y)/m of the
    truth's gap walk: a step at age y delivers with probability pmf(y)/S(y)."""
    n = 400
    inc = fa.CusumTest(ALT, 1.0).increments(0.5, DESIGN)
    pmf = fa.flag_interval_law(0.5, 2, attack).pmf
    pmf0, pmfa = fa.flag_interval_law(0.5, 2).pmf, fa.flag_interval_law(0.5, 2, ALT).pmf
    y = np.arange(1, pmf.size + 1)
    s = survival_of(pmf)
    m = float(y @ pmf)
    Y = inc.length
    f, q = inc.flag[np.minimum(y, Y) - 1], inc.quiet[np.minimum(y, Y) - 1]
    delivered = np.where(pmf > 0, pmf * np.where(pmf > 0, f, 0.0), 0.0)
    silent = np.concatenate((s[1:], [0.0])) * q
    per_step = float((delivered + silent).sum()) / m
    opening = float((s / m) @ opening_of(y, pmf0, pmfa))
    law = likelihood_ratio_law(0.5, 2, n, attack)
    grid_mean = float(law.values @ law.probability)
    assert law.alarm == 0.0 and law.above + law.below < 1e-12
    assert grid_mean == pytest.approx(opening + n * per_step, rel=1e-9, abs=1e-9)
    assert law.mean == pytest.approx(opening + n * per_step, rel=1e-9, abs=1e-9)


def test_mimicry_is_seen_at_the_false_alarm_rate():
    test = likelihood_ratio_test(0.5, 2, 300, 0.01)
    assert test.alpha_reached == pytest.approx(0.01, abs=1e-12)
    assert test.detection_probability(fa.MimicryAttack()) == pytest.approx(0.01, abs=1e-9)
    assert fa.detection_probability(0.5, 2, fa.MimicryAttack(), 300, 0.01, "lr") == pytest.approx(
        0.01, abs=1e-9
    )


def randomised_count_power(n, alpha, attack):
    """The most powerful count test against blocking (few flag-ACKs alarm), randomised at the atom
    to level alpha exactly, from the exact count laws of the flag process."""
    null = np.cumsum(fa.flag_process(0.5, DESIGN).count_law(n))
    alt = np.cumsum(fa.flag_process(0.5, DESIGN, attack).count_law(n))
    k = int(np.flatnonzero(null <= alpha)[-1])  # alarm surely at N <= k, with probability r at k + 1
    r = (alpha - null[k]) / (null[k + 1] - null[k])
    return float(alt[k] + r * (alt[k + 1] - alt[k]))


def test_the_lr_test_is_at_least_as_powerful_as_the_count_test():
    n, alpha = 600, 0.01
    test = likelihood_ratio_test(0.5, 2, n, alpha)
    lr = fa.detection_probability(0.5, 2, ALT, n, alpha, "lr")
    coarse = likelihood_ratio_law(0.5, 2, n, ALT, resolution=4.0).tail(test.critical)
    count = randomised_count_power(n, alpha, ALT)
    assert lr + abs(lr - coarse) >= count, (lr, coarse, count)
    assert lr >= fa.detection_probability(0.5, 2, ALT, n, alpha, "count")


def test_a_forger_below_the_attack_free_minimum_alarms_through_the_support_check():
    law = likelihood_ratio_law(0.5, 2, 200, fa.FlagInjection(0.05))
    short = fa.detection_probability(0.5, 2, fa.FlagInjection(0.05), 200, 0.01, "support")
    assert law.alarm == pytest.approx(short, rel=1e-9)


def test_the_law_keeps_its_mass():
    law = likelihood_ratio_law(0.5, 2, 100, fa.PeriodicBlocking(1, 5))
    total = law.probability.sum() + law.alarm + law.minus_infinity + law.above + law.below
    assert total == pytest.approx(1.0, abs=1e-12)


def test_a_gap_pmf_alternative_sends_longer_gaps_to_minus_infinity():
    """Gaps of 3 or 4 steps only: a window holding a longer gap (or opening in one) has
    Lambda = -inf under any law, so P(-inf) is at least P(the running gap passes 4 steps within
    the first step): the attack-free stationary age law beyond 4, S(y)/m summed over y >= 5."""
    pmf = fa.flag_interval_law(0.5, 2).pmf
    s = np.cumsum(pmf[::-1])[::-1]
    m = float(np.arange(1, pmf.size + 1) @ pmf)
    law = likelihood_ratio_law(0.5, 2, 50, alternative=[0, 0, 0.5, 0.5])
    assert law.minus_infinity >= float(s[4:].sum()) / m
    assert law.probability.sum() + law.alarm + law.minus_infinity == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="^alternative"):
        likelihood_ratio_test(0.5, 2, 50, alternative=fa.RandomBlocking(0.0))


def test_the_curves_take_the_lr_test():
    curves = fa.detection_curves(0.5, 2, [None, fa.MimicryAttack()], [150], tests=["lr", "count"])
    np.testing.assert_allclose(curves.probability[0, :, 0], 0.01, atol=1e-9)
    with pytest.raises(ValueError, match="^tests"):
        fa.detection_curves(0.5, 2, [None], [150], tests=["likelihood"])


@pytest.mark.parametrize(
    ("kwargs", "error", "name"),
    [
        ({"alpha": 1.5}, ValueError, "alpha"),
        ({"n_steps": 0}, ValueError, "n_steps"),
        ({"alternative": "blocking"}, TypeError, "alternative"),
        ({"z0": 0}, ValueError, "z0"),
        ({"channel": 1.5}, ValueError, "channel"),
    ],
)
def test_bad_arguments_are_named(kwargs, error, name):
    args = {"channel": 0.5, "z0": 2, "n_steps": 100, "alpha": 0.01} | kwargs
    with pytest.raises(error, match=f"^{name}"):
        likelihood_ratio_test(**args)


def test_bad_arguments_of_the_law_and_the_detection_probability_are_named():
    with pytest.raises(ValueError, match="^resolution"):
        likelihood_ratio_law(0.5, 2, 100, resolution=0.0)
    with pytest.raises(ValueError, match="^n_steps"):
        likelihood_ratio_law(0.5, 2, 10**7)  # past the work bound, refused before allocating
    with pytest.raises(ValueError, match="^lr_alternative"):
        fa.detection_probability(0.5, 2, None, 100, 0.01, "count", lr_alternative=ALT)
    with pytest.raises(ValueError, match="^beta_bar"):
        fa.detection_probability(0.5, 2, None, 100, 0.01, "lr", beta_bar=0.1)
    with pytest.raises(ValueError, match="^support"):
        fa.detection_probability(0.5, 2, None, 100, 0.01, "lr", support=False)
    with pytest.raises(ValueError, match="^alternative"):
        fa.detection_probability(0.5, 2, None, 100, 0.01, "lr", "less")
    test = likelihood_ratio_test(0.5, 2, 100)
    with pytest.raises(TypeError, match="^delivered"):
        test.statistic([1, 0], 3)
    with pytest.raises(ValueError, match="^gap"):
        test.statistic(np.zeros(100, bool), 0)
    with pytest.raises(ValueError, match="^delivered"):
        test.statistic(np.array([True]), 3)
