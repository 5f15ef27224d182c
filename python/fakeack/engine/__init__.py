"""The exact engine: any channel, sensor schedule and attacker automaton, as one finite automaton
whose stationary law and coupled Stein equations give every cost exactly (see :class:`Scenario`)."""

from .scenario import DEFAULT_MAX_STATES, EngineAutomaton, Scenario
from .stability import DEFAULT_GRID, StabilityRegion, stability_region

__all__ = [
    "Scenario",
    "EngineAutomaton",
    "DEFAULT_MAX_STATES",
    "stability_region",
    "StabilityRegion",
    "DEFAULT_GRID",
]
