r"""Traces :math:`\mathrm{Tr}\,h^i(\bar P)` in logarithms, and sums of them against probabilities.

The traces grow like :math:`\rho(A)^{2i}` and pass the double range (near i = 1950 on the paper's
example), while the probabilities they are weighted by shrink; a product of the two is often a
double even when the trace alone is not. The recursion carries a scale factor beside a matrix of
trace one, so ``log_traces`` is finite for every i.
"""

from __future__ import annotations

import math

import numpy as np

from .._internal.types import FloatArray
from ..model.system import LinearSystem

__all__ = ["log_traces", "weighted_sum"]

#: Below this largest log-trace, traces are used as doubles (exp(700) ~ 1e304).
_LOG_SAFE = 700.0


def log_traces(system: LinearSystem, n: int) -> tuple[FloatArray, FloatArray, float]:
    r"""``log Tr h^i(P̄)`` for i = 0..n, and :math:`h^n(\bar P) = e^{s}\,Y` as ``(Y, s)``.

    ``-inf`` where a trace is 0 (only when :math:`\bar P = 0` and Q = 0 leave it so).
    """
    A, Q = system.A, system.Q
    X = np.array(system.pbar, dtype=np.float64)
    scale = 0.0
    out = np.empty(n + 1)
    for i in range(n + 1):
        if i:
            # h(e^s X) = e^s (A X A' + e^{-s} Q); exp(-s) underflows to 0 once Q no longer counts.
            X = A @ X @ A.T + math.exp(-scale) * Q
        t = float(np.trace(X))
        if t > 0.0:
            X /= t
            scale += math.log(t)
            out[i] = scale
        else:
            out[i] = -math.inf
    return out, X, scale


def weighted_sum(prob: FloatArray, logtr: FloatArray) -> FloatArray:
    r""":math:`\sum_m \mathrm{prob}[..., m]\,\mathrm{tr}_m` over the last axis, ``inf`` only when the
    exact value is beyond the double range (zero probabilities contribute 0 whatever the trace)."""
    n = prob.shape[-1]
    lt = logtr[:n]
    if np.max(lt) < _LOG_SAFE:
        return np.asarray(prob @ np.exp(lt), dtype=np.float64)
    with np.errstate(divide="ignore"):
        v = np.log(prob) + lt
    top = np.max(v, axis=-1, keepdims=True)
    finite_top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(over="ignore"):
        out = np.exp(finite_top[..., 0]) * np.sum(np.exp(v - finite_top), axis=-1)
    return np.asarray(out, dtype=np.float64)
