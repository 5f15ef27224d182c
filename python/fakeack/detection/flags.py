"""The flag-ACKs the sensor receives (the paper's Remark 4.2): their rates under any attack, the
moments of the gaps between them, and the blocked fraction estimated from a count."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .. import _fakeack
from .._internal.validate import as_int
from ..attacks.kinds import AttackLike, as_attack, core_attack
from ..attacks.rates import AnyAttack, FlagRates, engine_for, high_power_rate, structured_route
from ..model.channels import ChannelLike
from ..model.exact import channel_of
from ..model.schedules import OnlineDesign, check_online, check_online_channel
from ..model.system import LinearSystem

__all__ = [
    "as_gaps",
    "attack_free_min_gap",
    "flag_interval_moments",
    "FlagRates",
    "flag_rates",
    "delivered_flag_rate",
    "estimate_beta",
]


# The flag process does not depend on the plant: any valid system serves for rates.
_ANY_SYSTEM: LinearSystem | None = None


def any_system() -> LinearSystem:
    global _ANY_SYSTEM
    if _ANY_SYSTEM is None:
        _ANY_SYSTEM = LinearSystem(0.5, 1.0, 1.0, 1.0)
    return _ANY_SYSTEM


def as_gaps(gaps: object) -> npt.NDArray[np.int64]:
    """``gaps`` (steps since the previous flag-ACK, one per flag-ACK) as a 1-D integer array, or a
    ``ValueError`` naming it."""
    g = np.asarray(gaps)
    if g.ndim != 1:
        raise ValueError(f"gaps must be a 1-D sequence of positive integers, got shape {g.shape}")
    if g.size and (g.dtype.kind not in "iu" or g.min() < 1):
        if g.dtype.kind == "f" and np.all(np.isfinite(g)) and np.all(g == np.round(g)) and g.min() >= 1:
            return g.astype(np.int64)
        raise ValueError("gaps must be positive integers (steps since the previous flag-ACK)")
    return g.astype(np.int64)


def attack_free_min_gap(design: OnlineDesign) -> int:
    """The shortest gap between flag-ACKs reaching the sensor without attack on the paper's
    channel: after a flag-ACK the high-power packet arrives, then z0 losses (z0 + 1 when mu = 0)
    send the next one (:attr:`fakeack.FlagProcess.min_gap` computes it on any channel)."""
    return design.z0 + 1 if design.mu > 0 else design.z0 + 2


def flag_interval_moments(lam: float, z0: int, mu: float = 1.0) -> tuple[float, float]:
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
    lam, (z0, mu) = check_online(lam, z0, mu)
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


def flag_rates(
    channel: ChannelLike | None = None,
    z0: int | None = None,
    attack: AnyAttack = None,
    mu: float = 1.0,
    *,
    lam: float | None = None,
) -> FlagRates:
    r"""Long-run flag-ACKs per step: sent by the detector, reaching the sensor, forged (exact).

    Under a periodic attack each level of the attacker's counter is left at the same rate
    :math:`F = u/D` (the renewal form of :func:`fakeack.j_attack`, with D its normaliser), so a
    period of t flags sends :math:`tF` and delivers :math:`(t - \text{blocked})F`. Independent
    blocking delivers :math:`1-\beta` of what is sent; a :class:`fakeack.FlagInjection` adds
    :math:`\gamma(1 - \text{sent})` forged flags, which the sensor cannot tell from genuine
    ones, so they count as delivered. The rates do not depend on the plant. Under a channel
    other than the paper's, and for the attacks only the exact engine computes, they are
    :meth:`fakeack.Scenario.flag_rates`.

    Parameters
    ----------
    channel : Channel or float
        The channel; a float is the paper's, with arrival probability :math:`\lambda \in (0, 1)`
        at low power.
    z0 : int
        Memory length of the event detector.
    attack : None, attack or (r, t), optional
        Any attack (:class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`,
        :class:`fakeack.RandomBlocking`, :class:`fakeack.FlagInjection`), and those only the exact
        engine computes: ``FlagInjection(min_gap > 1)``, a :class:`fakeack.MimicryAttack` or an
        :class:`fakeack.AttackerAutomaton`.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float).

    Returns
    -------
    FlagRates
        ``(sent, delivered, forged)``; with every flag-ACK blocked and none forged, ``sent`` is
        the all-blocked rate :math:`\lambda u/(1-u)` and ``delivered`` is 0.

    Examples
    --------
    >>> round(flag_rates(GilbertElliott(0.1, 0.1, 1, 0), 2, MaskBlocking([1])).sent, 6)  # all blocked
    0.236842
    >>> sent, delivered, forged = flag_rates(0.5, 2)
    >>> round(sent, 12) == round(delivered, 12) == round(1 / 7, 12) and forged == 0
    True
    """
    ch, name = channel_of(channel, lam, "flag_rates")
    if not structured_route(ch, attack):
        design = OnlineDesign(z0, mu)  # type: ignore[arg-type]  # OnlineDesign validates z0
        return FlagRates(*(float(x) for x in engine_for(ch, design, attack).flag_rates()))
    lam_v, design = check_online_channel(ch, name, z0, mu, "flag_rates")
    att = core_attack(as_attack(attack))  # type: ignore[arg-type]  # the engine's went above
    return FlagRates(*_fakeack.flag_rates(lam_v, design.z0, design.mu, att))


def delivered_flag_rate(lam: float, z0: int, attack: AttackLike = None, mu: float = 1.0) -> float:
    r"""Long-run flag-ACKs reaching the sensor per step under an attack (exact).

    Genuine and forged flags count alike: the sensor cannot tell them apart, and each makes it use
    high power, so this is :func:`fakeack.high_power_rate` under the name of what it counts.

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
    return high_power_rate(lam, z0, attack, mu)


def regime_rates(lam: float, design: OnlineDesign) -> tuple[float, float]:
    """(f_on, f_blk): flags per step unattacked and with every flag blocked."""
    z0, mu = design
    f_on = _fakeack.flag_rates(lam, z0, mu, None)[0]
    f_blk = _fakeack.flag_rates(lam, z0, mu, _fakeack.Attack.mask([True]))[0]
    return f_on, f_blk


def estimate_beta(delivered: int, n_steps: int, lam: float, z0: int, mu: float = 1.0) -> float:
    r"""Estimate the attacker's budget β from the delivered flag-ACK rate (maximum likelihood).

    In the large-period model (the attacker blocks long runs), a fraction β of flags falls in the
    all-blocked regime (flag rate :math:`f_{blk} = \lambda u/(1-u)`) and 1-β in the unattacked one
    (:math:`f_{on}`), so the delivered rate is
    :math:`\rho(\beta) = (1-\beta)/(\beta/f_{blk} + (1-\beta)/f_{on})`, decreasing in β. The
    count's rate is the model's one parameter and :math:`\hat\rho = N/n` its maximum-likelihood
    estimate, so by invariance the maximum-likelihood β on [0, 1] is :math:`\rho^{-1}(\hat\rho)`
    clipped to [0, 1]:
    :math:`\hat\beta = (1 - \hat\rho/f_{on}) / (1 + \hat\rho/f_{blk} - \hat\rho/f_{on})`. A
    window in which fewer than one flag-ACK is expected without attack
    (:math:`n f_{on} < 1`) carries no information on β (no flag is what the sensor expects
    anyway), and is refused rather than answered with β = 1. It assumes the observation window
    spans many attack periods; for the paper's short patterns the model is close (1000-step
    windows: mean estimate 0.203 at r/t = 1/5, 0.669 at 2/3);
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

    Returns
    -------
    float
        The estimate, in [0, 1].

    Raises
    ------
    ValueError
        For a bad argument (naming it), a count above ``n_steps``, or a window in which fewer than
        one flag-ACK is expected without attack (naming ``n_steps``).
    """
    lam, design = check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    d = as_int("delivered", delivered, minimum=0)
    if d > n:
        raise ValueError(f"delivered must not exceed n_steps = {n}, got {d}")
    f_on, f_blk = regime_rates(lam, design)
    if not f_on > 0.0:
        raise ValueError(
            f"z0: flag-ACKs are too rare to estimate beta (attack-free rate {f_on:.3g} per step "
            f"at lam={lam}, z0={design.z0})"
        )
    if n * f_on < 1.0 - 1e-12:  # (not a rounding of exactly one expected flag)
        raise ValueError(
            f"n_steps = {n}: fewer than one flag-ACK is expected in the window without attack "
            f"({n * f_on:.3g} at lam={lam}, z0={design.z0}), so its count says nothing about beta; "
            "use a longer window"
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
