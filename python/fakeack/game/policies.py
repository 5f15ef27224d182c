"""The sensor's policies in the game: which test it runs on each window, at which level, and how
long it falls back to the offline schedule after an alarm (see :mod:`fakeack.game`)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TypeVar, cast

import numpy as np

from .._internal.validate import as_int, as_probability
from ..detection.count import check_alternative

__all__ = [
    "SensorPolicy",
]


RULES = ("any", "harmful")
_SPECIAL = {"offline": "always offline", "never": "online, never test"}


@dataclass(frozen=True)
class SensorPolicy:
    """The sensor's policy in the repeated game.

    ``SensorPolicy(test, alpha, fallback, rule)``: run online and apply ``test`` ("count" or
    "interval") at level ``alpha`` to every online window; after an alarm run the offline schedule
    for ``fallback`` windows, then return online. With ``rule="any"`` every alarm triggers the
    fall-back, with ``"harmful"`` only an alarm whose estimated budget
    (:func:`fakeack.estimate_beta` of the window's count) exceeds β̄. With ``support=True`` (the
    default) the window also alarms at the support check: a flag-ACK reaching the sensor sooner
    after the previous one than any can without attack (:attr:`fakeack.FlagProcess.min_gap`,
    z0 + 1 on the paper's channel), which costs no false alarm and sees a forger that ignores
    the gaps. Two special policies:
    ``SensorPolicy("offline")`` (always offline) and ``SensorPolicy("never")`` (online, never
    test).

    Parameters
    ----------
    test : {"count", "interval", "offline", "never"}
        The test, or a special policy.
    alpha : float
        False-alarm level per window, in (0, 1) (tests only).
    fallback : int
        Offline windows after a triggering alarm, >= 0 (tests only).
    rule : {"any", "harmful"}, optional
        Which alarms trigger the fall-back (default "any").
    alternative : {"two-sided", "less", "greater"}, optional
        The count test's alternative (default two-sided; the interval test is two-sided).
    support : bool, optional
        Whether the sensor also runs the support check (tests only; default True). Its alarms
        follow ``rule`` as the test's do.

    Examples
    --------
    >>> str(SensorPolicy("count", 0.01, 2, "harmful"))
    'count test at alpha=0.01, 2 windows offline after a harmful alarm'
    >>> str(SensorPolicy("count", 0.01, 2, support=False))
    'count test at alpha=0.01, 2 windows offline after any alarm, without the support check'
    >>> str(SensorPolicy("offline"))
    'always offline'
    """

    test: str
    alpha: float | None = None
    fallback: int | None = None
    rule: str = "any"
    alternative: str = "two-sided"
    support: bool = True
    """The support check (False for the special policies, which test nothing)."""

    def __init__(
        self,
        test: str,
        alpha: float | None = None,
        fallback: int | None = None,
        rule: str = "any",
        alternative: str = "two-sided",
        support: bool | None = None,
    ) -> None:
        if test in _SPECIAL:
            if alpha is not None or fallback is not None or support is not None:
                raise ValueError(f"test: the special policy {test!r} takes no alpha, fallback or support")
            object.__setattr__(self, "test", test)
            object.__setattr__(self, "alpha", None)
            object.__setattr__(self, "fallback", None)
            object.__setattr__(self, "rule", "any")
            object.__setattr__(self, "alternative", "two-sided")
            object.__setattr__(self, "support", False)
            return
        if test not in ("count", "interval"):
            raise ValueError(f"test must be 'count', 'interval', 'offline' or 'never', got {test!r}")
        if alpha is None or fallback is None:
            raise TypeError(f"test {test!r} needs alpha and fallback")
        if rule not in RULES:
            raise ValueError(f"rule must be one of {RULES}, got {rule!r}")
        alternative = check_alternative(alternative)
        if test == "interval" and alternative != "two-sided":
            raise ValueError("alternative: the interval test is two-sided by construction")
        object.__setattr__(self, "test", test)
        object.__setattr__(self, "alpha", as_probability("alpha", alpha))
        object.__setattr__(self, "fallback", as_int("fallback", fallback, minimum=0))
        object.__setattr__(self, "rule", rule)
        object.__setattr__(self, "alternative", alternative)
        if support is None:
            support = True
        if not isinstance(support, (bool, np.bool_)):
            raise TypeError(f"support must be True or False, got {support!r}")
        object.__setattr__(self, "support", bool(support))

    @property
    def special(self) -> bool:
        """True for ``"offline"`` and ``"never"``."""
        return self.test in _SPECIAL

    def __str__(self) -> str:
        if self.special:
            return _SPECIAL[self.test]
        side = "" if self.test == "interval" or self.alternative == "two-sided" else f" ({self.alternative})"
        windows = "window" if self.fallback == 1 else "windows"
        after = "any alarm" if self.rule == "any" else "a harmful alarm"
        # The default (with the check) keeps the form it had before the check existed.
        without = "" if self.support else ", without the support check"
        return (
            f"{self.test} test{side} at alpha={self.alpha:g}, {self.fallback} {windows} offline after {after}"
            f"{without}"
        )


_T = TypeVar("_T")


def _listed(name: str, x: _T | Iterable[_T]) -> list[_T]:
    """One value or a sequence of them, as a non-empty list."""
    if isinstance(x, (str, bytes)) or not hasattr(x, "__iter__"):
        out = [x]
    else:
        out = list(cast(Iterable[_T], x))
    if not out:
        raise ValueError(f"{name} must not be empty")
    return out


def _policies(
    tests: str | Iterable[str],
    alphas: float | Iterable[float],
    fallbacks: int | Iterable[int],
    rules: str | Iterable[str],
    alternative: str,
    support: bool = True,
) -> list[SensorPolicy]:
    test_list: list[str] = _listed("tests", tests)
    alpha_list: list[float] = _listed("alphas", alphas)
    fallback_list: list[int] = _listed("fallbacks", fallbacks)
    rule_list: list[str] = _listed("rules", rules)
    for a in alpha_list:
        as_probability("alphas", a)
    for k in fallback_list:
        as_int("fallbacks", k, minimum=0)
    for t in test_list:
        if t not in ("count", "interval"):
            raise ValueError(f"tests: each must be 'count' or 'interval', got {t!r}")
    for r in rule_list:
        if r not in RULES:
            raise ValueError(f"rules: each must be one of {RULES}, got {r!r}")
    out = [SensorPolicy("offline"), SensorPolicy("never")]
    for t in test_list:
        for a in alpha_list:
            for k in fallback_list:
                for r in rule_list:
                    alt = alternative if t == "count" else "two-sided"
                    p = SensorPolicy(t, a, k, r, alt, support=support)
                    if p not in out:
                        out.append(p)
    return out
