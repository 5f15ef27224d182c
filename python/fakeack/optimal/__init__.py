"""Optimal attacks and schedules: the sensor's and the attacker's best choices, computed exactly.

:func:`optimal_power_policy` solves the sensor's power problem (the least long-run cost within an
energy budget, knowing the holding time from per-packet ACKs and possibly the channel state) as an
average-cost constrained MDP over occupation measures; :class:`HoldingTimePolicy` is the kind of
policy it returns, evaluated exactly as an automaton of the engine. :func:`optimal_jamming` gives
the jammer's best schedule against the data channel, over a finite horizon or in the long run.
:func:`worst_attack` gives the attacker's most damaging use of the flag-ACKs within a blocking
budget, as a :class:`StatePolicy` that reads the holding time and the detector's state.
:func:`attack_effort` compares jamming, blocking and forging per unit of attacker energy, and
:func:`robust_design` finds the online design of least worst-case J under blocking.
"""

from .attack import WorstAttack, worst_attack
from .effort import AttackEffort, AttackOption, attack_effort, jam_high_channel
from .jamming import JammingResult, optimal_jamming
from .policies import HoldingTimePolicy, PolicyAutomaton
from .power import PowerPolicyResult, optimal_power_policy
from .robust import RobustDesign, robust_design
from .state_policy import StatePolicy

__all__ = [
    "HoldingTimePolicy",
    "PolicyAutomaton",
    "PowerPolicyResult",
    "optimal_power_policy",
    "JammingResult",
    "optimal_jamming",
    "StatePolicy",
    "WorstAttack",
    "worst_attack",
    "AttackEffort",
    "AttackOption",
    "attack_effort",
    "jam_high_channel",
    "RobustDesign",
    "robust_design",
]
