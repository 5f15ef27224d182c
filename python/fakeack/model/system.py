"""The process and the sensor's steady-state Kalman filter."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy.typing as npt

from .. import _fakeack
from .._internal.types import FloatArray
from .._internal.validate import as_int, as_matrix, as_real

__all__ = [
    "LinearSystem",
]


class StateSpaceLike(Protocol):
    """What :meth:`LinearSystem.from_statespace` reads: the A and C matrices (python-control's
    ``StateSpace``, scipy's ``dlti`` and the like)."""

    @property
    def A(self) -> npt.ArrayLike: ...

    @property
    def C(self) -> npt.ArrayLike: ...


class LinearSystem:
    r"""An LTI process :math:`x_{k+1} = A x_k + w_k`, :math:`y_k = C x_k + v_k` observed by a smart
    sensor whose Kalman filter is in steady state (paper, Sec. II-A, eqs. (1)-(2), (5)).

    Parameters
    ----------
    A : array_like or float
        State matrix, ``(n_x, n_x)``; a scalar means a 1x1 system.
    C : array_like or float
        Output matrix, ``(n_y, n_x)``.
    Q : array_like or float
        Process-noise covariance, ``(n_x, n_x)``, symmetric positive semi-definite.
    R : array_like or float
        Measurement-noise covariance, ``(n_y, n_y)``, symmetric positive definite.
    tol : float, optional
        Relative tolerance of the Riccati doubling iteration (default ``1e-14``).
    max_iter : int, optional
        Cap on doubling steps (default 200); exceeding it raises
        :class:`fakeack.ConvergenceError` saying after how many.

    Raises
    ------
    TypeError
        If an argument is not numeric.
    ValueError
        If shapes disagree, an entry is NaN/inf, Q is not PSD, R is not PD, or (A, C) is not
        detectable (the message names the unobservable unstable eigenvalues).

    Notes
    -----
    :attr:`pbar` is the positive semi-definite solution of :math:`\tilde g(h(X)) = X` with
    :math:`h(X) = AXA' + Q` and :math:`\tilde g(X) = X - XC'(CXC' + R)^{-1}CX`. It is computed from
    the stabilising solution of the filtering DARE by the structure-preserving doubling algorithm;
    :attr:`residual` reports :math:`\|\tilde g(h(\bar P)) - \bar P\|_F / \|\bar P\|_F`.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)    # the paper's example
    >>> round(float(s.pbar[0, 0]), 6)
    0.924458
    """

    __slots__ = ("_A", "_C", "_Q", "_R", "_core", "_tol", "_max_iter")

    def __init__(
        self,
        A: npt.ArrayLike,
        C: npt.ArrayLike,
        Q: npt.ArrayLike,
        R: npt.ArrayLike,
        *,
        tol: float = _fakeack.DEFAULT_TOL,
        max_iter: int = _fakeack.DEFAULT_MAX_ITER,
    ) -> None:
        a = as_matrix("A", A)
        n = a.shape[0]
        if a.shape != (n, n):
            raise ValueError(f"A must be square, found shape {a.shape}")
        c = as_matrix("C", C)
        if c.shape[1] != n:
            raise ValueError(
                f"Incompatible dimensions of C matrix; expected ({c.shape[0]}, {n}) but found {c.shape}"
            )
        m = c.shape[0]
        q = as_matrix("Q", Q, shape=(n, n))
        r = as_matrix("R", R, shape=(m, m))
        tol = as_real("tol", tol)
        if tol <= 0:
            raise ValueError(f"tol must be positive, got {tol}")
        max_iter = as_int("max_iter", max_iter, minimum=1)
        self._core = _fakeack.LinearSystem(a, c, q, r, tol, max_iter)
        for arr in (a, c, q, r):
            arr.setflags(write=False)
        self._A, self._C, self._Q, self._R = a, c, q, r
        self._tol, self._max_iter = tol, max_iter

    def __reduce__(self) -> tuple[Callable[..., LinearSystem], tuple[object, ...]]:
        # Pickled as its matrices and solver settings (for process pools and Dask workers); the
        # copy solves for P̄ again, deterministically, so it computes exactly what this one does.
        return (_rebuild, (*self._matrices(), self._tol, self._max_iter))

    @classmethod
    def from_statespace(
        cls,
        sys: StateSpaceLike,
        Q: npt.ArrayLike,
        R: npt.ArrayLike,
        *,
        tol: float = _fakeack.DEFAULT_TOL,
        max_iter: int = _fakeack.DEFAULT_MAX_ITER,
    ) -> LinearSystem:
        r"""The system of a discrete-time state-space model, with the noise covariances added.

        Parameters
        ----------
        sys : control.StateSpace or object with ``A`` and ``C`` attributes
            A discrete-time python-control ``StateSpace`` (``dt`` True or positive), a
            ``scipy.signal.dlti`` state-space model, or any object with ``A`` and ``C``
            attributes. B and D are not used: the process noise enters the state directly
            (:math:`x_{k+1} = A x_k + w_k`), so noise that enters through B belongs in Q as
            :math:`B Q_w B'`.
        Q : array_like or float
            Process-noise covariance, ``(n_x, n_x)``.
        R : array_like or float
            Measurement-noise covariance, ``(n_y, n_y)``.
        tol : float, optional
            As for :class:`LinearSystem`.
        max_iter : int, optional
            As for :class:`LinearSystem`.

        Returns
        -------
        LinearSystem

        Raises
        ------
        TypeError
            If ``sys`` has no ``A`` or ``C`` attribute.
        ValueError
            If ``sys`` is a continuous-time model (the analysis is in discrete time: sample it
            first, e.g. ``sys.sample(Ts)`` in python-control), or for any reason
            :class:`LinearSystem` gives.

        Examples
        --------
        >>> import types
        >>> import fakeack as fa
        >>> model = types.SimpleNamespace(A=[[1.2]], C=[[0.7]])   # e.g. control.ss(1.2, 1, 0.7, 0, dt=1)
        >>> fa.LinearSystem.from_statespace(model, Q=0.8, R=0.8)
        LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
        """
        missing = [k for k in "AC" if not hasattr(sys, k)]
        if missing:
            raise TypeError(
                f"sys must be a state-space model with A and C attributes; "
                f"{type(sys).__name__} has no {' or '.join(missing)}"
            )
        if _is_continuous(sys):
            raise ValueError(
                f"sys is a continuous-time model ({type(sys).__name__}, dt={getattr(sys, 'dt', None)!r}); "
                "the fake-ACK analysis is in discrete time: sample it first (python-control: sys.sample(Ts))"
            )
        return cls(sys.A, sys.C, Q, R, tol=tol, max_iter=max_iter)

    # Read-only views: a system is immutable once P̄ is solved.
    @property
    def A(self) -> FloatArray:
        """State matrix (read-only)."""
        return self._A

    @property
    def C(self) -> FloatArray:
        """Output matrix (read-only)."""
        return self._C

    @property
    def Q(self) -> FloatArray:
        """Process-noise covariance (read-only)."""
        return self._Q

    @property
    def R(self) -> FloatArray:
        """Measurement-noise covariance (read-only)."""
        return self._R

    @property
    def n_x(self) -> int:
        """State dimension."""
        return int(self._A.shape[0])

    @property
    def n_y(self) -> int:
        """Output dimension."""
        return int(self._C.shape[0])

    @property
    def pbar(self) -> FloatArray:
        r"""Steady-state error covariance :math:`\bar P` of the sensor's Kalman filter (eq. (5))."""
        return self._core.pbar()

    @property
    def residual(self) -> float:
        r"""Relative residual :math:`\|\tilde g(h(\bar P)) - \bar P\|_F / \|\bar P\|_F`."""
        return self._core.residual

    @property
    def iterations(self) -> int:
        """Doubling steps the Riccati solver used."""
        return self._core.iterations

    @property
    def spectral_radius(self) -> float:
        r""":math:`\rho(A)`, the largest eigenvalue modulus of A."""
        return self._core.spectral_radius

    def h_traces(self, n: int) -> FloatArray:
        r"""Traces :math:`[\mathrm{Tr}\,h^0(\bar P), \ldots, \mathrm{Tr}\,h^n(\bar P)]`.

        Parameters
        ----------
        n : int
            Largest power, ``n >= 0``.

        Returns
        -------
        numpy.ndarray
            ``n + 1`` floats, increasing (Lemma 2.1). They grow like :math:`\rho(A)^{2i}`; entries
            beyond the double range are ``inf``, never NaN.
        """
        n = as_int("n", n, minimum=0)
        return self._core.weighted_traces(1.0, n)

    def weighted_traces(self, weight: float, n: int) -> FloatArray:
        r""":math:`w_i = \mathrm{weight}^i\,\mathrm{Tr}\,h^i(\bar P)` for :math:`i = 0..n`.

        The weight is carried inside the matrix recursion, so the result stays finite wherever
        :math:`\mathrm{weight}\cdot\rho(A)^2 < 1`, even where :math:`\mathrm{Tr}\,h^i(\bar P)` alone
        overflows. With ``weight = 1 - lam`` these are the terms of every cost J in the paper.

        Parameters
        ----------
        weight : float
            Non-negative weight, typically ``1 - lam``.
        n : int
            Largest power, ``n >= 0``.
        """
        weight = as_real("weight", weight)
        if weight < 0:
            raise ValueError(f"weight must be non-negative, got {weight}")
        n = as_int("n", n, minimum=0)
        return self._core.weighted_traces(weight, n)

    def __repr__(self) -> str:
        if self.n_x == 1 and self.n_y == 1:
            vals = ", ".join(f"{k}={float(v[0, 0]):g}" for k, v in zip("ACQR", self._matrices(), strict=True))
            return f"LinearSystem({vals})"
        return f"LinearSystem(n_x={self.n_x}, n_y={self.n_y})"

    def _matrices(self) -> tuple[FloatArray, ...]:
        return (self._A, self._C, self._Q, self._R)


def _is_continuous(sys: object) -> bool:
    """Whether a state-space object is in continuous time.

    python-control marks continuous time with ``dt == 0`` (True or a positive number is discrete,
    None unspecified); scipy.signal with the class (``lti`` against ``dlti``, whose continuous
    models have ``dt`` None). Other objects carry no time base and are taken as discrete.
    """
    if type(sys).__module__.startswith("scipy.signal"):
        from scipy import signal

        return isinstance(sys, signal.lti)
    dt = getattr(sys, "dt", None)
    return dt is not None and dt == 0


def _rebuild(
    A: FloatArray, C: FloatArray, Q: FloatArray, R: FloatArray, tol: float, max_iter: int
) -> LinearSystem:
    """Unpickle a :class:`LinearSystem`."""
    return LinearSystem(A, C, Q, R, tol=tol, max_iter=max_iter)


def compiled(system: object) -> _fakeack.LinearSystem:
    """The compiled system behind a :class:`LinearSystem` (TypeError otherwise)."""
    if not isinstance(system, LinearSystem):
        raise TypeError(f"system must be a fakeack.LinearSystem, got {type(system).__name__}")
    return system._core
