"""Optimal schedules as linear programs.

:func:`optimal_power_policy` solves the sensor's power problem (the least long-run cost within an
energy budget, knowing the holding time from per-packet ACKs and possibly the channel state) as an
average-cost constrained MDP over occupation measures; :class:`HoldingTimePolicy` is the kind of
policy it returns, evaluated exactly as an automaton of the engine.
"""

from .policies import HoldingTimePolicy, PolicyAutomaton
from .power import PowerPolicyResult, optimal_power_policy

__all__ = [
    "HoldingTimePolicy",
    "PolicyAutomaton",
    "PowerPolicyResult",
    "optimal_power_policy",
]
