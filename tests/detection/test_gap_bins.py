"""The interval test's bin counts from the flag process (``fakeack.detection.gap_bins``): equal to
the Markov renewal moments of the gap walk wherever both apply (two derivations, one over steps,
one over gaps), the attack-free law under mimicry, and the careful forger's detection probability
against a simulation of the protocol written from its description."""

import numpy as np
import pytest

import fakeack as fa
from fakeack.detection.gap_bins import bin_rates
from fakeack.detection.intervals import design_walk

EDGES = np.array([1, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 18])


@pytest.mark.parametrize(
    ("z0", "mu", "attack"),
    [
        (2, 1.0, None),
        (2, 1.0, fa.PeriodicBlocking(1, 5)),
        (2, 1.0, fa.RandomBlocking(0.3)),
        (2, 1.0, fa.FlagInjection(0.02, fa.RandomBlocking(0.2))),
        (3, 0.4, fa.MaskBlocking([1, 0, 1, 0, 0])),
        (1, 1.0, fa.FlagInjection(0.1)),
    ],
    ids=str,
)
def test_the_bin_moments_are_the_gap_walks(z0, mu, attack):
    design = fa.OnlineDesign(z0, mu)
    w = design_walk(0.5, design, attack)
    p, sigma = w.time_covariance(EDGES)
    r, s = bin_rates(fa.flag_process(0.5, design, attack), EDGES)
    np.testing.assert_allclose(r, p / w.mean, atol=1e-14)
    np.testing.assert_allclose(s, sigma, atol=1e-14)


def test_mimicry_has_the_attack_free_bin_moments():
    design = fa.OnlineDesign(2)
    free = bin_rates(fa.flag_process(0.5, design), EDGES)
    mimic = bin_rates(fa.flag_process(0.5, design, fa.MimicryAttack()), EDGES)
    np.testing.assert_allclose(mimic[0], free[0], atol=1e-13)
    np.testing.assert_allclose(mimic[1], free[1], atol=1e-12)
    alone = fa.detection_probability(0.5, 2, fa.MimicryAttack(), 1000, 0.01, "interval", support=False)
    assert alone == pytest.approx(0.01, abs=1e-9)


def protocol_interval_alarms(lam, z0, gamma, beta, min_gap, test, runs, burn, seed):
    """Windows of the protocol after a burn-in: a high-power packet (after a delivered flag)
    always arrives, a low one with probability lam; a loss adds one to the zero count, an arrival
    resets it; at z0 a flag is sent and the count restarts; the attacker blocks a genuine flag
    with probability beta and, on a step without one, forges a flag with probability gamma if at
    least min_gap steps have passed since the last flag-ACK the sensor received. Each window's
    gaps (the first reaching back before it) go into the test's bins; the alarm is Pearson's
    statistic above the test's critical value."""
    rng = np.random.default_rng(seed)
    n = test.n_steps
    high = np.ones(runs, bool)
    z = np.zeros(runs, int)
    age = np.zeros(runs, int)
    counts = np.zeros((runs, len(test.edges)))
    for k in range(burn + n):
        arrive = high | (rng.random(runs) < lam)
        z = np.where(arrive, 0, z + 1)
        flag = ~arrive & (z >= z0)
        z = np.where(flag, 0, z)
        age += 1
        forge = ~flag & (age >= min_gap) & (rng.random(runs) < gamma)
        deliver = (flag & (rng.random(runs) >= beta)) | forge
        if k >= burn:
            b = np.searchsorted(test.edges, age, side="right") - 1
            np.add.at(counts, (np.flatnonzero(deliver), b[deliver]), 1.0)
        age = np.where(deliver, 0, age)
        high = deliver
    x2 = ((counts - test.expected) ** 2 / test.expected).sum(axis=1)
    return x2 > test.critical


@pytest.mark.parametrize(("gamma", "beta"), [(0.02, 0.2), (0.05, 0.0)])
def test_the_careful_forgers_interval_detection_is_the_protocols(gamma, beta):
    """A forger with min_gap = z0 + 1, which the support check never sees: the interval test's
    normal approximation on the flag process against 40,000 simulated windows of 1000 steps."""
    runs = 40_000
    attack = fa.FlagInjection(gamma, fa.RandomBlocking(beta) if beta else None, min_gap=3)
    p = fa.detection_probability(0.5, 2, attack, 1000, 0.01, "interval")
    assert p == fa.detection_probability(0.5, 2, attack, 1000, 0.01, "interval", support=False)
    test = fa.interval_test(0.5, 2, 1000, 0.01)
    sim = protocol_interval_alarms(0.5, 2, gamma, beta, 3, test, runs, 300, seed=3).mean()
    assert 0.03 < p < 0.97
    # The statistic's law is a normal approximation: 4 standard errors and 0.01 of it.
    assert abs(sim - p) < 4 * np.sqrt(p * (1 - p) / runs) + 0.01, (sim, p)


def test_the_interval_test_on_another_true_channel():
    """A sensor that believes lam = 0.5 on a channel of 0.48: the gap walk at 0.48 and the flag
    process route agree (two derivations), and both exceed the false-alarm rate."""
    believed = fa.detection_probability(0.5, 2, None, 1000, 0.01, "interval", true_channel=0.48)
    test = fa.interval_test(0.5, 2, 1000, 0.01)
    w = design_walk(0.48, fa.OnlineDesign(2), None)
    r_walk = w.time_covariance(test.edges)[0] / w.mean
    r_proc = bin_rates(fa.flag_process(0.48, fa.OnlineDesign(2)), test.edges)[0]
    np.testing.assert_allclose(r_proc, r_walk, atol=1e-14)
    assert 0.02 < believed < 0.1
    bursty = fa.GilbertElliott(0.1, 0.3, 0.6, 0.2)
    assert 0.0 < fa.detection_probability(0.5, 2, None, 1000, 0.01, "interval", true_channel=bursty) <= 1.0


def test_the_extended_chain_is_refused_beyond_its_size():
    process = fa.flag_process(0.5, fa.OnlineDesign(2))
    with pytest.raises(ValueError, match="edges: the interval test's bins"):
        bin_rates(process, np.array([1, 10**7]))


def test_the_bin_moments_on_a_bursty_channel_are_the_protocols():
    """On a Gilbert-Elliott channel successive gaps are correlated and the gap walk does not
    apply. Windows of the protocol written from its description (the channel moves after each
    step; a high-power packet always arrives, a low one with the state's probability) against
    the flag process's bin means n r and covariances n Sigma."""
    p, q, good, bad = 0.1, 0.3, 0.9, 0.2
    n, runs, burn = 2000, 20_000, 200
    edges = np.array([1, 4, 6, 9, 14])
    rng = np.random.default_rng(12)
    state = rng.random(runs) < p / (p + q)  # True: bad, from the stationary law
    high = np.ones(runs, bool)
    z = np.zeros(runs, int)
    age = np.zeros(runs, int)
    counts = np.zeros((runs, len(edges)))
    for k in range(burn + n):
        arrive = high | (rng.random(runs) < np.where(state, bad, good))
        z = np.where(arrive, 0, z + 1)
        flag = ~arrive & (z >= 2)
        z = np.where(flag, 0, z)
        age += 1
        if k >= burn:
            b = np.searchsorted(edges, age, side="right") - 1
            np.add.at(counts, (np.flatnonzero(flag), b[flag]), 1.0)
        age = np.where(flag, 0, age)
        high = flag
        state = np.where(state, rng.random(runs) >= q, rng.random(runs) < p)
    r, sigma = bin_rates(fa.flag_process(fa.GilbertElliott(p, q, good, bad), fa.OnlineDesign(2)), edges)
    mean, cov = counts.mean(axis=0), np.cov(counts.T)
    assert np.all(np.abs(mean - n * r) < 4 * np.sqrt(np.diag(cov) / runs) + 0.02), (mean, n * r)
    # Covariances: within 6% of the diagonal's scale (the window's edges add O(1) terms).
    scale = np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    assert np.all(np.abs(cov - n * sigma) < 0.06 * scale), (cov, n * sigma)


@pytest.mark.parametrize(("gamma", "beta"), [(0.02, 0.2), (0.05, 0.0)])
def test_the_closed_loop_confirms_the_careful_forgers_interval_detection(gamma, beta):
    """The closed-loop kernel plays the careful forger move by move (as an attacker automaton):
    20,000 windows against the flag process's normal approximation, within 4 standard errors and
    0.005 (the approximation's own error, as against the protocol simulation above)."""
    attack = fa.FlagInjection(gamma, fa.RandomBlocking(beta) if beta else None, min_gap=3)
    p = fa.detection_probability(0.5, 2, attack, 1000, 0.01, "interval")
    r = fa.detection_rates(0.5, 2, attack, 1000, 20_000, test="interval", alternative="two-sided")
    assert abs(r.detection - p) < 4 * r.detection_stderr + 0.005, (r.detection, r.detection_stderr, p)


def protocol_interval_and_short(lam, z0, gamma, beta, test, runs, burn, seed):
    """As :func:`protocol_interval_alarms` for the naive forger (min_gap = 1), also returning
    whether each window held a gap shorter than z0 + 1 (the support check)."""
    rng = np.random.default_rng(seed)
    high = np.ones(runs, bool)
    z = np.zeros(runs, int)
    age = np.zeros(runs, int)
    short = np.zeros(runs, bool)
    counts = np.zeros((runs, len(test.edges)))
    for k in range(burn + test.n_steps):
        arrive = high | (rng.random(runs) < lam)
        z = np.where(arrive, 0, z + 1)
        flag = ~arrive & (z >= z0)
        z = np.where(flag, 0, z)
        age += 1
        deliver = (flag & (rng.random(runs) >= beta)) | (~flag & (rng.random(runs) < gamma))
        if k >= burn:
            b = np.searchsorted(test.edges, age, side="right") - 1
            np.add.at(counts, (np.flatnonzero(deliver), b[deliver]), 1.0)
            short |= deliver & (age < z0 + 1)
        age = np.where(deliver, 0, age)
        high = deliver
    x2 = ((counts - test.expected) ** 2 / test.expected).sum(axis=1)
    return x2 > test.critical, short


def test_the_interval_test_with_the_support_check_is_the_protocols():
    """The combination P(short) + P(no short) P_h(X² > c) against 40,000 protocol windows: the
    whole and the conditional part, X² given no short gap (the Doob transform's bin moments),
    within 4 standard errors and 0.005 (the normal approximation's error)."""
    from fakeack.detection.gap_bins import conditioned_bin_rates

    runs = 40_000
    attack = fa.FlagInjection(0.001, fa.RandomBlocking(0.2))
    test = fa.interval_test(0.5, 2, 1000, 0.01)
    p = fa.detection_probability(0.5, 2, attack, 1000, 0.01, "interval")
    p_s = fa.detection_probability(0.5, 2, attack, 1000, 0.01, "support")
    alarm, short = protocol_interval_and_short(0.5, 2, 0.001, 0.2, test, runs, 300, seed=8)
    sim = np.mean(alarm | short)
    assert abs(sim - p) < 4 * np.sqrt(p * (1 - p) / runs) + 0.005, (sim, p)
    given = (p - p_s) / (1 - p_s)  # P_h(X² > c)
    sim_given = alarm[~short].mean()
    assert abs(sim_given - given) < 4 * np.sqrt(given * (1 - given) / (~short).sum()) + 0.005
    process = fa.flag_process(0.5, fa.OnlineDesign(2), attack)
    rho = conditioned_bin_rates(process, test.edges, 3)[2]
    assert rho**1000 == pytest.approx(1 - p_s, abs=0.01)  # the survival rate, asymptotically
