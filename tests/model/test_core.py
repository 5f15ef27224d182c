"""The analytic core, each formula against an independent derivation (tests/reference.py)."""

import math
from fractions import Fraction

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
import reference as ref
from conftest import PAPER, PAPER_LAM, PAPER_RATIO, names, random_system

# ---------------------------------------------------------------- P̄ and traces


def test_paper_pbar_closed_form(paper):
    # Scalar: the prior p solves c^2 p^2 + (r - a^2 r - q c^2) p - q r = 0; P̄ = p r / (c^2 p + r).
    a, c, q, r = PAPER["A"], PAPER["C"], PAPER["Q"], PAPER["R"]
    qa, qb, qc = c * c, r - a * a * r - q * c * c, -q * r
    p = (-qb + math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
    assert_allclose(paper.pbar[0, 0], p * r / (c * c * p + r), rtol=1e-14)
    assert paper.residual < 1e-14


@pytest.mark.parametrize("q", [1e6, 1e9, 1e12, 1e14])
def test_pbar_of_a_precise_sensor_keeps_its_digits(q):
    """With q / r large, P̄ is a tiny fraction of the prior: the measurement update must not
    subtract two near-equal numbers (X - K C X lost 4 digits at q / r = 1e12 and 2 at 1e14,
    with a residual of 0 that did not show it). Reference: the prior from the quadratic formula
    (no cancellation: -b > 0) and P̄ = p r / (c^2 p + r)."""
    a, c, r = 0.5, 1.0, 1.0
    s = fa.LinearSystem(a, c, q, r)
    qb = r - a * a * r - q * c * c
    p = (-qb + math.sqrt(qb * qb + 4 * c * c * q * r)) / (2 * c * c)
    assert_allclose(s.pbar[0, 0], p * r / (c * c * p + r), rtol=4e-16)
    assert s.residual < 1e-15


def test_pbar_of_a_precise_coupled_sensor():
    """Two coupled states seen through C = R = I: P̄ = P⁻ (P⁻ + I)^{-1}. With A = 0, P⁻ = Q;
    for Q = [[1e12, 1e6], [1e6, 3]] that is [[3e12, 1e6], [1e6, 2e12 + 3]] / (3e12 + 4),
    exact in integers, each entry to a few ulps (the off-diagonal one is 1e-6 of the others)."""
    Q = np.array([[1e12, 1e6], [1e6, 3.0]])
    s = fa.LinearSystem(np.zeros((2, 2)), np.eye(2), Q, np.eye(2))
    expected = np.array([[3e12, 1e6], [1e6, 2e12 + 3]]) / (3e12 + 4)
    assert_allclose(s.pbar, expected, rtol=1e-14)


@pytest.mark.parametrize("n", [1, 2, 5, 20, 50, 200])
def test_pbar_matches_scipy(n):
    rng = np.random.default_rng(n)
    A, C, Q, R = random_system(rng, n)
    s = fa.LinearSystem(A, C, Q, R)
    expected = ref.pbar_scipy(A, C, Q, R)
    err = np.linalg.norm(s.pbar - expected) / np.linalg.norm(expected)
    assert err < 1e-9, err
    assert s.residual < 1e-10
    assert_allclose(s.pbar, s.pbar.T, atol=0)


def test_h_traces_and_weighted(paper):
    tr = paper.h_traces(30)
    assert_allclose(tr, ref.traces(1.2, 0.8, paper.pbar, 30), rtol=1e-13)
    assert np.all(np.diff(tr) > 0)  # Lemma 2.1
    w = paper.weighted_traces(0.5, 30)
    assert_allclose(w, 0.5 ** np.arange(31) * tr, rtol=1e-13)
    # Far out, Tr h^i overflows but the weighted terms stay finite (a rho^2 = 0.72 < 1).
    big = paper.h_traces(3000)
    assert np.isinf(big[-1]) and not np.isnan(big).any()
    wbig = paper.weighted_traces(0.5, 3000)
    assert np.all(np.isfinite(wbig)) and wbig[-1] < 1e-100


def test_vector_traces():
    rng = np.random.default_rng(3)
    A, C, Q, R = random_system(rng, 4)
    s = fa.LinearSystem(A, C, Q, R)
    assert_allclose(s.h_traces(25), ref.traces(A, Q, s.pbar, 25), rtol=1e-12)


def test_marginally_detectable_and_stable_zero_noise():
    # Eigenvalue on the unit circle, observed: converges.
    s = fa.LinearSystem(np.diag([1.0, 0.5]), [[1.0, 1.0]], np.eye(2), 1.0)
    assert_allclose(s.pbar, ref.pbar_scipy(np.diag([1.0, 0.5]), [[1.0, 1.0]], np.eye(2), 1.0), rtol=1e-9)
    # Q = 0 with stable A: P̄ = 0.
    z = fa.LinearSystem(0.5, 1.0, 0.0, 1.0)
    assert z.pbar[0, 0] == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize(
    "args, name",
    [
        ((1.2, 0.7, 0.8, -0.8), "R"),
        ((1.2, 0.7, -0.8, 0.8), "Q"),
        ((np.eye(2), [[1.0]], np.eye(2), 1.0), "C"),
        ((np.eye(2), [[1.0, 0.0]], np.eye(3), 1.0), "Q"),
        ((float("nan"), 0.7, 0.8, 0.8), "A"),
        ((1.2, 0.7, 0.8, np.inf), "R"),
        ((np.ones((2, 3)), [[1.0, 0, 0]], np.eye(2), 1.0), "A"),
        ((np.diag([2.0, 0.5]), [[0.0, 1.0]], np.eye(2), 1.0), "detectable"),
        ((np.eye(2), [[1.0, 0.0]], [[1.0, 0.5], [0.0, 1.0]], 1.0), "symmetric"),
    ],
)
def test_system_rejects(args, name):
    with pytest.raises(ValueError, match=names(name)):
        fa.LinearSystem(*args)


def test_system_type_errors():
    with pytest.raises(TypeError, match="A"):
        fa.LinearSystem("x", 1.0, 1.0, 1.0)
    with pytest.raises(TypeError, match="Q"):
        fa.LinearSystem(1.0, 1.0, 1 + 2j, 1.0)


# ---------------------------------------------------------------- offline schedule


def test_energy_ratio_exact():
    assert fa.energy_ratio(Fraction(10, 7) + Fraction(18, 7), 10, 3) == Fraction(1, 7)
    assert fa.energy_ratio("2.5", 4, 1) == Fraction(1, 2)
    assert fa.energy_ratio(0.3, 1, 0) == Fraction(3, 10)
    # Each message names its argument, case and word exact (kills a renamed or dropped name);
    # Delta = delta is refused before the division by Delta - delta (kills `<` turned `<=`).
    for bad, message in [
        ((3, 4, 3), r"^Psi must lie strictly between delta=3 and Delta=4"),
        ((4, 4, 1), r"^Psi must lie strictly between"),
        ((5, 4, 1), r"^Psi must lie strictly between"),
        ((2, 4, -1), r"^delta must be non-negative"),
        ((3, 3, 3), r"^Delta must exceed delta, got Delta=3, delta=3"),
        ((3, "x", 1), r"^Delta: cannot parse"),
    ]:
        with pytest.raises(ValueError, match=message):
            fa.energy_ratio(*bad)
    for i, name in enumerate(["Psi", "Delta", "delta"]):
        args = [3, 4, 1]
        args[i] = None
        with pytest.raises(TypeError, match=rf"^{name} must be a rational number"):
            fa.energy_ratio(*args)


def test_offline_schedule_model_note_example():
    assert fa.offline_schedule(Fraction(1, 7)).tolist() == [1, 0, 0, 0, 0, 0, 0]
    assert fa.offline_schedule("1/7").tolist() == [1, 0, 0, 0, 0, 0, 0]


@pytest.mark.parametrize("q", range(2, 25))
def test_offline_schedule_counts(q):
    for p in range(1, q):
        if math.gcd(p, q) != 1:
            continue
        s = fa.offline_schedule(Fraction(p, q))
        assert s.shape == (q,) and s.sum() == p and s[0] == 1


@pytest.mark.parametrize(
    "ratio", [Fraction(1, 7), Fraction(2, 7), Fraction(3, 8), Fraction(5, 12), Fraction(1, 2), Fraction(4, 5)]
)
@pytest.mark.parametrize("lam", [0.2, 0.5, 0.8])
def test_j_offline_equals_direct_average(paper, ratio, lam):
    pattern = fa.offline_schedule(ratio)
    tr = paper.h_traces(len(pattern) + 2)
    direct = ref.offline_direct(tr, lam, pattern)
    assert_allclose(fa.j_offline(paper, lam, ratio), direct, rtol=1e-12)


def test_offline_is_best_fixed_schedule(paper):
    # Theorem 3.1: among all patterns with p ones in q, the offline schedule has the least J.
    import itertools

    lam, p, q = 0.4, 2, 7
    tr = paper.h_traces(q + 2)
    best = min(
        ref.offline_direct(tr, lam, [1 if i in c else 0 for i in range(q)])
        for c in itertools.combinations(range(q), p)
        if 0 in c
    )
    assert fa.j_offline(paper, lam, Fraction(p, q)) == pytest.approx(best, rel=1e-12)


# ---------------------------------------------------------------- online schedule


@pytest.mark.parametrize("z0", [1, 2, 3, 5])
@pytest.mark.parametrize("mu", [0.0, 0.3, 1.0])
@pytest.mark.parametrize("lam", [0.1, 0.5, 0.9])
def test_online_formulas_against_chain(paper, z0, mu, lam):
    T, flag = ref.online_chain(lam, z0, mu)
    pi = ref.stationary_dense(T)
    tr = paper.h_traces(z0 + 1)
    assert_allclose(fa.j_online(paper, lam, z0, mu), pi @ tr, rtol=1e-12)
    assert_allclose(fa.online_high_power_rate(lam, z0, mu), pi @ flag, rtol=1e-10)


def test_online_model_note_checks():
    assert fa.online_high_power_rate(0.5, 2) == pytest.approx(1 / 7, rel=1e-15)
    assert fa.online_high_power_rate(0.3, 3, 0.0) == pytest.approx(
        fa.online_high_power_rate(0.3, 4, 1.0), rel=1e-15
    )


@pytest.mark.parametrize("lam", [0.5, 0.3, Fraction(2, 3), 0.05])
@pytest.mark.parametrize("ratio", [Fraction(1, 7), Fraction(1, 5), Fraction(1, 10), Fraction(3, 100)])
def test_design_online_meets_budget(lam, ratio):
    if ratio > (1 - Fraction(lam).limit_denominator(1000)) / (2 - Fraction(lam).limit_denominator(1000)):
        with pytest.raises(ValueError, match="ratio"):
            fa.design_online(lam, ratio)
        return
    z0, mu = fa.design_online(lam, ratio)
    assert z0 >= 1 and 0.0 <= mu <= 1.0
    assert fa.online_high_power_rate(float(lam), z0, mu) == pytest.approx(float(ratio), rel=1e-12)


def test_design_online_paper():
    assert fa.design_online(PAPER_LAM, PAPER_RATIO) == (2, 1.0)
    d = fa.design_online(0.5, Fraction(1, 10))
    assert d.z0 == 2 and 0 < d.mu < 1  # f(3, 1) = 1/15 < 1/10 < f(2, 1) = 1/7


def _rate_fixed_memory(lam: Fraction, z: int) -> Fraction:
    """f(z, 1) = λ a^z / (1 - a^(z+1)), a = 1 - λ: the high-power rate of a fixed memory z
    (Model note 2), in exact arithmetic."""
    a = 1 - lam
    return lam * a**z / (1 - a ** (z + 1))


def _rate_float(lam: float, z: int) -> float:
    """f(z, 1) in floating point, as a float ratio would be given."""
    ln_a = math.log1p(-lam)
    return lam * math.exp(z * ln_a) / -math.expm1((z + 1) * ln_a)


def _as_ratio(x: float) -> Fraction:
    """The fraction nearest x with a denominator the package accepts (at most 2^62); it rounds
    back to x."""
    q = Fraction(x).limit_denominator(2**62)
    assert float(q) == x
    return q


@pytest.mark.parametrize("z_target", [2_500, 4_000])
def test_design_online_long_memory(z_target):
    """Budgets so small that z0 exceeds the exact-arithmetic range (2000): the memory is the
    bracket f(z0 + 1, 1) < ratio <= f(z0, 1), checked in exact arithmetic, and μ solves
    f(z0, μ) = ratio (Model note 2's rate, written out here). Kills the float path's formula for
    μ and its bracket (each operator and constant of `_largest_z_float` and the μ expression)."""
    lam = 1e-3
    lam_q = Fraction(lam)
    a = 1 - lam_q
    # A budget inside the bracket of z_target (between f(z + 1, 1) and f(z, 1), nearer the top).
    ratio = _as_ratio(_rate_float(lam, z_target) * 0.9999 + _rate_float(lam, z_target + 1) * 0.0001)
    z0, mu = fa.design_online(lam, ratio)
    assert z0 == z_target
    assert _rate_fixed_memory(lam_q, z0 + 1) < ratio <= _rate_fixed_memory(lam_q, z0)
    assert 0.0 <= mu <= 1.0
    m = Fraction(mu)
    rate = lam_q * a**z0 * (m + (1 - m) * a) / (1 - m * a ** (z0 + 1) - (1 - m) * a ** (z0 + 2))
    assert float(rate / ratio) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("z", [2_048, 3_000])
def test_design_online_long_memory_at_the_top_of_a_bracket(z):
    """A budget exactly f(z, 1) in floating point gives memory z with μ = 1 (within rounding), not
    z - 1 (kills the bisection's `>=` turned `>`; at z = 2048, a power of two, also the doubling
    search's), and μ is clipped to at most 1 (the float formula overshoots by 1e-13 there)."""
    lam = 1e-3
    z0, mu = fa.design_online(lam, _as_ratio(_rate_float(lam, z)))
    assert z0 == z
    assert mu == pytest.approx(1.0, abs=1e-9) and mu <= 1.0


def test_design_online_limits_are_inclusive():
    """The largest budget, f(1, 1) = a / (1 + a) (1/3 at λ = 1/2), is allowed and gives (1, 1);
    the longest memory, 10^6 steps, is allowed and one step more is refused (kills `>` turned `>=`
    in both checks)."""
    assert fa.design_online(0.5, Fraction(1, 3)) == (1, 1.0)
    with pytest.raises(ValueError, match="ratio"):
        fa.design_online(0.5, Fraction(1, 3) + Fraction(1, 10**9))
    lam = 1e-5
    assert fa.design_online(lam, _as_ratio(_rate_float(lam, 1_000_000))).z0 == 1_000_000
    with pytest.raises(ValueError, match="memory"):
        fa.design_online(lam, _as_ratio(_rate_float(lam, 1_000_002)))


def test_online_beats_offline_random_systems():
    # Theorem 5.3 of Han et al.: J_on < J_off at the same energy.
    rng = np.random.default_rng(7)
    for _ in range(25):
        n = int(rng.integers(1, 4))
        s = fa.LinearSystem(*random_system(rng, n))
        lam = float(rng.uniform(0.2, 0.8))
        ratio = Fraction(int(rng.integers(1, 4)), int(rng.integers(8, 20)))
        try:
            z0, mu = fa.design_online(lam, ratio)
        except ValueError:
            continue
        assert fa.j_online(s, lam, z0, mu) < fa.j_offline(s, lam, ratio)


# ---------------------------------------------------------------- J_max


def test_j_max_series(paper):
    tr = paper.h_traces(400)
    lam = 0.5
    series = sum(lam * (1 - lam) ** i * tr[i] for i in range(401))
    assert_allclose(fa.j_max(paper, lam), series, rtol=1e-12)


def test_j_max_stability_condition():
    # A = 1.2, lam = 0.2 passes the printed test (0.96 < 1) but (1-lam) rho^2 = 1.152 >= 1.
    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    assert fa.j_max(s, 0.2) == math.inf
    assert math.isfinite(fa.j_attack(s, 0.2, 2, 5, 9))  # a finite-r attack stays finite


def test_j_max_vector():
    rng = np.random.default_rng(11)
    A, C, Q, R = random_system(rng, 3, unstable=False)
    s = fa.LinearSystem(A, C, Q, R)
    tr = ref.traces(A, Q, s.pbar, 2000)
    lam = 0.3
    series = np.sum(lam * (1 - lam) ** np.arange(2001) * tr)
    assert_allclose(fa.j_max(s, lam), series, rtol=1e-11)


# ---------------------------------------------------------------- attack chain


def test_chain_paper_example():
    lam = 0.37
    l, a = lam, 1 - lam
    Ts = np.array(
        [  # the paper's column-stochastic matrix with Model note 4 applied
            [l, l, 0, 0, 0, 0, 0, 0, 0, 0, 1],
            [a, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
            [0, a, 0, 0, 0, 0, 0, 0, 0, 0, 0],
            [0, 0, l, l, l, 0, l, 0, 0, 0, 0],
            [0, 0, 0, a, 0, 0, 0, 0, 0, 0, 0],
            [0, 0, 0, 0, a, 0, 0, 0, 0, 0, 0],
            [0, 0, a, 0, 0, 0, 0, 0, 0, 0, 0],
            [0, 0, 0, 0, 0, 0, a, 0, 0, 0, 0],
            [0, 0, 0, 0, 0, 1, 0, 1, l, l, 0],
            [0, 0, 0, 0, 0, 0, 0, 0, a, 0, 0],
            [0, 0, 0, 0, 0, 0, 0, 0, 0, a, 0],
        ]
    )
    states, T = fa.attack_chain(lam, 2, 1, 3)
    assert states.tolist() == [
        [0, 0],
        [1, 0],
        [2, 0],
        [0, 1],
        [1, 1],
        [2, 1],
        [3, 1],
        [4, 1],
        [0, 2],
        [1, 2],
        [2, 2],
    ]
    assert_allclose(T.toarray(), Ts.T, atol=0)


@pytest.mark.parametrize(
    "z0,r,t", [(1, 0, 1), (2, 1, 3), (2, 2, 3), (3, 4, 7), (1, 5, 6), (4, 2, 9), (2, 4, 6), (2, 0, 5)]
)
def test_chain_matches_exploration(z0, r, t):
    lam = 0.42
    states, T = fa.attack_chain(lam, z0, r, t)
    assert len(states) == r * (r + 1) * z0 // 2 + t * (z0 + 1) == fa.num_states(z0, r, t)
    order, Tref = ref.explore_chain(lam, z0, r, t)
    assert len(order) == len(states)  # every state reachable, none missing
    pos = {tuple(s): i for i, s in enumerate(states.tolist())}
    perm = [pos[s] for s in order]
    assert_allclose(T.toarray()[np.ix_(perm, perm)], Tref, atol=1e-15)
    assert_allclose(np.asarray(T.sum(axis=1)).ravel(), 1.0, atol=1e-15)


def test_chain_too_large_refused():
    with pytest.raises(ValueError, match="refused before allocating"):
        fa.attack_chain(0.5, 2, 10_000, 20_000)


@pytest.mark.parametrize(
    "bad, exc, name",
    [
        ((1.5, 2, 1, 3), ValueError, "lam"),
        ((0.5, 0, 1, 3), ValueError, "z0"),
        ((0.5, -1, 1, 3), ValueError, "z0"),
        ((0.5, 2, 3, 3), ValueError, "r"),
        ((0.5, 2, 1, 0), ValueError, "t"),
        ((0.5, 2.5, 1, 3), TypeError, "z0"),
        ((0.5, 2, "1", 3), TypeError, "r"),
        ((None, 2, 1, 3), TypeError, "lam"),
    ],
)
def test_chain_bad_input(bad, exc, name):
    with pytest.raises(exc, match=names(name)):
        fa.attack_chain(*bad)
    with pytest.raises(exc, match=names(name)):
        fa.stationary_distribution(*bad)


# ---------------------------------------------------------------- stationary law and J_attack


@pytest.mark.parametrize("lam", [0.05, 0.5, 0.95])
@pytest.mark.parametrize("z0,r,t", [(2, 1, 3), (1, 0, 1), (3, 4, 7), (2, 7, 8), (5, 3, 11), (2, 6, 9)])
def test_stationary_solvers_agree(lam, z0, r, t):
    fast = fa.stationary_distribution(lam, z0, r, t)
    gth = fa.stationary_distribution(lam, z0, r, t, method="gth")
    assert_allclose(fast, gth, atol=1e-12, rtol=0)
    _, T = fa.attack_chain(lam, z0, r, t)
    dense = ref.stationary_dense(T.toarray())
    assert_allclose(fast, dense, atol=1e-12)
    assert fast.min() >= 0 and abs(fast.sum() - 1) < 1e-12
    assert fa.balance_residual(lam, z0, r, t, fast) < 1e-13


def test_j_attack_equals_pi_dot_traces(paper):
    rng = np.random.default_rng(5)
    for _ in range(40):
        lam = float(rng.uniform(0.1, 0.9))
        z0 = int(rng.integers(1, 5))
        t = int(rng.integers(1, 15))
        r = int(rng.integers(0, t))
        states, T = fa.attack_chain(lam, z0, r, t)
        pi = ref.stationary_dense(T.toarray())
        tr = paper.h_traces(int(states[:, 0].max()))
        j = fa.j_attack(paper, lam, z0, r, t)
        # The LU reference loses relative accuracy on tiny probabilities weighted by traces up to
        # ~1e9; GTH (no subtractions) does not.
        assert_allclose(j, pi @ tr[states[:, 0]], rtol=1e-9)
        gth = fa.stationary_distribution(lam, z0, r, t, method="gth")
        assert_allclose(j, gth @ tr[states[:, 0]], rtol=1e-13)


def test_j_attack_sanity_laws(paper):
    lam, z0 = 0.5, 2
    # beta = 0 is the online schedule, whatever t.
    for t in (1, 2, 7):
        assert_allclose(fa.j_attack(paper, lam, z0, 0, t), fa.j_online(paper, lam, z0), rtol=1e-13)
    # Rising in r for fixed t, towards J_max as r/t -> 1 with t large.
    t = 400
    js = [fa.j_attack(paper, lam, z0, r, t) for r in range(0, t, 20)] + [
        fa.j_attack(paper, lam, z0, t - 1, t)
    ]
    assert np.all(np.diff(js) > 0)
    jmax = fa.j_max(paper, lam)
    assert js[-1] < jmax and js[-1] > 0.99 * jmax


def test_j_attack_random_vector_systems():
    rng = np.random.default_rng(21)
    for _ in range(10):
        s = fa.LinearSystem(*random_system(rng, int(rng.integers(2, 5))))
        lam = float(rng.uniform(0.3, 0.9))
        z0 = int(rng.integers(1, 4))
        states, T = fa.attack_chain(lam, z0, 3, 5)
        pi = ref.stationary_dense(T.toarray())
        tr = ref.traces(s.A, s.Q, s.pbar, int(states[:, 0].max()))
        assert_allclose(fa.j_attack(s, lam, z0, 3, 5), pi @ tr[states[:, 0]], rtol=1e-10)
        assert fa.j_online(s, lam, z0) <= fa.j_attack(s, lam, z0, 3, 5) <= fa.j_max(s, lam)


def test_ten_million_states(paper):
    # |S| = r(r+1)z0/2 + t(z0+1) >= 10^7 without building the matrix.
    z0, r, t = 2, 3162, 3200
    assert fa.num_states(z0, r, t) > 10**7
    j = fa.j_attack(paper, 0.5, z0, r, t)
    assert fa.j_online(paper, 0.5, z0) < j < fa.j_max(paper, 0.5)
    pi = fa.stationary_distribution(0.5, z0, r, t)
    assert pi.shape == (fa.num_states(z0, r, t),)
    assert abs(pi.sum() - 1) < 1e-12 and pi.min() >= 0
    assert fa.balance_residual(0.5, z0, r, t, pi) < 1e-12


def test_non_coprime_is_its_own_attack(paper):
    # 2 of 6 blocks two flags in a row; 1 of 3 blocks one: different attacks, different J.
    assert fa.j_attack(paper, 0.5, 2, 2, 6) > fa.j_attack(paper, 0.5, 2, 1, 3)


# ---------------------------------------------------------------- the paper's example


def test_paper_example_values(paper):
    """The corrected model's values, each from an independent route (reference chain, series)."""
    lam, z0 = PAPER_LAM, 2
    tr = paper.h_traces(60)
    j_off = ref.offline_direct(tr, lam, [1, 0, 0, 0, 0, 0, 0])
    T, _ = ref.online_chain(lam, z0, 1.0)
    j_on = ref.stationary_dense(T) @ tr[: z0 + 2]
    assert_allclose(fa.j_offline(paper, lam, PAPER_RATIO), j_off, rtol=1e-12)
    assert_allclose(fa.j_online(paper, lam, z0), j_on, rtol=1e-12)
    # The paper's qualitative claims hold in the corrected model.
    assert j_on < j_off
    assert fa.j_attack(paper, lam, z0, 1, 5) < j_off < fa.j_attack(paper, lam, z0, 2, 3)
    assert j_off < fa.j_max(paper, lam)
