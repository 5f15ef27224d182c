"""Argument validation shared by the public API.

Every check raises ``TypeError`` for a value of the wrong kind and ``ValueError`` for a value out of
its domain, and every message starts with the argument's name.
"""

from __future__ import annotations

import math
import numbers
from fractions import Fraction

import numpy as np

from .types import FloatArray

__all__ = [
    "MODES",
    "PROTOCOLS",
    "as_real",
    "as_probability",
    "as_int",
    "as_fraction",
    "as_ratio",
    "as_matrix",
]


#: Monte Carlo fidelities: average Tr P_k ("covariance") or simulate the noise and the errors ("state").
MODES = ("covariance", "state")

#: Flag-ACK protocols: "B" sends a flag packet the attacker drops, "A" a bit every step it flips.
PROTOCOLS = ("B", "A")


def _is_bool(x: object) -> bool:
    return isinstance(x, (bool, np.bool_))


def as_real(name: str, x: object) -> float:
    """A finite real number as ``float``."""
    if _is_bool(x) or not isinstance(x, (numbers.Real, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__}")
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    return v


def as_probability(name: str, x: object, *, closed: bool = False) -> float:
    """A number in (0, 1), or in [0, 1] when ``closed``."""
    v = as_real(name, x)
    ok = (0.0 <= v <= 1.0) if closed else (0.0 < v < 1.0)
    if not ok:
        interval = "[0, 1]" if closed else "(0, 1)"
        raise ValueError(f"{name} must lie in {interval}, got {v}")
    return v


#: Largest integer argument accepted anywhere (the core counts in 64-bit words).
MAX_INT = 2**62


def as_int(name: str, x: object, *, minimum: int | None = None, maximum: int = MAX_INT) -> int:
    """An integer (int, numpy integer, or an integral float/Fraction) in [minimum, maximum]."""
    if _is_bool(x):
        raise TypeError(f"{name} must be an integer, got bool")
    if isinstance(x, (numbers.Integral, np.integer)):
        v = int(x)
    elif isinstance(x, (numbers.Real, np.floating)):
        fx = float(x)
        if not math.isfinite(fx):
            raise ValueError(f"{name} must be a finite integer, got {fx}")
        if fx != int(fx) or (isinstance(x, Fraction) and x.denominator != 1):
            raise TypeError(f"{name} must be an integer, got {x!r}")
        v = int(fx)
    else:
        raise TypeError(f"{name} must be an integer, got {type(x).__name__}")
    if minimum is not None and v < minimum:
        raise ValueError(f"{name} must be at least {minimum}, got {v}")
    if v > maximum:
        raise ValueError(f"{name} must be at most {maximum}, got {v}")
    return v


def as_fraction(name: str, x: object) -> Fraction:
    """An exact rational.

    Integers and Fractions are exact. A float is taken as the simplest fraction with denominator up
    to 10**9 that rounds to the same float (so ``1/7`` becomes ``Fraction(1, 7)``), else as its
    exact binary value. Strings such as ``"1/7"`` are parsed by :class:`fractions.Fraction`.
    """
    if _is_bool(x):
        raise TypeError(f"{name} must be a rational number, got bool")
    if isinstance(x, str):
        try:
            return Fraction(x)
        except (ValueError, ZeroDivisionError) as exc:
            raise ValueError(f"{name}: cannot parse {x!r} as a fraction") from exc
    if isinstance(x, (numbers.Rational, np.integer)):
        return Fraction(int(x)) if isinstance(x, np.integer) else Fraction(x)
    if isinstance(x, (numbers.Real, np.floating)):
        fx = float(x)
        if not math.isfinite(fx):
            raise ValueError(f"{name} must be finite, got {fx}")
        simple = Fraction(fx).limit_denominator(10**9)
        return simple if float(simple) == fx else Fraction(fx)
    raise TypeError(f"{name} must be a rational number, got {type(x).__name__}")


def as_ratio(name: str, x: object) -> Fraction:
    """An energy ratio p/q strictly between 0 and 1."""
    v = as_fraction(name, x)
    if not 0 < v < 1:
        raise ValueError(f"{name} must lie strictly between 0 and 1, got {v}")
    if v.denominator > MAX_INT:
        raise ValueError(f"{name}: denominator {v.denominator} exceeds {MAX_INT}")
    return v


def as_matrix(name: str, x: object, *, shape: tuple[int, int] | None = None) -> FloatArray:
    """A finite real 2-D float64 array (a scalar becomes 1x1), C-contiguous and owned."""
    if _is_bool(x) or x is None or isinstance(x, (str, bytes)):
        raise TypeError(f"{name} must be a real scalar or 2-D array, got {type(x).__name__}")
    if isinstance(x, Fraction):
        x = float(x)
    try:
        arr = np.asarray(x)
    except Exception as exc:  # ragged lists and the like
        raise ValueError(f"{name}: cannot be read as an array ({exc})") from exc
    if arr.dtype == object:
        if not all(isinstance(v, (numbers.Real, np.number)) and not _is_bool(v) for v in arr.flat):
            raise TypeError(f"{name} must hold real numbers")
        try:
            arr = arr.astype(np.float64)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"{name} must hold real numbers") from exc
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a scalar or a 2-D array, got {arr.ndim}-D")
    if arr.size == 0:
        raise ValueError(f"{name} must not be empty")
    out = np.array(arr, dtype=np.float64, order="C", copy=True)
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{name} contains NaN or inf")
    if shape is not None and out.shape != shape:
        raise ValueError(f"Incompatible dimensions of {name} matrix; expected {shape} but found {out.shape}")
    return out
