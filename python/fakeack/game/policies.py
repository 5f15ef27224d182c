"""The sensor's policies in the game: which test it runs on each window (or, for the CUSUM, at
each step), at which level, and how long it falls back to the offline schedule after an alarm
(see :mod:`fakeack.game`)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar, cast

import numpy as np
import numpy.typing as npt

from .._internal.validate import as_int, as_probability
from ..detection.count import check_alternative
from ..detection.cusum import CusumTest
from ..detection.likelihood import DEFAULT_ALTERNATIVE, LikelihoodRatioTest, likelihood_ratio_test
from ..model.channels import ChannelLike
from ..model.schedules import OnlineDesign

__all__ = [
    "CusumStatistic",
    "SensorPolicy",
]


class CusumStatistic(Protocol):
    """What a CUSUM policy needs of its statistic (:class:`fakeack.CusumTest` has it).

    ``threshold`` is the alarm threshold h (finite, > 0); ``increments(channel, design)`` gives
    the increments of W per gap y = 1..Y (the last entry for every longer gap) at a step where a
    flag-ACK reaches the sensor and at a silent one: a pair ``(flag, quiet)`` of equal-length float
    arrays, or an object with ``flag`` and ``quiet`` attributes; entries may be +inf or -inf.
    """

    @property
    def threshold(self) -> float:
        """The alarm threshold h."""
        ...

    def increments(self, channel: Any, design: Any) -> Any:
        """The increments of W under ``channel`` and the online ``design``."""
        ...


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

    ``SensorPolicy("lr", alpha, fallback, lr_alternative=a)``: the likelihood-ratio test of
    :func:`fakeack.likelihood_ratio_test` against the attack ``a`` (default
    ``RandomBlocking(0.2)``) on every online window, at level ``alpha``; by Neyman and Pearson
    the most powerful window test against ``a`` itself. Every alarm triggers the fall-back
    (``rule="any"``: the harmful rule's count and the statistic have no joint law here) and its
    +inf increments are its support check (no ``support``). Back online after a fall-back the
    statistic waits for the first flag-ACK, whose gap the offline stretch set.

    ``SensorPolicy("cusum", fallback=K, cusum=c)``: run online with the CUSUM statistic W of ``c``
    (a :class:`fakeack.CusumTest`) updated at every online step, W <- max(0, W + inc) with the
    increment of the step's outcome (a flag-ACK or silence) at the current gap; an alarm
    (W >= h) sends the sensor offline for K windows, after which it returns online with W = 0
    and the statistic dormant until the first flag-ACK reaches it. Every alarm triggers the
    fall-back (``rule="any"``); its level is its threshold (no ``alpha``) and its +inf increments
    are its support check (no ``support``). Only :func:`fakeack.simulate_game` plays it.

    Parameters
    ----------
    test : {"count", "interval", "lr", "cusum", "offline", "never"}
        The test, or a special policy.
    alpha : float
        False-alarm level per window, in (0, 1) (the window tests only).
    fallback : int
        Offline windows after a triggering alarm, >= 0 (tests and the CUSUM).
    rule : {"any", "harmful"}, optional
        Which alarms trigger the fall-back (default "any").
    alternative : {"two-sided", "less", "greater"}, optional
        The count test's alternative (default two-sided; the interval test is two-sided).
    support : bool, optional
        Whether the sensor also runs the support check (the count and interval tests only;
        default True). Its alarms follow ``rule`` as the test's do.
    cusum : CusumStatistic, optional
        The CUSUM's statistic (``test="cusum"`` only): its ``threshold`` and ``increments``.
    lr_alternative : RandomBlocking, FlagInjection or array_like, optional
        The attack the likelihood-ratio test is tuned to (``test="lr"`` only; default
        ``RandomBlocking(0.2)``), as :func:`fakeack.likelihood_ratio_test` takes it.

    Raises
    ------
    ValueError
        For an unknown test or rule, or an argument the test does not take (named first).
    TypeError
        When a test lacks ``alpha`` or ``fallback``, or ``cusum`` lacks ``threshold`` or
        ``increments``.

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
    """The support check (False for the special policies, which test nothing, and the CUSUM)."""
    cusum: CusumStatistic | None = None
    """The CUSUM's statistic (None for the other policies)."""
    lr_alternative: object = None
    """The attack the likelihood-ratio test is tuned to (None for the other policies)."""

    def __init__(
        self,
        test: str,
        alpha: float | None = None,
        fallback: int | None = None,
        rule: str = "any",
        alternative: str = "two-sided",
        support: bool | None = None,
        cusum: CusumStatistic | None = None,
        lr_alternative: object = None,
    ) -> None:
        object.__setattr__(self, "cusum", None)
        object.__setattr__(self, "lr_alternative", None)
        if lr_alternative is not None and test != "lr":
            raise ValueError(f"lr_alternative: only the test 'lr' takes one, not {test!r}")
        if test == "cusum":
            self._init_cusum(fallback, cusum, alpha, rule, alternative, support)
            return
        if cusum is not None:
            raise ValueError(f"cusum: only the test 'cusum' takes a CUSUM statistic, not {test!r}")
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
        if test not in ("count", "interval", "lr"):
            raise ValueError(
                f"test must be 'count', 'interval', 'lr', 'cusum', 'offline' or 'never', got {test!r}"
            )
        if alpha is None or fallback is None:
            raise TypeError(f"test {test!r} needs alpha and fallback")
        if rule not in RULES:
            raise ValueError(f"rule must be one of {RULES}, got {rule!r}")
        if test == "lr":
            self._init_lr(alpha, fallback, rule, alternative, support, lr_alternative)
            return
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

    def _init_lr(
        self,
        alpha: float,
        fallback: int,
        rule: str,
        alternative: str,
        support: bool | None,
        lr_alternative: object,
    ) -> None:
        """The fields of a likelihood-ratio test policy, checked."""
        if rule != "any":
            raise ValueError(
                f"rule: every alarm of the likelihood-ratio test triggers the fall-back ('any'), got {rule!r}"
            )
        if alternative != "two-sided":
            raise ValueError("alternative: the likelihood-ratio test's alternative is lr_alternative")
        if support:
            raise ValueError("support: the likelihood-ratio statistic's +inf increments are its check")
        # The statistic's own checks (and its TypeError for an alternative it cannot take).
        alt = CusumTest(DEFAULT_ALTERNATIVE if lr_alternative is None else lr_alternative, 1.0).alternative
        object.__setattr__(self, "test", "lr")
        object.__setattr__(self, "alpha", as_probability("alpha", alpha))
        object.__setattr__(self, "fallback", as_int("fallback", fallback, minimum=0))
        object.__setattr__(self, "rule", "any")
        object.__setattr__(self, "alternative", "two-sided")
        object.__setattr__(self, "support", False)
        object.__setattr__(self, "lr_alternative", _Frozen(alt) if isinstance(alt, np.ndarray) else alt)

    def _init_cusum(
        self,
        fallback: int | None,
        cusum: CusumStatistic | None,
        alpha: float | None,
        rule: str,
        alternative: str,
        support: bool | None,
    ) -> None:
        """The fields of a CUSUM policy, checked."""
        if cusum is None or fallback is None:
            raise TypeError("test 'cusum' needs fallback and cusum")
        if not (hasattr(cusum, "threshold") and callable(getattr(cusum, "increments", None))):
            raise TypeError(
                "cusum must have a threshold and an increments method (a fakeack.CusumTest), "
                f"got {type(cusum).__name__}"
            )
        if getattr(cusum, "likelihood", "renewal") != "renewal":
            raise ValueError(
                "cusum: the closed-loop policy runs the renewal statistic (its increments per gap); "
                "a filter CUSUM's forward filters are not in the closed-loop kernel"
            )
        if alpha is not None:
            raise ValueError("alpha: the CUSUM's level is its threshold; it takes no alpha")
        if rule != "any":
            raise ValueError(f"rule: every alarm of the CUSUM triggers the fall-back ('any'), got {rule!r}")
        if alternative != "two-sided":
            raise ValueError("alternative: the CUSUM's alternative is in its statistic")
        if support:
            raise ValueError("support: the CUSUM's +inf increments are its support check")
        object.__setattr__(self, "test", "cusum")
        object.__setattr__(self, "alpha", None)
        object.__setattr__(self, "fallback", as_int("fallback", fallback, minimum=0))
        object.__setattr__(self, "rule", "any")
        object.__setattr__(self, "alternative", "two-sided")
        object.__setattr__(self, "support", False)
        object.__setattr__(self, "cusum", cusum)

    def lr_test(self, channel: ChannelLike, design: OnlineDesign, n_steps: int) -> LikelihoodRatioTest:
        """The likelihood-ratio test of a ``"lr"`` policy for windows of ``n_steps`` steps under
        ``channel`` and the online ``design`` (:func:`fakeack.likelihood_ratio_test`, cached)."""
        if self.test != "lr":
            raise ValueError(f"policy: {self} runs no likelihood-ratio test")
        return likelihood_ratio_test(
            channel,
            design.z0,
            n_steps,
            cast(float, self.alpha),
            design.mu,
            alternative=self.lr_alternative,
        )

    @property
    def special(self) -> bool:
        """True for ``"offline"`` and ``"never"``."""
        return self.test in _SPECIAL

    def __str__(self) -> str:
        if self.special:
            return _SPECIAL[self.test]
        windows = "window" if self.fallback == 1 else "windows"
        if self.test == "cusum":
            c = self.cusum
            against = getattr(c, "alternative", None)
            what = "" if against is None else f", against {_alternative(against)}"
            h = float(getattr(c, "threshold", math.nan))
            return f"CUSUM (h={h:g}{what}), {self.fallback} {windows} offline after an alarm"
        if self.test == "lr":
            return (
                f"lr test against {_alternative(self.lr_alternative)} at alpha={self.alpha:g}, "
                f"{self.fallback} {windows} offline after any alarm"
            )
        side = "" if self.test == "interval" or self.alternative == "two-sided" else f" ({self.alternative})"
        after = "any alarm" if self.rule == "any" else "a harmful alarm"
        # The default (with the check) keeps the form it had before the check existed.
        without = "" if self.support else ", without the support check"
        return (
            f"{self.test} test{side} at alpha={self.alpha:g}, {self.fallback} {windows} offline after {after}"
            f"{without}"
        )


def _alternative(alternative: object) -> str:
    """A CUSUM's alternative in words: an attack by its repr, a gap law as such."""
    if isinstance(alternative, (np.ndarray, _Frozen)):
        return f"a gap law on 1..{np.asarray(alternative).size}"
    return repr(alternative)


class _Frozen(tuple[float, ...]):
    """A gap pmf as a hashable value, so that a policy stays a dict key (the game's cache)."""

    def __array__(self, dtype: Any = None, copy: Any = None) -> npt.NDArray[np.float64]:
        return np.array(tuple(self), dtype=float if dtype is None else dtype)


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
    lr_alternative: object = None,
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
        if t not in ("count", "interval", "lr"):
            raise ValueError(f"tests: each must be 'count', 'interval' or 'lr', got {t!r}")
    if lr_alternative is not None and "lr" not in test_list:
        raise ValueError("lr_alternative: only with the test 'lr' among tests")
    for r in rule_list:
        if r not in RULES:
            raise ValueError(f"rules: each must be one of {RULES}, got {r!r}")
    out = [SensorPolicy("offline"), SensorPolicy("never")]
    for t in test_list:
        for a in alpha_list:
            for k in fallback_list:
                for r in rule_list:
                    if t == "lr":
                        if r != "any":
                            continue  # every alarm of the lr test triggers the fall-back
                        p = SensorPolicy("lr", a, k, lr_alternative=lr_alternative)
                    else:
                        alt = alternative if t == "count" else "two-sided"
                        p = SensorPolicy(t, a, k, r, alt, support=support)
                    if p not in out:
                        out.append(p)
    return out
