"""The exact engine: any channel, sensor schedule and attacker automaton, as one finite automaton
whose stationary law and coupled Stein equations give every cost exactly (see :class:`Scenario`)."""

from .binding import EngineAutomaton
from .chains import AttackPolicy, ScenarioChain, SchedulePolicy
from .scenario import DEFAULT_MAX_STATES, Scenario
from .stability import DEFAULT_GRID, StabilityRegion, stability_region

__all__ = [
    "Scenario",
    "EngineAutomaton",
    "ScenarioChain",
    "SchedulePolicy",
    "AttackPolicy",
    "DEFAULT_MAX_STATES",
    "stability_region",
    "StabilityRegion",
    "DEFAULT_GRID",
]
