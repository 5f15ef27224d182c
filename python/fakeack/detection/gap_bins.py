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

__all__ = ["bin_rates"]

#: Largest (states x ages) of the extended chain, about a second of sparse LU.
MAX_EXTENDED_STATES = 2 * 10**5


def bin_rates(process: FlagProcess, edges: IntArray) -> tuple[FloatArray, FloatArray]:
    """(r, Σ): the bin counts' mean and asymptotic covariance per step (module docstring).

    Bin i holds the gaps in [edges[i], edges[i+1]), the last one [edges[-1], inf); edges[0] = 1.
    """
    edges = np.asarray(edges, dtype=np.int64)
    k, S = len(edges), process.n_states
    L = max(int(edges[-1]), 1)  # ages 0..L-1; a delivery from age a is a gap of a + 1
    if S * L > MAX_EXTENDED_STATES:
        raise ValueError(
            f"edges: the interval test's bins up to gap {L} on an automaton of {S} states need "
            f"{S * L} states, more than {MAX_EXTENDED_STATES}"
        )
    age = np.arange(L)
    bin_of_age = np.searchsorted(edges, age + 1, side="right") - 1  # the bin of gap a + 1
    shift = sp.csr_array((np.ones(L), (age, np.minimum(age + 1, L - 1))), shape=(L, L))
    restart = sp.csr_array((np.ones(L), (age, np.zeros(L, dtype=np.int64))), shape=(L, L))
    D0, D1 = process.D0, process.D1
    P = (sp.kron(shift, D0) + sp.kron(restart, D1)).tocsr()
    pi = _stationary(P)
    d = np.asarray(D1.sum(axis=1)).ravel()
    # phi[x, b]: the expected bin reward of a step from x = (a, e); index x = a S + e.
    rows = np.arange(L * S)
    phi = sp.csr_array((np.tile(d, L), (rows, np.repeat(bin_of_age, S))), shape=(L * S, k)).toarray()
    r = pi @ phi
    h = _poisson(P, phi - r, pi)
    # M = sum_x pi_x e_b(x) (D1 h0)(e_x)': every D1 move lands at age 0, state e'.
    h0 = h[:S]  # h at (0, e')
    lands = np.asarray(D1 @ h0)  # (S, k): sum_e' D1[e, e'] h(0, e')
    M = np.zeros((k, k))
    weights = pi.reshape(L, S)  # pi at (a, e)
    for b in range(k):
        at = bin_of_age == b
        if at.any():
            M[b] = weights[at].sum(axis=0) @ lands
    sigma = np.diag(r) - np.outer(r, r) + M + M.T
    return r, 0.5 * (sigma + sigma.T)
