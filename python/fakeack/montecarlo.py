"""Schedules as objects, Monte Carlo of the real protocol, and exact finite-horizon curves."""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np

from . import _fakeack
from ._validate import MODES, PROTOCOLS, as_int, as_probability, as_ratio
from .attacks import MaskBlocking, PeriodicBlocking, as_attack, core_attack
from .schedules import design_online, offline_schedule
from .system import _core

__all__ = [
    "AttackPattern",
    "OfflineSchedule",
    "OnlineSchedule",
    "SimulationResult",
    "TraceCurve",
    "expected_trace_curve",
    "simulate",
]



@dataclass(frozen=True)
class OfflineSchedule:
    """The optimal offline schedule for an energy ratio (Theorem 3.1).

    Examples
    --------
    >>> OfflineSchedule(Fraction(1, 7))
    OfflineSchedule(ratio=Fraction(1, 7))
    >>> str(OfflineSchedule("1/7"))
    'offline 1/7: 1000000'
    """

    ratio: Fraction

    def __init__(self, ratio: Any):
        object.__setattr__(self, "ratio", as_ratio("ratio", ratio))

    @property
    def pattern(self) -> np.ndarray:
        """One period, 1 = high power."""
        return offline_schedule(self.ratio)

    def __str__(self) -> str:
        pat = self.pattern
        body = "".join(map(str, pat.tolist())) if len(pat) <= 40 else f"{len(pat)} steps"
        return f"offline {self.ratio}: {body}"


@dataclass(frozen=True)
class OnlineSchedule:
    """The ACK-based online schedule: a flag-ACK after z0 losses (z0+1 with probability 1-mu)."""

    z0: int
    mu: float = 1.0

    def __init__(self, z0: Any, mu: Any = 1.0):
        object.__setattr__(self, "z0", as_int("z0", z0, minimum=1))
        object.__setattr__(self, "mu", as_probability("mu", mu, closed=True))

    @classmethod
    def design(cls, lam: Any, ratio: Any) -> OnlineSchedule:
        """The schedule that spends the energy ratio exactly (:func:`fakeack.design_online`)."""
        z0, mu = design_online(lam, ratio)
        return cls(z0, mu)

    def __str__(self) -> str:
        return f"online z0={self.z0}" + ("" if self.mu == 1.0 else f", mu={self.mu:.6g}")


class AttackPattern:
    """Deprecated spelling of an attack: use :class:`fakeack.MaskBlocking` or
    :class:`fakeack.PeriodicBlocking`.

    ``AttackPattern(mask)`` returns ``MaskBlocking(mask)`` and ``AttackPattern.first(r, t)``
    returns ``PeriodicBlocking(r, t)``, with a ``DeprecationWarning``.
    """

    def __new__(cls, mask: Any) -> MaskBlocking:  # type: ignore[misc]
        warnings.warn(
            "fakeack.AttackPattern is deprecated; use fakeack.MaskBlocking(mask)",
            DeprecationWarning,
            stacklevel=2,
        )
        return MaskBlocking(mask)

    @staticmethod
    def first(r: Any, t: Any) -> PeriodicBlocking:
        """Block the first r of every t flag-ACKs: ``fakeack.PeriodicBlocking(r, t)``."""
        warnings.warn(
            "fakeack.AttackPattern.first is deprecated; use fakeack.PeriodicBlocking(r, t)",
            DeprecationWarning,
            stacklevel=2,
        )
        return PeriodicBlocking(r, t)


def _schedule_and_attack(
    sched: Any, attack: Any
) -> tuple[OfflineSchedule | OnlineSchedule, PeriodicBlocking | MaskBlocking | None]:
    """Validated schedule and attack (None: no attacker); offline schedules take none."""
    if not isinstance(sched, (OfflineSchedule, OnlineSchedule)):
        raise TypeError(
            f"sched must be a fakeack.OfflineSchedule or fakeack.OnlineSchedule, got {type(sched).__name__}"
        )
    att = as_attack(attack)
    if isinstance(sched, OfflineSchedule) and att is not None:
        raise ValueError("attack: an offline schedule ignores ACKs, so an attack has no effect")
    return sched, att


@dataclass(frozen=True)
class TraceCurve:
    """Exact :math:`\\mathbb E[\\mathrm{Tr}\\,P_k]` and :math:`J_k` for k = 1..horizon."""

    k: np.ndarray
    trace: np.ndarray
    """E[Tr P_k]."""
    j_k: np.ndarray
    """J_k = (1/k) Σ_{i<=k} E[Tr P_i] (the paper's Sec. V quantity)."""

    # Array-like: np.asarray(curve) and curve[k-1] give E[Tr P_k].
    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        return np.asarray(self.trace, dtype=dtype)

    def __len__(self) -> int:
        return len(self.trace)

    def __getitem__(self, index: Any) -> Any:
        return self.trace[index]


def expected_trace_curve(
    system: Any, lam: Any, sched: Any, horizon: Any = 200, attack: Any = None
) -> TraceCurve:
    r"""Exact finite-horizon curve :math:`\mathbb E[\mathrm{Tr}\,P_k]`, k = 1..horizon (no sampling).

    Propagates the law of the protocol's state (holding time, memory zeros, attacker counter) from
    the paper's initial condition (high power at k = 1, memory all ones, counter 0), so the
    transient of the paper's Figs. 3-4 appears without Monte Carlo noise. As k grows, ``j_k``
    tends to the stationary J (:func:`fakeack.j_offline`, :func:`fakeack.j_online`,
    :func:`fakeack.j_attack`).

    Parameters
    ----------
    system : LinearSystem
    lam : float
        Arrival probability at low power.
    sched : OfflineSchedule or OnlineSchedule
    horizon : int, optional
        Number of steps (default 200).
    attack : None, PeriodicBlocking, MaskBlocking or (r, t), optional
        The attack; online schedules only (an offline schedule ignores ACKs).

    Returns
    -------
    TraceCurve
        Entries are ``inf`` (never NaN) past the double range. The curve weights the plain traces
        :math:`\mathrm{Tr}\,h^\tau(\bar P)` by probabilities, so where
        :math:`(1-\lambda)\rho(A)^2 \ge 1` an entry is ``inf`` as soon as a reachable holding time
        passes the overflow of its trace (τ ≈ 1950 for the paper's system), even where
        E[Tr P_k] itself would still fit in a double.
    """
    core = _core(system)
    lam = as_probability("lam", lam)
    sched, att = _schedule_and_attack(sched, attack)
    horizon = as_int("horizon", horizon, minimum=1)
    if isinstance(sched, OfflineSchedule):
        r = sched.ratio
        trace = core.curve_offline(lam, r.numerator, r.denominator, horizon)
    else:
        if isinstance(att, MaskBlocking) and all(att.mask):
            raise ValueError("attack blocks every flag-ACK: the state space is unbounded")
        trace = core.curve_online(lam, sched.z0, sched.mu, core_attack(att), horizon)
    k = np.arange(1, horizon + 1)
    with np.errstate(over="ignore"):  # a running sum past the double range is inf, as documented
        j_k = np.cumsum(trace) / k
    return TraceCurve(k, trace, j_k)


@dataclass(frozen=True)
class SimulationResult:
    """Monte Carlo estimates of the protocol (see :func:`simulate`)."""

    j_k: np.ndarray
    """J_k = (1/k) Σ_{i<=k} Tr P_i averaged over runs, k = 1..horizon."""
    mean_trace: np.ndarray
    """Tr P_k (covariance mode) or ||x_k - x̂_k||² (state mode) averaged over runs."""
    j: float
    """Time average over the horizon, averaged over runs (= j_k[-1])."""
    stderr: float
    """Standard error of ``j`` across runs."""
    high_power_rate: float
    """Fraction of steps at high power Δ: the first step and every step after a flag-ACK reached
    the sensor, genuine or forged."""
    flags_sent: float
    """Genuine flag-ACKs sent by the detector per step."""
    flags_blocked: float
    """Genuine flag-ACKs blocked (Type B) or flipped to 0 (Type A) by the attacker per step."""
    runs: int
    horizon: int
    seed: int
    mode: str
    protocol: str
    schedule: str = field(default="")
    attack: str = field(default="none")
    delivered_per_run: np.ndarray | None = field(default=None, repr=False)
    """Flag-ACKs delivered to the sensor in each run, genuine or forged (the sensor cannot tell
    them apart); only with ``record_runs=True``."""
    flags_forged: float = 0.0
    """Flag-ACKs forged by the attacker per step (:class:`fakeack.FlagInjection`; Type B: a forged
    packet, Type A: an ACK bit flipped to 1). Flag-ACKs reaching the sensor per step:
    ``flags_sent - flags_blocked + flags_forged``."""

    def __str__(self) -> str:
        return (
            f"J = {self.j:.6f} ± {self.stderr:.6f} ({self.runs} runs x {self.horizon} steps, "
            f"{self.schedule}, {self.attack}, {self.mode} mode)"
        )

    def _repr_html_(self) -> str:
        from . import _html

        return _html.key_values(
            "SimulationResult",
            [
                ("J (time average over the horizon)", f"{self.j:.6f} ± {self.stderr:.6f}"),
                ("runs × steps", f"{self.runs} × {self.horizon}"),
                ("schedule", self.schedule or "–"),
                ("attack", self.attack),
                ("mode, protocol", f"{self.mode}, {self.protocol}"),
                ("high-power rate", self.high_power_rate),
                ("flag-ACKs sent per step", self.flags_sent),
                ("flag-ACKs blocked per step", self.flags_blocked),
                ("seed", self.seed),
            ],
            "± is one standard error across runs; j_k and mean_trace hold the curves.",
        )


class _Progress:
    """A tqdm bar that appears only if a run lasts longer than a second."""

    def __init__(self, total: int, enabled: bool | None):
        self.total, self.bar, self.start = total, None, time.monotonic()
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)

    def __call__(self, done: int) -> None:
        if not self.enabled:
            return
        if self.bar is None:
            if time.monotonic() - self.start < 1.0:
                return
            try:
                from tqdm.auto import tqdm
            except ImportError:  # the bar is optional (pip install fakeack[progress])
                self.enabled = False
                return
            self.bar = tqdm(total=self.total, unit="run", desc="fakeack simulate")
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def simulate(
    system: Any,
    lam: Any,
    sched: Any,
    horizon: Any = 1000,
    runs: Any = 100_000,
    seed: Any = 1,
    attack: Any = None,
    mode: str = "covariance",
    protocol: str = "B",
    progress: bool | None = None,
    record_runs: bool = False,
) -> SimulationResult:
    r"""Monte Carlo of the real protocol: sensor, lossy channel, event detector, attacker.

    Simulates the mechanisms, not the Markov chain, so it independently checks every analytic
    formula. Each step the sensor picks Δ (always arrives) or δ (arrives with probability
    :math:`\lambda`); the remote estimator follows eq. (7)-(8); the event detector keeps the ACK
    memory (z0 bits with probability μ, else z0+1; reset after each flag-ACK); the attacker blocks
    flag-ACKs per its mask (:class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`) or
    independently with probability β (:class:`fakeack.RandomBlocking`), and a
    :class:`fakeack.FlagInjection` forges a flag-ACK with probability γ on each step on which the
    detector sends none, after which the sensor uses Δ. Runs start from the paper's initial
    condition.

    Parameters
    ----------
    system : LinearSystem
    lam : float
        Arrival probability at low power.
    sched : OfflineSchedule or OnlineSchedule
    horizon : int, optional
        Steps per run (default 1000).
    runs : int, optional
        Independent runs (default 100000, as in the paper). Memory does not grow with runs.
    seed : int, optional
        Results depend only on the seed, not on the number of threads.
    attack : None, attack, (r, t) or str, optional
        Fake-ACK attack (online schedules only): :class:`fakeack.PeriodicBlocking`,
        :class:`fakeack.MaskBlocking`, :class:`fakeack.RandomBlocking`,
        :class:`fakeack.FlagInjection`, or any spelling ``fakeack.attacks.as_attack`` reads
        (``"1/5"``, ``"random:0.3"``, ``"inject:0.1+random:0.3"``).
    mode : {"covariance", "state"}
        ``"covariance"`` tracks the holding time and averages :math:`\mathrm{Tr}\,P_k`;
        ``"state"`` simulates Gaussian noise, the sensor's steady-state Kalman filter and the
        remote estimator, and averages the squared estimation error (the error dynamics are
        simulated directly, so unstable A never overflows).
    protocol : {"B", "A"}
        Type B: a flag packet that the attacker drops (or forges); Type A: a bit every step that
        the attacker flips (1 to 0 to block, 0 to 1 to forge). The statistics are identical
        (Sec. IV-A), draw for draw.
    progress : bool or None
        Show a tqdm bar for runs over a second; ``None`` (default) shows it only on a terminal.
    record_runs : bool
        Also return each run's count of flag-ACKs delivered to the sensor, genuine or forged
        (``delivered_per_run``; 8 bytes per run, the one output whose memory grows with
        ``runs``), as used by :func:`fakeack.detection_rates`.

    Returns
    -------
    SimulationResult

    Notes
    -----
    Runs in parallel on all cores with the GIL released; Ctrl-C raises ``KeyboardInterrupt``
    within a fraction of a second.

    Covariance mode simulates 256 runs at once as the bit lanes of four machine words whenever the
    holding time is bounded by 32 (and the memory under attack too) and the attack mask has at
    most four runs of ones, and under random blocking or forging also when few runs pass 32 steps
    without an arrival (those are followed one by one); other plans use a lane-parallel kernel,
    as does state mode. Both are
    exact simulations of the same protocol, but they consume the random streams differently: for
    one seed, a covariance run and a state run of such a plan are different (equally distributed)
    samples, not paired ones.
    """
    core = _core(system)
    lam = as_probability("lam", lam)
    sched, att = _schedule_and_attack(sched, attack)
    horizon = as_int("horizon", horizon, minimum=1)
    runs = as_int("runs", runs, minimum=1)
    seed = as_int("seed", seed, minimum=0)
    if seed >= 2**64:
        raise ValueError(f"seed must be below 2**64, got {seed}")
    if mode not in MODES:
        raise ValueError(f"mode must be 'covariance' or 'state', got {mode!r}")
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol must be 'A' or 'B', got {protocol!r}")
    if isinstance(sched, OfflineSchedule):
        kind, p, q, z0, mu = "offline", sched.ratio.numerator, sched.ratio.denominator, 1, 1.0
    else:
        kind, p, q, z0, mu = "online", 1, 2, sched.z0, sched.mu
    bar = _Progress(runs, progress)
    try:
        out = _fakeack.simulate(
            core, lam, kind, p, q, z0, mu, core_attack(att), mode, protocol, horizon, runs, seed,
            bar, bool(record_runs),
        )
    finally:
        bar.close()
    return SimulationResult(
        j_k=out["j_k"],
        mean_trace=out["mean_trace"],
        j=out["j"],
        stderr=out["stderr"],
        high_power_rate=out["high_power_rate"],
        flags_sent=out["flags_sent"],
        flags_blocked=out["flags_blocked"],
        flags_forged=out["flags_forged"],
        runs=runs,
        horizon=horizon,
        seed=seed,
        mode=mode,
        protocol=protocol,
        schedule=str(sched),
        attack="none" if att is None else str(att),
        delivered_per_run=out["delivered_per_run"] if record_runs else None,
    )
