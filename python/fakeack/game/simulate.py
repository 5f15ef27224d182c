"""The game in closed loop: a Monte Carlo of the sensor's tests, alarms and fall-backs against an
attack, which checks the payoff computed from the window formulas."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import cast

from .. import _fakeack
from .._internal.progress import Progress
from .._internal.types import FloatArray, IntArray, RatioLike
from .._internal.validate import as_int
from ..attacks.kinds import AttackLike, as_attack, core_attack
from ..detection.count import alarm_bounds, harmful_bound
from ..detection.interval_test import cached_interval_test
from ..detection.probability import KernelTest
from ..model.system import LinearSystem, compiled
from .payoff import _Setting
from .policies import SensorPolicy

__all__ = [
    "GameSimulation",
    "simulate_game",
]


# ---------------------------------------------------------------------------------------------
# The closed loop.


@dataclass(frozen=True)
class GameSimulation:
    """Closed-loop Monte Carlo of one (policy, attack) pair (see :func:`simulate_game`)."""

    j: float
    """Mean over runs of each run's average Tr P_k."""
    stderr: float
    high_power: float
    """Fraction of steps at high power."""
    high_power_stderr: float
    online: float
    """Fraction of steps run online."""
    alarm_rate: float
    """Alarms per tested window."""
    alarm_stderr: float
    fallback_rate: float
    """Triggering alarms per tested window: the simulated d."""
    fallback_stderr: float
    runs: int
    horizon: int
    n_steps: int
    seed: int
    delivered_per_run: IntArray = field(repr=False)
    """Flag-ACKs that reached the sensor in each run's measured horizon."""


def _ratio_se(num: FloatArray, den: FloatArray) -> tuple[float, float]:
    """Ratio estimator Σnum/Σden over runs and its standard error (delta method)."""
    total = den.sum()
    if total == 0:
        return math.nan, math.nan
    r = num.sum() / total
    if len(num) < 2:
        return float(r), math.inf
    resid = num - r * den
    se = math.sqrt(resid.var(ddof=1) * len(num)) / total
    return float(r), float(se)


def simulate_game(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    policy: SensorPolicy,
    attack: AttackLike,
    horizon: int,
    runs: int,
    seed: int,
    *,
    n_steps: int = 1000,
    burn_in: int = 0,
    beta_bar: float | None = None,
    progress: bool | None = None,
) -> GameSimulation:
    r"""Closed-loop Monte Carlo of the game: the real protocol with the sensor's test and fall-back.

    Each run plays ``burn_in + horizon`` steps of the protocol (sensor, lossy channel, remote
    estimator, event detector, attacker) from the paper's initial condition, cut into windows of
    ``n_steps`` from the first step; the sensor tests every online window with its policy's test
    (the same statistic and critical value as :func:`fakeack.detect_attack` /
    :func:`fakeack.detect_intervals`), and a triggering alarm sends it offline for ``fallback``
    windows. Costs, rates and alarms are measured after the burn-in. Nothing here uses the payoff
    formula, so it checks :func:`game_payoff` including what the formula neglects (transients at
    switches, dependence between windows).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio p/q (the offline schedule, and the online one via :func:`fakeack.design_online`).
    policy : SensorPolicy
        The sensor's policy.
    attack : None or attack
        The attack, kept throughout.
    horizon : int
        Measured steps per run.
    runs : int
        Independent runs.
    seed : int
        The results depend on the seed only (not on threads).
    n_steps : int, optional
        Window length (default 1000).
    burn_in : int, optional
        Steps played (with the policy in the loop) before the measurement starts (default 0); a few
        fall-back cycles put the measured horizon in the game's stationary regime, which the
        payoff formula describes.
    beta_bar : float, optional
        The harmful rule's threshold (default as :func:`solve_game`).
    progress : bool or None
        Show a progress bar for runs over a second (default: only on a terminal).

    Returns
    -------
    GameSimulation

    Notes
    -----
    Runs in parallel with the GIL released; Ctrl-C raises ``KeyboardInterrupt`` promptly.
    """
    if not isinstance(policy, SensorPolicy):
        raise TypeError(f"policy must be a fakeack.SensorPolicy, got {type(policy).__name__}")
    setting = _Setting.make(system, lam, ratio, n_steps, beta_bar)
    att = as_attack(attack)
    horizon = as_int("horizon", horizon, minimum=1)
    runs = as_int("runs", runs, minimum=1)
    seed = as_int("seed", seed, minimum=0)
    if seed >= 2**64:
        raise ValueError(f"seed must be below 2**64, got {seed}")
    burn_in = as_int("burn_in", burn_in, minimum=0)
    args = _kernel_policy(setting, policy)
    bar = Progress(runs, progress)
    r = setting.ratio
    try:
        out = _fakeack.simulate_game(
            compiled(system),
            setting.lam,
            r.numerator,
            r.denominator,
            setting.design.z0,
            setting.design.mu,
            core_attack(att),
            *args,
            setting.n,
            horizon,
            burn_in,
            runs,
            seed,
            bar,
        )
    finally:
        bar.close()
    cost, hp = out["cost"], out["high_power"]
    tested = out["tested"].astype(float)
    alarm, alarm_se = _ratio_se(out["alarms"].astype(float), tested)
    fb, fb_se = _ratio_se(out["fallbacks"].astype(float), tested)

    def sd(x: FloatArray) -> float:
        return float(x.std(ddof=1) / math.sqrt(len(x))) if len(x) > 1 else math.inf

    return GameSimulation(
        float(cost.mean()),
        sd(cost),
        float(hp.mean()),
        sd(hp),
        float(out["online"].mean()),
        alarm,
        alarm_se,
        fb,
        fb_se,
        runs,
        horizon,
        setting.n,
        seed,
        out["delivered"],
    )


def _kernel_policy(setting: _Setting, policy: SensorPolicy) -> KernelTest:
    """The compiled kernel's arguments for a policy."""
    if policy.test == "offline":
        return ("offline", -1, 0, [], [], 0.0, None, 0)
    if policy.test == "never":
        return ("online", -1, 0, [], [], 0.0, None, 0)
    # A test policy has both (SensorPolicy checks it).
    alpha, fallback = cast(float, policy.alpha), cast(int, policy.fallback)
    harm = (
        harmful_bound(setting.lam, setting.design, setting.n, setting.beta_bar)
        if policy.rule == "harmful"
        else None
    )
    if policy.test == "count":
        lo, hi = alarm_bounds(setting.lam, setting.design, setting.n, alpha, policy.alternative)
        return ("count", lo, hi, [], [], 0.0, harm, fallback)
    t = cached_interval_test(setting.lam, setting.design, setting.n, alpha)
    return (
        "interval",
        -1,
        0,
        [int(e) for e in t.edges],
        [float(e) for e in t.expected],
        float(t.critical),
        harm,
        fallback,
    )
