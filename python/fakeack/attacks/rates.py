"""The high-power rate and the energy per step under any attack: what the flag-ACKs that reach the
sensor, genuine or forged, cost it in energy."""

from __future__ import annotations

from .. import _fakeack
from .._internal.validate import as_real
from ..model.schedules import OnlineDesign, check_online
from .kinds import Attack, AttackLike, as_attack, core_attack

__all__ = [
    "high_power_rate",
    "online_high_power_rate",
    "energy_per_step",
]


def high_power_rate(lam: float, z0: int, attack: AttackLike = None, mu: float = 1.0) -> float:
    r"""Long-run fraction of steps at high power under an attack (exact).

    The sensor uses high power after every flag-ACK that reaches it, genuine or forged, so this is
    the rate of delivered plus forged flags: with ``s`` genuine flags sent per step, a blocking
    attack delivers a fraction of them and a :class:`fakeack.FlagInjection` adds
    :math:`\gamma(1 - s)` forged ones. Without attack (``attack=None``) it is the online
    schedule's rate in closed form (Model note 2),

    .. math:: \frac{\lambda a^{z_0}(\mu + (1-\mu)a)}{1 - \mu a^{z_0+1} - (1-\mu)a^{z_0+2}}.

    This is the one high-power rate of the package: :func:`fakeack.online_high_power_rate` is its
    attack-free case and :func:`fakeack.delivered_flag_rate` the same function under the name of
    the flag-ACKs it counts.

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    attack : None or attack, optional
        Any attack (:class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`,
        :class:`fakeack.RandomBlocking`, :class:`fakeack.FlagInjection`, or ``(r, t)``).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).

    Examples
    --------
    >>> round(high_power_rate(0.5, 2), 12) == round(1 / 7, 12)
    True
    >>> high_power_rate(0.5, 2, FlagInjection(1.0))
    1.0
    """
    lam, design = check_online(lam, z0, mu)
    return design_high_power_rate(lam, design, as_attack(attack))


def design_high_power_rate(lam: float, design: OnlineDesign, attack: Attack | None) -> float:
    """:func:`high_power_rate` of a validated schedule and attack."""
    if attack is None:
        return _fakeack.high_power_rate(lam, design.z0, design.mu)
    return _fakeack.flag_rates(lam, design.z0, design.mu, core_attack(attack))[1]


def online_high_power_rate(lam: float, z0: int, mu: float = 1.0) -> float:
    r"""Long-run fraction of steps at high power under :math:`\theta_{\mathrm{on}}` without attack
    (Model note 2): :func:`high_power_rate` with ``attack=None``.

    .. math:: \frac{\lambda a^{z_0}(\mu + (1-\mu)a)}{1 - \mu a^{z_0+1} - (1-\mu)a^{z_0+2}}

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).

    Examples
    --------
    >>> round(online_high_power_rate(0.5, 2), 12)    # 1/7
    0.142857142857
    """
    return high_power_rate(lam, z0, None, mu)


def energy_per_step(
    lam: float, z0: int, Delta: float, delta: float, attack: AttackLike = None, mu: float = 1.0
) -> float:
    r"""Long-run energy per step: :math:`\delta + (\Delta - \delta)\,f`, f the high-power rate.

    With ``attack=None`` and the designed schedule this is the budget :math:`\Psi`. An attack that
    forges flag-ACKs raises it above :math:`\Psi`, so a battery sized for :math:`\Psi` lasts
    :math:`\Psi/e` of its planned life; blocking lowers it (the sensor saves energy and loses
    accuracy).

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    Delta, delta : float
        Energy of a high-power and a low-power transmission, :math:`\Delta > \delta \ge 0`.
    attack : None or attack, optional
        As in :func:`high_power_rate`.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).

    Examples
    --------
    >>> round(energy_per_step(0.5, 2, 3, 1), 12) == round(9 / 7, 12)   # the paper's Psi
    True
    """
    hi, lo = as_real("Delta", Delta), as_real("delta", delta)
    if lo < 0:
        raise ValueError(f"delta must be non-negative, got {lo}")
    if not hi > lo:
        raise ValueError(f"Delta must exceed delta, got Delta={hi}, delta={lo}")
    return lo + (hi - lo) * high_power_rate(lam, z0, attack, mu)
