"""The conversion of a built-in scenario (channel, schedule, attack) to the compiled engine's arguments."""

from __future__ import annotations

from typing import Any, NamedTuple, cast

import scipy.sparse as sp

from ..attacks.automata import AttackerAutomaton, MimicryAttack, Transition
from ..attacks.jamming import JammingAttack
from ..attacks.kinds import Attack, AttackLike, FlagInjection, as_attack, core_attack
from ..model.channels import Channel
from ..model.schedules import OfflineSchedule, OnlineDesign
from .chains import AttackPolicy, SchedulePolicy, has_chain

__all__ = [
    "EngineAutomaton",
    "ScenarioAttack",
    "ScenarioSchedule",
    "AnySchedule",
    "AnyAttack",
    "as_schedule",
    "as_scenario_attack",
    "binding_args",
    "MAX_OFFLINE_PERIOD",
]

#: Longest offline period passed to the engine.
MAX_OFFLINE_PERIOD = 10_000_000

ScenarioAttack = Attack | MimicryAttack | AttackerAutomaton
ScenarioSchedule = OnlineDesign | OfflineSchedule
#: Every schedule a scenario takes.
AnySchedule = OnlineDesign | OfflineSchedule | SchedulePolicy
#: Every attack a scenario takes.
AnyAttack = Attack | MimicryAttack | AttackerAutomaton | JammingAttack | AttackPolicy


class EngineAutomaton(NamedTuple):
    """The automaton E of a scenario: a label per state and the loss / arrival parts of K."""

    labels: list[str]
    """One readable label per state of E."""
    K0: sp.csr_array
    """Transitions on which the packet is lost (tau -> tau + 1)."""
    K1: sp.csr_array
    """Transitions on which the packet arrives (tau -> 0)."""


def as_schedule(schedule: object) -> OnlineDesign | OfflineSchedule | SchedulePolicy:
    """A scenario's schedule, checked (a sensor policy by its ``scenario_chain``)."""
    if isinstance(schedule, (OnlineDesign, OfflineSchedule)):
        return schedule
    if has_chain(schedule):
        return cast("SchedulePolicy", schedule)
    raise TypeError(
        "schedule must be a fakeack.OnlineDesign, fakeack.OfflineSchedule or a sensor policy with "
        f"scenario_chain(channel) (fakeack.HoldingTimePolicy), got {type(schedule).__name__}"
    )


def as_scenario_attack(attack: object) -> ScenarioAttack | None:
    """A built-in attack, an attacker automaton or mimicry, checked."""
    if isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        return attack
    return as_attack(cast("AttackLike", attack))  # as_attack validates any object


def transitions(events: tuple[tuple[Transition, ...], ...]) -> list[list[Transition]]:
    """An automaton's moves as lists."""
    return [list(ev) for ev in events]


def binding_args(
    ch: Channel, schedule: ScenarioSchedule, a: ScenarioAttack | None, max_states: int
) -> tuple[Any, ...]:
    """The arguments of ``_fakeack.Engine`` for a channel, a schedule and a built-in attack."""
    P, low, high = ch.P.tolist(), ch.low.tolist(), ch.high.tolist()
    offline: list[bool] | None = None
    if isinstance(schedule, OfflineSchedule):
        r = schedule.ratio
        if r is not None and r.denominator > MAX_OFFLINE_PERIOD:
            raise ValueError(
                f"schedule: an offline period of {r.denominator} steps exceeds {MAX_OFFLINE_PERIOD}"
            )
        offline = [bool(x) for x in schedule.pattern]
        z0, mu = 1, 1.0
    else:
        z0, mu = schedule.z0, schedule.mu
    att, min_gap, mimicry, automaton = None, 1, None, None
    if isinstance(a, MimicryAttack):
        vch = a.channel if a.channel is not None else ch
        assert isinstance(schedule, OnlineDesign)  # offline scenarios take no attack
        design = a.design if a.design is not None else schedule
        mimicry = (vch.P.tolist(), vch.low.tolist(), vch.high.tolist(), design.z0, design.mu)
    elif isinstance(a, AttackerAutomaton):
        automaton = (transitions(a.flag), transitions(a.quiet), a.start)
    elif a is not None:
        att = core_attack(a, engine=True)
        if isinstance(a, FlagInjection):
            min_gap = a.min_gap
    return (P, low, high, z0, mu, offline, att, min_gap, mimicry, automaton, max_states)
