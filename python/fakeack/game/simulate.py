"""The game in closed loop: a Monte Carlo of the sensor's tests, alarms and fall-backs against an
attack, which checks the payoff computed from the window formulas."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from .. import _fakeack
from .._internal.progress import Progress
from .._internal.types import FloatArray, IntArray, RatioLike
from .._internal.validate import as_int, as_probability, as_real
from ..attacks._args import required
from ..attacks.automata import AttackerAutomaton, MimicryAttack, discard_forgeries
from ..attacks.kinds import AttackLike
from ..detection.count import alarm_bounds, harmful_bound
from ..detection.interval_test import cached_interval_test
from ..detection.likelihood import lr_tables
from ..detection.probability import KernelTest
from ..detection.process import flag_process
from ..detection.rates import paper_min_gap
from ..model.channels import Channel, ChannelLike, channel_argument, is_paper_channel
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem, compiled
from ..montecarlo._automaton import as_sim_attack, kernel_attack
from ._channel import PlayedGame, channel_game
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
    """Alarms per tested window (for the CUSUM: per step at which the statistic ran, online and
    not dormant)."""
    alarm_stderr: float
    fallback_rate: float
    """Triggering alarms per tested window: the simulated d (for the CUSUM, per running step)."""
    fallback_stderr: float
    runs: int
    horizon: int
    n_steps: int
    seed: int
    delivered_per_run: IntArray = field(repr=False)
    """Flag-ACKs that reached the sensor in each run's measured horizon."""
    channel: Channel | None = None
    """The channel played."""
    burn_in: int = 0
    """Steps played before the measurement (by default the attack's mixing time, in windows)."""
    alarms_per_online_step: float = math.nan
    """Alarms per measured online step, Σ alarms / Σ online steps over runs (any policy; 0 for
    ``"never"``, NaN for ``"offline"``): the CUSUM's false-alarm rate when there is no attack."""
    alarms_per_online_step_stderr: float = math.nan
    """Its standard error (delta method over runs)."""
    online_steps_between_alarms: float = math.nan
    """Mean online steps between alarms, Σ online steps / Σ alarms (inf without alarms, NaN
    without online steps): for the CUSUM without attack, the mean online time to a false alarm
    (its average run length), under attack the mean online time to detection."""
    alarms_per_run: IntArray | None = field(default=None, repr=False)
    """Alarms in each run's measured horizon."""
    online_steps_per_run: IntArray | None = field(default=None, repr=False)
    """Online steps in each run's measured horizon."""


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
    channel: ChannelLike | None = None,
    ratio: RatioLike | None = None,
    policy: SensorPolicy | None = None,
    attack: AttackLike | MimicryAttack | AttackerAutomaton = None,
    horizon: int | None = None,
    runs: int | None = None,
    seed: int | None = None,
    *,
    n_steps: int = 1000,
    burn_in: int | None = None,
    beta_bar: float | None = None,
    progress: bool | None = None,
    lam: float | None = None,
    authenticated: bool = False,
) -> GameSimulation:
    r"""Closed-loop Monte Carlo of the game: the real protocol with the sensor's test and fall-back.

    Each run plays ``burn_in + horizon`` steps of the protocol (sensor, lossy channel, remote
    estimator, event detector, attacker) from the paper's initial condition, cut into windows of
    ``n_steps`` from the first step; the sensor tests every online window with its policy's test
    (the same statistic and critical value as :func:`fakeack.detect_attack` /
    :func:`fakeack.detect_intervals`) and, if the policy's ``support`` is on, the support check (an
    alarm at a gap between flag-ACKs shorter than :attr:`fakeack.FlagProcess.min_gap`, z0 + 1 on
    the paper's channel; the gap across the window's start counts, the first after an offline
    stretch does not), and a triggering alarm sends it offline for ``fallback`` windows. Costs,
    rates and alarms are measured after the burn-in. Nothing here uses the payoff formula, so it
    checks :func:`game_payoff` including what the formula neglects (transients at switches,
    dependence between windows).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The channel: a float is the paper's (low-power arrival probability λ in (0, 1)); under a
        Markov channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`) the
        online schedule is :func:`fakeack.design_online` under it, the fall-back schedule the best
        offline pattern of :func:`fakeack.offline_search`, and the count test's bounds come from
        the attack-free flag law under the channel (:func:`fakeack.flag_process`: exact below 100
        expected flags per window, else normal with the window's exact moments); the interval
        test, whose law assumes independent gaps, is refused there.
    ratio : Fraction
        Energy ratio p/q (the offline schedule, and the online one via :func:`fakeack.design_online`).
    policy : SensorPolicy
        The sensor's policy; a CUSUM (``SensorPolicy("cusum", fallback=K, cusum=c)``) updates its
        statistic at every online step, with the increments ``c.increments(channel, design)``
        of the played channel and online design, falls back for K windows at once on an alarm
        and restarts dormant (W = 0 until the first flag-ACK back online).
    attack : None or attack
        The attack, kept throughout, online and offline: a built-in attack, or any attacker
        automaton (:class:`fakeack.MimicryAttack`, which without its own channel or design runs
        the simulated ones, an :class:`fakeack.AttackerAutomaton`, a
        :class:`fakeack.FlagInjection` with ``min_gap > 1``), which the kernel plays move by move
        as :func:`fakeack.simulate` does.
    horizon : int
        Measured steps per run.
    runs : int
        Independent runs.
    seed : int
        The results depend on the seed only (not on threads).
    n_steps : int, optional
        Window length (default 1000).
    burn_in : int, optional
        Steps played (with the policy in the loop) before the measurement starts. The default
        is the attack's mixing time (:meth:`fakeack.FlagProcess.mixing_steps` of the flag
        process under the attack and without it, the longer), rounded up to whole windows: the
        attacker's phase, which a long-period attack keeps for 10^4 steps, then follows its
        long-run law, which the payoff formula assumes. A few fall-back cycles more put the
        online and offline stretches in their stationary regime too. ``0`` starts measuring at
        the paper's initial condition. The result's ``burn_in`` states the value used.
    beta_bar : float, optional
        The harmful rule's threshold (default as :func:`solve_game`).
    progress : bool or None
        Show a progress bar for runs over a second (default: only on a terminal).
    lam : float, optional
        The former name of ``channel`` (a float): ``simulate_game(system, lam=0.5, ...)`` still
        works; giving both is a ``TypeError``.
    authenticated : bool, optional
        Whether the sensor authenticates flag-ACKs, rejecting forged ones (default False): only
        the attack's blocking part is played (``fakeack.attacks.discard_forgeries``).

    Returns
    -------
    GameSimulation

    Raises
    ------
    ValueError
        For an invalid argument (named first), among them a CUSUM whose increments are not two
        equal-length 1-D arrays without NaN or whose threshold is not finite and positive.
    TypeError
        For a missing argument or one of the wrong type.

    Notes
    -----
    Runs in parallel with the GIL released; Ctrl-C raises ``KeyboardInterrupt`` promptly.
    """
    ch, name = channel_argument(channel, lam, "simulate_game")
    if ratio is None:
        raise TypeError("simulate_game() missing required argument: 'ratio'")
    ratio_ = ratio
    if not isinstance(policy, SensorPolicy):
        raise TypeError(f"policy must be a fakeack.SensorPolicy, got {type(policy).__name__}")
    horizon = as_int("horizon", required("simulate_game", "horizon", horizon), minimum=1)
    runs = as_int("runs", required("simulate_game", "runs", runs), minimum=1)
    seed = as_int("seed", required("simulate_game", "seed", seed), minimum=0)
    if seed >= 2**64:
        raise ValueError(f"seed must be below 2**64, got {seed}")
    att = as_sim_attack(attack)
    if is_paper_channel(ch):
        setting = _Setting.make(system, as_probability(name, float(ch.low[0])), ratio_, n_steps, beta_bar)
        kernel = PlayedGame(
            setting.lam,
            setting.ratio,
            setting.design,
            setting.n,
            _kernel_policy(setting, policy),
            min_gap=paper_min_gap(setting.design) if policy.support else 0,
        )
    else:
        kernel = channel_game(system, ch, ratio_, policy, n_steps, beta_bar)
    if authenticated:
        att = discard_forgeries(att, channel=ch, design=kernel.design)
    if burn_in is None:
        played = kernel.lam if kernel.channel is None else kernel.channel
        mixing = max(flag_process(played, kernel.design, a).mixing_steps() for a in (None, att))
        burn_in = -(-mixing // kernel.n) * kernel.n  # whole windows: the measurement starts one
    burn_in = as_int("burn_in", burn_in, minimum=0)
    core, automaton = kernel_attack(att, ch, kernel.design)
    cusum = _cusum_args(policy, ch, kernel.design)
    lr = lr_tables(policy.lr_test(ch, kernel.design, kernel.n)) if policy.test == "lr" else None
    bar = Progress(runs, progress)
    r = kernel.ratio
    try:
        out = _fakeack.simulate_game(
            compiled(system),
            kernel.lam,
            r.numerator,
            r.denominator,
            kernel.design.z0,
            kernel.design.mu,
            core,
            *kernel.policy,
            kernel.n,
            horizon,
            burn_in,
            runs,
            seed,
            bar,
            **kernel.channel_args(),
            min_gap=kernel.min_gap,
            automaton=automaton,
            cusum=cusum,
            lr=lr,
        )
    finally:
        bar.close()
    cost, hp = out["cost"], out["high_power"]
    tested = out["tested"].astype(float)
    alarm, alarm_se = _ratio_se(out["alarms"].astype(float), tested)
    fb, fb_se = _ratio_se(out["fallbacks"].astype(float), tested)
    alarms, online_steps = out["alarms"], out["online_steps"]
    per_step, per_step_se = _ratio_se(alarms.astype(float), online_steps.astype(float))
    total_alarms, total_online = int(alarms.sum()), int(online_steps.sum())
    if total_online == 0:
        between = math.nan
    else:
        between = total_online / total_alarms if total_alarms else math.inf

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
        kernel.n,
        seed,
        out["delivered"],
        ch,
        burn_in,
        per_step,
        per_step_se,
        between,
        alarms,
        online_steps,
    )


def _kernel_policy(setting: _Setting, policy: SensorPolicy) -> KernelTest:
    """The compiled kernel's arguments for a policy."""
    if policy.test == "offline":
        return ("offline", -1, 0, [], [], 0.0, None, 0)
    if policy.test == "never":
        return ("online", -1, 0, [], [], 0.0, None, 0)
    if policy.test == "cusum":  # its statistic goes as the kernel's `cusum` argument
        return ("cusum", -1, 0, [], [], 0.0, None, cast(int, policy.fallback))
    # A test policy has both (SensorPolicy checks it).
    alpha, fallback = cast(float, policy.alpha), cast(int, policy.fallback)
    if policy.test == "lr":  # its tables go as the kernel's `lr` argument
        critical = policy.lr_test(setting.lam, setting.design, setting.n).critical
        return ("lr", -1, 0, [], [], critical, None, fallback)
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


def _cusum_args(
    policy: SensorPolicy, channel: Channel, design: OnlineDesign
) -> tuple[list[float], list[float], float] | None:
    """The kernel's ``cusum`` argument, (inc_flag, inc_quiet, threshold), checked; None but for
    the CUSUM."""
    if policy.test != "cusum":
        return None
    c = policy.cusum
    inc = c.increments(channel, design)  # type: ignore[union-attr]  # a CUSUM policy has one
    if hasattr(inc, "flag") and hasattr(inc, "quiet"):
        flag, quiet = inc.flag, inc.quiet
    else:
        try:
            flag, quiet = inc
        except (TypeError, ValueError):
            raise ValueError(
                f"cusum: increments() must give (flag, quiet) arrays, got {type(inc).__name__}"
            ) from None
    tables = []
    for name, x in (("inc_flag", flag), ("inc_quiet", quiet)):
        a = np.asarray(x, dtype=float)
        if a.ndim != 1 or a.size == 0:
            raise ValueError(f"cusum: {name} must be a non-empty 1-D array, got shape {a.shape}")
        if np.isnan(a).any():
            raise ValueError(f"cusum: {name} must not contain NaN")
        tables.append([float(v) for v in a])
    if len(tables[0]) != len(tables[1]):
        raise ValueError(
            "cusum: inc_flag and inc_quiet must have the same length, "
            f"got {len(tables[0])} and {len(tables[1])}"
        )
    h = as_real("cusum.threshold", c.threshold)  # type: ignore[union-attr]
    if not (math.isfinite(h) and h > 0):
        raise ValueError(f"cusum.threshold must be finite and > 0, got {h}")
    return tables[0], tables[1], h
