"""Monte Carlo of the real protocol: sensor, lossy channel, event detector and attacker, run by the
compiled kernels (:func:`simulate`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .. import _fakeack
from .._internal.progress import Progress
from .._internal.types import FloatArray, IntArray
from .._internal.validate import MODES, PROTOCOLS, as_int, as_probability
from ..attacks.automata import AttackerAutomaton, MimicryAttack
from ..attacks.kinds import AttackLike, core_attack
from ..model.channels import BernoulliChannel, Channel, ChannelLike, channel_argument
from ..model.schedules import OfflineSchedule, OnlineDesign
from ..model.system import LinearSystem, compiled
from . import _automaton

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
    ``flags_sent - flags_blocked + flags_forged``. Under an attacker automaton: the flag-ACKs it
    delivered on steps without a genuine one (and ``flags_blocked`` the genuine ones it did not
    deliver)."""
    channel: Channel | None = None
    """The channel simulated: :func:`simulate` sets it, a float ``lam`` giving
    ``BernoulliChannel(lam)``."""

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
                ("channel", "–" if self.channel is None else repr(self.channel)),
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


def _two_state(ch: Channel) -> tuple[float, float, float, float] | None:
    """``(p, q, low_good, low_bad)`` of a two-state channel on which a high-power packet always
    arrives (the bit-sliced kernel's channels), else ``None``."""
    if ch.n_states != 2 or not all(float(h) == 1.0 for h in ch.high):
        return None
    return (float(ch.P[0, 1]), float(ch.P[1, 0]), float(ch.low[0]), float(ch.low[1]))


def simulate(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    sched: OfflineSchedule | OnlineDesign | None = None,
    horizon: int = 1000,
    runs: int = 100_000,
    seed: int = 1,
    attack: AttackLike | MimicryAttack | AttackerAutomaton = None,
    mode: str = "covariance",
    protocol: str = "B",
    progress: bool | None = None,
    record_runs: bool = False,
    *,
    lam: float | None = None,
) -> SimulationResult:
    r"""Monte Carlo of the real protocol: sensor, lossy channel, event detector, attacker.

    Simulates the mechanisms, not the Markov chain, so it independently checks every analytic
    formula and the exact engine (:class:`fakeack.Scenario`). Each step the sensor picks Δ or δ;
    in the channel's current state the packet arrives with the probability of that power (the
    paper's channel: always at Δ, with probability :math:`\lambda` at δ), and the channel then
    moves to its next state; the remote estimator follows eq. (7)-(8); the event detector keeps
    the ACK memory (z0 bits with probability μ, else z0+1; reset after each flag-ACK); the
    attacker blocks flag-ACKs per its mask (:class:`fakeack.PeriodicBlocking`,
    :class:`fakeack.MaskBlocking`) or independently with probability β
    (:class:`fakeack.RandomBlocking`), a :class:`fakeack.FlagInjection` forges a flag-ACK with
    probability γ on each step on which the detector sends none (at least ``min_gap`` steps after
    the last one the sensor received), after which the sensor uses Δ; a
    :class:`fakeack.MimicryAttack` delivers the flag-ACKs of a virtual attack-free system, and an
    :class:`fakeack.AttackerAutomaton` whatever its table says. Runs start from the paper's
    initial condition (high power at k = 1, memory all ones, the attacker at its start, the first
    channel state drawn from the stationary law).

    Parameters
    ----------
    system : LinearSystem
    channel : Channel or float
        :class:`fakeack.BernoulliChannel`, :class:`fakeack.MarkovChannel`,
        :class:`fakeack.GilbertElliott`, or a float: the paper's channel of that low-power arrival
        probability :math:`\lambda`.
    sched : OfflineSchedule or OnlineSchedule
        The online design ``(z0, mu)``, or an offline schedule by its ratio or by any pattern
        (``OfflineSchedule(pattern="0100")``: first symbol = step 1).
    horizon : int, optional
        Steps per run (default 1000).
    runs : int, optional
        Independent runs (default 100000, as in the paper). Memory does not grow with runs.
    seed : int, optional
        Results depend only on the seed, not on the number of threads.
    attack : None, attack, (r, t) or str, optional
        Fake-ACK attack (online schedules only): :class:`fakeack.PeriodicBlocking`,
        :class:`fakeack.MaskBlocking`, :class:`fakeack.RandomBlocking`,
        :class:`fakeack.FlagInjection` (any ``min_gap``), :class:`fakeack.MimicryAttack` (its
        ``None`` channel and design are this simulation's), :class:`fakeack.AttackerAutomaton`,
        or any spelling ``fakeack.attacks.as_attack`` reads (``"1/5"``, ``"random:0.3"``,
        ``"inject:0.1+random:0.3"``).
    mode : {"covariance", "state"}
        ``"covariance"`` tracks the holding time and averages :math:`\mathrm{Tr}\,P_k`;
        ``"state"`` simulates Gaussian noise, the sensor's steady-state Kalman filter and the
        remote estimator, and averages the squared estimation error (the error dynamics are
        simulated directly, so unstable A does not overflow; an error that still does, after an
        astronomically long loss run, gives ``inf``, never NaN). Both modes take every channel,
        schedule and attack (see Notes).
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
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float): ``simulate(system, lam=0.5, sched=...)`` still
        works. Giving both is a TypeError.

    Returns
    -------
    SimulationResult
        With ``channel`` the channel simulated.

    Raises
    ------
    TypeError
        For a missing or doubly given channel, or an argument of the wrong type (naming it).
    ValueError
        For a value out of its domain (naming it), or an attack on an offline schedule.

    Notes
    -----
    Runs in parallel on all cores with the GIL released; Ctrl-C raises ``KeyboardInterrupt``
    within a fraction of a second.

    Two families of kernels. On the paper's channel (one state, high power always arrives) with
    an online design or ``OfflineSchedule(ratio)`` and a built-in attack with ``min_gap = 1``,
    the specialised kernels run: covariance mode simulates 256 runs at once as the bit lanes of
    four machine words whenever the holding time is bounded by 32 (and the memory under attack
    too) and the attack mask has at most four runs of ones, and under random blocking or forging
    also when few runs pass 32 steps without an arrival (those are followed one by one); other
    plans use a lane-parallel kernel, as does state mode. Both are exact simulations of the same
    protocol, but they consume the random streams differently: for one seed, a covariance run
    and a state run of such a plan are different (equally distributed) samples, not paired
    ones.

    A two-state Markov channel on which a high-power packet always arrives
    (``GilbertElliott(p, q, lam_good, lam_bad)`` with ``high_good = high_bad = 1``, or any such
    two-state :class:`fakeack.MarkovChannel`) runs on the same bit-sliced kernel, its state one
    more bit per run, for the same schedules and attacks and within the same limits (random
    blocking and forging: at any depth), in covariance mode; its draws are exact like the
    others' and come from the same seeded streams, so the seed alone fixes the result. Such a
    plan outside those limits, and state mode under such a channel, go to the automaton kernel
    below, as the lane-parallel kernel does not take a Markov channel.

    Everything else (another channel, an offline pattern, mimicry, an attacker automaton, an
    injection with ``min_gap > 1``) runs on a plain per-run Monte Carlo of the attack written as
    an automaton (``fakeack.attacks.as_automaton``); it steps the channel, the detector and the
    attacker's table, never the exact engine's product chain. Its state mode runs the same error
    recursions as the lane kernels' (the remote error starts at the sensor's, as the holding time
    starts at 0, which matters where the first packet may be lost), and for one seed its runs
    follow the same protocol path as its covariance runs (same arrivals, flag-ACKs and attacker
    moves; only the noise is added). The protocols A and B are the same in law and give the same
    result there.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    >>> res = fa.simulate(s, ge, fa.OnlineDesign(2), 200, 2000, seed=1, progress=False)
    >>> res.channel == ge
    True
    """
    core = compiled(system)
    ch, channel_name = channel_argument(channel, lam, "simulate")
    sched = _automaton.schedule_argument(sched)
    att = _automaton.attack_argument(attack, sched)
    horizon = as_int("horizon", horizon, minimum=1)
    runs = as_int("runs", runs, minimum=1)
    seed = as_int("seed", seed, minimum=0)
    if seed >= 2**64:
        raise ValueError(f"seed must be below 2**64, got {seed}")
    if mode not in MODES:
        raise ValueError(f"mode must be 'covariance' or 'state', got {mode!r}")
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol must be 'A' or 'B', got {protocol!r}")
    markov = _two_state(ch)
    # A two-state channel with high power always arriving runs on the bit-sliced kernel in
    # covariance mode when the schedule and the attack are ones the specialised kernels take
    # (judged on the paper's channel); everything else, and state mode under a Markov channel,
    # runs on the automaton kernel (also the fall-back when a plan is outside the bit-sliced one).
    fast = not _automaton.needs_automaton(ch if markov is None else BernoulliChannel(0.5), sched, att)
    if markov is not None and mode != "covariance":
        fast = False
    bar = Progress(runs, progress)
    try:
        out = None
        if fast:
            assert not isinstance(att, (MimicryAttack, AttackerAutomaton))  # needs_automaton
            # On a Markov channel lam is not read.
            lam_value = 0.5 if markov is not None else as_probability(channel_name, float(ch.low[0]))
            if isinstance(sched, OfflineSchedule):
                assert sched.ratio is not None  # a pattern needs the automaton kernel
                kind, p, q, z0, mu = "offline", sched.ratio.numerator, sched.ratio.denominator, 1, 1.0
            else:
                kind, p, q, z0, mu = "online", 1, 2, sched.z0, sched.mu
            out = _fakeack.simulate(
                core,
                lam_value,
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
                markov,
            )
        if out is None:
            out = _automaton.run_automaton(
                core, ch, sched, att, horizon, runs, seed, bar, bool(record_runs), mode
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
        channel=ch,
    )
