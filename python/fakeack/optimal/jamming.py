r"""Optimal denial-of-service jamming of the data channel: which steps a jammer with a budget
should jam to make the remote estimate worst.

A jammed step loses the sensor's packet whatever its power; an unjammed one arrives with the
channel's probability at the sensor's power. With :math:`\tau_k` the steps since the last arrival
after step k, :math:`P_k = h^{\tau_k}(\bar P)` and the cost is the average of
:math:`\mathrm{Tr}\,E[P_k]`. Two problems:

* a finite horizon T with at most n jams chosen in advance (the open-loop problem of the
  optimal-DoS literature: Zhang, Cheng, Shi and Chen, IEEE TAC 2015 and IEEE TCST 2016);
* the long run with a jammed fraction at most r, the jammer seeing τ (it overhears the data
  packets and their ACKs) and jamming with a probability that depends on min(τ, τ_max).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .._internal.types import BoolArray, FloatArray
from .._internal.validate import as_int, as_probability
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.schedules import OfflineSchedule
from ..model.system import LinearSystem, compiled
from ._longrun import policy_cost as _policy_cost
from ._longrun import solve_long_run, unbounded_witness
from ._traces import log_traces, weighted_sum

__all__ = ["JammingResult", "optimal_jamming", "MAX_EXHAUSTIVE"]

#: Most schedules compared one by one; beyond, the best consecutive block is returned.
MAX_EXHAUSTIVE = 200_000
#: Largest work (schedules x horizon^2 x channel states / 2) of one finite-horizon call.
_MAX_WORK = 4e8
#: Schedules evaluated together (memory: this x (T + 1) x K doubles).
_CHUNK = 8192
#: τ_max of the long run when none is given.
DEFAULT_TAU = 200
#: Largest τ_max accepted.
MAX_TAU = 2000


@dataclass(frozen=True, eq=False)
class JammingResult:
    """The optimal jamming found by :func:`optimal_jamming`; fields of the other problem are ``None``."""

    j: float
    r"""J under the returned jamming: :math:`\frac1T\sum_{k=1}^T \mathrm{Tr}\,E[P_k]` (finite
    horizon) or the exact long-run average of the returned policy; ``inf`` when unbounded or beyond
    the double range."""
    method: str
    """How optimality was established: ``"closed form"`` (ideal channel), ``"exhaustive"`` (every
    schedule with n jams compared), ``"best consecutive block"`` (the best of the T - n + 1 blocks of
    n consecutive jams, not proven optimal), ``"linear program"`` (long run, optimal within
    ``tail_bound``) or ``"unbounded"`` (long run, a policy within the rate makes J infinite)."""
    horizon: int | None
    """T, or ``None`` in the long run."""
    n_jams: int | None
    """The jam budget n (the schedule uses exactly n jams), or ``None`` in the long run."""
    jammed_steps: tuple[int, ...] | None
    """The jammed steps, 1-based, increasing (finite horizon)."""
    trace: FloatArray | None
    r""":math:`\mathrm{Tr}\,E[P_k]` for k = 1..T under the returned schedule (finite horizon)."""
    rate: float | None
    """The largest long-run jammed fraction r (long run)."""
    tau_max: int | None
    """τ_max: the jam probability depends on min(τ, τ_max) (long run)."""
    jam_probability: FloatArray | None
    """``(tau_max + 1,)`` the probability of jamming when min(τ_{k-1}, τ_max) = s (long run); for
    ``"unbounded"`` a policy within the rate whose J is infinite."""
    idle_probability: FloatArray | None
    r"""``1 - jam_probability`` to full relative precision (long run): optimal policies jam at
    τ_max with a probability within :math:`(1-\lambda)^{\tau_\max}` of 1, which
    ``jam_probability`` rounds to 1."""
    j_lp: float | None
    """The LP's optimum, with the cost beyond τ_max frozen at its value at τ_max + 1 (long run): a
    lower bound of J of the returned policy, and at least the optimum minus ``tail_bound``."""
    tail_bound: float | None
    """Rigorous bound on what freezing the cost beyond τ_max leaves out: the optimum over the
    policies of this class lies in [``j_lp``, ``j_lp + tail_bound``], and so does ``j``."""
    jammed_fraction: float | None
    """The returned policy's long-run jammed fraction (at most ``rate``)."""


def optimal_jamming(
    system: LinearSystem,
    channel: ChannelLike,
    n_jams: int | None = None,
    horizon: int | None = None,
    *,
    schedule: OfflineSchedule | None = None,
    rate: float | None = None,
    tau_max: int | None = None,
) -> JammingResult:
    r"""The jamming of the data channel that maximises the estimation error.

    **Finite horizon** (``horizon=T``, ``n_jams=n``): the jammed steps are chosen in advance.
    :math:`J = \frac1T\sum_{k=1}^T \mathrm{Tr}\,E[P_k]`, :math:`P_k = h^{\tau_k}(\bar P)`, with
    :math:`\tau_0 = 0` at k = 0: the estimate is fresh before step 1, and step 1 may be jammed. (The
    paper's initial condition, used by the cost curves, is instead that step 1's packet arrives.)
    Jamming more steps never lowers J: the channel's state does not depend on the jamming, so on
    every sample path of the channel τ_k can only grow with the set of jammed steps, and the traces
    increase with τ (Lemma 2.1). So "at most n" and "exactly n" jams have the same optimum, and
    the returned schedule jams exactly n steps.

    * Ideal channel (every packet the sensor sends arrives): each run of l consecutive jams costs
      :math:`\mathrm{tr}_1 + \dots + \mathrm{tr}_l`, which is superadditive in l, so every block
      of n consecutive jams is optimal, with
      :math:`J = [(T-n)\,\mathrm{tr}_0 + \mathrm{tr}_1 + \dots + \mathrm{tr}_n]/T`
      (``method="closed form"``; the block 1..n is returned).
    * Otherwise, if :math:`\binom{T}{n} \le` ``MAX_EXHAUSTIVE``, every schedule is evaluated
      exactly and the best returned (``"exhaustive"``); beyond, the best of the T - n + 1 blocks
      of consecutive jams is returned (``"best consecutive block"``), which is not proven optimal.

    :math:`E[P_k]` is exact: the law of :math:`(\tau_k, c_k)` is carried forward step by step
    (an arrival sends τ to 0, a loss or a jam adds one; the channel moves after each step).

    **Long run** (``rate=r``): the jammer jams with probability ``x[min(τ_{k-1}, tau_max)]``,
    its long-run jammed fraction at most r, to maximise the long-run average of
    :math:`\mathrm{Tr}\,P_k`. It is solved as a linear program over the stationary occupation
    measure of (min(τ, τ_max), jam or not); the cost beyond τ_max, which the LP freezes, is
    bounded by ``tail_bound``, and ``j`` is the exact J of the returned policy. If
    :math:`\rho(A) \ge 1`, holding a jam probability :math:`x^*` with
    :math:`(1 - (1 - x^*)\lambda)\rho(A)^2 \ge 1` beyond τ_max makes J infinite at a jammed
    fraction that shrinks like :math:`(1-\lambda)^{\tau_\max}`: when such a policy fits the rate,
    the result has ``j = inf``, ``method="unbounded"`` and that policy (no exception).

    Parameters
    ----------
    system : LinearSystem
        The process and the sensor's filter.
    channel : Channel or float
        The channel; a float is the paper's channel with that ``lam``, ``1.0`` an ideal channel.
        A Markov channel starts in its stationary law. The long run needs a one-state channel.
    n_jams : int, optional
        The jam budget n, ``0 <= n <= horizon`` (finite horizon only).
    horizon : int, optional
        T >= 1. Give exactly one of ``horizon`` and ``rate``.
    schedule : OfflineSchedule, optional
        The sensor's power levels (finite horizon only): its pattern repeated from step 1; an
        unjammed step arrives with the channel's high- or low-power probability. ``None``: one
        level, every step at low power (the channel's ``low``; ``lam`` for a float).
    rate : float, optional
        Largest long-run jammed fraction, in [0, 1].
    tau_max : int, optional
        Long run only: the jam probability depends on min(τ, τ_max) (default 200, at most 2000).

    Returns
    -------
    JammingResult

    Raises
    ------
    TypeError
        For a wrong kind of argument, both or neither of ``horizon`` and ``rate``, ``n_jams``
        missing with ``horizon`` or given with ``rate``, a schedule with ``rate``, ``tau_max``
        with ``horizon``.
    ValueError
        ``n_jams`` above ``horizon`` or negative, ``rate`` outside [0, 1], a horizon too long to
        evaluate (the message says the work), a long run on a channel with memory or on an ideal
        channel with :math:`\rho(A) < 1` (the optimum is not attained), a ``tau_max`` at which the
        optimal policy's probabilities leave the double range (the message gives a smaller one).
    RuntimeError
        If HiGHS fails, or its policy's exact J falls outside [``j_lp``, ``j_lp + tail_bound``]
        (never observed; the result would not be certified).

    Notes
    -----
    On the paper's channel and on Markov channels at one power level, every exhaustive optimum
    found (T <= 20) is a block of consecutive jams, in the middle of the horizon; under an offline
    schedule it is not (the jammer goes for the high-power steps), so there the block scan beyond
    ``MAX_EXHAUSTIVE`` is only a lower bound on the optimum.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> r = fa.optimal_jamming(s, 1.0, n_jams=3, horizon=10)
    >>> r.method, r.jammed_steps
    ('closed form', (1, 2, 3))
    >>> tr = s.h_traces(3)
    >>> bool(abs(r.j - (7 * tr[0] + tr[1] + tr[2] + tr[3]) / 10) < 1e-12)
    True
    """
    compiled(system)
    ch = as_channel(channel)
    if (horizon is None) == (rate is None):
        raise TypeError(
            "horizon or rate: give exactly one (a finite horizon T, or a long-run jammed fraction)"
        )
    if rate is not None:
        if n_jams is not None:
            raise TypeError("n_jams applies to a finite horizon; the long run takes rate")
        if schedule is not None:
            raise TypeError("schedule applies to a finite horizon; the long run has one power level")
        r = as_probability("rate", rate, closed=True)
        m = as_int("tau_max", DEFAULT_TAU if tau_max is None else tau_max, minimum=1, maximum=MAX_TAU)
        if ch.n_states != 1:
            raise ValueError(
                "channel: the long run needs a one-state channel (the jammer sees τ, not the channel's state)"
            )
        lam = float(ch.low[0])
        if lam == 1.0 and system.spectral_radius < 1.0 and r > 0.0:
            raise ValueError(
                "channel: on an ideal channel (lam = 1) the long-run optimum is approached by jamming "
                "ever more rarely and for ever longer, and is not attained; use a finite horizon"
            )
        return _long_run(system, lam, r, m)
    if tau_max is not None:
        raise TypeError("tau_max applies to the long run (rate); a finite horizon has no τ cap")
    T = as_int("horizon", horizon, minimum=1)
    if n_jams is None:
        raise TypeError("n_jams is missing: the number of steps the jammer may jam in the horizon")
    n = as_int("n_jams", n_jams, minimum=0)
    if n > T:
        raise ValueError(f"n_jams must be at most horizon = {T}, got {n}")
    if schedule is not None and not isinstance(schedule, OfflineSchedule):
        raise TypeError(f"schedule must be a fakeack.OfflineSchedule or None, got {type(schedule).__name__}")
    return _finite(system, ch, n, T, schedule)


def _long_run(system: LinearSystem, lam: float, rate: float, tau_max: int) -> JammingResult:
    witness = unbounded_witness(system, lam, rate, tau_max)
    if witness is not None:
        # _policy_cost is the exact J and jammed fraction of a policy on min(τ, τ_max): the
        # stationary law plus the geometric tail. The engine's fa.Scenario.from_automaton(system,
        # K0, K1), with the jammer as an automaton on s = min(τ, τ_max) (K1 the kernel of a jammed
        # step), computes the same and can take its place here and in solve_long_run.
        _, fraction = _policy_cost(system, lam, 1.0 - witness)
        return JammingResult(
            math.inf,
            "unbounded",
            None,
            None,
            None,
            None,
            rate,
            tau_max,
            _frozen(witness),
            _frozen(1.0 - witness),
            math.inf,
            0.0,
            fraction,
        )
    lr = solve_long_run(system, lam, rate, tau_max)
    return JammingResult(
        lr.j,
        "linear program",
        None,
        None,
        None,
        None,
        rate,
        tau_max,
        _frozen(1.0 - lr.idle_probability),
        _frozen(lr.idle_probability),
        lr.j_lp,
        lr.tail_bound,
        lr.jammed_fraction,
    )


def _arrival(ch: Channel, T: int, schedule: OfflineSchedule | None) -> FloatArray:
    """``(T, K)`` arrival probability of step k's unjammed packet in each channel state."""
    if schedule is None:
        return np.tile(ch.low, (T, 1))
    pattern = schedule.pattern
    level = pattern[np.arange(T) % len(pattern)].astype(bool)
    return np.where(level[:, None], ch.high[None, :], ch.low[None, :])


def expected_traces(ch: Channel, arrival: FloatArray, jam: BoolArray, logtr: FloatArray) -> FloatArray:
    r"""``(S, T)`` :math:`\mathrm{Tr}\,E[P_k]` under each of the S jam masks ``jam`` (S, T).

    Carries the law of :math:`(\tau_{k-1}, c_k)`, starting from τ = 0 and the stationary c.
    """
    S, T = jam.shape
    K = ch.n_states
    law = np.zeros((S, T + 1, K))
    law[:, 0, :] = ch.stationary
    out = np.empty((S, T))
    for k in range(T):
        q = np.where(jam[:, k, None], 0.0, arrival[k][None, :])  # (S, K)
        head = law[:, : k + 1, :]  # τ_{k-1} <= k - 1 < k + 1
        arrived = np.einsum("stk,sk->sk", head, q)
        lost = head * (1.0 - q)[:, None, :]
        law[:, 1 : k + 2, :] = lost
        law[:, 0, :] = arrived
        out[:, k] = weighted_sum(law[:, : k + 2, :].sum(axis=2), logtr)
        if K > 1:
            law[:, : k + 2, :] = law[:, : k + 2, :] @ ch.P
    return out


def _finite(
    system: LinearSystem, ch: Channel, n: int, T: int, schedule: OfflineSchedule | None
) -> JammingResult:
    logtr, _, _ = log_traces(system, T)
    arrival = _arrival(ch, T, schedule)
    support = ch.stationary > 0.0  # the chain stays in its closed class
    if np.all(arrival[:, support] == 1.0):
        tr = np.exp(np.minimum(logtr, 709.0))
        tr[logtr >= 709.0] = math.inf
        trace = np.concatenate([tr[1 : n + 1], np.full(T - n, tr[0])])
        j = float(_mean(trace[None, :])[0])
        return _finite_result(j, "closed form", T, n, tuple(range(1, n + 1)), trace)
    count = math.comb(T, n)
    if count <= MAX_EXHAUSTIVE:
        _check_work(count, T, ch.n_states)
        best_j, best_steps, best_trace = -1.0, tuple[int, ...](), np.empty(0)
        combos = itertools.combinations(range(T), n)
        while True:
            chunk = list(itertools.islice(combos, _CHUNK))
            if not chunk:
                break
            jam = np.zeros((len(chunk), T), dtype=bool)
            if n:
                idx = np.array(chunk)
                jam[np.arange(len(chunk))[:, None], idx] = True
            traces = expected_traces(ch, arrival, jam, logtr)
            js = _mean(traces)
            i = int(np.argmax(js))
            if js[i] > best_j:
                best_j, best_steps, best_trace = float(js[i]), tuple(int(v) + 1 for v in chunk[i]), traces[i]
        return _finite_result(best_j, "exhaustive", T, n, best_steps, best_trace)
    blocks = T - n + 1
    _check_work(blocks, T, ch.n_states)
    jam = np.zeros((blocks, T), dtype=bool)
    for b in range(blocks):
        jam[b, b : b + n] = True
    traces = expected_traces(ch, arrival, jam, logtr)
    js = _mean(traces)
    b = int(np.argmax(js))
    return _finite_result(
        float(js[b]), "best consecutive block", T, n, tuple(range(b + 1, b + n + 1)), traces[b]
    )


def _check_work(schedules: int, T: int, K: int) -> None:
    work = schedules * T * T * K / 2
    if work > _MAX_WORK:
        raise ValueError(
            f"horizon = {T}: evaluating {schedules} schedules exactly takes about {work:.2g} "
            f"operations (limit {_MAX_WORK:.0e}); use a shorter horizon"
        )


def _finite_result(
    j: float, method: str, T: int, n: int, steps: tuple[int, ...], trace: FloatArray
) -> JammingResult:
    return JammingResult(j, method, T, n, steps, _frozen(trace), None, None, None, None, None, None, None)


def _mean(traces: FloatArray) -> FloatArray:
    """Row means, ``inf`` only when the mean itself passes the double range (terms divided first)."""
    with np.errstate(over="ignore"):
        return np.asarray(np.sum(traces / traces.shape[1], axis=1), dtype=np.float64)


def _frozen(values: FloatArray) -> FloatArray:
    out = np.array(values, dtype=np.float64)
    out.flags.writeable = False
    return out
