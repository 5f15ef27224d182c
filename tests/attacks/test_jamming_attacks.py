"""Jamming of the data channel (fa.attacks.Jamming, RandomJamming) through fa.Scenario, against
independent derivations: the geometric law of an i.i.d. loss, the periodic closed form of a
pattern (the holding time's law from the arrival probabilities step by step, phase 0 at step 1),
a deterministic run of the online protocol on a channel that decides every packet, and a Monte
Carlo of the online protocol written from its description. The finite-horizon optimum of
fa.optimal_jamming is J_T of the cost curve, not the long-run J."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack.attacks import Jamming, RandomJamming

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
STABLE = fa.LinearSystem(0.9, 1.0, 1.0, 1.0)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
PBAR = float(S.pbar[0, 0])


def traces(n, system=S):
    """Tr h^t(Pbar), t = 0..n, by the scalar recursion tr_{t+1} = A^2 tr_t + Q."""
    a2, q = float(system.A[0, 0]) ** 2, float(system.Q[0, 0])
    tr = [float(system.pbar[0, 0])]
    for _ in range(n):
        tr.append(a2 * tr[-1] + q)
    return np.array(tr)


def geometric_j(q, terms=3000):
    """sum_tau (1 - q) q^tau Tr h^tau(Pbar), as x_tau = q^tau tr_tau (no overflow)."""
    x, weight, total = PBAR, 1.0, 0.0
    for _ in range(terms):
        total += (1 - q) * x
        x, weight = q * (1.44 * x + 0.8 * weight), q * weight
    return total


def periodic_trace(arrive, k, depth=None):
    """E Tr h^{tau_k}(Pbar) with step m's packet arriving with probability arrive(m), independently:
    from tau_0 = 0 (depth None), or from the infinite past cut at depth steps back."""
    y, w, total = PBAR, 1.0, 0.0  # w = P(tau_k >= j), y = w tr_j
    for j in range(k if depth is None else depth):
        a = arrive(k - j)
        total += a * y  # P(tau_k = j) tr_j
        y, w = (1 - a) * (1.44 * y + 0.8 * w), (1 - a) * w
    return total + (y if depth is None else 0.0)  # tau_k = k: every packet lost since step 0


@pytest.mark.parametrize("rate", [0.1, 0.3])
@pytest.mark.parametrize("pattern, high", [("0", False), ("1", True)])
def test_random_jamming_is_a_geometric_holding_time(rate, pattern, high):
    lam = 0.5
    q = 1.0 - (1.0 - rate) * (1.0 if high else lam)  # every step lost with probability q
    sc = fa.Scenario(S, lam, fa.OfflineSchedule(pattern=pattern), RandomJamming(rate))
    assert_allclose(sc.cost(), geometric_j(q), rtol=1e-12)
    assert_allclose(sc.holding_time_law(5)[:5], [(1 - q) * q**j for j in range(5)], rtol=1e-12)
    assert sc.high_power_rate() == (1.0 if high else 0.0)


@pytest.mark.parametrize("pattern", ["0011", "010", "0001111", "0"])
def test_pattern_on_an_ideal_channel_is_the_hand_average(pattern):
    L = len(pattern)
    tau, taus = 0, []
    for k in range(1, 3 * L + 1):  # every unjammed packet arrives; step 1 is phase 0
        tau = tau + 1 if pattern[(k - 1) % L] == "1" else 0
        taus.append(tau)
    tr = traces(3 * L)
    sc = fa.Scenario(S, 1.0, fa.OfflineSchedule(pattern="1"), Jamming(pattern))
    assert_allclose(sc.cost_curve(3 * L).trace, tr[taus], rtol=1e-12)
    assert_allclose(sc.cost(), np.mean(tr[taus[-L:]]), rtol=1e-12)


@pytest.mark.parametrize(
    "offline, pattern",
    [("10", "10"), ("10", "01"), ("1000000", "001"), ("0", "0100"), ("110", "0001")],
)
def test_pattern_matches_the_periodic_closed_form(offline, pattern):
    lam = 0.7
    M, L = len(offline), len(pattern)
    N = M * L // math.gcd(M, L)

    def arrive(m):  # step m >= 1
        if pattern[(m - 1) % L] == "1":
            return 0.0
        return 1.0 if offline[(m - 1) % M] == "1" else lam

    sc = fa.Scenario(S, lam, fa.OfflineSchedule(pattern=offline), Jamming(pattern))
    start = 50 * N  # deep enough that the law from tau_0 = 0 has forgotten it
    long_run = np.mean([periodic_trace(arrive, k, 400) for k in range(start + 1, start + N + 1)])
    assert_allclose(sc.cost(), long_run, rtol=1e-10)
    curve = [periodic_trace(arrive, k) for k in range(1, 3 * N + 1)]
    assert_allclose(sc.cost_curve(3 * N).trace, curve, rtol=1e-11)


def test_holding_time_law_and_stability_index_of_a_pattern():
    sc = fa.Scenario(S, 1.0, fa.OfflineSchedule(pattern="1"), Jamming("0011"))
    assert_allclose(sc.holding_time_law(3), [0.5, 0.25, 0.25, 0.0], atol=1e-15)  # tau 0, 0, 1, 2
    assert sc.stability_index() == 0.0  # no loop of losses: tau is at most 2
    # Low power on lam = 0.5, every other step jammed: over a period the packet is lost with
    # probability 1 * 0.5, so rho(K0) = sqrt(0.5).
    sc = fa.Scenario(S, 0.5, fa.OfflineSchedule(pattern="0"), Jamming("01"))
    assert_allclose(sc.stability_index(), math.sqrt(0.5) * 1.44, rtol=1e-10)
    assert sc.cost() == math.inf


def test_the_phase_at_step_one_matters():
    lam = 0.7
    on_high = fa.Scenario(S, lam, fa.OfflineSchedule(pattern="10"), Jamming("10")).cost()
    on_low = fa.Scenario(S, lam, fa.OfflineSchedule(pattern="10"), Jamming("01")).cost()
    assert on_high > on_low * 1.1


def run_online(low, high, z0, pattern, steps):
    """The online protocol on a channel that decides every packet (arrival 0 or 1): tau_k, the
    sensor's power and the flag-ACKs, step by step (mu = 1)."""
    L = len(pattern)
    tau, count, hi = 0, 0, True
    taus, his, flags = [], [], []
    for k in range(1, steps + 1):
        arrived = pattern[(k - 1) % L] == "0" and (high if hi else low) == 1.0
        his.append(hi)
        tau = 0 if arrived else tau + 1
        count = 0 if arrived else count + 1
        flag = count >= z0
        count = 0 if flag else count
        hi = flag
        taus.append(tau)
        flags.append(flag)
    return np.array(taus), np.array(his), np.array(flags)


@pytest.mark.parametrize("pattern", ["0010", "011", "00", "0110", "00101", "01"])
@pytest.mark.parametrize("z0", [1, 2])
def test_online_pattern_on_a_deciding_channel_is_the_deterministic_run(pattern, z0):
    ch = fa.MarkovChannel([[1.0]], [0.0], [1.0])  # low power never arrives, high always
    L = len(pattern)
    n = 40 * L
    taus, his, flags = run_online(0.0, 1.0, z0, pattern, n)
    cycle = slice(n - 4 * L * (z0 + 1), n)  # the run is periodic by then
    if np.all(taus[n // 2 :] > 0):  # no packet ever arrives again: J is infinite
        with pytest.raises(ValueError, match=names("attack")):
            fa.Scenario(S, ch, fa.OnlineDesign(z0), Jamming(pattern))
        return
    sc = fa.Scenario(S, ch, fa.OnlineDesign(z0), Jamming(pattern))
    tr = traces(int(taus.max()))
    assert_allclose(sc.cost_curve(n).trace, tr[taus], rtol=1e-12)
    assert_allclose(sc.cost(), np.mean(tr[taus[cycle]]), rtol=1e-12)
    assert_allclose(sc.high_power_rate(), np.mean(his[cycle]), rtol=1e-12)
    assert_allclose(sc.flag_rates().sent, np.mean(flags[cycle]), rtol=1e-12)


def monte_carlo(channel, design, jam, n=4000, burn=60, steps=540, seed=1):
    """Per-path time averages of Tr P_k, of high-power steps and of flag-ACKs sent over steps
    burn+1..steps (whole jamming periods), of the online protocol as the docs state it."""
    rng = np.random.default_rng(seed)
    P, low, high = channel.P, channel.low, channel.high
    tr = traces(steps + 1, STABLE)
    c = rng.choice(channel.n_states, size=n, p=channel.stationary)
    tau, count = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
    hi = np.ones(n, dtype=bool)
    cost, power, sent = np.zeros(n), np.zeros(n), np.zeros(n)
    for k in range(1, steps + 1):
        if isinstance(jam, Jamming):
            jammed = np.full(n, jam.pattern[(k - 1) % jam.period] == 1)
        else:
            jammed = rng.random(n) < jam.rate
        p = np.where(hi, high[c], low[c]) * ~jammed
        arrived = rng.random(n) < p
        tau = np.where(arrived, 0, tau + 1)
        count = np.where(arrived, 0, count + 1)
        flag = ~arrived & ((count > design.z0) | ((count == design.z0) & (rng.random(n) < design.mu)))
        count = np.where(flag, 0, count)
        if k > burn:
            cost += tr[tau]
            power += hi
            sent += flag
        hi = flag
        c = np.where(rng.random(n) < P[c, 1], 1, 0) if channel.n_states == 2 else c
    return [x / (steps - burn) for x in (cost, power, sent)]


@pytest.mark.parametrize(
    "channel, jam",
    [(0.5, Jamming("0100")), (GE, Jamming("001")), (GE, RandomJamming(0.25))],
)
def test_online_jamming_matches_a_monte_carlo_of_the_protocol(channel, jam):
    ch = channel if isinstance(channel, fa.MarkovChannel) else fa.BernoulliChannel(channel)
    design = fa.OnlineDesign(2, 0.6)
    sc = fa.Scenario(STABLE, ch, design, jam)
    got = [sc.cost(), sc.high_power_rate(), sc.flag_rates().sent]
    for value, paths in zip(got, monte_carlo(ch, design, jam), strict=True):
        se = paths.std() / math.sqrt(paths.size)
        assert abs(value - paths.mean()) < 4.5 * se, (value, paths.mean(), se)
    # The jammed steps are losses the detector sees: more flag-ACKs than without jamming.
    assert got[2] > fa.Scenario(STABLE, ch, design).flag_rates().sent


@pytest.mark.parametrize("channel", [1.0, 0.5, GE])
def test_finite_horizon_optimum_is_the_cost_curve_not_the_long_run(channel):
    T, n = 8, 3
    r = fa.optimal_jamming(S, channel, n_jams=n, horizon=T)
    pattern = "".join("1" if k in r.jammed_steps else "0" for k in range(1, T + 1))
    sc = fa.Scenario(S, channel, fa.OfflineSchedule(pattern="0"), Jamming(pattern))
    # optimal_jamming's J is (1/T) sum_{k<=T} E Tr P_k from tau_0 = 0: J_T of the cost curve.
    assert_allclose(sc.cost_curve(T).j_k[-1], r.j, rtol=1e-12)
    if channel == 1.0:  # every period restarts at tau = 0 after its unjammed last step
        assert_allclose(sc.cost(), r.j, rtol=1e-12)
    else:  # tau carries over from one period to the next: the long run costs more
        assert sc.cost() > r.j * (1 + 1e-6)


def test_jamming_arguments_are_checked():
    for bad, exc in [
        ("", ValueError),
        ("012", ValueError),
        ("111", ValueError),
        ([[0, 1]], ValueError),
        ([0, 2], ValueError),
        (5, TypeError),
        (None, TypeError),
        (b"01", TypeError),
        (["a"], TypeError),
    ]:
        with pytest.raises(exc, match=names("pattern")):
            Jamming(bad)
    for bad, exc in [(-0.1, ValueError), (1.5, ValueError), (math.nan, ValueError), ("0.2", TypeError)]:
        with pytest.raises(exc, match=names("rate")):
            RandomJamming(bad)
    with pytest.raises(TypeError, match=names("rate")):
        RandomJamming(True)
    assert Jamming([True, False]).pattern == (1, 0)
    assert Jamming(np.array([0, 1, 1])).jammed_fraction == pytest.approx(2 / 3)
    assert repr(Jamming("0110")) == "Jamming('0110')"
    assert RandomJamming(0).rate == 0.0


def test_jammed_channels():
    ch = Jamming("01").jammed_channel(GE)
    assert ch.n_states == 4
    assert_allclose(ch.low, [0.9, 0.0, 0.2, 0.0])
    assert_allclose(ch.P[0], [0.0, 0.9, 0.0, 0.1])
    assert_allclose(RandomJamming(0.25).jammed_channel(GE).high, [0.75, 0.75])
    flip = fa.MarkovChannel([[0.0, 1.0], [1.0, 0.0]], [0.5, 0.5], [1.0, 1.0])
    with pytest.raises(ValueError, match=names("channel")):
        Jamming("01").jammed_channel(flip)  # period 2 twice: the phase never mixes
    with pytest.raises(ValueError, match=names("channel")):
        Jamming("0" * 600).jammed_channel(GE)
    # Scenario starts the phase at 0 itself, so a periodic channel is no obstacle there.
    sc = fa.Scenario(S, flip, fa.OfflineSchedule(pattern="1"), Jamming("01"))
    assert math.isfinite(sc.cost())


def test_jamming_in_a_scenario_is_checked():
    with pytest.raises(ValueError, match=names("max_states")):
        fa.Scenario(S, GE, fa.OnlineDesign(2), Jamming("0" * 50 + "1"), max_states=100)
    with pytest.raises(ValueError, match=names("attack")):
        fa.Scenario(S, 0.5, fa.OnlineDesign(2), RandomJamming(1.0))  # no packet ever arrives
