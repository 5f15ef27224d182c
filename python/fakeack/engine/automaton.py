r"""An automaton E given as :math:`K_0` and :math:`K_1`: the checks and the conversion for
:meth:`fakeack.Scenario.from_automaton`.

The compiled core checks the rest (row sums of :math:`K_0 + K_1`, the initial law, that it reaches
every state, that an arrival is reachable from every state) and names the argument too.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from .._internal.validate import as_int

__all__ = ["automaton_args"]

_Coo = tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.float64]]


def _shape(name: str, m: object) -> tuple[int, int]:
    """The shape of a square 2-D sparse or dense matrix of real numbers."""
    if sp.issparse(m):
        arr: Any = m
    else:
        if m is None or isinstance(m, (str, bytes, bool)):
            raise TypeError(f"{name} must be a scipy.sparse array or a 2-D array, got {type(m).__name__}")
        try:
            arr = np.asarray(m)
        except Exception as exc:  # ragged lists and the like
            raise ValueError(f"{name}: cannot be read as an array ({exc})") from exc
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
        raise ValueError(f"{name} must be a square 2-D matrix, got shape {arr.shape}")
    return int(arr.shape[0]), int(arr.shape[1])


def _coo(name: str, m: object) -> _Coo:
    """(rows, cols, vals) of the nonzero entries, each entry finite and non-negative."""
    src: Any = m if sp.issparse(m) else np.asarray(m)
    c = sp.coo_array(src)
    rows = np.asarray(c.row, dtype=np.int64)
    cols = np.asarray(c.col, dtype=np.int64)
    vals = np.asarray(c.data, dtype=np.float64)
    bad = ~(np.isfinite(vals) & (vals >= 0))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{name} must hold probabilities (finite, >= 0); {name}[{rows[k]}, {cols[k]}] = {vals[k]}"
        )
    return rows, cols, vals


def automaton_args(
    K0: object, K1: object, init: object, labels: object, max_states: object
) -> tuple[int, _Coo, _Coo, npt.NDArray[np.float64] | None, list[str] | None, int]:
    """The arguments of ``_fakeack.Engine.from_automaton``, checked; sizes before any copy."""
    max_states = as_int("max_states", max_states, minimum=1)
    n, _ = _shape("K0", K0)
    if _shape("K1", K1) != (n, n):
        raise ValueError(f"K1 must have K0's shape {(n, n)}, got {_shape('K1', K1)}")
    if n == 0:
        raise ValueError("K0 must have at least one state")
    if n > max_states:
        raise ValueError(f"K0: {n} states, more than max_states = {max_states}; refused before allocating")
    law: npt.NDArray[np.float64] | None = None
    if init is not None:
        try:
            law = np.array(init, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"init must be a 1-D array of probabilities ({exc})") from exc
        if law.shape != (n,):
            raise ValueError(f"init must have shape {(n,)} (one entry per state), got {law.shape}")
    names: list[str] | None = None
    if labels is not None:
        if isinstance(labels, str) or not isinstance(labels, Sequence):
            raise TypeError(f"labels must be a sequence of str, got {type(labels).__name__}")
        if not all(isinstance(x, str) for x in labels):
            raise TypeError("labels must hold str only")
        if len(labels) != n:
            raise ValueError(f"labels must have one entry per state ({n}), got {len(labels)}")
        names = list(labels)
    return n, _coo("K0", K0), _coo("K1", K1), law, names, max_states
