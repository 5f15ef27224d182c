"""The route a researcher would write for a scenario the paper's formulas do not cover: the explicit
chain of (holding time tau, everything else e), tau truncated where its tail mass is below 1e-12,
solved with scipy.sparse. ``benches/compare.py --tasks engine`` times it against ``fa.Scenario``.

The peer is given the automaton's K0 and K1 (from ``fa.Scenario(...).automaton()``) and the
truncation level (from the engine's holding-time law) outside its timed region, which favours it:
all it does in the timed region is build the explicit chain, solve its balance equations and sum
J = sum pi(tau, e) Tr h^tau(P̄).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

TAIL = 1e-12


def truncation(scenario, tail: float = TAIL) -> int:
    """The smallest number of holding-time levels L with P(tau >= L) below ``tail``."""
    n = 64
    while True:
        law = scenario.holding_time_law(n)
        if law[-1] < tail:
            above = np.cumsum(law[::-1])[::-1]  # above[k] = P(tau >= k)
            return int(np.argmax(above < tail))
        n *= 2


def traces(A, Q, pbar, n: int) -> np.ndarray:
    """Tr h^tau(P̄) for tau = 0..n-1, with h(X) = A X A' + Q."""
    A, Q, X = np.atleast_2d(A), np.atleast_2d(Q), np.atleast_2d(pbar).copy()
    out = np.empty(n)
    for tau in range(n):
        out[tau] = np.trace(X)
        X = A @ X @ A.T + Q
    return out


def explicit_j(K0: sp.csr_array, K1: sp.csr_array, levels: int, tr: np.ndarray) -> float:
    """J of the explicit (tau, e) chain with tau < levels (the last level lumps the tail)."""
    n = K0.shape[0]
    k0, k1 = K0.tocoo(), K1.tocoo()
    rows, cols, vals = [], [], []
    for tau in range(levels):
        rows += [tau * n + k1.row, tau * n + k0.row]
        cols += [k1.col, min(tau + 1, levels - 1) * n + k0.col]
        vals += [k1.data, k0.data]
    N = levels * n
    T = sp.csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N))
    # Balance equations pi (T - I) = 0 with the last one replaced by sum(pi) = 1 (a state's pin
    # could hit a transient state; a last dense row adds fill to that row only).
    M = (T - sp.csr_array(sp.identity(N, format="csr"))).T.tolil()
    M[N - 1, :] = np.ones(N)
    b = np.zeros(N)
    b[-1] = 1.0
    pi = spla.spsolve(M.tocsc(), b)  # SuperLU with its default COLAMD ordering
    pi /= pi.sum()
    return float(pi.reshape(levels, n).sum(axis=1) @ tr[:levels])


def explicit_j_limited(K0: sp.csr_array, K1: sp.csr_array, levels: int, tr: np.ndarray, gib: float = 8.0):
    """:func:`explicit_j` in a child process limited to ``gib`` GiB of address space: SuperLU's fill
    on the explicit chain grows past any machine's memory long before the engine's solves do, and
    it then aborts the process instead of raising. Returns (J, seconds) or (None, reason)."""
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    q = ctx.Queue()
    child = ctx.Process(target=_child, args=(q, K0, K1, levels, tr, gib))
    child.start()
    child.join()
    if child.exitcode != 0:
        return None, f"the explicit chain's solve failed within {gib:g} GiB (SuperLU's fill)"
    return q.get()


def _child(q, K0, K1, levels, tr, gib):
    import resource
    import time

    limit = int(gib * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    t0 = time.perf_counter()
    j = explicit_j(K0, K1, levels, tr)
    q.put((j, time.perf_counter() - t0))
