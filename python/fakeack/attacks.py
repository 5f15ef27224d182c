"""One model of an attack on the flag-ACKs, accepted everywhere an attack is.

The attacker counts the flag-ACKs the remote detector sends, modulo the attack's period, and
blocks (Type B) or flips to an ordinary ACK (Type A) the ones its pattern marks; both types have
the same statistics. ``None`` means no attack wherever an attack is optional.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from . import _fakeack
from ._validate import as_fraction, as_int

__all__ = ["Attack", "MAX_MASK", "MaskBlocking", "PeriodicBlocking", "as_attack", "as_mask"]

#: Longest blocking mask (in flag-ACKs per period) accepted.
MAX_MASK = 10_000_000


def as_mask(mask: Any) -> list[bool]:
    """A non-empty 1-D 0/1 (or bool) blocking mask as a list of bools."""
    if isinstance(mask, (str, bytes)) or mask is None:
        raise TypeError(f"mask must be a sequence of 0/1, got {type(mask).__name__}")
    arr = np.asarray(mask)
    if arr.size > MAX_MASK:
        raise ValueError(f"mask: longer than {MAX_MASK} flag-ACKs")
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"mask must be a non-empty 1-D sequence of 0/1, got shape {arr.shape}")
    if arr.dtype.kind not in "biu" and not (arr.dtype.kind == "f" and np.all(np.isin(arr, (0, 1)))):
        raise TypeError(f"mask must hold 0/1 or booleans, got dtype {arr.dtype}")
    if not np.all(np.isin(arr, (0, 1))):
        raise ValueError("mask must hold only 0 and 1")
    return [bool(x) for x in arr]


@dataclass(frozen=True)
class PeriodicBlocking:
    """Block the first ``r`` of every ``t`` flag-ACKs: the paper's Algorithm 1 (Model note 3).

    A pair not in lowest terms is a different attack: ``PeriodicBlocking(2, 6)`` blocks two flags
    in a row out of six, which hurts more than ``PeriodicBlocking(1, 3)``.

    Parameters
    ----------
    r : int
        Blocked flag-ACKs per period, ``0 <= r < t``.
    t : int
        Period in flag-ACKs, ``t >= 1``.

    Examples
    --------
    >>> PeriodicBlocking(1, 5)
    PeriodicBlocking(r=1, t=5)
    >>> PeriodicBlocking(1, 5).beta
    Fraction(1, 5)
    >>> str(PeriodicBlocking(2, 6))
    'block 2 of every 6 flag-ACKs'
    """

    r: int
    t: int

    def __init__(self, r: Any, t: Any):
        # No cap on t: the analysis of this attack costs O(r z0) whatever t is.
        t = as_int("t", t, minimum=1)
        r = as_int("r", r, minimum=0)
        if r >= t:
            raise ValueError(f"r must be smaller than t = {t}, got r = {r}")
        object.__setattr__(self, "r", r)
        object.__setattr__(self, "t", t)

    @property
    def beta(self) -> Fraction:
        """The budget :math:`\\beta = r/t`, the fraction of flag-ACKs blocked."""
        return Fraction(self.r, self.t)

    @property
    def mask(self) -> tuple[bool, ...]:
        """One period as a mask (True = blocked): ``r`` ones, then ``t - r`` zeros."""
        return (True,) * self.r + (False,) * (self.t - self.r)

    @property
    def label(self) -> str:
        """``"r/t"`` as written (the form configs and the command line use)."""
        return f"{self.r}/{self.t}"

    def __str__(self) -> str:
        return f"block {self.r} of every {self.t} flag-ACKs"


@dataclass(frozen=True)
class MaskBlocking:
    """Block the flag-ACK counted ``sigma`` in each period of ``len(mask)`` whenever ``mask[sigma]``.

    Generalises :class:`PeriodicBlocking` (``[1]*r + [0]*(t-r)`` is the paper's attack). A mask
    of all ones blocks every flag-ACK: the Monte Carlo runs it, and its stationary cost is
    :func:`fakeack.j_max`.

    Parameters
    ----------
    mask : sequence of 0/1 or bool
        One period of the pattern.

    Examples
    --------
    >>> MaskBlocking([1, 0, 1, 0, 0])
    MaskBlocking('10100')
    >>> MaskBlocking([1, 0, 1, 0, 0]).beta
    Fraction(2, 5)
    """

    mask: tuple[bool, ...]

    def __init__(self, mask: Any):
        object.__setattr__(self, "mask", tuple(as_mask(mask)))

    @property
    def beta(self) -> Fraction:
        """The budget: the fraction of flag-ACKs blocked."""
        return Fraction(sum(self.mask), len(self.mask))

    @property
    def label(self) -> str:
        """The mask as a string of 0/1 (its length and count when longer than 64)."""
        if len(self.mask) <= 64:
            return "".join("1" if b else "0" for b in self.mask)
        return f"{sum(self.mask)} of {len(self.mask)} (mask)"

    def __repr__(self) -> str:
        if len(self.mask) <= 64:
            return f"MaskBlocking({self.label!r})"
        return f"MaskBlocking(<{sum(self.mask)} blocked of {len(self.mask)}>)"

    def __str__(self) -> str:
        return f"block mask {self.label}"


#: Every attack type (for annotations).
Attack = PeriodicBlocking | MaskBlocking

_RT = re.compile(r"^\s*(\d+)\s*/\s*(\d+)\s*$")


def _periodic_from_text(value: str, name: str) -> PeriodicBlocking:
    m = _RT.match(value)
    if m:  # "r/t" is kept as written: "2/6" blocks two in a row, not one of three
        return _periodic(int(m.group(1)), int(m.group(2)), value, name)
    try:
        f = as_fraction(name, value.strip())
    except ValueError:
        raise ValueError(f"{name} must look like 'r/t' (e.g. '1/5'), got {value!r}") from None
    return _periodic(f.numerator, f.denominator, value, name)


def _periodic(r: int, t: int, value: Any, name: str) -> PeriodicBlocking:
    if t < 1:
        raise ValueError(f"{name}: the period t must be at least 1, got {value!r}")
    if not 0 <= r < t:
        raise ValueError(
            f"{name} must lie in [0, 1) (block r < t of every t flag-ACKs; r = t is J_max), got {value!r}"
        )
    return PeriodicBlocking(r, t)


def as_attack(value: Any, name: str = "attack") -> PeriodicBlocking | MaskBlocking | None:
    """Any accepted way of writing an attack, as an attack object (``None``: no attack).

    Parameters
    ----------
    value : None, PeriodicBlocking, MaskBlocking, (r, t), str or number
        An attack object is returned as it is. A pair ``(r, t)`` is
        ``PeriodicBlocking(r, t)``. A string ``"r/t"`` is kept as written (``"2/6"`` is not
        ``"1/3"``); a decimal string such as ``"0.2"``, an exact ``Fraction``, an ``int`` 0, or a
        float in ``[0, 1)`` (read as the simplest fraction with denominator up to 1000 that equals
        it to 1e-12) gives the budget in lowest terms.
    name : str, optional
        The argument's name in error messages.

    Returns
    -------
    PeriodicBlocking, MaskBlocking or None

    Raises
    ------
    TypeError
        For a value of another kind (a list is not read as a mask: write ``MaskBlocking(...)``).
    ValueError
        For a budget outside ``[0, 1)`` or a malformed string.
    """
    if value is None or isinstance(value, (PeriodicBlocking, MaskBlocking)):
        return value
    if isinstance(value, tuple) and len(value) == 2:
        return PeriodicBlocking(*value)
    if isinstance(value, str):
        return _periodic_from_text(value, name)
    if isinstance(value, bool) or not isinstance(value, (int, float, Fraction)):
        raise TypeError(
            f"{name} must be None, fakeack.PeriodicBlocking, fakeack.MaskBlocking, an (r, t) pair "
            f"or a fraction 'r/t', got {type(value).__name__}"
        )
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value}")
        f = Fraction(value).limit_denominator(1000)
        if abs(float(f) - value) > 1e-12:
            raise ValueError(f"{name} {value!r} is not a simple fraction; write it as 'r/t'")
    else:
        f = Fraction(value)
    return _periodic(f.numerator, f.denominator, value, name)


def core_attack(attack: PeriodicBlocking | MaskBlocking | None) -> Any:
    """The compiled core's form of a validated attack object (``None`` stays ``None``)."""
    if attack is None:
        return None
    if isinstance(attack, PeriodicBlocking):
        return _fakeack.Attack.periodic(attack.r, attack.t)
    return _fakeack.Attack.mask(list(attack.mask))


def attack_argument(
    r: Any, t: Any, attack: Any
) -> PeriodicBlocking | MaskBlocking:
    """The attack of a call that takes either ``r, t`` or ``attack=`` (or an attack object as r)."""
    if attack is None and t is None and r is not None and not isinstance(r, (int, np.integer)):
        attack, r = r, None
    if attack is not None:
        if r is not None or t is not None:
            raise TypeError("give either r and t, or attack, not both")
        got = as_attack(attack)
        if got is None:
            raise TypeError("attack must not be None here")
        return got
    if r is None or t is None:
        raise TypeError("missing the attack: give r and t, or attack=fakeack.PeriodicBlocking(r, t)")
    return PeriodicBlocking(r, t)
