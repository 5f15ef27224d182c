"""Sweeps, thresholds, masks and mu < 1, each against the general chain (GTH) or scipy."""

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import PAPER_LAM, PAPER_RATIO, random_system


def j_by_general_chain(s, lam, z0, mask, mu):
    """Independent route: explicit (tau, zeros, sigma) chain, scipy sparse solve, pi . traces."""
    states, T = fa.general_attack_chain(lam, z0, mask, mu)
    n = T.shape[0]
    A = (T.T - sp.eye(n)).tolil()
    A[0, :] = 1.0  # pin one balance equation (the fair scipy approach)
    b = np.zeros(n)
    b[0] = 1.0
    pi = spla.spsolve(A.tocsc(), b)
    tr = s.h_traces(int(states[:, 0].max()))
    return pi @ tr[states[:, 0]]


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


def test_choose_schedule(paper):
    bb = fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO)
    lo = fa.choose_schedule(paper, PAPER_LAM, PAPER_RATIO, bb.limit * 0.9)
    hi = fa.choose_schedule(paper, PAPER_LAM, PAPER_RATIO, Fraction(2, 3))
    assert lo.schedule == "online" and hi.schedule == "offline"
    assert lo.j_online_attacked < lo.j_offline < hi.j_online_attacked
    assert fa.choose_schedule(paper, PAPER_LAM, PAPER_RATIO, 0).j_online_attacked == pytest.approx(lo.j_online)


def test_worst_mask_exhaustive(paper):
    res = fa.worst_mask(paper, 0.5, 2, 8, 3)
    # Independent exhaustive search through the general chain for a small case.
    best = max(
        (j_by_general_chain(paper, 0.5, 2, [1 if i in c else 0 for i in range(8)], 1.0), c)
        for c in itertools.combinations(range(8), 3)
    )
    assert_allclose(res.j, best[0], rtol=1e-10)
    assert res.mask.sum() == 3
    assert_allclose(res.j_consecutive, fa.j_attack(paper, 0.5, 2, 3, 8), rtol=1e-12)


@pytest.mark.parametrize("call, exc, name", [
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
])
def test_bad_input(paper, call, exc, name):
    with pytest.raises(exc, match=name):
        call(paper)


def test_infinite_j_max_limit():
    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    lam = 0.2  # (1 - lam) rho^2 = 1.152
    assert fa.j_attack_limit(s, lam, 2, 0.01) == math.inf
    assert math.isfinite(fa.j_attack(s, lam, 2, 40, 100))
