"""The flag-ACK CUSUM and its run lengths: the hazards against the gap walk's exact gap law, the
Brook-Evans chain against an integer CUSUM solved by hand, and the run lengths against a
simulation of the protocol written from its description."""

import math

import numpy as np
import pytest
import scipy.sparse as sp

import fakeack as fa
from fakeack.detection.cusum import CusumIncrements
from fakeack.detection.process import FlagProcess
from fakeack.detection.run_length import run_length_bounds

DESIGN = fa.OnlineDesign(2)


def hazards_of(pmf, n=40):
    """h(y) = P(G = y) / P(G >= y) for y = 1..n (the survival from the pmf's own sums)."""
    survival = 1.0 - np.concatenate(([0.0], np.cumsum(pmf[: n - 1])))
    return pmf[:n] / survival


@pytest.mark.parametrize(
    ("z0", "mu", "attack"),
    [
        (2, 1.0, None),
        (2, 1.0, fa.RandomBlocking(0.3)),
        (2, 1.0, fa.FlagInjection(0.02, fa.RandomBlocking(0.2))),
        (3, 0.4, fa.RandomBlocking(0.5)),
    ],
    ids=str,
)
def test_the_hazards_are_the_gap_laws(z0, mu, attack):
    design = fa.OnlineDesign(z0, mu)
    inc = fa.CusumTest(attack or fa.RandomBlocking(0.1), 1.0).increments(0.5, design)
    hazards = inc.ha if attack is not None else inc.h0
    hazards = np.concatenate((hazards, np.full(40, hazards[-1])))[:40]  # the last entry holds on
    law = fa.flag_interval_law(0.5, z0, attack, mu)
    expected = hazards_of(law.pmf)
    np.testing.assert_allclose(hazards, expected, atol=1e-11)


def test_the_increments_are_the_log_likelihood_ratios():
    inc = fa.CusumTest(fa.RandomBlocking(0.3), 1.0).increments(0.5, DESIGN)
    h0 = hazards_of(fa.flag_interval_law(0.5, 2).pmf)
    ha = hazards_of(fa.flag_interval_law(0.5, 2, fa.RandomBlocking(0.3)).pmf)
    y = np.arange(2, 30)  # gaps 3..30: both possible
    np.testing.assert_allclose(inc.flag[y], np.log(ha[y] / h0[y]), atol=1e-12)
    np.testing.assert_allclose(inc.quiet[y], np.log((1 - ha[y]) / (1 - h0[y])), atol=1e-12)
    # Gaps 1 and 2 are impossible without attack (z0 + 1 = 3): a flag there alarms at once.
    assert np.all(inc.flag[:2] == math.inf) and np.all(inc.quiet[:2] == 0.0)


def test_a_gap_pmf_alternative_ends_with_its_support():
    inc = fa.CusumTest([0.0, 0.0, 0.5, 0.5], 2.0).increments(0.5, DESIGN)
    h0 = hazards_of(fa.flag_interval_law(0.5, 2).pmf)
    assert inc.flag[2] == pytest.approx(math.log(0.5 / h0[2]))
    assert inc.flag[3] == pytest.approx(math.log(1.0 / h0[3]))
    assert inc.quiet[3] == -math.inf  # silence past gap 4 is impossible for the alternative
    assert np.all(inc.flag[4:] == -math.inf) and np.all(inc.quiet[4:] == -math.inf)


def integer_cusum_arl(p, up, down, h):
    """The CUSUM W <- max(0, W + up) on a flag (probability p each step, i.i.d.), max(0, W - down)
    otherwise, alarm at W >= h, all integers: the chain over W = 0..h-1 solved directly."""
    Q = np.zeros((h, h))
    for w in range(h):
        if w + up < h:
            Q[w, w + up] += p
        Q[w, max(0, w - down)] += 1 - p
    return np.linalg.solve(np.eye(h) - Q, np.ones(h))[0]


@pytest.mark.parametrize(("p", "up", "down", "h"), [(0.2, 2, 1, 5), (0.1, 3, 1, 7), (0.35, 1, 1, 4)])
@pytest.mark.parametrize("per_unit", [1, 4])
def test_the_chain_is_exact_on_an_integer_cusum(p, up, down, h, per_unit):
    """Constant hazards (one automaton state) make a Bernoulli CUSUM; with integer increments on
    a grid that holds the integers every rounding is exact."""
    one = np.ones(1)
    process = FlagProcess(
        fa.BernoulliChannel(0.5), DESIGN, None, p, 0.0,
        sp.csr_array([[1 - p]]), sp.csr_array([[p]]), one, one,
    )  # fmt: skip
    inc = CusumIncrements(np.array([float(up)]), np.array([-float(down)]), np.array([0.5]), np.array([0.5]))
    m = h * per_unit
    start = np.zeros(m)
    start[0] = 1.0
    expected = integer_cusum_arl(p, up, down, h)
    for rounding in ("split", "up", "down"):
        assert run_length_bounds(process, inc, float(h), start, m, rounding) == pytest.approx(
            expected, rel=1e-12
        )


def protocol_run_lengths(lam, z0, attack_of, inc, h, runs, seed, pre=0, channel=None):
    """Steps to the alarm of the CUSUM over the protocol written from its description: a
    high-power packet (after a delivered flag) always arrives, a low one with probability lam
    (per channel state: (p, q, good, bad) of a Gilbert-Elliott channel that moves after each
    step); a loss adds one to the zero count, an arrival resets it; at z0 a flag is sent and the
    count restarts. attack_of(flag, age, rng) says which flags reach the sensor. The statistic
    adds inc.flag or inc.quiet at the gap y (capped at the tables' length). With ``pre`` steps
    first without attack, the runs that alarm before the onset are dropped and the delay counts
    from the onset."""
    rng = np.random.default_rng(seed)
    Y = inc.length
    high = np.ones(runs, bool)
    z = np.zeros(runs, int)
    y = np.ones(runs, int)
    w = np.zeros(runs)
    alarm = np.full(runs, -1)
    dropped = np.zeros(runs, bool)
    bad = None if channel is None else rng.random(runs) < channel[0] / (channel[0] + channel[1])
    k = 0
    while ((alarm < 0) & ~dropped).any() and k < pre + 200_000:
        good_p = lam if channel is None else np.where(bad, channel[3], channel[2])
        arrive = high | (rng.random(runs) < good_p)
        z = np.where(arrive, 0, z + 1)
        flag = ~arrive & (z >= z0)
        z = np.where(flag, 0, z)
        deliver = flag if k < pre else attack_of(flag, y, rng)
        step = np.where(deliver, inc.flag[np.minimum(y, Y) - 1], inc.quiet[np.minimum(y, Y) - 1])
        with np.errstate(invalid="ignore"):
            w = np.maximum(0.0, w + step)
        new = (w >= h) & (alarm < 0) & ~dropped
        if k < pre:
            dropped |= new
        else:
            alarm[new] = k + 1 - pre
        y = np.where(deliver, 1, y + 1)
        high = deliver
        if channel is not None:
            bad = np.where(bad, rng.random(runs) >= channel[1], rng.random(runs) < channel[0])
        k += 1
    kept = alarm[~dropped]
    assert (kept > 0).all(), "some runs never alarmed"
    return kept.mean(), kept.std() / math.sqrt(kept.size)


def blocking(beta):
    return lambda flag, y, rng: flag & (rng.random(flag.size) >= beta)


def careful_forger(gamma, min_gap):
    return lambda flag, y, rng: flag | (~flag & (y >= min_gap) & (rng.random(flag.size) < gamma))


@pytest.mark.parametrize(
    ("attack", "attack_of"),
    [
        (None, blocking(0.0)),
        (fa.RandomBlocking(0.5), blocking(0.5)),
        (fa.FlagInjection(0.05, min_gap=3), careful_forger(0.05, 3)),
    ],
    ids=["none", "random:0.5", "careful forger"],
)
def test_the_run_lengths_are_the_protocols(attack, attack_of):
    test = fa.CusumTest(fa.RandomBlocking(0.5), 2.5)
    exact = fa.cusum_run_length(0.5, DESIGN, test, attack)
    mc, se = protocol_run_lengths(0.5, 2, attack_of, test.increments(0.5, DESIGN), 2.5, 20_000, 3)
    assert abs(mc - exact.mean) < 4 * se + exact.error, (mc, se, exact)
    assert exact.lower <= exact.mean <= exact.upper


def test_the_steady_state_delay_is_the_protocols():
    test = fa.CusumTest(fa.RandomBlocking(0.5), 2.5)
    exact = fa.cusum_run_length(0.5, DESIGN, test, fa.RandomBlocking(0.5), "stationary")
    renewal = fa.cusum_run_length(0.5, DESIGN, test, fa.RandomBlocking(0.5))
    mc, se = protocol_run_lengths(
        0.5, 2, blocking(0.5), test.increments(0.5, DESIGN), 2.5, 20_000, 4, pre=400
    )
    assert abs(mc - exact.mean) < 4 * se + exact.error, (mc, se, exact)
    assert exact.mean < renewal.mean  # the pre-change W is already above 0 on average


def test_the_run_length_on_a_bursty_channel_is_the_protocols():
    p, q, good, bad = 0.1, 0.3, 0.9, 0.2
    ge = fa.GilbertElliott(p, q, good, bad)
    test = fa.CusumTest(fa.RandomBlocking(0.5), 2.0)
    exact = fa.cusum_run_length(ge, DESIGN, test, fa.RandomBlocking(0.5))
    mc, se = protocol_run_lengths(
        None, 2, blocking(0.5), test.increments(ge, DESIGN), 2.0, 20_000, 5, channel=(p, q, good, bad)
    )
    assert abs(mc - exact.mean) < 4 * se + exact.error, (mc, se, exact)


def test_mimicry_is_seen_at_the_false_alarm_rate():
    test = fa.CusumTest(fa.RandomBlocking(0.3), 3.0)
    arl0 = fa.cusum_run_length(0.5, DESIGN, test)
    mimic = fa.cusum_run_length(0.5, DESIGN, test, fa.MimicryAttack())
    assert mimic.mean == pytest.approx(arl0.mean, rel=1e-10)


def test_authenticated_flags_leave_only_the_blocking():
    test = fa.CusumTest(fa.RandomBlocking(0.3), 3.0)
    forger = fa.FlagInjection(0.05, fa.RandomBlocking(0.3))
    auth = fa.cusum_run_length(0.5, DESIGN, test, forger, authenticated=True)
    assert auth.mean == pytest.approx(fa.cusum_run_length(0.5, DESIGN, test, fa.RandomBlocking(0.3)).mean)


def test_the_threshold_gives_its_arl0():
    h = fa.cusum_threshold(0.5, DESIGN, fa.RandomBlocking(0.5), 500)
    arl0 = fa.cusum_run_length(0.5, DESIGN, fa.CusumTest(fa.RandomBlocking(0.5), h))
    assert arl0.mean == pytest.approx(500, rel=0.01)  # each ARL0 is accurate to rtol = 0.01
    higher = fa.cusum_threshold(0.5, DESIGN, fa.RandomBlocking(0.5), 2000)
    assert higher > h


def test_bad_arguments_name_themselves():
    with pytest.raises(TypeError, match="alternative"):
        fa.CusumTest(fa.PeriodicBlocking(1, 5), 2.0)
    with pytest.raises(TypeError, match="alternative"):
        fa.CusumTest(fa.FlagInjection(0.1, fa.PeriodicBlocking(1, 5)), 2.0)
    with pytest.raises(ValueError, match="alternative"):
        fa.CusumTest([0.5, 0.2], 2.0)
    with pytest.raises(ValueError, match="threshold"):
        fa.CusumTest(fa.RandomBlocking(0.2), 0.0)
    test = fa.CusumTest(fa.RandomBlocking(0.2), 2.0)
    with pytest.raises(TypeError, match="cusum"):
        fa.cusum_run_length(0.5, DESIGN, "cusum")
    with pytest.raises(ValueError, match="start"):
        fa.cusum_run_length(0.5, DESIGN, test, start="later")
    with pytest.raises(ValueError, match="rtol"):
        fa.cusum_run_length(0.5, DESIGN, test, rtol=0.0)
    with pytest.raises(ValueError, match="bins"):
        fa.cusum_run_length(0.5, DESIGN, test, bins=10**6, max_states=10**5)
    with pytest.raises(ValueError, match="arl0"):
        fa.cusum_threshold(0.5, DESIGN, fa.RandomBlocking(0.2), 0.5)
    with pytest.raises(TypeError, match="design"):
        test.increments(0.5, (2, 1.0))
