"""Schedules as objects, Monte Carlo of the real protocol, and exact finite-horizon curves."""

from __future__ import annotations

from dataclasses import dataclass, field

from .. import _fakeack
from .._internal.progress import Progress
from .._internal.types import FloatArray, IntArray
from .._internal.validate import MODES, PROTOCOLS, as_int, as_probability
from ..attacks.kinds import AttackLike, core_attack
from ..model.schedules import OfflineSchedule, OnlineDesign
from ..model.system import LinearSystem, compiled
from .curves import _schedule_and_attack

__all__ = [
    "SimulationResult",
    "simulate",
]


@dataclass(frozen=True)
class SimulationResult:
    """Monte Carlo estimates of the protocol (see :func:`simulate`)."""

    j_k: FloatArray
    """J_k = (1/k) Σ_{i<=k} Tr P_i averaged over runs, k = 1..horizon."""
    mean_trace: FloatArray
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
    delivered_per_run: IntArray | None = field(default=None, repr=False)
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
        from .._internal import html as _html

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


def simulate(
    system: LinearSystem,
    lam: float,
    sched: OfflineSchedule | OnlineDesign,
    horizon: int = 1000,
    runs: int = 100_000,
    seed: int = 1,
    attack: AttackLike = None,
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
    core = compiled(system)
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
        assert sched.ratio is not None  # _schedule_and_attack refuses a schedule given by its pattern
        kind, p, q, z0, mu = "offline", sched.ratio.numerator, sched.ratio.denominator, 1, 1.0
    else:
        kind, p, q, z0, mu = "online", 1, 2, sched.z0, sched.mu
    bar = Progress(runs, progress)
    try:
        out = _fakeack.simulate(
            core,
            lam,
            kind,
            p,
            q,
            z0,
            mu,
            core_attack(att),
            mode,
            protocol,
            horizon,
            runs,
            seed,
            bar,
            bool(record_runs),
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
