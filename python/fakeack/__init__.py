"""fakeack: the fake-ACK attack on ACK-based sensor power schedules for remote state estimation.

Exact steady-state analysis, Monte Carlo of the real protocol and the attacker threshold, after
Y. Li, D. E. Quevedo, S. Dey, L. Shi, "Fake-Acknowledgment Attack on ACK-based Sensor Power
Schedule for Remote State Estimation", with the corrections listed in the README's model notes.
"""

from ._fakeack import MAX_BUILD_STATES, MAX_VECTOR_STATES, ConvergenceError
from ._fakeack import __version__ as __version__  # written once, in Cargo.toml
from .attack import (
    attack_chain,
    balance_residual,
    general_attack_chain,
    j_attack,
    num_states,
    stationary_distribution,
    stationary_gth,
)
from .attacks import FlagInjection, MaskBlocking, PeriodicBlocking, RandomBlocking
from .detection import (
    Detection,
    DetectionRates,
    FlagRates,
    delivered_flag_rate,
    detect_attack,
    detection_rates,
    estimate_beta,
    flag_interval_moments,
    flag_rates,
)
from .detectors import (
    IntervalDetection,
    IntervalTest,
    detect_intervals,
    detection_probability,
    interval_test,
)
from .grid import study_grid
from .intervals import FlagCount, IntervalLaw, flag_count_moments, flag_interval_law
from .montecarlo import (
    AttackPattern,
    OfflineSchedule,
    OnlineSchedule,
    SimulationResult,
    TraceCurve,
    expected_trace_curve,
    simulate,
)
from .other_attacks import (
    RandomSweep,
    beta_bar_random,
    energy_per_step,
    high_power_rate,
    random_blocking_sweep,
    rate_matching_attack,
)
from .schedules import (
    OnlineDesign,
    design_online,
    energy_ratio,
    j_max,
    j_offline,
    j_online,
    offline_schedule,
    online_high_power_rate,
)
from .system import LinearSystem
from .threshold import (
    BetaBar,
    BetaSweep,
    Decision,
    MaskSearch,
    beta_bar,
    beta_sweep,
    choose_schedule,
    j_attack_limit,
    j_attack_pattern,
    worst_mask,
)

__all__ = [
    "FlagInjection",
    "FlagRates",
    "MaskBlocking",
    "PeriodicBlocking",
    "RandomBlocking",
    "RandomSweep",
    "beta_bar_random",
    "energy_per_step",
    "high_power_rate",
    "random_blocking_sweep",
    "rate_matching_attack",
    "Detection",
    "DetectionRates",
    "delivered_flag_rate",
    "detect_attack",
    "detection_rates",
    "estimate_beta",
    "flag_interval_moments",
    "flag_rates",
    "FlagCount",
    "IntervalDetection",
    "IntervalLaw",
    "IntervalTest",
    "detect_intervals",
    "detection_probability",
    "flag_count_moments",
    "flag_interval_law",
    "interval_test",
    "study_grid",
    "AttackPattern",
    "OfflineSchedule",
    "OnlineSchedule",
    "SimulationResult",
    "TraceCurve",
    "expected_trace_curve",
    "simulate",
    "BetaBar",
    "BetaSweep",
    "Decision",
    "MaskSearch",
    "beta_bar",
    "beta_sweep",
    "choose_schedule",
    "general_attack_chain",
    "j_attack_limit",
    "j_attack_pattern",
    "stationary_gth",
    "worst_mask",
    "MAX_BUILD_STATES",
    "MAX_VECTOR_STATES",
    "ConvergenceError",
    "LinearSystem",
    "OnlineDesign",
    "attack_chain",
    "balance_residual",
    "design_online",
    "energy_ratio",
    "j_attack",
    "j_max",
    "j_offline",
    "j_online",
    "num_states",
    "offline_schedule",
    "online_high_power_rate",
    "stationary_distribution",
]
