"""Every error of the compiled core reaches Python as the exception its kind calls for."""

import numpy as np
import pytest

import fakeack as fa
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


@pytest.mark.parametrize("kind, exc, text", [
    ("invalid", ValueError, "arg: is wrong"),
    ("too_large", ValueError, "arg: the request needs 2 elements, more than the limit of 1"),
    ("not_converged", fa.ConvergenceError, "a solver did not converge after 3 iterations"),
    ("interrupted", KeyboardInterrupt, "interrupted"),
])
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
