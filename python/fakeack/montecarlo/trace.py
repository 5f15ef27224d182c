"""The result type of the exact finite-horizon curves, :class:`TraceCurve`.

A module of its own, importing only the annotation names, so that both routes that compute the curve,
:func:`fakeack.expected_trace_curve` and :meth:`fakeack.Scenario.cost_curve`, return it without
importing each other (:func:`fakeack.expected_trace_curve` hands Markov channels to the engine).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .._internal.types import FloatArray, IntArray

__all__ = [
    "TraceCurve",
]


@dataclass(frozen=True)
class TraceCurve:
    """Exact :math:`\\mathbb E[\\mathrm{Tr}\\,P_k]` and :math:`J_k` for k = 1..horizon."""

    k: IntArray
    trace: FloatArray
    """E[Tr P_k]."""
    j_k: FloatArray
    """J_k = (1/k) Σ_{i<=k} E[Tr P_i] (the paper's Sec. V quantity)."""

    # Array-like: np.asarray(curve) and curve[k-1] give E[Tr P_k].
    def __array__(
        self, dtype: npt.DTypeLike | None = None, copy: bool | None = None
    ) -> npt.NDArray[np.generic]:
        return np.asarray(self.trace, dtype=dtype)

    def __len__(self) -> int:
        return len(self.trace)

    def __getitem__(self, index: int | slice) -> float | FloatArray:
        return self.trace[index]
