"""The high-power rate and the energy per step under any attack: what the flag-ACKs that reach the
sensor, genuine or forged, cost it in energy."""

from __future__ import annotations

from typing import NamedTuple

from .. import _fakeack
from .._internal.validate import as_real
from ..model.channels import Channel, ChannelLike, is_paper_channel
from ..model.exact import channel_of, engine
from ..model.schedules import OnlineDesign, check_online_channel
from .automata import AttackerAutomaton, MimicryAttack
from .kinds import Attack, AttackLike, EngineOnlyAttack, FlagInjection, as_attack, core_attack

__all__ = [
    "FlagRates",
    "high_power_rate",
    "online_high_power_rate",
    "energy_per_step",
    "engine_for",
    "structured_route",
]

#: What the rates take as an attack: any built-in spelling, or an automaton of the engine.
AnyAttack = AttackLike | MimicryAttack | AttackerAutomaton


class FlagRates(NamedTuple):
    """Long-run flag-ACKs per step (see :func:`flag_rates`)."""

    sent: float
    """Genuine flag-ACKs sent by the remote detector."""
    delivered: float
    """Flag-ACKs reaching the sensor, genuine or forged: the sensor's high-power rate."""
    forged: float
    """Forged flag-ACKs (part of ``delivered``)."""

    @property
    def blocked(self) -> float:
        """Genuine flag-ACKs that did not reach the sensor: ``sent - (delivered - forged)``."""
        return self.sent - (self.delivered - self.forged)


def structured_route(ch: Channel, attack: object) -> bool:
    """Whether today's structured route computes this channel and attack (else the exact engine):
    the paper's channel and an attack it knows (not a :class:`fakeack.MimicryAttack`, an
    :class:`fakeack.AttackerAutomaton` nor a :class:`fakeack.FlagInjection` with ``min_gap > 1``,
    which only the engine computes, as :func:`fakeack.j_attack` does)."""
    if not is_paper_channel(ch) or isinstance(attack, EngineOnlyAttack):
        return False
    return not (isinstance(attack, FlagInjection) and attack.min_gap > 1)


def engine_for(ch: Channel, design: OnlineDesign, attack: object) -> _fakeack.Engine:
    """The exact engine of the online ``design`` on ``ch`` under ``attack``, as
    :class:`fakeack.Scenario` builds it (a mimicry attacker's ``None`` channel and design are
    these)."""
    z0, mu = design
    if isinstance(attack, MimicryAttack):
        vch = attack.channel if attack.channel is not None else ch
        vd = attack.design if attack.design is not None else design
        return engine(ch, z0, mu, mimicry=(vch.P.tolist(), vch.low.tolist(), vch.high.tolist(), vd.z0, vd.mu))
    if isinstance(attack, AttackerAutomaton):
        moves = ([list(ev) for ev in attack.flag], [list(ev) for ev in attack.quiet], attack.start)
        return engine(ch, z0, mu, automaton=moves)
    a = as_attack(attack)  # type: ignore[arg-type]  # as_attack validates any object
    gap = a.min_gap if isinstance(a, FlagInjection) else 1
    return engine(ch, z0, mu, attack=core_attack(a, engine=True), min_gap=gap)


def high_power_rate(
    channel: ChannelLike | None = None,
    z0: int | None = None,
    attack: AnyAttack = None,
    mu: float = 1.0,
    *,
    lam: float | None = None,
) -> float:
    r"""Long-run fraction of steps at high power under an attack (exact).

    The sensor uses high power after every flag-ACK that reaches it, genuine or forged, so this is
    the rate of delivered plus forged flags: with ``s`` genuine flags sent per step, a blocking
    attack delivers a fraction of them and a :class:`fakeack.FlagInjection` adds
    :math:`\gamma(1 - s)` forged ones. Without attack (``attack=None``) it is the online
    schedule's rate in closed form (Model note 2),

    .. math:: \frac{\lambda a^{z_0}(\mu + (1-\mu)a)}{1 - \mu a^{z_0+1} - (1-\mu)a^{z_0+2}}.

    This is the one high-power rate of the package: :func:`fakeack.online_high_power_rate` is its
    attack-free case and :func:`fakeack.delivered_flag_rate` the same function under the name of
    the flag-ACKs it counts. Under a channel other than the paper's, and for the attacks only
    the exact engine computes, it is :meth:`fakeack.Scenario.high_power_rate`.

    Parameters
    ----------
    channel : Channel or float
        The channel; a float is the paper's, with arrival probability :math:`\lambda \in (0, 1)`
        at low power.
    z0 : int
        Memory length of the event detector.
    attack : None or attack, optional
        Any attack (:class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`,
        :class:`fakeack.RandomBlocking`, :class:`fakeack.FlagInjection`, or ``(r, t)``), and those
        only the exact engine computes: ``FlagInjection(min_gap > 1)``, a
        :class:`fakeack.MimicryAttack` or an :class:`fakeack.AttackerAutomaton`.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float).

    Examples
    --------
    >>> round(high_power_rate(GilbertElliott(0.1, 0.1, 1, 0), 2), 6)   # bursts: 1/7 if i.i.d.
    0.166052
    >>> round(high_power_rate(0.5, 2), 12) == round(1 / 7, 12)
    True
    >>> high_power_rate(0.5, 2, FlagInjection(1.0))
    1.0
    """
    ch, name = channel_of(channel, lam, "high_power_rate")
    if not structured_route(ch, attack):
        design = OnlineDesign(z0, mu)  # type: ignore[arg-type]  # OnlineDesign validates z0
        return float(engine_for(ch, design, attack).high_power_rate())
    lam_v, design = check_online_channel(ch, name, z0, mu, "high_power_rate")
    return design_high_power_rate(lam_v, design, as_attack(attack))  # type: ignore[arg-type]


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
    channel: ChannelLike | None = None,
    z0: int | None = None,
    Delta: float | None = None,
    delta: float | None = None,
    attack: AnyAttack = None,
    mu: float = 1.0,
    *,
    lam: float | None = None,
) -> float:
    r"""Long-run energy per step: :math:`\delta + (\Delta - \delta)\,f`, f the high-power rate.

    With ``attack=None`` and the designed schedule this is the budget :math:`\Psi`. An attack that
    forges flag-ACKs raises it above :math:`\Psi`, so a battery sized for :math:`\Psi` lasts
    :math:`\Psi/e` of its planned life; blocking lowers it (the sensor saves energy and loses
    accuracy).

    Parameters
    ----------
    channel : Channel or float
        The channel; a float is the paper's, with arrival probability :math:`\lambda \in (0, 1)`
        at low power.
    z0 : int
        Memory length of the event detector.
    Delta, delta : float
        Energy of a high-power and a low-power transmission, :math:`\Delta > \delta \ge 0`.
    attack : None or attack, optional
        As in :func:`high_power_rate`.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float).

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
    return lo + (hi - lo) * high_power_rate(channel, z0, attack, mu, lam=lam)
