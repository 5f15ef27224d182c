"""The count test: how many flag-ACKs reached the sensor in a window, against the attack-free
renewal law of the count, with its alarm bounds and its one-shot decision (:func:`detect_attack`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.special import ndtr

from .._internal.validate import as_int, as_probability, as_real
from ..model.schedules import OnlineDesign, check_online
from .flags import estimate_beta, flag_interval_moments, regime_rates

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


def alarm_bounds(lam: float, design: OnlineDesign, n: int, alpha: float, alternative: str) -> tuple[int, int]:
    """:func:`count_alarm_bounds` of a validated schedule, window, level and alternative."""
    count_law(n, lam, design)  # ValueError naming z0 when flags are too rare to test
    m, v = flag_interval_moments(lam, design.z0, design.mu)

    def alarm(d: int, side: str) -> bool:
        z = count_z(d, n, m, v)
        if side == "low" and z >= 0:
            return False
        if side == "high" and z <= 0:
            return False
        return count_p_value(z, alternative) < alpha

    # p-values are monotone on each side of the mean; bisection on integers.
    mean = n / m
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


def count_law(n: int, lam: float, design: OnlineDesign) -> tuple[float, float]:
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
    """P[a count at least this extreme | no attacker] (normal approximation): as few flags for
    ``alternative="less"``, as many for ``"greater"``, either for ``"two-sided"``."""
    beta_hat: float
    delivered: int
    expected: float
    n_steps: int
    alpha: float
    alternative: str = "less"


def detect_attack(
    delivered: int,
    n_steps: int,
    lam: float,
    z0: int,
    mu: float = 1.0,
    alpha: float = 0.01,
    alternative: str = "less",
) -> Detection:
    r"""Test for a fake-ACK attacker from the count of flag-ACKs received in ``n_steps`` steps.

    Without attack, inter-flag intervals are i.i.d. with mean m and variance v
    (:func:`flag_interval_moments`), so by the renewal central limit theorem the count N over n
    steps is approximately :math:`\mathcal N(n/m,\, n v/m^3)`, and
    :math:`z = (N - n/m)/\sqrt{n v/m^3}`. Blocking removes flags, forging adds them: with
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
    """

    lam, design = check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    d = as_int("delivered", delivered, minimum=0)
    alpha = as_probability("alpha", alpha)
    alternative = check_alternative(alternative)
    expected, _ = count_law(n, lam, design)  # ValueError when flags are too rare to test
    m, v = flag_interval_moments(lam, design.z0, design.mu)
    z = count_z(d, n, m, v)
    p = count_p_value(z, alternative)
    beta = estimate_beta(d, n, lam, design.z0, design.mu)
    return Detection(p < alpha, z, p, beta, d, expected, n, alpha, alternative)
