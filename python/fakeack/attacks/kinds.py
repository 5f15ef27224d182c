"""Schedules as objects, Monte Carlo of the real protocol, and exact finite-horizon curves."""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from fractions import Fraction
from typing import TypeAlias, cast, overload

import numpy as np
import numpy.typing as npt

from .. import _fakeack
from .._internal.validate import as_fraction, as_int

__all__ = [
    "AttackPattern",
    "MAX_MASK",
    "as_mask",
    "PeriodicBlocking",
    "MaskBlocking",
    "RandomBlocking",
    "FlagInjection",
    "Attack",
    "AttackLike",
    "EngineOnlyAttack",
    "as_attack",
]


class AttackPattern:
    """Deprecated spelling of an attack: use :class:`fakeack.MaskBlocking` or
    :class:`fakeack.PeriodicBlocking`.

    ``AttackPattern(mask)`` returns ``MaskBlocking(mask)`` and ``AttackPattern.first(r, t)``
    returns ``PeriodicBlocking(r, t)``, with a ``DeprecationWarning``.
    """

    def __new__(cls, mask: npt.ArrayLike) -> MaskBlocking:  # type: ignore[misc]  # a deprecated alias: it returns another class
        warnings.warn(
            "fakeack.AttackPattern is deprecated; use fakeack.MaskBlocking(mask)",
            DeprecationWarning,
            stacklevel=2,
        )
        return MaskBlocking(mask)

    @staticmethod
    def first(r: int, t: int) -> PeriodicBlocking:
        """Block the first r of every t flag-ACKs: ``fakeack.PeriodicBlocking(r, t)``."""
        warnings.warn(
            "fakeack.AttackPattern.first is deprecated; use fakeack.PeriodicBlocking(r, t)",
            DeprecationWarning,
            stacklevel=2,
        )
        return PeriodicBlocking(r, t)


#: Longest blocking mask (in flag-ACKs per period) accepted.
MAX_MASK = 10_000_000


def as_mask(mask: npt.ArrayLike) -> list[bool]:
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

    def __init__(self, r: int, t: int) -> None:
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

    def __init__(self, mask: npt.ArrayLike) -> None:
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


def _probability(name: str, x: object) -> float:
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, Fraction, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number in [0, 1], got {type(x).__name__}")
    v = float(x)
    if not (math.isfinite(v) and 0.0 <= v <= 1.0):
        raise ValueError(f"{name} must lie in [0, 1], got {v}")
    return v


@dataclass(frozen=True)
class RandomBlocking:
    """Block each flag-ACK independently with probability ``beta``: a memoryless jammer.

    Unlike :class:`PeriodicBlocking` it keeps no counter. Its cost is exact in closed renewal form
    (:func:`fakeack.j_attack`); ``beta = 0`` is no attack and ``beta = 1`` blocks every flag
    (:func:`fakeack.j_max`).

    Parameters
    ----------
    beta : float or Fraction
        Probability of blocking each flag-ACK, in [0, 1].

    Examples
    --------
    >>> RandomBlocking(0.3)
    RandomBlocking(beta=0.3)
    >>> str(RandomBlocking(0.3))
    'block each flag-ACK with probability 0.3'
    """

    beta: float

    def __init__(self, beta: float | Fraction) -> None:
        object.__setattr__(self, "beta", _probability("beta", beta))

    @property
    def label(self) -> str:
        """``"random:beta"``, the form configs and the command line use."""
        return f"random:{self.beta:g}"

    def __str__(self) -> str:
        return f"block each flag-ACK with probability {self.beta:g}"


@dataclass(frozen=True)
class FlagInjection:
    r"""Forge a flag-ACK with probability ``gamma`` on every step the detector sends none (and, with
    ``min_gap``, only that long after the last flag-ACK the sensor received).

    The sensor then uses high power on the next step (Type B: a forged flag packet; Type A: the
    ACK bit flipped to 1; both have the same statistics). Forging lowers the estimation error but
    spends the sensor's energy: see :func:`fakeack.energy_per_step`. ``block`` combines it with a
    blocking attack on the genuine flag-ACKs.

    Parameters
    ----------
    gamma : float or Fraction
        Probability of a forged flag-ACK on a step without a genuine one, in [0, 1].
    block : RandomBlocking, PeriodicBlocking, MaskBlocking or None, optional
        The attack on the genuine flag-ACKs (default none).
    min_gap : int, optional
        Forge at step k only if :math:`k - k_{\mathrm{last}} \ge` ``min_gap``, with
        :math:`k_{\mathrm{last}}` the last step whose flag-ACK reached the sensor (0 at the start).
        The default 1 is no restriction; ``min_gap = z0 + 1`` never delivers two flag-ACKs closer
        than the detector can send them. Only :class:`fakeack.Scenario` (the exact engine)
        computes ``min_gap > 1``; the other routes refuse it.

    Examples
    --------
    >>> FlagInjection(0.1)
    FlagInjection(gamma=0.1, block=None)
    >>> FlagInjection(0.1, min_gap=3)
    FlagInjection(gamma=0.1, block=None, min_gap=3)
    >>> str(FlagInjection(0.1, RandomBlocking(0.3)))
    'forge a flag-ACK with probability 0.1, and block each flag-ACK with probability 0.3'
    """

    gamma: float
    block: PeriodicBlocking | MaskBlocking | RandomBlocking | None = None
    min_gap: int = 1

    def __init__(
        self,
        gamma: float | Fraction,
        block: PeriodicBlocking | MaskBlocking | RandomBlocking | None = None,
        min_gap: int = 1,
    ) -> None:
        object.__setattr__(self, "gamma", _probability("gamma", gamma))
        object.__setattr__(self, "min_gap", as_int("min_gap", min_gap, minimum=1))
        if block is not None and not isinstance(block, (PeriodicBlocking, MaskBlocking, RandomBlocking)):
            raise TypeError(
                "block must be None, fakeack.RandomBlocking, fakeack.PeriodicBlocking or "
                f"fakeack.MaskBlocking, got {type(block).__name__}"
            )
        object.__setattr__(self, "block", block)

    @property
    def beta(self) -> Fraction | float:
        """The budget of the blocking part (0 without one)."""
        return 0 if self.block is None else self.block.beta

    @property
    def label(self) -> str:
        """``"inject:gamma"``, with ``+`` and the blocking attack's label when there is one (and
        `` min_gap=m`` when ``min_gap > 1``)."""
        head = f"inject:{self.gamma:g}"
        head = head if self.block is None else f"{head}+{self.block.label}"
        return head if self.min_gap == 1 else f"{head} min_gap={self.min_gap}"

    def __repr__(self) -> str:
        gap = "" if self.min_gap == 1 else f", min_gap={self.min_gap}"
        return f"FlagInjection(gamma={self.gamma!r}, block={self.block!r}{gap})"

    def __str__(self) -> str:
        head = f"forge a flag-ACK with probability {self.gamma:g}"
        if self.min_gap > 1:
            head += f" at least {self.min_gap} steps after the last one received"
        return head if self.block is None else f"{head}, and {self.block}"


class EngineOnlyAttack:
    """Base of the attacks that only :class:`fakeack.Scenario` (the exact engine) computes:
    :class:`fakeack.MimicryAttack` and :class:`fakeack.AttackerAutomaton`."""

    __slots__ = ()


#: Every attack type (for annotations).
Attack: TypeAlias = PeriodicBlocking | MaskBlocking | RandomBlocking | FlagInjection

#: What :func:`as_attack` reads: no attack, an attack, an ``(r, t)`` pair, a spelling such as
#: ``"1/5"`` or ``"inject:0.1+random:0.3"``, or a periodic budget (an int 0, a Fraction, a float).
AttackLike: TypeAlias = Attack | tuple[int, int] | str | Fraction | float | None

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


def _periodic(r: int, t: int, value: object, name: str) -> PeriodicBlocking:
    if t < 1:
        raise ValueError(f"{name}: the period t must be at least 1, got {value!r}")
    if not 0 <= r < t:
        raise ValueError(
            f"{name} must lie in [0, 1) (block r < t of every t flag-ACKs; r = t is J_max), got {value!r}"
        )
    return PeriodicBlocking(r, t)


def _attack_from_text(value: str, name: str) -> Attack:
    """``"r/t"``, ``"random:beta"``, ``"inject:gamma"`` or ``"inject:gamma+<blocking>"``."""
    text = value.strip()
    head, plus, rest = text.partition("+")
    if head.startswith("inject:"):
        gamma = _number_text(head[len("inject:") :], name)
        block = _attack_from_text(rest, name) if plus else None
        if isinstance(block, FlagInjection):
            raise ValueError(f"{name}: an injection's blocking part cannot inject, got {value!r}")
        return FlagInjection(gamma, block)
    if plus:
        raise ValueError(f"{name}: only 'inject:gamma+...' combines attacks, got {value!r}")
    if text.startswith("random:"):
        return RandomBlocking(_number_text(text[len("random:") :], name))
    return _periodic_from_text(text, name)


def _number_text(text: str, name: str) -> float:
    try:
        return float(as_fraction(name, text.strip()))
    except ValueError:
        raise ValueError(f"{name}: cannot read {text!r} as a probability") from None


def as_attack(value: AttackLike, name: str = "attack") -> Attack | None:
    """Any accepted way of writing an attack, as an attack object (``None``: no attack).

    Parameters
    ----------
    value : None, attack object, (r, t), str or number
        An attack object is returned as it is. A pair ``(r, t)`` is
        ``PeriodicBlocking(r, t)``. A string ``"r/t"`` is kept as written (``"2/6"`` is not
        ``"1/3"``); ``"random:0.3"`` is ``RandomBlocking(0.3)``; ``"inject:0.1"`` is
        ``FlagInjection(0.1)`` and ``"inject:0.1+random:0.3"`` (or ``"inject:0.1+1/5"``) adds a
        blocking attack. A decimal string such as ``"0.2"``, an exact ``Fraction``, an ``int`` 0,
        or a float in ``[0, 1)`` (read as the simplest fraction with denominator up to 1000 that
        equals it to 1e-12) gives a periodic budget in lowest terms.
    name : str, optional
        The argument's name in error messages.

    Returns
    -------
    PeriodicBlocking, MaskBlocking, RandomBlocking, FlagInjection or None

    Raises
    ------
    TypeError
        For a value of another kind (a list is not read as a mask: write ``MaskBlocking(...)``).
    ValueError
        For a budget outside ``[0, 1)`` or a malformed string.
    """
    if value is None or isinstance(value, (PeriodicBlocking, MaskBlocking, RandomBlocking, FlagInjection)):
        return value
    if isinstance(value, EngineOnlyAttack):
        raise TypeError(
            f"{name}: {type(value).__name__} is computed only by fakeack.Scenario (the exact engine)"
        )
    if isinstance(value, tuple) and len(value) == 2:
        return PeriodicBlocking(*value)
    if isinstance(value, str):
        return _attack_from_text(value, name)
    if isinstance(value, bool) or not isinstance(value, (int, float, Fraction)):
        raise TypeError(
            f"{name} must be None, an attack (fakeack.PeriodicBlocking, MaskBlocking, RandomBlocking, "
            f"FlagInjection), an (r, t) pair or a string such as '1/5', got {type(value).__name__}"
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


@overload
def core_attack(attack: Attack, *, engine: bool = False) -> _fakeack.Attack: ...
@overload
def core_attack(attack: None, *, engine: bool = False) -> None: ...
@overload
def core_attack(attack: Attack | None, *, engine: bool = False) -> _fakeack.Attack | None: ...
def core_attack(attack: Attack | None, *, engine: bool = False) -> _fakeack.Attack | None:
    """The compiled core's form of a validated attack object (``None`` stays ``None``).

    A :class:`FlagInjection` with ``min_gap > 1`` is refused (ValueError naming ``attack``) unless
    ``engine``: the exact engine takes ``min_gap`` as an argument of its own; today's routes
    cannot compute it.
    """
    if attack is None:
        return None
    if isinstance(attack, FlagInjection) and attack.min_gap > 1 and not engine:
        raise ValueError(
            f"attack: FlagInjection with min_gap={attack.min_gap} is computed only by fakeack.Scenario "
            "(the exact engine); this route takes min_gap=1"
        )
    if isinstance(attack, EngineOnlyAttack):
        raise TypeError(
            f"attack: {type(attack).__name__} is computed only by fakeack.Scenario (the exact engine)"
        )
    if isinstance(attack, PeriodicBlocking):
        return _fakeack.Attack.periodic(attack.r, attack.t)
    if isinstance(attack, RandomBlocking):
        return _fakeack.Attack.random(attack.beta)
    if isinstance(attack, FlagInjection):
        return _fakeack.Attack.injection(attack.gamma, core_attack(attack.block))
    return _fakeack.Attack.mask(list(attack.mask))


def attack_argument(r: int | AttackLike, t: int | None, attack: AttackLike) -> Attack:
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
    # PeriodicBlocking checks r at run time (a pair or a string in r's place is a TypeError there).
    return PeriodicBlocking(cast(int, r), t)
