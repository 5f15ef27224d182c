"""The online design of :func:`fakeack.design_online` for the cells of a parameter study.

:func:`fakeack.design_online` settles the bracket of z0 and computes mu in exact rationals
(:class:`fractions.Fraction`), hundreds of microseconds a cell. The compiled core makes the same
decisions and the same correctly rounded mu in integer arithmetic
(:func:`fakeack._fakeack.grid_designs`), bit for bit, microseconds a cell and in parallel, which
matters when a study designs 10^4-10^6 (lam, ratio) pairs. The cells it leaves (a budget out of
reach, a memory beyond its exact range) are designed by :func:`fakeack.design_online` itself, so
their errors are its own.
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from functools import lru_cache

import numpy as np

from ... import _fakeack
from ..._internal.validate import as_fraction
from ...model.schedules import OnlineDesign, design_online

__all__ = [
    "lam_fractions",
    "design",
]


@lru_cache(maxsize=4096)
def _lam_parts(lam: float) -> tuple[int, int]:
    """(n, d) with lam = n/d as :func:`fakeack.design_online` reads a float lam (the simplest
    fraction with d <= 10^9 that rounds to it), or (0, 0) where it reads the float's exact binary
    value, which the core then takes from the float itself."""
    f = as_fraction("lam", lam)
    return (f.numerator, f.denominator) if f.denominator <= 10**9 else (0, 0)


def lam_fractions(lam: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """The ``lam_num``, ``lam_den`` arrays of :func:`fakeack._fakeack.grid_designs` for ``lam``."""
    parts = [_lam_parts(float(x)) for x in lam]
    num = np.array([n for n, _ in parts], dtype=np.uint64)
    den = np.array([d for _, d in parts], dtype=np.uint64)
    return num, den


def design(lam: float, ratio: Fraction) -> OnlineDesign:
    """:func:`fakeack.design_online` ``(lam, ratio)`` for a float ``lam`` in (0, 1) and a ratio in
    lowest terms, bit for bit; raises its ``ValueError`` where it does.
    """
    num, den = lam_fractions([lam])
    z0, mu = _fakeack.grid_designs(
        np.array([lam], dtype=np.float64),
        num,
        den,
        np.array([ratio.numerator], dtype=np.uint64),
        np.array([ratio.denominator], dtype=np.uint64),
    )
    if z0[0] == 0:
        return design_online(lam, ratio)
    return OnlineDesign(int(z0[0]), float(mu[0]))
