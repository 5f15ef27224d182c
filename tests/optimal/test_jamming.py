"""optimal_jamming: the finite-horizon open-loop jammer and the long-run jammer that sees τ.

Every expected value comes from a route written here: the law of τ_k in product form (an arrival
at step k - m, then m losses), exact enumeration of channel paths for a Markov channel, all jam
subsets enumerated, a Monte Carlo of the jammed protocol, and for the long run the renewal-reward
formula over cycles that start at an arrival (not the stationary law nor the Stein equation that
the package uses).
"""

import itertools
import math

import numpy as np
import pytest

import fakeack as fa
import reference as ref
from conftest import PAPER, names
from fakeack.optimal import JammingResult, optimal_jamming

LAM = 0.5


@pytest.fixture(scope="module")
def paper():
    return fa.LinearSystem(**PAPER)


@pytest.fixture(scope="module")
def stable():
    """rho(A) = 0.9: the long-run J is bounded whatever the jammer does."""
    return fa.LinearSystem(0.9, 0.7, 0.8, 0.8)


def traces(system, n):
    pbar = ref.pbar_scipy(system.A, system.C, system.Q, system.R)
    return ref.traces(system.A, system.Q, pbar, n)


def tau_law(p):
    """law[s, k-1, m] = P(tau_k = m) for arrival probabilities p[s, j-1] at steps j (0 = jammed),
    tau_0 = 0: the last arrival at step k - m and none after, or none at all (m = k)."""
    S, T = p.shape
    law = np.zeros((S, T, T + 1))
    for k in range(1, T + 1):
        run = np.ones(S)
        for m in range(k):
            law[:, k - 1, m] = p[:, k - m - 1] * run
            run = run * (1 - p[:, k - m - 1])
        law[:, k - 1, k] = run
    return law


def masks_of(T, sets):
    jam = np.zeros((len(sets), T), dtype=bool)
    for i, s in enumerate(sets):
        jam[i, list(s)] = True
    return jam


def j_bernoulli(tr, lam, jam, levels=None):
    """J of each jam mask on the paper's channel (levels: 1 = high power, arrives surely)."""
    p = np.where(jam, 0.0, lam if levels is None else np.where(levels, 1.0, lam))
    return (tau_law(p) @ tr[: jam.shape[1] + 1]).mean(axis=1)


# ---------------------------------------------------------------- finite horizon, ideal channel


def test_ideal_channel_closed_form_and_every_block(paper):
    """(T - n) tr_0 + tr_1 + ... + tr_n over T: a run of l jams costs tr_1 + ... + tr_l and the
    other steps tr_0; every block of n consecutive jams gives it, a split block less."""
    T, n = 12, 4
    tr = traces(paper, T)
    closed = ((T - n) * tr[0] + tr[1 : n + 1].sum()) / T
    res = optimal_jamming(paper, 1.0, n, T)
    assert isinstance(res, JammingResult) and res.method == "closed form"
    assert res.j == pytest.approx(closed, rel=1e-12)
    assert res.jammed_steps == tuple(range(res.jammed_steps[0], res.jammed_steps[0] + n))
    blocks = [range(b, b + n) for b in range(T - n + 1)]
    np.testing.assert_allclose(j_bernoulli(tr, 1.0, masks_of(T, blocks)), closed, rtol=1e-12)
    split = j_bernoulli(tr, 1.0, masks_of(T, [(0, 1, 5, 6)]))[0]
    assert split < closed - 1e-3
    np.testing.assert_allclose(res.trace.mean(), res.j, rtol=1e-14)
    # a Markov channel whose packets all arrive is ideal too
    ideal = fa.MarkovChannel([[0.9, 0.1], [0.5, 0.5]], [1.0, 1.0], [1.0, 1.0])
    assert optimal_jamming(paper, ideal, n, T).j == pytest.approx(closed, rel=1e-12)


# ---------------------------------------------------------------- finite horizon, lossy channel


@pytest.mark.parametrize("T", [8, 12])
def test_exhaustive_over_all_subsets_on_the_paper_channel(paper, T):
    """All 2^T jam sets: the optimum with at most n jams uses exactly n (more jams never help),
    the package finds it, and on the paper's system at lam = 1/2 it is a consecutive block."""
    tr = traces(paper, T)
    sets = [s for k in range(T + 1) for s in itertools.combinations(range(T), k)]
    js = j_bernoulli(tr, LAM, masks_of(T, sets))
    sizes = np.array([len(s) for s in sets])
    for n in range(T + 1):
        best_at_most = js[sizes <= n].max()
        best_exactly = js[sizes == n].max()
        assert best_exactly == pytest.approx(best_at_most, rel=1e-13)
        res = optimal_jamming(paper, LAM, n, T)
        assert res.method == "exhaustive"
        assert res.j == pytest.approx(best_at_most, rel=1e-12)
        steps = res.jammed_steps
        assert len(steps) == n and list(steps) == sorted(steps)
        assert n == 0 or steps[-1] - steps[0] == n - 1  # a consecutive block
        assert j_bernoulli(tr, LAM, masks_of(T, [[s - 1 for s in steps]]))[0] == pytest.approx(
            res.j, rel=1e-12
        )


def test_horizon_20_exhaustive_and_the_block_scan(paper):
    """T = 20, n = 5 (15504 schedules) and n = 15: the exhaustive optimum is the best block; the
    block scan alone (above the exhaustive budget) returns the same block."""
    T = 20
    tr = traces(paper, T)
    for n in (5, 15):
        sets = list(itertools.combinations(range(T), n))
        js = j_bernoulli(tr, LAM, masks_of(T, sets))
        blocks = j_bernoulli(tr, LAM, masks_of(T, [range(b, b + n) for b in range(T - n + 1)]))
        assert js.max() == pytest.approx(blocks.max(), rel=1e-13)
        res = optimal_jamming(paper, LAM, n, T)
        assert res.method == "exhaustive" and res.j == pytest.approx(js.max(), rel=1e-12)
    from fakeack.optimal import jamming

    old = jamming.MAX_EXHAUSTIVE
    try:
        jamming.MAX_EXHAUSTIVE = 10
        res = optimal_jamming(paper, LAM, 5, T)
    finally:
        jamming.MAX_EXHAUSTIVE = old
    assert res.method == "best consecutive block"
    n = 5
    blocks = j_bernoulli(tr, LAM, masks_of(T, [range(b, b + n) for b in range(T - n + 1)]))
    assert res.j == pytest.approx(blocks.max(), rel=1e-12)
    # the blocks at b and T - n + 2 - b tie (reversal symmetry): any of the best will do
    assert blocks[res.jammed_steps[0] - 1] == pytest.approx(blocks.max(), rel=1e-12)


def test_offline_schedule_levels(paper):
    """An offline pattern: high-power steps arrive surely unless jammed."""
    T, n = 10, 3
    tr = traces(paper, T)
    sched = fa.OfflineSchedule(pattern="1000")
    levels = np.array([1, 0, 0, 0] * 3)[:T].astype(bool)
    sets = list(itertools.combinations(range(T), n))
    js = j_bernoulli(tr, LAM, masks_of(T, sets), levels)
    res = optimal_jamming(paper, LAM, n, T, schedule=sched)
    assert res.j == pytest.approx(js.max(), rel=1e-12)


def test_markov_channel_by_enumerating_channel_paths(paper):
    """Gilbert-Elliott channel, T = 7: E Tr P_k averaged over every channel path (stationary
    start), each path giving independent arrivals; every jam set of size 3 compared."""
    T, n = 7, 3
    ch = fa.GilbertElliott(0.2, 0.4, 0.9, 0.1)
    tr = traces(paper, T)
    pi = np.array([0.4 / 0.6, 0.2 / 0.6])
    P = np.array([[0.8, 0.2], [0.4, 0.6]])
    low = np.array([0.9, 0.1])
    sets = list(itertools.combinations(range(T), n))
    jam = masks_of(T, sets)
    total = np.zeros(len(sets))
    for path in itertools.product((0, 1), repeat=T):
        prob = pi[path[0]] * np.prod([P[a, b] for a, b in zip(path, path[1:], strict=False)])
        total += prob * j_bernoulli(tr, low[list(path)], jam)
    res = optimal_jamming(paper, ch, n, T)
    assert res.method == "exhaustive" and res.j == pytest.approx(total.max(), rel=1e-12)
    assert total[sets.index(tuple(s - 1 for s in res.jammed_steps))] == pytest.approx(total.max(), rel=1e-12)


def test_monte_carlo_of_the_jammed_protocol(paper):
    """20000 runs of the protocol (a jam adds one to tau, an unjammed packet arrives with lam):
    the average of Tr P_k agrees with J within 4 standard errors, and so does each step."""
    T, n, runs = 30, 8, 20_000
    res = optimal_jamming(paper, LAM, n, T)
    assert res.method == "best consecutive block"
    jammed = np.zeros(T + 1, dtype=bool)
    jammed[list(res.jammed_steps)] = True
    tr = traces(paper, T)
    rng = np.random.default_rng(7)
    tau = np.zeros(runs, dtype=np.int64)
    costs = np.empty((runs, T))
    for k in range(1, T + 1):
        arrived = ~jammed[k] & (rng.random(runs) < LAM)
        tau = np.where(arrived, 0, tau + 1)
        costs[:, k - 1] = tr[tau]
    per_run = costs.mean(axis=1)
    se = per_run.std(ddof=1) / math.sqrt(runs)
    assert abs(per_run.mean() - res.j) < 4 * se
    se_k = costs.std(axis=0, ddof=1) / math.sqrt(runs)
    assert np.all(np.abs(costs.mean(axis=0) - res.trace) < 4 * se_k + 1e-12)


def test_long_horizon_with_traces_beyond_the_double_range(paper):
    """T = 2000 on the paper's system: Tr h^2000(P̄) ~ 1e317 overflows but is reached only with
    probability 2^-2000; J is finite and matches the product form in logarithms. A block of 2085
    jams makes J exceed the double range (a lower bound in logs shows it): inf, never NaN."""
    T = 2000
    # scalar system: h^m(p) = A^(2m) p + Q (A^(2m) - 1) / (A^2 - 1), in logarithms
    pbar, c, m = ref.pbar_scipy(1.2, 0.7, 0.8, 0.8)[0, 0], 0.8 / 0.44, np.arange(T + 1)
    log_tr = m * math.log(1.44) + np.log(pbar + c - c * 1.44 ** (-m))
    j = 0.0
    for k in range(1, T + 1):
        m = np.arange(k + 1)
        logp = np.where(m < k, np.log(LAM), 0.0) + m * np.log(1 - LAM)
        j += np.exp(logp + log_tr[: k + 1]).sum()
    res = optimal_jamming(paper, LAM, 0, T)
    assert res.j == pytest.approx(j / T, rel=1e-9)
    big = optimal_jamming(paper, LAM, 2085, 2100)
    assert 2085 * math.log(1.44) - math.log(2100) > 709.8 and big.j == math.inf


# ---------------------------------------------------------------- long run


def scalar_traces(system):
    """tr_i = A^(2i) (p - c) + c with c = Q / (1 - A^2), exact for a scalar system (A^2 != 1)."""
    A2, Q = float(system.A[0, 0]) ** 2, float(system.Q[0, 0])
    p = ref.pbar_scipy(system.A, system.C, system.Q, system.R)[0, 0]
    c = Q / (1 - A2)
    return A2, p, c


def renewal(system, lam, idle):
    """(J, jammed fraction) of the policy by renewal-reward over cycles from an arrival: the chain
    reaches s <= M with probability prod_{t<s} g_t and then stays 1/(lam idle_M) steps in M, where
    tau - M is geometric; the sum over that tail is closed (scalar traces)."""
    A2, p, c = scalar_traces(system)
    M = len(idle) - 1
    x, leave = 1 - idle, lam * idle
    g = 1 - leave
    reach = np.concatenate(([1.0], np.cumprod(g[:M])))
    s = np.arange(M)
    tr = lambda i: A2**i * (p - c) + c  # noqa: E731
    cost_below = reach[:M] @ (leave[:M] * tr(0) + g[:M] * tr(s + 1))
    gm, lm = g[M], leave[M]
    if gm * A2 >= 1:
        return math.inf, None
    tail = A2 ** (M + 1) * (p - c) / (1 - gm * A2) + c / lm  # sum_j g^j tr_{M+1+j}; 1 - g = lm
    length = reach[:M].sum() + reach[M] / lm
    cost = cost_below + reach[M] * (tr(0) + gm * tail)
    jams = reach[:M] @ x[:M] + reach[M] * x[M] / lm
    return cost / length, jams / length


def families(M):
    """Jam-when-m <= tau < m + L windows below M, and jam-with-p-once-tau >= m thresholds."""
    for m in range(M):
        for L in range(1, M - m + 1):
            idle = np.ones(M + 1)
            idle[m : m + L] = 0.0
            yield idle
    for m in range(M + 1):
        for p in np.linspace(0.02, 0.98, 49):
            idle = np.ones(M + 1)
            idle[m:] = 1 - p
            yield idle


def best_in_families(system, lam, rate, M):
    best = -math.inf
    for idle in families(M):
        j, f = renewal(system, lam, idle)
        if f is not None and f <= rate:
            best = max(best, j)
    return best


def check_policy(system, res, lam):
    """The returned J and fraction by renewal-reward; feasible; within the LP's bracket."""
    j, f = renewal(system, lam, res.idle_probability)
    assert res.method == "linear program"
    assert res.j == pytest.approx(j, rel=1e-9)
    assert res.jammed_fraction == pytest.approx(f, rel=1e-9, abs=1e-15)
    assert f <= res.rate * (1 + 1e-12)
    np.testing.assert_allclose(res.jam_probability, 1 - res.idle_probability, atol=1e-15)
    assert res.j_lp * (1 - 1e-9) <= res.j <= (res.j_lp + res.tail_bound) * (1 + 1e-9)


@pytest.mark.parametrize(("lam", "rate", "tau_max"), [(0.5, 0.1, 10), (0.3, 0.2, 8), (0.5, 0.05, 12)])
def test_long_run_lp_against_windows_and_thresholds(stable, lam, rate, tau_max):
    res = optimal_jamming(stable, lam, rate=rate, tau_max=tau_max)
    check_policy(stable, res, lam)
    best = best_in_families(stable, lam, rate, tau_max)
    assert res.j >= best - 1e-9 * best
    assert res.j <= (res.j_lp + res.tail_bound) * (1 + 1e-9)


def test_long_run_optimum_at_tau_max_200(stable):
    """tau_max = 200: the optimum never jams below tau_max and jams there with probability
    1 - O(2^-200), so that fraction r of the time tau is huge and costs tr_inf while the rest
    follows the unjammed chain: J = (1 - r) J_unjammed + r tr_inf, with J_unjammed =
    lam sum_i (1-lam)^i tr_i = lam [(p - c)/(1 - (1-lam) A^2) + c/lam] (scalar traces)."""
    lam, rate = 0.5, 0.1
    A2, p, c = scalar_traces(stable)
    j_unjammed = lam * ((p - c) / (1 - (1 - lam) * A2) + c / lam)
    assert j_unjammed == pytest.approx(fa.j_max(stable, lam), rel=1e-12)
    res = optimal_jamming(stable, lam, rate=rate, tau_max=200)
    check_policy(stable, res, lam)
    assert res.j == pytest.approx((1 - rate) * j_unjammed + rate * c, rel=1e-9)
    assert np.all(res.jam_probability[:200] == 0.0) and 0 < res.idle_probability[200] < 1e-50


def test_long_run_with_an_unstable_process(paper):
    """rho(A) = 1.2, tau_max = 5, rate 1/100: bounded (holding x* = 7/18 beyond tau_max would cost
    more than the rate); every window and threshold policy stays within j_lp + tail_bound. At
    tau_max = 8 that holding policy fits the rate and J is infinite."""
    lam, rate = 0.5, 0.01
    x_star = 1 - (1 - 1 / 1.44) / lam
    for M, bounded in ((5, True), (8, False)):
        hold = np.ones(M + 1)
        hold[M] = 1 - x_star
        _, f_star = renewal(paper, lam, hold * (1 + 1e-12))  # just inside g rho^2 < 1
        assert (f_star > rate) == bounded
        res = optimal_jamming(paper, lam, rate=rate, tau_max=M)
        if bounded:
            check_policy(paper, res, lam)
            best = best_in_families(paper, lam, rate, M)
            assert best <= (res.j_lp + res.tail_bound) * (1 + 1e-9)
            assert res.j >= best - res.tail_bound
        else:
            assert res.method == "unbounded" and res.j == math.inf
            assert (1 - lam * res.idle_probability[M]) * 1.44 >= 1 - 1e-12
            # the witness's fraction (at g rho^2 = 1 exactly the renewal tail diverges; nudge idle)
            nudged = res.idle_probability.copy()
            nudged[M] *= 1 + 1e-9
            assert renewal(paper, lam, nudged)[1] <= rate


def test_long_run_unbounded_cases(paper):
    """The paper's example at tau_max = 200: any rate > 0 makes J infinite. At lam = 0.2,
    (1 - lam) rho^2 = 1.152 >= 1: J is infinite without any jamming (the witness never jams)."""
    res = optimal_jamming(paper, LAM, rate=0.1)
    assert res.method == "unbounded" and res.j == math.inf and res.jammed_fraction < 1e-50
    res = optimal_jamming(paper, 0.2, rate=0.1)
    assert res.method == "unbounded" and not res.jam_probability.any() and res.jammed_fraction == 0.0
    # The witness jams at tau_max with the probability that puts (1 - (1 - p) lam) rho^2 at 1;
    # in floating point it lands within rounding of 1 on either side (at lam = 0.6 just below),
    # where the tail's Lyapunov equation is singular: unbounded all the same.
    for lam in (0.55, 0.6, 0.65):
        res = optimal_jamming(paper, lam, rate=0.1)
        assert res.method == "unbounded" and res.j == math.inf, lam


def test_long_run_without_budget_is_the_unjammed_cost(stable):
    res = optimal_jamming(stable, LAM, rate=0.0, tau_max=30)
    assert res.j == pytest.approx(fa.j_max(stable, LAM), rel=1e-9) and res.jammed_fraction == 0.0


def test_long_run_with_every_step_jammed_is_the_trace_limit(stable):
    """rate = 1: jam for ever, tau grows without end: J = lim tr_i = Q / (1 - A^2)."""
    res = optimal_jamming(stable, LAM, rate=1.0, tau_max=20)
    assert res.j == pytest.approx(0.8 / (1 - 0.81), rel=1e-9)


def test_long_run_hard_cases():
    """Cases that need care: a far state carrying the scale floor (lam = 0.8, tau_max = 200, where
    HiGHS's simplex gives up and its interior-point solver answers), rho(A) = 1 (bounded, with a
    huge tail bound), a 2x2 system (the bracket and the rate), and lam = 0.99 at tau_max = 200,
    where the optimal policy's probabilities leave the double range (refused, naming tau_max)."""
    fast = fa.LinearSystem(0.5, 1.0, 1.0, 1.0)
    for lam, rate in ((0.8, 0.01), (0.8, 0.2)):
        res = optimal_jamming(fast, lam, rate=rate, tau_max=200)
        check_policy(fast, res, lam)
    marginal = fa.LinearSystem(1.0, 1.0, 1.0, 1.0)
    res = optimal_jamming(marginal, LAM, rate=0.1, tau_max=10)
    assert res.method == "linear program" and res.j_lp <= res.j <= res.j_lp + res.tail_bound
    two = fa.LinearSystem([[0.8, 0.3], [0.0, 0.7]], [[1.0, 0.0]], np.eye(2), 1.0)
    for rate, m in ((0.05, 10), (0.2, 200)):
        res = optimal_jamming(two, 0.3, rate=rate, tau_max=m)
        assert res.j_lp * (1 - 1e-9) <= res.j <= (res.j_lp + res.tail_bound) * (1 + 1e-9)
        assert res.jammed_fraction <= rate
    with pytest.raises(ValueError, match=names("tau_max")):
        optimal_jamming(fa.LinearSystem(0.9, 0.7, 0.8, 0.8), 0.99, rate=0.1, tau_max=200)


# ---------------------------------------------------------------- arguments


@pytest.mark.parametrize(
    ("kwargs", "exc", "arg"),
    [
        (dict(n_jams=11, horizon=10), ValueError, "n_jams"),
        (dict(n_jams=-1, horizon=10), ValueError, "n_jams"),
        (dict(n_jams=2.5, horizon=10), TypeError, "n_jams"),
        (dict(n_jams=1, horizon=0), ValueError, "horizon"),
        (dict(horizon=10), TypeError, "n_jams"),
        (dict(n_jams=1), TypeError, "horizon"),
        (dict(n_jams=1, horizon=10, rate=0.1), TypeError, "horizon"),
        (dict(rate=1.5), ValueError, "rate"),
        (dict(rate=-0.1), ValueError, "rate"),
        (dict(rate=0.1, n_jams=3), TypeError, "n_jams"),
        (dict(rate=0.1, tau_max=0), ValueError, "tau_max"),
        (dict(rate=0.1, schedule=fa.OfflineSchedule(pattern="10")), TypeError, "schedule"),
        (dict(n_jams=1, horizon=5, schedule="10"), TypeError, "schedule"),
        (dict(n_jams=1, horizon=5, tau_max=10), TypeError, "tau_max"),
        (dict(rate=0.1, tau_max=2001), ValueError, "tau_max"),
    ],
)
def test_arguments_are_named(stable, kwargs, exc, arg):
    with pytest.raises(exc, match=names(arg)):
        optimal_jamming(stable, LAM, **kwargs)


def test_channel_and_system_arguments(stable):
    with pytest.raises(ValueError, match=names("channel")):
        optimal_jamming(stable, 1.5, 1, 5)
    with pytest.raises(TypeError, match=names("system")):
        optimal_jamming("A", LAM, 1, 5)
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    with pytest.raises(ValueError, match=names("channel")):
        optimal_jamming(stable, ge, rate=0.1)
    with pytest.raises(ValueError, match=names("channel")):
        optimal_jamming(stable, 1.0, rate=0.1)
    with pytest.raises(ValueError, match=names("horizon")):
        optimal_jamming(stable, LAM, 3000, 6000)
