"""Exact finite-horizon curves: E Tr P_k and J_k from the paper's initial condition, the curves the
Monte Carlo of the protocol estimates."""

from __future__ import annotations

import numpy as np

from .._internal.validate import as_int, as_probability
from ..attacks.automata import AttackerAutomaton, MimicryAttack
from ..attacks.kinds import Attack, AttackLike, FlagInjection, MaskBlocking, as_attack, core_attack
from ..model.channels import ChannelLike, channel_argument, is_paper_channel
from ..model.schedules import OfflineSchedule, OnlineDesign
from ..model.system import LinearSystem, compiled
from .trace import TraceCurve

__all__ = [
    "TraceCurve",
    "expected_trace_curve",
]

CurveAttack = Attack | MimicryAttack | AttackerAutomaton


def _schedule_and_attack(
    sched: object, attack: object
) -> tuple[OfflineSchedule | OnlineDesign, CurveAttack | None]:
    """Validated schedule and attack (None: no attacker); offline schedules take none."""
    if sched is None:
        raise TypeError("expected_trace_curve() missing the schedule sched")
    if not isinstance(sched, (OfflineSchedule, OnlineDesign)):
        raise TypeError(
            f"sched must be a fakeack.OfflineSchedule or fakeack.OnlineSchedule, got {type(sched).__name__}"
        )
    att: CurveAttack | None
    if isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        att = attack
    else:
        att = as_attack(attack)  # type: ignore[arg-type]  # as_attack validates any object
    if isinstance(sched, OfflineSchedule) and att is not None:
        raise ValueError("attack: an offline schedule ignores ACKs, so an attack has no effect")
    return sched, att


def _structured(sched: OfflineSchedule | OnlineDesign, att: CurveAttack | None) -> bool:
    """Whether today's structured curve computes this on the paper's channel: an online design or
    ``OfflineSchedule(ratio)``, a built-in attack with ``min_gap = 1``, not every flag blocked."""
    if isinstance(sched, OfflineSchedule):
        return sched.ratio is not None
    if isinstance(att, (MimicryAttack, AttackerAutomaton)):
        return False
    if isinstance(att, FlagInjection) and att.min_gap > 1:
        return False
    return not (isinstance(att, MaskBlocking) and all(att.mask))


def expected_trace_curve(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    sched: OfflineSchedule | OnlineDesign | None = None,
    horizon: int = 200,
    attack: AttackLike | MimicryAttack | AttackerAutomaton = None,
    *,
    lam: float | None = None,
) -> TraceCurve:
    r"""Exact finite-horizon curve :math:`\mathbb E[\mathrm{Tr}\,P_k]`, k = 1..horizon (no sampling).

    Propagates the law of the protocol's state (holding time, memory zeros, attacker counter) from
    the paper's initial condition (high power at k = 1, memory all ones, counter 0; on a Markov
    channel the first channel state has the stationary law), so the transient of the paper's
    Figs. 3-4 appears without Monte Carlo noise. As k grows, ``j_k`` tends to the stationary J
    (:func:`fakeack.j_offline`, :func:`fakeack.j_online`, :func:`fakeack.j_attack`,
    :meth:`fakeack.Scenario.cost`).

    On the paper's channel (one state, a high-power packet always arrives) with an online design
    or ``OfflineSchedule(ratio)`` and a built-in attack with ``min_gap = 1`` (a mask that blocks
    every flag-ACK aside), the structured propagation of the holding time runs, unchanged. Every
    other case (a Markov channel, an offline pattern, :class:`fakeack.MimicryAttack`,
    :class:`fakeack.AttackerAutomaton`, an injection with ``min_gap > 1``, every flag-ACK blocked)
    is the exact engine's :meth:`fakeack.Scenario.cost_curve`, which propagates the law of its
    automaton E from the same initial condition and returns the same :class:`TraceCurve`.

    Parameters
    ----------
    system : LinearSystem
    channel : Channel or float
        :class:`fakeack.BernoulliChannel`, :class:`fakeack.MarkovChannel`,
        :class:`fakeack.GilbertElliott`, or a float: the paper's channel of that low-power arrival
        probability :math:`\lambda` (in (0, 1) on the structured route).
    sched : OfflineSchedule or OnlineSchedule
        The online design ``(z0, mu)``, or an offline schedule by its ratio or by any pattern
        (``OfflineSchedule(pattern="0100")``: first symbol = step 1).
    horizon : int, optional
        Number of steps (default 200).
    attack : None, attack, (r, t), str, MimicryAttack or AttackerAutomaton, optional
        The attack; online schedules only (an offline schedule ignores ACKs). Any built-in attack
        or spelling ``fakeack.attacks.as_attack`` reads, :class:`fakeack.MimicryAttack` (its
        ``None`` channel and design are this curve's) or :class:`fakeack.AttackerAutomaton`.
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float): ``expected_trace_curve(system, lam=0.5,
        sched=...)`` still works. Giving both is a TypeError.

    Returns
    -------
    TraceCurve
        Entries are ``inf`` (never NaN) past the double range. The curve weights the plain traces
        :math:`\mathrm{Tr}\,h^\tau(\bar P)` by probabilities, so where
        :math:`(1-\lambda)\rho(A)^2 \ge 1` an entry is ``inf`` as soon as a reachable holding time
        passes the overflow of its trace (τ ≈ 1950 for the paper's system), even where
        E[Tr P_k] itself would still fit in a double.

    Raises
    ------
    TypeError, ValueError
        For a missing or doubly given channel or a bad argument (naming it), an attack on an
        offline schedule, or (engine route) a scenario from some state of which no packet ever
        arrives again.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    >>> curve = fa.expected_trace_curve(s, ge, fa.OnlineDesign(2), 3000)
    >>> round(float(curve.j_k[-1]), 2), round(fa.Scenario(s, ge, fa.OnlineDesign(2)).cost(), 2)
    (1.33, 1.33)
    """
    core = compiled(system)
    ch, channel_name = channel_argument(channel, lam, "expected_trace_curve")
    sched, att = _schedule_and_attack(sched, attack)
    horizon = as_int("horizon", horizon, minimum=1)
    if not (is_paper_channel(ch) and _structured(sched, att)):
        from ..engine.scenario import Scenario  # the engine returns this module's TraceCurve

        return Scenario(system, ch, sched, att).cost_curve(horizon)
    lam_value = as_probability(channel_name, float(ch.low[0]))
    assert not isinstance(att, (MimicryAttack, AttackerAutomaton))  # _structured
    if isinstance(sched, OfflineSchedule):
        r = sched.ratio
        assert r is not None  # _structured: a pattern goes to the engine
        trace = core.curve_offline(lam_value, r.numerator, r.denominator, horizon)
    else:
        trace = core.curve_online(lam_value, sched.z0, sched.mu, core_attack(att), horizon)
    k = np.arange(1, horizon + 1)
    with np.errstate(over="ignore"):  # a running sum past the double range is inf, as documented
        j_k = np.cumsum(trace) / k
    return TraceCurve(k, trace, j_k)
