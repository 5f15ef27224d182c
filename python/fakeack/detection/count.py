"""The count test: how many flag-ACKs reached the sensor in a window, against the attack-free
renewal law of the count, with its alarm bounds and its one-shot decision (:func:`detect_attack`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.special import ndtr

from .._internal.types import FloatArray
from .._internal.validate import as_int, as_probability, as_real
from ..model.schedules import OnlineDesign, check_online
from .flags import as_gaps, attack_free_min_gap, estimate_beta, flag_interval_moments, regime_rates

__all__ = [
    "ALTERNATIVES",
    "count_alarm_bounds",
    "harmful_count_bound",
    "Detection",
    "detect_attack",
]

#: Alternatives of the count test (as in scipy.stats): fewer flags, more flags, either.
ALTERNATIVES = ("less", "greater", "two-sided")


def check_alternative(alternative: object) -> str:
    """A valid ``alternative`` of the count test."""
    if alternative not in ALTERNATIVES:
        raise ValueError(f"alternative must be one of {ALTERNATIVES}, got {alternative!r}")
    return str(alternative)


def count_p_value(z: float, alternative: str) -> float:
    """p-value of the count test's z score (normal approximation)."""
    if alternative == "less":
        return float(ndtr(z))
    if alternative == "greater":
        return float(ndtr(-z))
    return float(min(1.0, 2.0 * min(ndtr(z), ndtr(-z))))


def count_z(delivered: int, n: int, m: float, v: float) -> float:
    """(delivered - n/m) / sqrt(n v / m³): the count test's z score (as :func:`detect_attack`)."""
    expected = n / m
    sd = math.sqrt(n / m) * math.sqrt(v) / m  # m**3 alone may overflow
    if sd > 0:
        return (delivered - expected) / sd
    return 0.0 if delivered == expected else math.copysign(math.inf, delivered - expected)


def count_alarm_bounds(
    lam: float, z0: int, n_steps: int, alpha: float, alternative: str = "less", mu: float = 1.0
) -> tuple[int, int]:
    """The count test's alarm region as integers: alarm iff N <= lo or N >= hi.

    ``lo = -1`` when no count is too low, ``hi = n_steps + 1`` when none is too high. The region
    is the one :func:`fakeack.detect_attack` uses, found by evaluating its p-value at the
    boundary counts (so the two agree exactly).
    """
    lam, design = check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    return alarm_bounds(lam, design, n, as_probability("alpha", alpha), check_alternative(alternative))


#: Below this many expected flag-ACKs per window the count test uses the exact count law (the
#: renewal normal approximation is off in the tails there; a window of 200 steps of the paper's
#: example expects 29).
EXACT_BELOW = 100


def uses_exact_law(n: int, lam: float, design: OnlineDesign) -> bool:
    """Whether the count test of this window uses the exact attack-free count law."""
    m, _ = flag_interval_moments(lam, design.z0, design.mu)
    return math.isfinite(m) and n / m < EXACT_BELOW


@lru_cache(maxsize=256)
def exact_count_law(n: int, lam: float, design: OnlineDesign, attack: Any = None) -> FloatArray:
    """P(N = c), c = 0.., of a stationary window's count (:meth:`fakeack.FlagProcess.count_law`)."""
    from .process import flag_process

    return flag_process(lam, design, attack).count_law(n)


def exact_p_value(law: FloatArray, d: int, alternative: str) -> float:
    """The count test's exact p-value of the count ``d`` under the attack-free ``law``."""
    below = float(law[: d + 1].sum())  # P(N <= d)
    above = float(law[d:].sum()) if d < len(law) else 0.0  # P(N >= d)
    if alternative == "less":
        return min(below, 1.0)
    if alternative == "greater":
        return min(above, 1.0)
    return float(min(1.0, 2.0 * min(below, above)))


def _exact_bounds(law: FloatArray, n: int, alpha: float, alternative: str) -> tuple[int, int]:
    """The alarm region of the exact test: the counts whose exact p-value is below alpha."""
    lo, hi = -1, n + 1
    mean = float(np.arange(len(law)) @ law)
    for d in range(0, min(n, math.floor(mean)) + 1):  # p-values fall away from the mean
        if alternative != "greater" and exact_p_value(law, d, alternative) < alpha:
            lo = d
    # From n down (counts past the law's support, of probability below 1e-300, have p-value 0).
    for d in range(min(n, len(law)), max(0, math.ceil(mean)) - 1, -1):
        if alternative != "less" and exact_p_value(law, d, alternative) < alpha:
            hi = d
    return lo, hi


def exact_alarm_probability(bounds: tuple[int, int], law: FloatArray, harm: int | None) -> float:
    """P(count alarm) under the exact count ``law``; with ``harm``, only alarms with N <= harm."""
    lo, hi = bounds
    top = len(law) - 1 if harm is None else min(harm, len(law) - 1)
    p = float(law[: min(lo, top) + 1].sum()) if lo >= 0 else 0.0
    if hi <= top:
        p += float(law[hi : top + 1].sum())
    return min(max(p, 0.0), 1.0)


def alarm_bounds(lam: float, design: OnlineDesign, n: int, alpha: float, alternative: str) -> tuple[int, int]:
    """:func:`count_alarm_bounds` of a validated schedule, window, level and alternative."""
    renewal_moments(n, lam, design)  # ValueError naming z0 when flags are too rare to test
    if uses_exact_law(n, lam, design):
        return _exact_bounds(exact_count_law(n, lam, design), n, alpha, alternative)
    m, v = flag_interval_moments(lam, design.z0, design.mu)

    def alarm(d: int, side: str) -> bool:
        z = count_z(d, n, m, v)
        if side == "low" and z >= 0:
            return False
        if side == "high" and z <= 0:
            return False
        return count_p_value(z, alternative) < alpha

    # p-values are monotone on each side of the mean; bisection on integers.
    return _bisect_bounds(alarm, n, n / m, alternative)


def _bisect_bounds(alarm: Any, n: int, mean: float, alternative: str) -> tuple[int, int]:
    """The integer alarm region (lo, hi) of a test whose p-value is monotone on each side of the
    mean: ``alarm(d, side)`` says whether count d alarms; bisection on integers."""
    lo = -1
    if alternative != "greater":
        a, b = -1, min(n, math.floor(mean))  # alarm(a) holds by convention, look for the last
        if alarm(0, "low"):
            a = 0
            while b - a > 1:
                c = (a + b) // 2
                a, b = (c, b) if alarm(c, "low") else (a, c)
            lo = b if alarm(b, "low") else a
    hi = n + 1
    if alternative != "less":
        a, b = max(0, math.ceil(mean)), n
        if alarm(n, "high"):
            while b - a > 1:
                c = (a + b) // 2
                a, b = (a, c) if alarm(c, "high") else (c, b)
            hi = a if alarm(a, "high") else b
    return lo, hi


def process_alarm_bounds(process: Any, n: int, alpha: float, alternative: str) -> tuple[int, int]:
    """The count test's alarm region for the attack-free flag process of any channel
    (:func:`fakeack.flag_process`): the exact law below :data:`EXACT_BELOW` expected flag-ACKs,
    else the normal law with the window's exact mean and variance (stationary start)."""
    if n * process.rate < EXACT_BELOW:
        return _exact_bounds(process.count_law(n), n, alpha, alternative)
    mean, var = process.count_moments(n)
    sd = math.sqrt(var)

    def alarm(d: int, side: str) -> bool:
        z = (d - mean) / sd if sd > 0 else math.copysign(math.inf, d - mean) if d != mean else 0.0
        if (side == "low" and z >= 0) or (side == "high" and z <= 0):
            return False
        return count_p_value(z, alternative) < alpha

    return _bisect_bounds(alarm, n, mean, alternative)


def harmful_count_bound(lam: float, z0: int, n_steps: int, beta_bar: float, mu: float = 1.0) -> int:
    """Largest count N whose estimated budget (:func:`fakeack.estimate_beta`) exceeds ``beta_bar``.

    The estimate decreases with N, so "estimated budget above β̄" is N <= this bound
    (-1 when no count qualifies).
    """
    lam, design = check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    return harmful_bound(lam, design, n, as_real("beta_bar", beta_bar))


def harmful_bound(lam: float, design: OnlineDesign, n: int, bb: float) -> int:
    """:func:`harmful_count_bound` of a validated schedule, window and threshold."""
    f_on, f_blk = regime_rates(lam, design)
    return rates_harmful_bound(f_on, f_blk, n, bb)


def rates_harmful_bound(f_on: float, f_blk: float, n: int, bb: float) -> int:
    """:func:`harmful_count_bound` from the flag rates unattacked and all blocked (any channel)."""

    def beta_hat(d: int) -> float:  # fakeack.estimate_beta's formula
        rho = d / n
        if rho >= f_on:
            return 0.0
        b = (1.0 - rho / f_on) / (1.0 + rho / f_blk - rho / f_on)
        return min(max(b, 0.0), 1.0)

    if not beta_hat(0) > bb:
        return -1
    a, b = 0, n
    if beta_hat(n) > bb:
        return n
    while b - a > 1:
        c = (a + b) // 2
        a, b = (c, b) if beta_hat(c) > bb else (a, c)
    return a


def renewal_moments(n: int, lam: float, design: OnlineDesign) -> tuple[float, float]:
    """Mean n/m and standard deviation sqrt(n v / m^3) of the attack-free flag count in n steps
    (renewal CLT); ValueError when the interval moments exceed the double range."""
    m, v = flag_interval_moments(lam, design.z0, design.mu)
    if not (math.isfinite(m) and math.isfinite(v)):
        raise ValueError(
            f"z0: flag-ACKs are too rare to test (interval moments beyond the double range at "
            f"lam={lam}, z0={design.z0})"
        )
    return n / m, math.sqrt(n / m) * math.sqrt(v) / m  # m**3 alone may overflow


@dataclass(frozen=True)
class Detection:
    """Outcome of :func:`detect_attack`."""

    attack_detected: bool
    z_score: float
    """(observed - expected delivered flags) / standard deviation under no attack."""
    p_value: float
    """P[a count at least this extreme | no attacker]: as few flags for ``alternative="less"``,
    as many for ``"greater"``, either for ``"two-sided"``; exact (the count law of
    :meth:`fakeack.FlagProcess.count_law`) below 100 expected flag-ACKs per window, the normal
    approximation above."""
    beta_hat: float
    """:func:`fakeack.estimate_beta` of the count; NaN where fewer than one flag-ACK is expected
    without attack (the window carries no information on the budget)."""
    delivered: int
    expected: float
    n_steps: int
    alpha: float
    alternative: str = "less"
    short_gap: bool | None = None
    """With ``gaps``: whether one was shorter than any possible without attack (None: no gaps)."""


#: Points of a lam range at which the count test is evaluated (its ends included).
LAM_RANGE_POINTS = 9


def check_lam_range(lam_range: object) -> tuple[float, float]:
    """``lam_range`` as a validated pair 0 < lo <= hi < 1, or an error naming it."""
    if not isinstance(lam_range, (tuple, list)) or len(lam_range) != 2:
        raise TypeError(f"lam_range must be a pair (lo, hi), got {lam_range!r}")
    lo, hi = (as_probability(f"lam_range[{i}]", x) for i, x in enumerate(lam_range))
    if not lo <= hi:
        raise ValueError(f"lam_range must have lo <= hi, got {lam_range!r}")
    return lo, hi


def _p_value(d: int, n: int, lam: float, design: OnlineDesign, alternative: str) -> float:
    """The count test's p-value of ``d`` flags in ``n`` steps at ``lam`` (exact below
    :data:`EXACT_BELOW` expected flags)."""
    if uses_exact_law(n, lam, design):
        return exact_p_value(exact_count_law(n, lam, design), d, alternative)
    m, v = flag_interval_moments(lam, design.z0, design.mu)
    return count_p_value(count_z(d, n, m, v), alternative)


def detect_attack(
    delivered: int,
    n_steps: int,
    lam: float,
    z0: int,
    mu: float = 1.0,
    alpha: float = 0.01,
    alternative: str = "less",
    *,
    gaps: object = None,
    support: bool = True,
    lam_range: tuple[float, float] | None = None,
) -> Detection:
    r"""Test for a fake-ACK attacker from the count of flag-ACKs received in ``n_steps`` steps.

    Without attack, inter-flag intervals are i.i.d. with mean m and variance v
    (:func:`flag_interval_moments`), so by the renewal central limit theorem the count N over n
    steps is approximately :math:`\mathcal N(n/m,\, n v/m^3)`, and
    :math:`z = (N - n/m)/\sqrt{n v/m^3}`. Where fewer than 100 flag-ACKs are expected per window
    (n/m < 100) that approximation is off in the tails, and the p-value is the exact one of the
    stationary count law (:meth:`fakeack.FlagProcess.count_law`, a forward recursion over the
    engine's automaton). Blocking removes flags, forging adds them: with
    ``alternative="less"`` (the default) "no attacker" is rejected at level α when
    :math:`\Phi(z) < \alpha`, with ``"greater"`` when :math:`\Phi(-z) < \alpha`, with
    ``"two-sided"`` when :math:`2\min(\Phi(z), \Phi(-z)) < \alpha` (the alternatives of
    scipy.stats). :func:`fakeack.detect_intervals` also looks at when the flags came.

    Parameters
    ----------
    delivered : int
        Flag-ACKs the sensor received (equivalently, its high-power steps triggered by flags).
    n_steps : int
        Observation length in steps.
    lam, z0, mu
        The online schedule's parameters.
    alpha : float
        False-alarm probability, in (0, 1).
    alternative : {"less", "greater", "two-sided"}
        Which counts are alarms: too few (blocking; default), too many (forging), or either.
    gaps : sequence of int, optional
        The gap before each flag-ACK received (as :func:`fakeack.detect_intervals` takes them).
        With ``support``, a gap shorter than the attack-free minimum (z0 + 1 steps; z0 + 2 when
        mu = 0) is an alarm too: no attack-free window holds one, so the level stays alpha.
    support : bool, optional
        Apply that support check when ``gaps`` is given (default True).
    lam_range : (float, float), optional
        A sensor that knows only that lam lies in [lo, hi]: the p-value is the largest over the
        range (at 9 points, ends included), so the test alarms only where the test of every lam
        of the range does and its false-alarm rate is at most alpha at each of them
        (:func:`fakeack.detection_probability` gives its power). ``z_score``, ``expected`` and
        ``beta_hat`` stay those at ``lam``.
    """

    lam, design = check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    d = as_int("delivered", delivered, minimum=0)
    alpha = as_probability("alpha", alpha)
    alternative = check_alternative(alternative)
    expected, _ = renewal_moments(n, lam, design)  # ValueError when flags are too rare to test
    m, v = flag_interval_moments(lam, design.z0, design.mu)
    z = count_z(d, n, m, v)
    p = _p_value(d, n, lam, design, alternative)
    if lam_range is not None:
        lo, hi = check_lam_range(lam_range)
        # Alarm only where the test of every lam of the range alarms: the largest p-value.
        p = max(_p_value(d, n, float(x), design, alternative) for x in np.linspace(lo, hi, LAM_RANGE_POINTS))
    # Fewer than one expected flag-ACK: the count can still show forging, but not a budget.
    beta = estimate_beta(d, n, lam, design.z0, design.mu) if expected >= 1.0 - 1e-12 else math.nan
    short = None
    if gaps is not None:
        g = as_gaps(gaps)
        short = bool(support) and bool(g.size) and int(g.min()) < attack_free_min_gap(design)
    return Detection(p < alpha or bool(short), z, p, beta, d, expected, n, alpha, alternative, short)
