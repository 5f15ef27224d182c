"""The online design of :func:`fakeack.design_online`, in integer arithmetic, for parameter studies.

:func:`fakeack.design_online` settles the bracket of z0 and computes mu in exact rationals
(:class:`fractions.Fraction`), which normalises every intermediate result by a gcd of numbers
with thousands of bits. Every quantity it compares or rounds is a ratio of polynomials in the
integers of lam = n/d and ratio = p/q, so the same decisions and the same correctly rounded mu
follow from plain integer arithmetic (a = m/d with m = d - n):

* f(z, 1) >= p/q  iff  q n m^z >= p (d^(z+1) - m^(z+1)),   f(z, 1) = lam a^z / (1 - a^(z+1));
* mu = [p (d^(z0+2) - m^(z0+2)) - q n m^(z0+1)] / [n m^z0 (q n + p m)], rounded to a float by
  Python's correctly rounded integer division, as ``float(Fraction)`` rounds it.

The result equals :func:`fakeack.design_online` bit for bit (the tests compare them over random and
boundary cases); anything else (a budget out of reach, a memory beyond the exact range) is left to
:func:`fakeack.design_online` itself, so its errors are its own. It runs in microseconds instead of
hundreds, which matters when a study designs 10^4-10^6 (lam, ratio) pairs.
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache

from ._validate import as_fraction
from .schedules import EXACT_DESIGN_Z0, OnlineDesign, design_online

__all__ = ["design", "design_pq"]


@lru_cache(maxsize=4096)
def _lam_parts(lam: float) -> tuple[int, int]:
    """(n, d) with lam = n/d exactly as :func:`fakeack.design_online` reads a float lam."""
    f = as_fraction("lam", lam)
    return f.numerator, f.denominator


def _meets(n: int, d: int, p: int, q: int, z: int) -> bool:
    """f(z, 1) >= p/q, exactly."""
    m = d - n
    mz = m**z
    return q * n * mz >= p * (d ** (z + 1) - mz * m)


def _largest_z_estimate(lam: float, rho: float) -> int | None:
    """The largest z with f(z, 1) >= rho, within one: f(z, 1) >= rho iff a^z (lam + rho a) >= rho,
    so z <= ln(rho / (lam + rho a)) / ln a, in closed form (the exact walk that follows settles
    the last step). None when the bound is out of range."""
    bound = math.log(rho / (lam + rho * (1.0 - lam))) / math.log1p(-lam)
    return int(bound) if math.isfinite(bound) and bound < 2**40 else None


def design(lam: float, ratio: Fraction) -> OnlineDesign:
    """:func:`fakeack.design_online` ``(lam, ratio)`` for a float ``lam`` in (0, 1) and a ratio in
    lowest terms, bit for bit; raises its ``ValueError`` where it does.
    """
    return design_pq(lam, ratio.numerator, ratio.denominator)


# Keyed on plain numbers: hashing a Fraction costs more than the design of a cached pair.
@lru_cache(maxsize=1 << 18)
def design_pq(lam: float, p: int, q: int) -> OnlineDesign:
    """:func:`design` for the ratio p/q in lowest terms."""
    n, d = _lam_parts(lam)
    m = d - n
    # design_online's first check: the budget exceeds f(1, 1) = lam a / (1 - a^2).
    if p * (d * d - m * m) > q * n * m:
        return design_online(lam, Fraction(p, q))
    z0 = _largest_z_estimate(lam, p / q)
    if z0 is None or z0 > EXACT_DESIGN_Z0:
        return design_online(lam, Fraction(p, q))
    z0 = max(1, z0 - 1)
    while _meets(n, d, p, q, z0 + 1):
        z0 += 1
    mz = m**z0
    # f(z0, 1) == p/q: a fixed memory spends the budget exactly.
    if q * n * mz == p * (d ** (z0 + 1) - mz * m):
        return OnlineDesign(z0, 1.0)
    mz1 = mz * m
    num = p * (d ** (z0 + 2) - mz1 * m) - q * n * mz1
    den = n * mz * (q * n + p * m)
    return OnlineDesign(z0, num / den)
