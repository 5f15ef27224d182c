"""Sweeps, thresholds, masks and mu < 1, each against the general chain (GTH) or scipy."""

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
import reference as ref
from conftest import PAPER_LAM, PAPER_RATIO, names, random_system


def j_by_general_chain(s, lam, z0, mask, mu):
    """Independent route: the reference's (tau, zeros, sigma) chain explored from the protocol's
    rules (tests/reference.py, no package code), scipy sparse solve, pi . traces."""
    states, T = ref.explore_mask_chain(lam, z0, list(mask), mu, sparse=True)
    pi = ref.stationary_sparse(T)
    taus = np.array([st[0] for st in states])
    tr = ref.traces(s.A, s.Q, s.pbar, int(taus.max()))
    return pi @ tr[taus]


def test_general_chain_reduces_to_paper_chain():
    states, T = fa.general_attack_chain(0.4, 2, [1, 0, 0])
    states2, T2 = fa.attack_chain(0.4, 2, 1, 3)
    assert len(states) == len(states2)
    pi = fa.stationary_gth(T)
    pi2 = fa.stationary_distribution(0.4, 2, 1, 3)
    # Same law on (tau, sigma) (zeros are implied by tau when mu = 1).
    d1 = {(int(a), int(c)): p for (a, _, c), p in zip(states, pi, strict=True)}
    d2 = {(int(a), int(c)): p for (a, c), p in zip(states2, pi2, strict=True)}
    assert d1.keys() == d2.keys()
    for k in d1:
        assert d1[k] == pytest.approx(d2[k], abs=1e-13)


@pytest.mark.parametrize("mask, mu", [([1, 0, 0], 1.0), ([0, 1, 1, 0, 1], 0.3), ([1, 1, 0], 0.0)])
def test_general_chain_is_the_reference_chain(mask, mu):
    """The package's general chain, state by state, against the reference's exploration."""
    states, T = fa.general_attack_chain(0.45, 2, mask, mu)
    order, Tref = ref.explore_mask_chain(0.45, 2, mask, mu)
    pos = {tuple(int(x) for x in st): i for i, st in enumerate(states)}
    assert sorted(pos) == sorted(order)
    perm = [pos[st] for st in order]
    assert_allclose(T.toarray()[np.ix_(perm, perm)], Tref, atol=1e-15)
    assert_allclose(fa.stationary_gth(T)[perm], ref.stationary_dense(Tref), atol=1e-13)


@pytest.mark.parametrize("mu", [1.0, 0.7, 0.2, 0.0])
@pytest.mark.parametrize("mask", [[1, 0, 0], [1, 1, 0, 1, 0], [0, 1, 1, 1, 0, 0, 1], [1, 0, 1, 1]])
def test_pattern_against_general_chain(paper, mu, mask):
    for lam, z0 in [(0.5, 2), (0.3, 1), (0.8, 3)]:
        got = fa.j_attack_pattern(paper, lam, z0, mask, mu)
        assert_allclose(got, j_by_general_chain(paper, lam, z0, mask, mu), rtol=1e-10)


def test_mu_attack_against_chain_vector_system():
    rng = np.random.default_rng(4)
    s = fa.LinearSystem(*random_system(rng, 3))
    for mu in (0.0, 0.35, 1.0):
        got = fa.j_attack(s, 0.55, 2, 3, 7, mu=mu)
        mask = [1] * 3 + [0] * 4
        assert_allclose(got, j_by_general_chain(s, 0.55, 2, mask, mu), rtol=1e-10)


def test_mu_one_and_zero_are_fixed_memories(paper):
    # mu = 0 with z0 is the fixed memory z0 + 1.
    assert_allclose(fa.j_attack(paper, 0.4, 2, 3, 5, mu=0.0), fa.j_attack(paper, 0.4, 3, 3, 5), rtol=1e-13)
    assert_allclose(fa.j_attack(paper, 0.4, 2, 0, 5, mu=0.3), fa.j_online(paper, 0.4, 2, 0.3), rtol=1e-13)


def test_sweep_matches_single_calls(paper):
    sw = fa.beta_sweep(paper, PAPER_LAM, PAPER_RATIO, t_max=300)
    assert sw.z0 == 2 and sw.mu == 1.0
    expected_count = sum(1 for t in range(2, 301) for r in range(1, t) if math.gcd(r, t) == 1)
    assert len(sw) == expected_count
    assert np.all(np.diff(sw.beta) > 0)
    rng = np.random.default_rng(0)
    for i in rng.choice(len(sw), 2000, replace=False):
        r, t = int(sw.r[i]), int(sw.t[i])
        assert math.gcd(r, t) == 1 and sw.beta[i] == r / t
        assert_allclose(sw.j_attack[i], fa.j_attack(paper, PAPER_LAM, 2, r, t), rtol=1e-12)
    assert sw.j_offline == fa.j_offline(paper, PAPER_LAM, PAPER_RATIO)
    assert sw.j_online == fa.j_online(paper, PAPER_LAM, 2)


def test_sweep_with_mu_below_one(paper):
    ratio = Fraction(1, 10)  # design gives z0 = 2 with mu in (0, 1) at lam = 0.5
    sw = fa.beta_sweep(paper, 0.5, ratio, t_max=40)
    assert 0 < sw.mu < 1
    for i in range(0, len(sw), 37):
        mask = [1] * int(sw.r[i]) + [0] * int(sw.t[i] - sw.r[i])
        assert_allclose(sw.j_attack[i], j_by_general_chain(paper, 0.5, sw.z0, mask, sw.mu), rtol=1e-10)


def test_sweep_overflow_safe():
    # Tr h^tau(P̄) overflows a double near tau ~ 1950 here (rho^2 = 1.44), but every J stays finite.
    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    assert np.isinf(s.h_traces(4000)[-1])
    sw = fa.beta_sweep(s, 0.5, Fraction(1, 7), t_max=10_000)
    assert len(sw) == 30_397_485
    assert np.all(np.isfinite(sw.j_attack))
    assert sw.j_attack.max() < fa.j_max(s, 0.5)
    i = len(sw) - 1  # 9999/10000, tau up to 2*10^4
    assert sw.r[i] == 9999 and sw.t[i] == 10_000


def test_beta_bar_definitions(paper):
    bb = fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO, t_max=60)
    sw = fa.beta_sweep(paper, PAPER_LAM, PAPER_RATIO, t_max=60)
    first = np.argmax(sw.j_attack >= sw.j_offline)
    assert bb.finite == Fraction(int(sw.r[first]), int(sw.t[first]))
    assert np.all(sw.j_attack[:first] < sw.j_offline)
    # The limit solves J_inf(beta) = J_off; J_inf is increasing, so it is the unique root.
    assert_allclose(fa.j_attack_limit(paper, PAPER_LAM, 2, bb.limit), bb.j_offline, rtol=1e-12)
    # No finite pattern beats the limit: finite threshold >= limit threshold.
    assert float(bb.finite) >= bb.limit
    big = fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO, t_max=5000)
    assert abs(float(big.finite) - bb.limit) < 2e-3


def test_limit_is_limit_of_repetitions(paper):
    # J(k r, k t) increases with k towards J_inf(r/t).
    for r, t in [(1, 5), (2, 3), (1, 3)]:
        js = [fa.j_attack(paper, 0.5, 2, k * r, k * t) for k in (1, 2, 4, 16, 256, 4096)]
        assert np.all(np.diff(js) > 0)
        lim = fa.j_attack_limit(paper, 0.5, 2, Fraction(r, t))
        assert js[-1] < lim and abs(js[-1] - lim) < 1e-3 * lim


def test_limit_closed_form_independently(paper):
    # J_inf from flag rates and regime costs computed independently of the Rust renewal sums.
    lam, z0 = 0.5, 2
    a = 1 - lam
    f_on = fa.online_high_power_rate(lam, z0)
    u = a**z0
    f_blk = lam * u / (1 - u)  # flags per step with every flag blocked: each arrival-free walk
    jon, jmax = fa.j_online(paper, lam, z0), fa.j_max(paper, lam)
    for beta in (0.1, 0.3, 0.7):
        expect = (beta * jmax / f_blk + (1 - beta) * jon / f_on) / (beta / f_blk + (1 - beta) / f_on)
        assert_allclose(fa.j_attack_limit(paper, lam, z0, beta), expect, rtol=1e-12)


def _regime_reference(s, lam, z0, mu):
    """(J_on, J_max, f_on, f_blk, traces) from tests/reference.py alone: the online holding-time
    chain, the series of J_max and the all-blocked memory chain."""
    tr = ref.traces(s.A, s.Q, s.pbar, 1200)  # the paper's system: 1.44^1200 ~ 1e190, finite
    T, flag = ref.online_chain(lam, z0, mu)
    pi = ref.stationary_dense(T)
    a = 1 - lam
    j_max = sum(lam * a**i * tr[i] for i in range(len(tr)))  # a rho^2 = 0.72: tail below 1e-160
    Tb, fb = ref.memory_chain_all_blocked(lam, z0, mu)
    return pi @ tr[: z0 + 2], j_max, pi @ flag, ref.stationary_dense(Tb) @ fb, tr


@pytest.mark.parametrize("mu", [1.0, 0.35])
def test_choose_schedule_against_an_independent_regime_mix(paper, mu):
    """The decision compares J_inf(beta), the time-weighted mix of the unattacked and all-blocked
    regimes, with J_off; beta_bar is the root of J_inf = J_off. Everything expected comes from the
    reference chains and a bisection here (tests/attacks/test_attack_model.py checks the same mix built
    from the package's own J_on, J_max and flag rates, which a wrong u would corrupt alike).

    Kills: dropping mu from the regime rates (u = a^z0 instead of a^z0 (mu + (1-mu) a)); not
    passing mu to j_attack_limit, beta_bar or choose_schedule; the decision taken on J_online
    instead of J_inf(beta); '<=' for '<' at beta_bar; beta_bar from the finite sweep."""
    lam, z0, ratio = PAPER_LAM, 2, PAPER_RATIO
    j_on, j_max, f_on, f_blk, tr = _regime_reference(paper, lam, z0, mu)
    j_off = ref.offline_direct(tr[:10], lam, [1, 0, 0, 0, 0, 0, 0])

    def mix(b):
        return (b * j_max / f_blk + (1 - b) * j_on / f_on) / (b / f_blk + (1 - b) / f_on)

    lo, hi = 0.0, 1.0
    for _ in range(200):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if mix(mid) < j_off else (lo, mid)
    root = (lo + hi) / 2
    assert 0.1 < root < 0.6
    bar = fa.beta_bar(paper, lam, ratio, z0=z0, mu=mu)
    assert_allclose(bar.limit, root, rtol=1e-9)
    for beta in (0.0, 0.05, root * (1 - 1e-6), root * (1 + 1e-6), 0.8, 1.0):
        d = fa.choose_schedule(paper, lam, ratio, beta, z0=z0, mu=mu)
        assert_allclose(d.j_online_attacked, mix(beta), rtol=1e-10)
        assert_allclose(fa.j_attack_limit(paper, lam, z0, beta, mu), mix(beta), rtol=1e-10)
        assert_allclose(d.beta_bar, root, rtol=1e-9)
        assert_allclose([d.j_online, d.j_offline], [j_on, j_off], rtol=1e-11)
        assert d.schedule == ("online" if beta < root else "offline"), beta
    # The designed schedule (mu = 1 here) is the default; z0 given without mu means mu = 1.
    assert fa.choose_schedule(paper, lam, ratio, 0.3) == fa.choose_schedule(
        paper, lam, ratio, 0.3, z0=2, mu=1.0
    )


def test_z0_without_mu_means_a_fixed_memory(paper):
    """Kills: a default mu other than 1 when z0 is given alone (beta_sweep, beta_bar,
    choose_schedule share it)."""
    lam, ratio = PAPER_LAM, PAPER_RATIO
    sw = fa.beta_sweep(paper, lam, ratio, t_max=12, z0=3)
    assert sw.mu == 1.0 and sw.z0 == 3
    assert_allclose(
        sw.j_attack[:5],
        [
            j_by_general_chain(paper, lam, 3, [1] * int(r) + [0] * int(t - r), 1.0)
            for r, t in zip(sw.r[:5], sw.t[:5], strict=True)
        ],
        rtol=1e-10,
    )
    assert fa.beta_bar(paper, lam, ratio, z0=3) == fa.beta_bar(paper, lam, ratio, z0=3, mu=1.0)
    d = fa.choose_schedule(paper, lam, ratio, 0.2, z0=3)
    assert d.mu == 1.0 and d == fa.choose_schedule(paper, lam, ratio, 0.2, z0=3, mu=1.0)
    assert d.j_online != fa.choose_schedule(paper, lam, ratio, 0.2, z0=3, mu=0.0).j_online


def _j_reference_mask(s, lam, z0, mask, mu=1.0):
    states, T = ref.explore_mask_chain(lam, z0, list(mask), mu)
    pi = ref.stationary_dense(T)
    taus = np.array([st[0] for st in states])
    return float(pi @ ref.traces(s.A, s.Q, s.pbar, int(taus.max()))[taus])


@pytest.mark.parametrize("t, blocked, mu", [(8, 3, 1.0), (7, 2, 0.45)])
def test_worst_mask_exhaustive(paper, t, blocked, mu):
    """Against an exhaustive search over the independent chain (tests/reference.py).

    Kills: returning a mask that does not attain the returned J (J alone was checked before);
    consecutive_is_worst constant or inverted; j_consecutive of another mask; a mask with the
    wrong number of blocked flags."""
    res = fa.worst_mask(paper, 0.5, 2, t, blocked, mu)
    js = {
        c: _j_reference_mask(paper, 0.5, 2, [1 if i in c else 0 for i in range(t)], mu)
        for c in itertools.combinations(range(t), blocked)
    }
    best = max(js.values())
    assert_allclose(res.j, best, rtol=1e-10)
    assert res.mask.shape == (t,) and res.mask.sum() == blocked
    assert_allclose(_j_reference_mask(paper, 0.5, 2, res.mask, mu), best, rtol=1e-10)
    consecutive = js[tuple(range(blocked))]
    assert_allclose(res.j_consecutive, consecutive, rtol=1e-10)
    assert res.consecutive_is_worst == (consecutive >= best * (1 - 1e-9))


def test_consecutive_is_worst_compares_the_two_costs(paper, monkeypatch):
    """Consecutive blocking was the worst mask in every case tried (README; a search over 14
    systems, 5 λ, 3 z0, 4 μ and 6 (t, blocked) found no exception), so the flag's False branch
    is exercised with a stub core that reports a worse mask.

    Kills: consecutive_is_worst constant True, or the comparison reversed."""
    import fakeack.attacks.masks as th

    class Stub:
        def __init__(self, j, jc):
            self.out = ([True, False, True, False], j, jc)

        def worst_mask(self, *args):
            return self.out

    for j, jc, worst in [(2.0, 1.5, False), (1.5, 1.5, True), (1.5 * (1 + 1e-13), 1.5, True)]:
        stub = Stub(j, jc)
        monkeypatch.setattr(th, "compiled", lambda system, stub=stub: stub)
        res = fa.worst_mask(paper, 0.5, 2, 4, 2)
        assert res.consecutive_is_worst is worst and res.j == j and res.j_consecutive == jc
        assert res.mask.tolist() == [1, 0, 1, 0]


@pytest.mark.parametrize(
    "call, exc, name",
    [
        (lambda s: fa.beta_sweep(s, 0.5, Fraction(1, 7), t_max=1), ValueError, "t_max"),
        (lambda s: fa.beta_sweep(s, 0.5, Fraction(1, 7), t_max=10**7), ValueError, "t_max"),
        (lambda s: fa.j_attack_pattern(s, 0.5, 2, [1, 1]), ValueError, "mask"),
        (lambda s: fa.j_attack_pattern(s, 0.5, 2, [1, 2]), ValueError, "mask"),
        (lambda s: fa.j_attack_pattern(s, 0.5, 2, []), ValueError, "mask"),
        (lambda s: fa.j_attack_limit(s, 0.5, 2, 1.5), ValueError, "beta"),
        (lambda s: fa.choose_schedule(s, 0.5, Fraction(1, 7), -0.1), ValueError, "beta"),
        (lambda s: fa.worst_mask(s, 0.5, 2, 30, 3), ValueError, "t"),
        (lambda s: fa.j_attack(s, 0.5, 2, 1, 3, mu=1.2), ValueError, "mu"),
        (lambda s: fa.beta_bar(s, 0.5, Fraction(1, 2)), ValueError, "ratio"),
    ],
)
def test_bad_input(paper, call, exc, name):
    with pytest.raises(exc, match=names(name)):
        call(paper)


def test_infinite_j_max_limit():
    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    lam = 0.2  # (1 - lam) rho^2 = 1.152
    assert fa.j_attack_limit(s, lam, 2, 0.01) == math.inf
    assert math.isfinite(fa.j_attack(s, lam, 2, 40, 100))


def test_worst_mask_limits(paper):
    """The smallest search (z0 = 1, t = 1, nothing blocked) is the unattacked online cost; t = 24
    is the largest exhaustive search allowed and 25 is refused; blocking every flag (blocked = t)
    is refused (kills the bounds turned into `minimum=2`, `>= 24`, `> 25`, `minimum=1` and
    `blocked > t`)."""
    for z0, t in [(1, 1), (2, 4)]:
        res = fa.worst_mask(paper, 0.5, z0, t, 0)
        assert res.mask.tolist() == [0] * t
        assert_allclose(res.j, fa.j_online(paper, 0.5, z0), rtol=1e-12)
    res = fa.worst_mask(paper, 0.5, 2, 24, 1)
    assert res.mask.sum() == 1 and res.mask.shape == (24,)
    with pytest.raises(ValueError, match=r"^t must be at most 24"):
        fa.worst_mask(paper, 0.5, 2, 25, 1)
    with pytest.raises(ValueError, match=r"^blocked must be smaller than t = 3, got 3"):
        fa.worst_mask(paper, 0.5, 2, 3, 3)


def test_threshold_results_carry_their_inputs(paper):
    """Defaults and echoed fields: beta_bar's t_max is 60 and beta_sweep's 1000 unless given;
    the results carry λ, the ratio, the unattacked online cost and the schedule's (z0, μ); the
    decision carries the budget it was asked about (kills each field replaced by None and each
    default moved by one)."""
    bb = fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO)
    assert bb.t_max == 60
    assert_allclose(bb.j_online, fa.j_online(paper, PAPER_LAM, 2), rtol=1e-12)
    assert (bb.z0, bb.mu) == (2, 1.0)
    sw = fa.beta_sweep(paper, PAPER_LAM, PAPER_RATIO)
    assert sw.t.max() == 1000 and sw.t.min() == 2
    assert (sw.lam, sw.ratio, sw.z0, sw.mu) == (PAPER_LAM, PAPER_RATIO, 2, 1.0)
    d = fa.choose_schedule(paper, PAPER_LAM, PAPER_RATIO, 0.25)
    assert (d.beta, d.z0, d.mu) == (0.25, 2, 1.0)
    # The shortest memory may be asked for (kills its lower bound raised to 2).
    one = fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO, z0=1)
    assert (one.z0, one.mu) == (1, 1.0)
    assert_allclose(one.j_online, fa.j_online(paper, PAPER_LAM, 1), rtol=1e-12)


def test_beta_bar_finite_none_when_no_short_pattern_hurts(paper):
    """With periods up to 2 the only attack is 1/2, and J(1, 2) < J_off on the paper's example:
    no finite threshold (None, not an error). Up to 3 the candidates are 1/3, 1/2, 2/3 and only
    2/3 reaches J_off (kills `finite` built from a missing first pattern)."""
    joff = fa.j_offline(paper, PAPER_LAM, PAPER_RATIO)
    j = {(r, t): fa.j_attack(paper, PAPER_LAM, 2, r, t) for r, t in [(1, 2), (1, 3), (2, 3)]}
    assert j[(1, 2)] < joff and j[(1, 3)] < joff <= j[(2, 3)]
    assert fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO, t_max=2).finite is None
    assert fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO, t_max=3).finite == Fraction(2, 3)
