"""Every error of the compiled core reaches Python as the exception its kind calls for."""

import math

import numpy as np
import pytest
import scipy.linalg as sla
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import random_system
from fakeack import _fakeack


def test_invalid_argument_is_a_value_error_naming_the_argument():
    with pytest.raises(ValueError, match=r"^r: must be smaller than t = 3"):
        _fakeack.Attack.periodic(3, 3)
    with pytest.raises(ValueError, match=r"^z0: must be at least 1"):
        _fakeack.high_power_rate(0.5, 0, 1.0)


def test_too_large_is_refused_before_allocating():
    with pytest.raises(ValueError, match=r"refused before allocating"):
        _fakeack.attack_chain(0.5, 2, 10**6, 10**6 + 1)


def test_non_convergence_is_a_convergence_error():
    # The paper's system needs several doubling steps; one is not enough at the default tolerance.
    assert fa.LinearSystem(1.2, 0.7, 0.8, 0.8).iterations > 1
    with pytest.raises(fa.ConvergenceError, match="did not converge after 1 iterations"):
        fa.LinearSystem(1.2, 0.7, 0.8, 0.8, max_iter=1)
    assert issubclass(fa.ConvergenceError, ValueError)


def test_solver_defaults_come_from_the_core():
    import inspect

    sig = inspect.signature(fa.LinearSystem.__init__)
    assert sig.parameters["tol"].default == _fakeack.DEFAULT_TOL
    assert sig.parameters["max_iter"].default == _fakeack.DEFAULT_MAX_ITER


def test_malformed_csr_is_a_value_error():
    bad = np.array([0, 2], dtype=np.int64)
    with pytest.raises(ValueError, match="T: malformed CSR"):
        _fakeack.stationary_gth(bad, np.array([0], dtype=np.int64), np.array([1.0]))


@pytest.mark.parametrize(
    "kind, exc, text",
    [
        ("invalid", ValueError, "arg: is wrong"),
        ("too_large", ValueError, "arg: the request needs 2 elements, more than the limit of 1"),
        ("not_converged", fa.ConvergenceError, "a solver did not converge after 3 iterations"),
        ("interrupted", KeyboardInterrupt, "interrupted"),
    ],
)
def test_every_core_error_maps_to_its_exception(kind, exc, text):
    with pytest.raises(exc, match=text):
        _fakeack.raise_core_error(kind)
    with pytest.raises(ValueError, match="kind"):
        _fakeack.raise_core_error("other")


def test_offline_cost_beyond_the_double_range_is_inf_not_nan():
    """(1 - lam) rho(A)^2 = 1.08 > 1: a period of 16384 makes J finite but far beyond a double.
    It must be +inf (IEEE overflow), never NaN; shorter periods stay finite and increasing."""
    import math
    from fractions import Fraction

    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    assert fa.j_offline(s, 0.25, Fraction(1, 16384)) == math.inf
    small = [fa.j_offline(s, 0.25, Fraction(1, q)) for q in (64, 1024, 4096)]
    assert all(math.isfinite(x) for x in small) and small == sorted(small)


# ---------------------------------------------------------------- solver limits and attributes


def _closed_loop_radius(A, C, Q, R):
    """rho(A (I - K C)) at scipy's stabilising prior P: the doubling's contraction."""
    A, C, Q, R = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (A, C, Q, R))
    P = sla.solve_discrete_are(A.T, C.T, Q, R)
    K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    return max(abs(np.linalg.eigvals(A @ (np.eye(A.shape[0]) - K @ C))))


SOLVER_CASES = [
    ((1.2, 0.7, 0.8, 0.8), "paper"),
    ((1.0, 0.1, 1.0, 1.0), "slow"),  # closed loop 0.909: the doubling needs 9 steps
    ((1.0, 0.001, 1.0, 1.0), "slower"),  # closed loop 0.999: 16 steps
    ((np.array([[1.1, 0.3], [0.0, 0.7]]), [[1.0, 0.5]], np.eye(2) * 0.5, 0.3), "n=2"),
]


@pytest.mark.parametrize("args, name", SOLVER_CASES)
def test_iterations_and_max_iter(args, name):
    """LinearSystem.iterations: the doubling squares the closed-loop contraction rho each step,
    so after k steps the change is about rho^(2^k): k = ceil(log2(log tol / log rho)) within
    one. max_iter = k reproduces P̄; max_iter = k - 1 raises ConvergenceError naming k - 1.

    Kills: an off-by-one in the reported count, max_iter not honoured (one step more or less),
    the convergence test on the absolute instead of the relative change, a wrong tolerance."""
    rho = _closed_loop_radius(*args)
    for tol in (1e-2, 1e-8, 1e-14):
        s = fa.LinearSystem(*args, tol=tol)
        k_pred = math.ceil(math.log2(math.log(tol) / math.log(rho)))
        assert abs(s.iterations - k_pred) <= 1, (name, tol, s.iterations, k_pred)
    s = fa.LinearSystem(*args)
    k = s.iterations
    assert_allclose(fa.LinearSystem(*args, max_iter=k).pbar, s.pbar, rtol=0, atol=0)
    with pytest.raises(fa.ConvergenceError, match=rf"did not converge after {k - 1} iterations"):
        fa.LinearSystem(*args, max_iter=k - 1)


def test_tolerance_limits():
    """A looser tolerance never needs more steps; tol and max_iter outside their domain are
    refused naming the argument; a tolerance below what doubles can resolve still converges when
    the contraction underflows to zero (A_k = 0), rather than running to max_iter."""
    its = [fa.LinearSystem(1.0, 0.01, 1.0, 1.0, tol=t).iterations for t in (1e-1, 1e-4, 1e-8, 1e-12)]
    assert its == sorted(its) and its[0] < its[-1]
    assert fa.LinearSystem(1.2, 0.7, 0.8, 0.8, tol=1e-300).iterations < 12
    for bad in (0.0, -1e-3, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="tol"):
            fa.LinearSystem(1.2, 0.7, 0.8, 0.8, tol=bad)
    with pytest.raises(ValueError, match="max_iter"):
        fa.LinearSystem(1.2, 0.7, 0.8, 0.8, max_iter=0)
    err = pytest.raises(fa.ConvergenceError, fa.LinearSystem, 1.0, 0.001, 1.0, 1.0, max_iter=3)
    assert isinstance(err.value, ValueError) and "after 3 iterations" in str(err.value)


@pytest.mark.parametrize(
    "A, rho",
    [
        (1.2, 1.2),
        (-0.9, 0.9),
        (np.array([[0.0, -1.1], [1.1, 0.0]]), 1.1),  # complex pair +-1.1i
        (np.array([[0.5, 1.0], [0.0, 0.5]]), 0.5),  # Jordan block
        (np.array([[0.0, 1.0], [0.0, 0.0]]), 0.0),  # nilpotent
        (np.diag([0.3, -1.25, 1.2]), 1.25),
    ],
)
def test_spectral_radius_closed_forms(A, rho):
    """Kills: the largest real part (or eigenvalue) instead of the largest modulus."""
    n = np.atleast_2d(A).shape[0]
    s = fa.LinearSystem(A, np.eye(n), np.eye(n), np.eye(n))
    assert s.spectral_radius == pytest.approx(rho, abs=1e-12)


def test_spectral_radius_random_against_numpy():
    rng = np.random.default_rng(7)
    for n in (2, 5, 30):
        A, C, Q, R = random_system(rng, n)
        s = fa.LinearSystem(A, C, Q, R)
        assert s.spectral_radius == pytest.approx(max(abs(np.linalg.eigvals(A))), rel=1e-10)
        # The stability test of J_max (Model note 5) uses it: inf exactly past a rho^2 = 1.
        lam_edge = 1 - 1 / s.spectral_radius**2
        if 0.01 < lam_edge < 0.99:
            assert fa.j_max(s, lam_edge * 0.99) == math.inf
            assert math.isfinite(fa.j_max(s, min(lam_edge * 1.01 + 1e-3, 0.999)))


def _states_with_count(target):
    """(z0, r, t) with num_states = r (r + 1) z0 / 2 + t (z0 + 1) == target exactly."""
    for z0 in (1, 2, 3):
        for r in range(1000, 1100):
            rest = target - r * (r + 1) * z0 // 2
            if (r * (r + 1) * z0) % 2 == 0 and rest % (z0 + 1) == 0 and rest // (z0 + 1) > r:
                return z0, r, rest // (z0 + 1)
    raise AssertionError(target)


def test_size_limits():
    """MAX_BUILD_STATES (2e7, the README's limit) for built chains, MAX_VECTOR_STATES (1e8) for
    stationary vectors: one state over the limit is refused before allocating, with the
    requested count and the limit in the message; the structured cost needs neither.

    Kills: a limit other than the documented one, the check after the allocation, the message
    without the numbers."""
    assert fa.MAX_BUILD_STATES == 2 * 10**7 and fa.MAX_VECTOR_STATES == 10**8
    z0, r, t = _states_with_count(fa.MAX_BUILD_STATES + 1)
    assert fa.num_states(z0, r, t) == fa.MAX_BUILD_STATES + 1
    with pytest.raises(
        ValueError, match=rf"{fa.MAX_BUILD_STATES + 1}.*{fa.MAX_BUILD_STATES}.*refused before allocating"
    ):
        fa.attack_chain(0.5, z0, r, t)
    with pytest.raises(ValueError, match="refused before allocating"):
        fa.stationary_distribution(0.5, z0, r, t, method="gth")  # GTH builds the chain
    z0, r, t = _states_with_count(fa.MAX_VECTOR_STATES + 1)
    with pytest.raises(
        ValueError, match=rf"{fa.MAX_VECTOR_STATES + 1}.*{fa.MAX_VECTOR_STATES}.*refused before allocating"
    ):
        fa.stationary_distribution(0.5, z0, r, t)
    paper = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    assert math.isfinite(fa.j_attack(paper, 0.5, z0, r, t))  # O(r z0): no vector needed


def test_system_matrices_are_read_only_and_from_statespace_passes_its_solver_options():
    """A system's matrices cannot be changed behind its P̄ (kills `write=False` turned True);
    `from_statespace` hands `tol` and `max_iter` on (kills either dropped: one iteration must
    fail, and a loose tolerance must stop the doubling sooner)."""
    control = pytest.importorskip("control")
    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    for name in "ACQR":
        with pytest.raises(ValueError, match="read-only"):
            getattr(s, name)[0, 0] = 2.0
    plant = control.ss(1.2, 1, 0.7, 0, dt=True)
    with pytest.raises(fa.ConvergenceError):
        fa.LinearSystem.from_statespace(plant, Q=0.8, R=0.8, max_iter=1)
    tight = fa.LinearSystem.from_statespace(plant, Q=0.8, R=0.8)
    loose = fa.LinearSystem.from_statespace(plant, Q=0.8, R=0.8, tol=1e-2)
    assert loose.iterations < tight.iterations


@pytest.mark.parametrize(
    "T, message",
    [
        (np.ones((2, 3)) / 3, "non-empty square"),
        (np.zeros((0, 0)), "non-empty square"),
        (np.ones((1, 1, 1)), None),
        (np.array([[1.5, -0.5], [0.5, 0.5]]), "non-negative"),
        (np.array([[np.nan, 1.0], [0.5, 0.5]]), "finite"),
        (np.array([[0.5, 0.5 + 2e-10], [0.5, 0.5]]), "row-stochastic"),
    ],
)
def test_stationary_gth_checks_its_matrix(T, message):
    """Each defect of T is refused with its reason (kills each clause of the checks turned into
    another, or dropped); zero entries and a single state are valid (kills `< 0` turned `<= 0`
    and the empty check turned `== 1`)."""
    with pytest.raises((ValueError, TypeError), match=message):
        fa.stationary_gth(T)


def test_stationary_gth_of_the_smallest_chains():
    """One state; a zero entry, dense or stored explicitly in a sparse T (valid: only negative
    entries are refused); rows off by less than the 1e-10 tolerance."""
    import scipy.sparse as sp

    assert fa.stationary_gth(np.array([[1.0]])).tolist() == [1.0]
    stored_zero = sp.csr_array((np.array([0.0, 1.0, 1.0]), np.array([0, 1, 0]), np.array([0, 2, 3])))
    assert_allclose(fa.stationary_gth(stored_zero), [0.5, 0.5], rtol=1e-15)
    pi = fa.stationary_gth(np.array([[0.0, 1.0], [0.5, 0.5]]))
    assert_allclose(pi, [1 / 3, 2 / 3], rtol=1e-15)
    pi = fa.stationary_gth(np.array([[0.5, 0.5 + 5e-11], [0.5, 0.5]]))
    assert_allclose(pi, [0.5, 0.5], atol=1e-10)
