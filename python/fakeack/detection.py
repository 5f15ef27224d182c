"""Detecting the attacker from the flag-ACKs the sensor receives (the paper's Remark 4.2)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from . import _fakeack
from ._validate import as_int, as_probability
from .attacks import as_attack, core_attack
from .schedules import _check_online as _online
from .system import LinearSystem

__all__ = [
    "Detection",
    "DetectionRates",
    "delivered_flag_rate",
    "detect_attack",
    "detection_rates",
    "estimate_beta",
    "flag_interval_moments",
    "flag_rates",
]

# The flag process does not depend on the plant: any valid system serves for rates.
_ANY_SYSTEM: LinearSystem | None = None


def _any_system() -> LinearSystem:
    global _ANY_SYSTEM
    if _ANY_SYSTEM is None:
        _ANY_SYSTEM = LinearSystem(0.5, 1.0, 1.0, 1.0)
    return _ANY_SYSTEM


def flag_interval_moments(lam: Any, z0: Any, mu: Any = 1.0) -> tuple[float, float]:
    r"""Mean and variance of the steps between delivered flag-ACKs without attack.

    After a flag-ACK the sensor transmits at high power (the packet arrives and the detector's
    memory restarts), so inter-flag intervals are i.i.d. X = 1 + T, T the absorption time of the
    memory's zero count z (reset by every arrival, absorbed when z reaches z0 with probability μ,
    or z0 + 1). With Q the transient part, :math:`N = (I-Q)^{-1}`,
    :math:`E[T] = (N\mathbf 1)_0` and :math:`E[T^2] = ((2N - I)N\mathbf 1)_0`. The mean equals
    1 / :func:`fakeack.online_high_power_rate` (checked in the tests).

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).

    Returns
    -------
    (mean, variance) : tuple of float
        ``inf`` where a moment exceeds the double range (memories of hundreds of steps).
    """
    lam, z0, mu = _online(lam, z0, mu)
    if z0 > 10_000:
        raise ValueError(f"z0 must be at most 10000 here, got {z0}")
    a = 1.0 - lam
    n = z0 + 2  # z = 0..z0+1 after a step without a flag
    flag = np.zeros(n + 1)
    flag[z0] = mu
    flag[z0 + 1] = 1.0
    Q = np.zeros((n, n))
    for z in range(n):
        Q[z, 0] += lam
        if z + 1 < n:
            Q[z, z + 1] += a * (1.0 - flag[z + 1])
    # Long memories make the moments astronomically large (the mean grows like a^-z0): what
    # overflows is reported as inf, never NaN or OverflowError.
    with np.errstate(over="ignore", invalid="ignore"):
        N = np.linalg.inv(np.eye(n) - Q)
        t1 = N @ np.ones(n)
        t2 = (2 * N - np.eye(n)) @ t1
    mean_t, second = float(t1[0]), float(t2[0])
    if not math.isfinite(mean_t):
        return math.inf, math.inf
    if not math.isfinite(second):
        return 1.0 + mean_t, math.inf
    return 1.0 + mean_t, max(second - mean_t * mean_t, 0.0)


class FlagRates(NamedTuple):
    """Long-run flag-ACKs per step (see :func:`flag_rates`)."""

    sent: float
    """Genuine flag-ACKs sent by the remote detector."""
    delivered: float
    """Flag-ACKs reaching the sensor, genuine or forged: the sensor's high-power rate."""
    forged: float
    """Forged flag-ACKs (part of ``delivered``)."""


def flag_rates(lam: Any, z0: Any, attack: Any = None, mu: Any = 1.0) -> FlagRates:
    r"""Long-run flag-ACKs per step: sent by the detector, reaching the sensor, forged (exact).

    Under a periodic attack each level of the attacker's counter is left at the same rate
    :math:`F = u/D` (the renewal form of :func:`fakeack.j_attack`, with D its normaliser), so a
    period of t flags sends :math:`tF` and delivers :math:`(t - \text{blocked})F`. Independent
    blocking delivers :math:`1-\beta` of what is sent; a :class:`fakeack.FlagInjection` adds
    :math:`\gamma(1 - \text{sent})` forged flags, which the sensor cannot tell from genuine
    ones, so they count as delivered. The rates do not depend on the plant.

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    attack : None, attack or (r, t), optional
        Any attack (:class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`,
        :class:`fakeack.RandomBlocking`, :class:`fakeack.FlagInjection`).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).

    Returns
    -------
    FlagRates
        ``(sent, delivered, forged)``; with every flag-ACK blocked and none forged, ``sent`` is
        the all-blocked rate :math:`\lambda u/(1-u)` and ``delivered`` is 0.

    Examples
    --------
    >>> sent, delivered, forged = flag_rates(0.5, 2)
    >>> round(sent, 12) == round(delivered, 12) == round(1 / 7, 12) and forged == 0
    True
    """
    lam, z0, mu = _online(lam, z0, mu)
    return FlagRates(*_fakeack.flag_rates(lam, z0, mu, core_attack(as_attack(attack))))


def delivered_flag_rate(lam: Any, z0: Any, attack: Any = None, mu: Any = 1.0) -> float:
    r"""Long-run flag-ACKs reaching the sensor per step under an attack (exact).

    Genuine and forged flags count alike: the sensor cannot tell them apart.

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    attack : None, attack or (r, t)
        Any attack; ``None`` gives the online high-power rate.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    """
    return flag_rates(lam, z0, attack, mu)[1]


def _regime_rates(lam: float, z0: int, mu: float) -> tuple[float, float]:
    """(f_on, f_blk): flags per step unattacked and with every flag blocked."""
    f_on = _fakeack.flag_rates(lam, z0, mu, None)[0]
    f_blk = _fakeack.flag_rates(lam, z0, mu, _fakeack.Attack.mask([True]))[0]
    return f_on, f_blk


def estimate_beta(delivered: Any, n_steps: Any, lam: Any, z0: Any, mu: Any = 1.0) -> float:
    r"""Estimate the attacker's budget β from the delivered flag-ACK rate.

    In the large-period model (the attacker blocks long runs), a fraction β of flags falls in the
    all-blocked regime (flag rate :math:`f_{blk} = \lambda u/(1-u)`) and 1-β in the unattacked one
    (:math:`f_{on}`), so the delivered rate is
    :math:`\rho(\beta) = (1-\beta)/(\beta/f_{blk} + (1-\beta)/f_{on})`, decreasing in β. Inverting
    at the observed rate gives
    :math:`\hat\beta = (1 - \hat\rho/f_{on}) / (1 + \hat\rho/f_{blk} - \hat\rho/f_{on})`, clipped to
    [0, 1]. It assumes the observation window spans many attack periods; for the paper's short
    patterns the model is close (1000-step windows: mean estimate 0.203 at r/t = 1/5, 0.669 at 2/3);
    :func:`detection_rates` reports the simulated mean and spread.

    Parameters
    ----------
    delivered : int
        Flag-ACKs the sensor received.
    n_steps : int
        Observation length in steps.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    """
    lam, z0, mu = _online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    d = as_int("delivered", delivered, minimum=0)
    if d > n:
        raise ValueError(f"delivered must not exceed n_steps = {n}, got {d}")
    f_on, f_blk = _regime_rates(lam, z0, mu)
    if not f_on > 0.0:
        raise ValueError(
            f"z0: flag-ACKs are too rare to estimate beta (attack-free rate {f_on:.3g} per step "
            f"at lam={lam}, z0={z0})"
        )
    rho = d / n
    if rho >= f_on:  # at least the attack-free rate (the formula's denominator can vanish here)
        return 0.0
    if rho == 0.0:
        return 1.0
    # The inversion above, multiplied through by f_blk/f_on = g: no division by a rate that
    # underflows, and no 1 + x - x cancellation when the two rates nearly agree (g -> 1 gives
    # 1 - rho/f_on, the value for equal rates).
    g = f_blk / f_on
    beta = g * (f_on - rho) / (f_blk + rho * (1.0 - g))
    return float(min(max(beta, 0.0), 1.0))


def _count_law(n: int, lam: float, z0: int, mu: float) -> tuple[float, float]:
    """Mean n/m and standard deviation sqrt(n v / m^3) of the attack-free flag count in n steps
    (renewal CLT); ValueError when the interval moments exceed the double range."""
    m, v = flag_interval_moments(lam, z0, mu)
    if not (math.isfinite(m) and math.isfinite(v)):
        raise ValueError(
            f"z0: flag-ACKs are too rare to test (interval moments beyond the double range at "
            f"lam={lam}, z0={z0})"
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
    delivered: Any,
    n_steps: Any,
    lam: Any,
    z0: Any,
    mu: Any = 1.0,
    alpha: Any = 0.01,
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
    from .detectors import check_alternative, count_p_value, count_z

    lam, z0, mu = _online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    d = as_int("delivered", delivered, minimum=0)
    alpha = as_probability("alpha", alpha)
    alternative = check_alternative(alternative)
    expected, _ = _count_law(n, lam, z0, mu)  # ValueError when flags are too rare to test
    m, v = flag_interval_moments(lam, z0, mu)
    z = count_z(d, n, m, v)
    p = count_p_value(z, alternative)
    beta = estimate_beta(d, n, lam, z0, mu)
    return Detection(p < alpha, z, p, beta, d, expected, n, alpha, alternative)


@dataclass(frozen=True)
class DetectionRates:
    """Simulated performance of the sensor's tests (see :func:`detection_rates`)."""

    false_alarm: float
    """Fraction of attack-free windows flagged as attacked (should be close to alpha)."""
    detection: float
    """Fraction of attacked windows flagged."""
    beta_hat_mean: float
    """Mean of :func:`estimate_beta` over the attacked windows."""
    beta_hat_std: float
    beta: float
    """The attack's budget (the blocking part's, for an injection)."""
    runs: int
    n_steps: int
    alpha: float
    false_alarm_stderr: float = math.nan
    detection_stderr: float = math.nan
    test: str = "count"
    alternative: str = "less"
    burn_in: int = 0


def detection_rates(
    lam: Any,
    z0: Any,
    attack: Any,
    n_steps: Any = 1000,
    runs: Any = 2000,
    mu: Any = 1.0,
    alpha: Any = 0.01,
    seed: Any = 1,
    test: str = "count",
    alternative: str | None = None,
    burn_in: Any = 0,
) -> DetectionRates:
    """False-alarm and detection rates of the sensor's tests by Monte Carlo of the protocol.

    Simulates ``runs`` attack-free and ``runs`` attacked observation windows of ``n_steps`` steps
    (one window per run, after ``burn_in`` steps; the flag process does not depend on the plant)
    with the closed-loop kernel of :func:`fakeack.simulate_game`, and applies the test to
    each: the count test of :func:`detect_attack` or the interval test of
    :func:`fakeack.detect_intervals`, with their exact alarm regions. With ``burn_in=0`` every
    window starts from the paper's initial condition; a burn-in of a window or more puts the
    window near the stationary regime that :func:`fakeack.detection_probability` describes. Forged flag-ACKs
    (:class:`fakeack.FlagInjection`) count as delivered: the sensor cannot tell them from genuine
    ones, which is how :func:`fakeack.rate_matching_attack` hides from the count test.

    Parameters
    ----------
    lam : float
        Arrival probability at low power.
    z0 : int
        Memory length of the event detector.
    attack : attack, (r, t) or str
        The attack to detect: :class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`,
        :class:`fakeack.RandomBlocking` or :class:`fakeack.FlagInjection` (its ``beta`` is that of
        its blocking part), or a spelling such as ``"1/5"`` or ``"inject:0.04+random:0.2"``.
    n_steps : int, optional
        Observation window in steps (default 1000).
    runs : int, optional
        Windows simulated with and without the attack (default 2000).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    alpha : float, optional
        Level of the test (default 0.01).
    seed : int, optional
        Seed of the attack-free windows (the attacked ones use seed + 1).
    test : {"count", "interval"}, optional
        The test (default the count test).
    alternative : {"less", "greater", "two-sided"}, optional
        The count test's alternative (default "less", as :func:`detect_attack`); the interval test
        is two-sided (the default for it, and the only value it takes).
    burn_in : int, optional
        Steps simulated before each window, rounded up to whole windows (default 0).
    """
    from .detectors import check_alternative, check_test, simulate_windows

    lam, z0, mu = _online(lam, z0, mu)
    att = as_attack(attack)
    if att is None:
        raise ValueError("attack: give the attack whose detection rate you want, e.g. (1, 5)")
    n = as_int("n_steps", n_steps, minimum=1)
    runs = as_int("runs", runs, minimum=2, maximum=1 << 24)
    alpha = as_probability("alpha", alpha)
    seed = as_int("seed", seed, minimum=0, maximum=2**63)
    test = check_test(test)
    if alternative is None:
        alternative = "less" if test == "count" else "two-sided"
    alternative = check_alternative(alternative)
    if test == "interval" and alternative != "two-sided":
        raise ValueError("alternative: the interval test is two-sided by construction")
    burn_in = as_int("burn_in", burn_in, minimum=0)
    flagged, se = {}, {}
    delivered = None
    for name, a, sd in (("clean", None, seed), ("attacked", att, seed + 1)):
        alarms, counts = simulate_windows(lam, z0, mu, a, n, runs, sd, test, alpha, alternative, burn_in)
        p = float(np.mean(alarms))
        flagged[name], se[name] = p, math.sqrt(max(p * (1 - p), 0.0) / runs)
        delivered = counts
    betas = np.array([estimate_beta(int(c), n, lam, z0, mu) for c in delivered])
    beta = float(att.beta)
    return DetectionRates(flagged["clean"], flagged["attacked"], float(betas.mean()),
                          float(betas.std(ddof=1)), beta, runs, n, alpha, se["clean"], se["attacked"],
                          test, alternative, burn_in)
