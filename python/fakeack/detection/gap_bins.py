r"""The interval test's bin counts under any channel and attack, from the flag process.

The counts :math:`O_b` of delivered flag-ACKs whose gap since the previous delivery falls in bin b
are an additive functional of the chain :math:`(a_k, e_k)`: the engine's automaton state e and
the age a (steps since the last delivery, capped at the last edge minus one). It moves by
:math:`D_0` to :math:`(\min(a + 1, L - 1), e')` and by :math:`D_1` to :math:`(0, e')`, and a
:math:`D_1` move from age a adds one to the bin of the gap a + 1. With :math:`\pi` its stationary
law and :math:`\varphi(a, e) = (D_1\mathbf 1)_e\, \mathbf e_{b(a+1)}` the expected reward of a
step, the counts of n steps have mean :math:`n r`, :math:`r = \pi\varphi`, and covariance
:math:`\approx n\Sigma` with

.. math:: \Sigma = \mathrm{diag}(r) - r r^\top + M + M^\top,\qquad
          M = \sum_x \pi_x \sum_y D_1(x, y)\, \mathbf e_{b(x)}\, h(y)^\top,

where :math:`h` solves the Poisson equation :math:`(I - P)h = \varphi - r`, :math:`\pi h = 0`
(the lag-l covariances :math:`E_\pi[R_0 (P^{l-1}(\varphi - r))(X_1)^\top]` summed over l >= 1).
On the paper's channel under a built-in attack this is the Markov renewal covariance of
:meth:`fakeack.detection.intervals._Walk.time_covariance`, derived there over the gaps instead
of the steps; the tests compare the two.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._internal.types import FloatArray, IntArray
from .process import FlagProcess, _poisson, _stationary

__all__ = ["bin_rates", "conditioned_bin_rates"]

#: Largest (states x ages) of the extended chain, about a second of sparse LU.
MAX_EXTENDED_STATES = 2 * 10**5


def bin_rates(process: FlagProcess, edges: IntArray) -> tuple[FloatArray, FloatArray]:
    """(r, Σ): the bin counts' mean and asymptotic covariance per step (module docstring).

    Bin i holds the gaps in [edges[i], edges[i+1]), the last one [edges[-1], inf); edges[0] = 1.
    """
    P0, P1, bins, k = _extended(process, edges, 1)
    return _moments(P0, P1, bins, k)


def conditioned_bin_rates(
    process: FlagProcess, edges: IntArray, min_gap: int
) -> tuple[FloatArray, FloatArray, float]:
    r"""(r, Σ, ρ) of the bin counts given that no gap is shorter than ``min_gap``.

    The deliveries from an age below ``min_gap - 1`` (the support check's alarms) are removed
    from the extended chain, which leaves a substochastic kernel :math:`\tilde P` with Perron
    root ρ and right eigenvector h. Conditioned on surviving a long window the chain moves by the
    Doob transform :math:`P_h(x, y) = \tilde P(x, y) h(y) / (\rho h(x))` (away from the window's
    ends), and the bin counts are its additive functional: the interval statistic's law in a
    window the support check let pass.
    """
    P0, P1, bins, k = _extended(process, edges, min_gap)
    P = (P0 + P1).tocsr()
    rho, h = _perron(P)
    live = h > 0
    scale = np.where(live, h, 1.0)
    D = _diagonal(1.0 / (rho * scale))
    H = _diagonal(np.where(live, h, 0.0))
    P0h, P1h = (D @ P0 @ H).tocsr(), (D @ P1 @ H).tocsr()
    stuck = np.flatnonzero(~live)  # never reached by a surviving path: a self-loop keeps P_h stochastic
    P0h = (P0h + sp.csr_array((np.ones(stuck.size), (stuck, stuck)), shape=P.shape)).tocsr()
    r, sigma = _moments(P0h, P1h, bins, k)
    return r, sigma, rho


def _extended(
    process: FlagProcess, edges: IntArray, min_gap: int
) -> tuple[sp.csr_array, sp.csr_array, IntArray, int]:
    """The chain on (age, state) split by deliveries (P1) and the rest (P0), without the
    deliveries from an age below ``min_gap - 1``; each state's bin (of the gap a delivery from it
    closes); index x = a S + e."""
    edges = np.asarray(edges, dtype=np.int64)
    k, S = len(edges), process.n_states
    L = max(int(edges[-1]), int(min_gap), 1)  # ages 0..L-1; a delivery from age a is a gap of a + 1
    if S * L > MAX_EXTENDED_STATES:
        raise ValueError(
            f"edges: the interval test's bins up to gap {L} on an automaton of {S} states need "
            f"{S * L} states, more than {MAX_EXTENDED_STATES}"
        )
    age = np.arange(L)
    bin_of_age = np.searchsorted(edges, age + 1, side="right") - 1  # the bin of gap a + 1
    shift = sp.csr_array((np.ones(L), (age, np.minimum(age + 1, L - 1))), shape=(L, L))
    kept = age >= min_gap - 1
    restart = sp.csr_array(
        (np.ones(kept.sum()), (age[kept], np.zeros(kept.sum(), dtype=np.int64))), shape=(L, L)
    )
    P0 = sp.kron(shift, process.D0).tocsr()
    P1 = sp.kron(restart, process.D1).tocsr()
    return P0, P1, np.repeat(bin_of_age, S), k


def _moments(P0: sp.csr_array, P1: sp.csr_array, bins: IntArray, k: int) -> tuple[FloatArray, FloatArray]:
    """(r, Σ) of the counts of P1 moves by the bin of the state they leave, for the stochastic
    chain P0 + P1 (module docstring)."""
    P = (P0 + P1).tocsr()
    n = P.shape[0]
    pi = _stationary(P)
    d = np.asarray(P1.sum(axis=1)).ravel()
    phi = sp.csr_array((d, (np.arange(n), bins)), shape=(n, k)).toarray()
    r = pi @ phi
    h = _poisson(P, phi - r, pi)
    # M = sum_x pi_x e_b(x) (P1 h)(x)': the lag covariances through the Poisson equation.
    lands = np.asarray(P1 @ h)  # (n, k)
    M = np.zeros((k, k))
    np.add.at(M, bins, pi[:, None] * lands)
    sigma = np.diag(r) - np.outer(r, r) + M + M.T
    return r, 0.5 * (sigma + sigma.T)


def _diagonal(values: FloatArray) -> sp.csr_array:
    """A diagonal sparse array (``scipy.sparse.diags_array`` needs SciPy 1.11; we support 1.10)."""
    idx = np.arange(len(values))
    return sp.csr_array((values, (idx, idx)), shape=(len(values), len(values)))


def _perron(P: sp.csr_array, tol: float = 1e-14, max_iter: int = 100_000) -> tuple[float, FloatArray]:
    """Perron root and right eigenvector (max 1) of a nonnegative substochastic matrix, by power
    iteration on (I + P)/2, which has the same eigenvector and no periodicity."""
    h = np.ones(P.shape[0])
    lazy = 0.5 * (sp.identity(P.shape[0], format="csr") + P)
    for _ in range(max_iter):
        new = lazy @ h
        top = float(new.max())
        if top <= 0.0:
            raise ValueError("min_gap: every path of the chain has a short gap")
        new /= top
        if np.abs(new - h).max() < tol:
            return 2.0 * top - 1.0, new
        h = new
    raise ValueError(f"min_gap: the conditioned chain's eigenvector did not settle in {max_iter} steps")
