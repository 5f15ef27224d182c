"""Attacks on the flag-ACKs and jamming of the data channel: the attack objects, the attack chain
and its stationary law, the cost under attack, the attacker threshold and the sensor's decision,
and the families beyond the paper's."""

from .automata import AttackerAutomaton, MimicryAttack, as_automaton, discard_forgeries
from .chain import (
    attack_chain,
    balance_residual,
    general_attack_chain,
    j_attack,
    num_states,
    stationary_distribution,
    stationary_gth,
)
from .jamming import Jamming, JammingAttack, RandomJamming
from .kinds import (
    Attack,
    AttackPattern,
    FlagInjection,
    MaskBlocking,
    PeriodicBlocking,
    RandomBlocking,
    as_attack,
)
from .masks import MaskSearch, j_attack_pattern, worst_mask
from .random import RandomSweep, beta_bar_random, random_blocking_sweep, rate_matching_attack
from .rates import energy_per_step, high_power_rate, online_high_power_rate
from .threshold import (
    BetaBar,
    BetaSweep,
    Decision,
    beta_bar,
    beta_sweep,
    choose_schedule,
    j_attack_limit,
)

__all__ = [
    "AttackerAutomaton",
    "MimicryAttack",
    "as_automaton",
    "discard_forgeries",
    "AttackPattern",
    "PeriodicBlocking",
    "MaskBlocking",
    "RandomBlocking",
    "FlagInjection",
    "Attack",
    "Jamming",
    "RandomJamming",
    "JammingAttack",
    "as_attack",
    "num_states",
    "attack_chain",
    "stationary_distribution",
    "balance_residual",
    "j_attack",
    "general_attack_chain",
    "stationary_gth",
    "j_attack_pattern",
    "j_attack_limit",
    "BetaSweep",
    "beta_sweep",
    "BetaBar",
    "beta_bar",
    "Decision",
    "choose_schedule",
    "MaskSearch",
    "worst_mask",
    "high_power_rate",
    "energy_per_step",
    "online_high_power_rate",
    "beta_bar_random",
    "RandomSweep",
    "random_blocking_sweep",
    "rate_matching_attack",
]
