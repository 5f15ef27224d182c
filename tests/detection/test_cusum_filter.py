"""The filter CUSUM (the exact log-likelihood ratio of the whole flag-ACK stream): its predictive
flag probabilities against the renewal hazards on the paper's channel and against a brute-force
sum over the protocol's paths on a Gilbert-Elliott channel, its simulated run lengths against a
simulation of the protocol written from its description, and its delay beside the renewal
CUSUM's at equal ARL0."""

import itertools
import math

import numpy as np
import pytest

import fakeack as fa
from fakeack.detection.cusum_filter import _models

DESIGN = fa.OnlineDesign(2)
GE = (0.1, 0.3, 0.9, 0.2)  # p, q, lam_good, lam_bad (high power always arrives)


def predictive(channel, alternative, x):
    """The package's predictive flag probabilities (null, alternative) along a batch of streams."""
    null, alt = _models(
        fa.GilbertElliott(*channel) if isinstance(channel, tuple) else channel, DESIGN, alternative
    )
    F0, Fa = null.begin(x.shape[0]), alt.begin(x.shape[0])
    p0, pa = np.empty(x.shape), np.empty(x.shape)
    for k in range(x.shape[1]):
        _, p0[:, k], AB0 = null.predict(F0)
        _, pa[:, k], ABa = alt.predict(Fa)
        F0, Fa = null.update(AB0, x[:, k]), alt.update(ABa, x[:, k])
    return p0, pa


def gap_streams(pmf, runs, steps, rng):
    """Streams whose gaps are i.i.d. draws of pmf (gaps g = 1..len), starting just after a flag."""
    x = np.zeros((runs, steps), bool)
    for r in range(runs):
        k = -1
        while True:
            k += rng.choice(pmf.size, p=pmf / pmf.sum()) + 1
            if k >= steps:
                break
            x[r, k] = True
    return x


# (a) On the paper's channel a delivery fixes the automaton's state: the filter restarts at every
# flag-ACK and its predictive probability is the Palm hazard h(y) at the gap y.
@pytest.mark.parametrize(
    "alternative", [fa.RandomBlocking(0.3), fa.FlagInjection(0.05, min_gap=3)], ids=["random", "careful"]
)
def test_on_the_papers_channel_the_filter_is_the_renewal_statistic(alternative):
    rng = np.random.default_rng(11)
    renewal = fa.CusumTest(alternative, 3.0)
    inc = renewal.increments(0.5, DESIGN)
    law = fa.flag_interval_law(0.5, 2).pmf[:60]
    x = np.concatenate(
        (gap_streams(law, 6, 300, rng), rng.random((2, 300)) < 0.3)
    )  # the last two: short gaps
    p0, pa = predictive(0.5, alternative, x)
    y = np.ones(x.shape, int)
    for k in range(1, x.shape[1]):
        y[:, k] = np.where(x[:, k - 1], 1, y[:, k - 1] + 1)
    at = np.minimum(y, inc.length) - 1
    np.testing.assert_allclose(p0, inc.h0[at], atol=1e-12)
    np.testing.assert_allclose(pa, inc.ha[at], atol=1e-12)
    filt = fa.CusumTest(alternative, 3.0, likelihood="filter").statistic(0.5, DESIGN, x)
    expected = renewal.statistic(0.5, DESIGN, x)
    np.testing.assert_allclose(filt, expected, atol=1e-12, rtol=0)
    assert np.isinf(filt[6:]).any() and np.isfinite(filt[:6]).all()  # short gaps hit the support check


def test_a_gap_pmf_alternative_keeps_its_hazards():
    """Past the pmf's support the alternative is impossible (W restarts at 0), as in the renewal
    statistic; on the paper's channel the two paths agree."""
    rng = np.random.default_rng(12)
    pmf = [0.0, 0.0, 0.2, 0.3, 0.3, 0.2]
    x = gap_streams(np.array([0, 0, 0.2, 0.3, 0.2, 0.1, 0.1, 0.1]), 8, 200, rng)
    filt = fa.CusumTest(pmf, 2.0, likelihood="filter").statistic(0.5, DESIGN, x)
    np.testing.assert_allclose(filt, fa.CusumTest(pmf, 2.0).statistic(0.5, DESIGN, x), atol=1e-12, rtol=0)
    y = np.ones(x.shape, int)
    for k in range(1, x.shape[1]):
        y[:, k] = np.where(x[:, k - 1], 1, y[:, k - 1] + 1)
    assert np.all(filt[y > 6] == 0.0) and (y > 6).any()


def protocol_matrices(p, q, good, bad, z0=2, beta=0.0):
    """The protocol written from its description, as a chain over (c, z, high) with the bit x:
    a high-power packet always arrives, a low one with probability lam_c; a loss adds one to the
    zero count z and an arrival resets it; at z0 the detector sends a flag-ACK and restarts the
    count; the attacker blocks the flag with probability beta; the sensor transmits at high power
    on the next step iff a flag reached it; the channel moves after each step. T[x][s, s']."""
    lam, P = (good, bad), ((1 - p, p), (q, 1 - q))
    states = list(itertools.product((0, 1), range(z0), (False, True)))
    index = {s: i for i, s in enumerate(states)}
    T = np.zeros((2, len(states), len(states)))
    for c, z, high in states:
        arrive = 1.0 if high else lam[c]
        outcomes = [(arrive, 0, False)]
        if z + 1 >= z0:  # a loss: the count reaches z0, a flag is sent
            outcomes += [((1 - arrive) * (1 - beta), 0, True), ((1 - arrive) * beta, 0, False)]
        else:
            outcomes += [(1 - arrive, z + 1, False)]
        for prob, z2, delivered in outcomes:
            for c2 in (0, 1):
                T[int(delivered), index[(c, z, high)], index[(c2, z2, delivered)]] += prob * P[c][c2]
    K = T[0] + T[1]
    w, v = np.linalg.eig(K.T)
    pi = np.real(v[:, np.argmin(abs(w - 1))])
    pi /= pi.sum()
    palm = pi @ T[1]
    return T, palm / palm.sum(), states


# (b) On a Gilbert-Elliott channel: P(x_k = 1 | x_1..x_{k-1}) from the joint probabilities of all
# 2^k streams, each a sum over the protocol's paths from the law just after a delivery.
@pytest.mark.parametrize("beta", [0.0, 0.5], ids=["null", "random:0.5"])
def test_the_predictive_probability_is_the_brute_force_conditional(beta):
    T, palm, _ = protocol_matrices(*GE, beta=beta)
    k = 9
    streams = np.array(list(itertools.product((False, True), repeat=k)))
    joint = np.array(
        [palm @ np.linalg.multi_dot([T[int(b)] for b in s]) @ np.ones(len(palm)) for s in streams]
    )
    assert joint.sum() == pytest.approx(1.0, abs=1e-12)
    expected = np.full(streams.shape, np.nan)
    for j in range(k):
        # P(prefix) and P(prefix, x_j = 1), each summed over every completion of the stream.
        prefix = {}
        for s, pr in zip(streams, joint, strict=True):
            key = tuple(s[:j])
            tot, ones = prefix.get(key, (0.0, 0.0))
            prefix[key] = (tot + pr, ones + pr * s[j])
        for r, s in enumerate(streams):
            tot, ones = prefix[tuple(s[:j])]
            expected[r, j] = ones / tot if tot > 1e-300 else np.nan
    p0, pa = predictive(GE, fa.RandomBlocking(0.5), streams)
    got = p0 if beta == 0.0 else pa
    seen = ~np.isnan(expected)
    assert seen.sum() > 1000
    np.testing.assert_allclose(got[seen], expected[seen], atol=1e-12)


def protocol_filter_run_lengths(h, beta, runs, seed):
    """Steps to the alarm of the filter CUSUM against RandomBlocking(0.5) over the protocol on the
    Gilbert-Elliott channel (as protocol_matrices describes it; beta: the attacker's blocking),
    from the paper's initial condition (high power, count 0, channel state stationary), each
    filter over the protocol's chain from its law just after a delivery."""
    p, q, good, bad = GE
    rng = np.random.default_rng(seed)
    T0, palm0, _ = protocol_matrices(*GE)
    Ta, palma, _ = protocol_matrices(*GE, beta=0.5)
    F0 = np.tile(palm0, (runs, 1))
    Fa = np.tile(palma, (runs, 1))
    c = (rng.random(runs) < p / (p + q)).astype(int)
    z, high = np.zeros(runs, int), np.ones(runs, bool)
    w = np.zeros(runs)
    alarm = np.zeros(runs, int)
    live = np.arange(runs)
    for k in range(1, 10**6):
        arrive = high | (rng.random(live.size) < np.where(c == 1, bad, good))
        z = np.where(arrive, 0, z + 1)
        flag = ~arrive & (z >= 2)
        z = np.where(flag, 0, z)
        x = flag & (rng.random(live.size) >= beta)
        A0, B0 = F0 @ T0[0], F0 @ T0[1]
        Aa, Ba = Fa @ Ta[0], Fa @ Ta[1]
        num = np.where(x, Ba.sum(1), Aa.sum(1))
        den = np.where(x, B0.sum(1), A0.sum(1))
        w = np.maximum(0.0, w + np.log(num) - np.log(den))  # both laws can produce every stream here
        F0 = np.where(x[:, None], B0, A0)
        Fa = np.where(x[:, None], Ba, Aa)
        F0 /= F0.sum(1, keepdims=True)
        Fa /= Fa.sum(1, keepdims=True)
        high = x
        c = np.where(
            c == 1, (rng.random(live.size) >= q).astype(int), (rng.random(live.size) < p).astype(int)
        )
        done = w >= h
        alarm[live[done]] = k
        keep = ~done
        live, F0, Fa, c, z, high, w = live[keep], F0[keep], Fa[keep], c[keep], z[keep], high[keep], w[keep]
        if live.size == 0:
            break
    return alarm.mean(), alarm.std(ddof=1) / math.sqrt(runs)


# (c) The simulated run length against the protocol's.
@pytest.mark.parametrize(
    ("attack", "beta"), [(None, 0.0), (fa.RandomBlocking(0.5), 0.5)], ids=["none", "random"]
)
def test_the_simulated_run_length_is_the_protocols(attack, beta):
    h = 2.0
    test = fa.CusumTest(fa.RandomBlocking(0.5), h, likelihood="filter")
    sim = fa.cusum_run_length(fa.GilbertElliott(*GE), DESIGN, test, attack, runs=3000, seed=5)
    mc, se = protocol_filter_run_lengths(h, beta, 3000, 6)
    assert abs(sim.mean - mc) < 4 * math.hypot(sim.error, se), (sim, mc, se)
    assert sim.runs == 3000 and sim.start == "renewal"


def test_the_filter_threshold_on_the_papers_channel_is_the_renewal_one():
    """There the two statistics coincide: the simulated threshold meets the exact one."""
    exact = fa.cusum_threshold(0.5, DESIGN, fa.RandomBlocking(0.5), 300)
    simulated = fa.cusum_threshold(0.5, DESIGN, fa.RandomBlocking(0.5), 300, likelihood="filter", seed=3)
    assert simulated == pytest.approx(exact, abs=0.08)  # 2000 runs: ARL0 to about 2.2%, h to ~0.03


# (d) Measured: on GilbertElliott(0.1, 0.3, 0.9, 0.2), against RandomBlocking(0.5) at ARL0 = 1000
# (renewal threshold 2.4909 from fa.cusum_threshold, exact; filter threshold 2.4616 from
# fa.cusum_threshold(likelihood="filter", seed=1)), the mean delays under RandomBlocking(0.5)
# are 196.8 (renewal) and 191.7 +- 2.3 (filter): the whole-stream likelihood gains under 3%.
def test_the_filter_delay_beside_the_renewal_delay_at_equal_arl0():
    ge = fa.GilbertElliott(*GE)
    alt = fa.RandomBlocking(0.5)
    renewal = fa.CusumTest(alt, 2.4909)
    filt = fa.CusumTest(alt, 2.4616, likelihood="filter")
    arl0_r = fa.cusum_run_length(ge, DESIGN, renewal, rtol=0.02)
    arl0_f = fa.cusum_run_length(ge, DESIGN, filt, runs=2000, seed=7)
    assert arl0_r.mean == pytest.approx(1000, rel=0.03)
    assert abs(arl0_f.mean - 1000) < 4 * arl0_f.error
    delay_r = fa.cusum_run_length(ge, DESIGN, renewal, alt).mean
    delay_f = fa.cusum_run_length(ge, DESIGN, filt, alt, runs=2000, seed=8)
    assert delay_r == pytest.approx(196.8, rel=0.02)
    # Within 6% of each other (the simulation's error and the ARL0s' matching included).
    assert abs(delay_f.mean - delay_r) < 0.06 * delay_r, (delay_f, delay_r)


def test_the_closed_loop_policy_refuses_the_filter():
    with pytest.raises(ValueError, match="^cusum"):
        fa.SensorPolicy(
            "cusum", fallback=1, cusum=fa.CusumTest(fa.RandomBlocking(0.5), 2.0, likelihood="filter")
        )


def test_the_likelihood_is_part_of_the_test():
    a = fa.CusumTest(fa.RandomBlocking(0.5), 2.0)
    b = fa.CusumTest(fa.RandomBlocking(0.5), 2.0, likelihood="filter")
    assert (
        a != b
        and a.likelihood == "renewal"
        and hash(b) == hash(fa.CusumTest(fa.RandomBlocking(0.5), 2.0, likelihood="filter"))
    )
    assert "filter" in str(b) and "filter" not in str(a)


def test_bad_arguments_name_themselves():
    filt = fa.CusumTest(fa.RandomBlocking(0.5), 2.0, likelihood="filter")
    renewal = fa.CusumTest(fa.RandomBlocking(0.5), 2.0)
    with pytest.raises(ValueError, match="^likelihood"):
        fa.CusumTest(fa.RandomBlocking(0.5), 2.0, likelihood="exact")
    with pytest.raises(TypeError, match="^seed"):
        fa.cusum_run_length(0.5, DESIGN, filt)
    with pytest.raises(ValueError, match="^start"):
        fa.cusum_run_length(0.5, DESIGN, filt, fa.RandomBlocking(0.5), "stationary", seed=1)
    with pytest.raises(ValueError, match="^bins"):
        fa.cusum_run_length(0.5, DESIGN, filt, bins=100, seed=1)
    with pytest.raises(ValueError, match="^runs"):
        fa.cusum_run_length(0.5, DESIGN, filt, runs=1, seed=1)
    with pytest.raises(ValueError, match="^max_steps"):
        fa.cusum_run_length(0.5, DESIGN, filt, seed=1, max_steps=50)
    for name in ("runs", "seed", "max_steps"):
        with pytest.raises(ValueError, match=f"^{name}"):
            fa.cusum_run_length(0.5, DESIGN, renewal, **{name: 10})
    with pytest.raises(TypeError, match="^seed"):
        fa.cusum_threshold(0.5, DESIGN, fa.RandomBlocking(0.5), 100, likelihood="filter")
    with pytest.raises(ValueError, match="^likelihood"):
        fa.cusum_threshold(0.5, DESIGN, fa.RandomBlocking(0.5), 100, likelihood="exact")
    with pytest.raises(TypeError, match="^delivered"):
        filt.statistic(0.5, DESIGN, [0.5, 1.0])
    with pytest.raises(ValueError, match="^delivered"):
        filt.statistic(0.5, DESIGN, np.zeros((2, 2, 2), bool))
    with pytest.raises(TypeError, match="^design"):
        filt.statistic(0.5, (2, 1.0), [0, 1])
