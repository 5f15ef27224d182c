r"""Run lengths of the flag-ACK CUSUM (:class:`fakeack.CusumTest`): the mean time to a false alarm
(ARL0) and the mean delay to detect an attack (ARL1), on any channel and under any attacker.

The statistic W moves deterministically given the gap y and whether a flag-ACK reached the
sensor, and the flag-ACKs are the Markov arrival process :math:`K = D_0 + D_1` of the exact
engine's automaton E (:func:`fakeack.flag_process`). So (e, y, W) is a Markov chain, and the mean
run length solves :math:`(I - Q)\,t = \mathbf 1` over its states without an alarm. W takes a
continuum of values; on a grid of m points :math:`W = i\Delta`, :math:`\Delta = h/m`, the chain
of Brook and Evans (1972) rounds each new W to a grid point. Rounding **down** gives a statistic
never above the true one on every path, so it alarms later: an upper bound on the mean run
length; rounding **up** a lower bound. The estimate splits each new W between its two grid points
in proportion to the distance (the mean of W kept), which is accurate to second order; the
bracket closes like :math:`\Delta` as the caller adds bins. The bracket is rigorous for the
renewal start; for the stationary start the pre-change law of W is itself computed on the grid.
The filter CUSUM (``likelihood="filter"``) has no finite chain; its run lengths are simulated
(``fakeack.detection.cusum_filter``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import brentq
from scipy.sparse.linalg import splu

from .._internal.types import FloatArray
from .._internal.validate import as_int, as_real
from ..attacks.automata import discard_forgeries
from ..model.channels import ChannelLike, as_channel
from ..model.schedules import OnlineDesign
from .cusum import CusumIncrements, CusumTest
from .cusum_filter import (
    SimulatedRunLength,
    _check_runs,
    _passage_threshold,
    _simulate_passage_times,
    _summarise,
)
from .process import FlagProcess, flag_process

__all__ = [
    "CusumRunLength",
    "cusum_run_length",
    "cusum_threshold",
    "run_length_bounds",
]

#: Largest chain (states of (e, y, W)) built unless told otherwise.
MAX_CHAIN_STATES = 1_000_000
_STARTS = ("renewal", "stationary")
_ROUNDINGS = ("down", "up", "split")


@dataclass(frozen=True)
class CusumRunLength:
    """The mean run length of a CUSUM (see :func:`cusum_run_length`)."""

    mean: float
    """The estimate (each new W split between its two grid points)."""
    error: float
    """How far the estimate moved when the grid was halved: its stated accuracy."""
    lower: float
    """Lower bound: W rounded up on the grid (alarms sooner), at ``bins``."""
    upper: float
    """Upper bound: W rounded down (alarms later); ``inf`` where the grid is too coarse for the
    smallest increments to move W. The bracket closes slowly (like 1/bins); ``error`` is the
    estimate's accuracy."""
    bins: int
    """Grid points m of W in [0, h)."""
    states: int
    """States of the (e, y, W) chain."""
    start: str
    """``"renewal"`` or ``"stationary"``."""


def _grid_moves(
    inc: float, m: int, delta: float, rounding: str
) -> list[tuple[FloatArray, FloatArray, FloatArray]]:
    """From every grid point i, where one increment sends W: (source i, target j, weight), the
    alarms (j >= m) left out, so they leave the chain."""
    i = np.arange(m, dtype=np.float64)
    if inc == math.inf:
        return []
    if inc == -math.inf:
        return [(i, np.zeros(m), np.ones(m))]
    x = np.maximum(i + inc / delta, 0.0)
    # A relative 1e-9 of a bin absorbs the rounding of i + inc/delta at exact grid points.
    if rounding == "down":
        parts = [(np.floor(x + 1e-9), np.ones(m))]
    elif rounding == "up":
        parts = [(np.ceil(x - 1e-9), np.ones(m))]
    else:
        lo = np.floor(x + 1e-9)
        frac = np.clip(x - lo, 0.0, 1.0)
        parts = [(lo, 1.0 - frac), (lo + 1.0, frac)]
    out = []
    for j, w in parts:
        keep = (j < m) & (w > 0.0)
        out.append((i[keep], j[keep], w[keep]))
    return out


def _chain(
    D: tuple[sp.csr_array, sp.csr_array], inc: CusumIncrements, threshold: float, m: int, rounding: str
) -> sp.csc_array:
    """Q over (y, e, i), index ((y - 1) n_e + e) m + i: the transitions without an alarm."""
    n_e, Y = D[0].shape[0], inc.length
    delta = threshold / m
    rows, cols, vals = [], [], []
    for x, table in ((0, inc.quiet), (1, inc.flag)):
        coo = D[x].tocoo()
        if coo.nnz == 0:
            continue
        for y in range(1, Y + 1):
            y2 = 1 if x else min(y + 1, Y)
            for src, dst, w in _grid_moves(float(table[y - 1]), m, delta, rounding):
                base_r = ((y - 1) * n_e + coo.row[:, None]) * m
                base_c = ((y2 - 1) * n_e + coo.col[:, None]) * m
                rows.append((base_r + src[None, :].astype(np.int64)).ravel())
                cols.append((base_c + dst[None, :].astype(np.int64)).ravel())
                vals.append((coo.data[:, None] * w[None, :]).ravel())
    n = n_e * Y * m
    if not rows:
        return sp.csc_array((n, n))
    Q = sp.coo_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return Q.tocsc()


def _mean_time(Q: sp.csc_array, p0: FloatArray) -> float:
    """p0 (I - Q)^{-1} 1, or inf where some state reachable from p0 never alarms."""
    n = Q.shape[0]
    A = (sp.identity(n, format="csc") - Q).T.tocsc()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a singular factor is reported as inf below
        try:
            u = splu(A, permc_spec="MMD_AT_PLUS_A").solve(p0)
        except RuntimeError:
            return math.inf
    t = float(u.sum())
    if not np.all(np.isfinite(u)) or np.any(u < -1e-9 * max(1.0, abs(t))) or t <= 0.0:
        return math.inf
    return t


def run_length_bounds(
    process: FlagProcess,
    increments: CusumIncrements,
    threshold: float,
    start: FloatArray,
    bins: int,
    rounding: str = "split",
) -> float:
    r"""The mean run length of a CUSUM on a flag process from a law of (y, e, W) on the grid.

    Parameters
    ----------
    process : FlagProcess
        The delivered flag-ACKs (true channel and attack).
    increments : CusumIncrements
        The statistic's increments (:meth:`fakeack.CusumTest.increments`).
    threshold : float
        The alarm level h.
    start : numpy.ndarray
        The law of the chain's state at the first step, flat over ((y - 1) n_e + e) m + i.
    bins : int
        Grid points m.
    rounding : {"split", "down", "up"}
        How a new W meets the grid (the module docstring).

    Returns
    -------
    float
        The mean number of steps to the alarm, the alarm's step included (inf if it may never
        come).
    """
    if rounding not in _ROUNDINGS:
        raise ValueError(f"rounding must be one of {_ROUNDINGS}, got {rounding!r}")
    Q = _chain((process.D0, process.D1), increments, threshold, bins, rounding)
    return _mean_time(Q, start)


def _check_size(n_e: int, Y: int, m: int, max_states: int) -> int:
    n = n_e * Y * m
    if n > max_states:
        raise ValueError(
            f"bins: the CUSUM chain would have {n} states ({n_e} automaton states x {Y} gaps x {m} "
            f"bins), more than max_states = {max_states}"
        )
    return n


def _attack_map(null: FlagProcess, attacked: FlagProcess) -> sp.csr_array:
    """The attacked automaton's state at the attack's onset from the attack-free one: the same
    channel state, zero count and power, the attacker in its start state."""

    def key(label: str) -> str:
        return label.split(" attacker=")[0]

    first = attacked.labels[0]
    start = first.split(" attacker=")[-1] if " attacker=" in first else None
    where = {
        key(lab): k
        for k, lab in enumerate(attacked.labels)
        if start is None or lab.endswith(f"attacker={start}")
    }
    rows, cols = [], []
    for k, lab in enumerate(null.labels):
        if null.stationary[k] <= 0.0:
            continue
        if key(lab) not in where:
            raise ValueError(
                "start: the attack cannot begin from every attack-free state in its start state "
                f"(no state {key(lab)!r} with the attacker at its start); use start='renewal'"
            )
        rows.append(k)
        cols.append(where[key(lab)])
    return sp.csr_array((np.ones(len(rows)), (rows, cols)), shape=(null.n_states, attacked.n_states))


def _quasi_stationary(Q: sp.csc_array, p: FloatArray, tol: float = 1e-12, limit: int = 200_000) -> FloatArray:
    """The law of the chain's state given no alarm yet, in the long run: the left Perron vector
    of Q, by the power method from p on (I + Q)/2 (same vector, no periodicity)."""
    Qt = (0.5 * (sp.identity(Q.shape[0], format="csr") + Q.T)).tocsr()
    for _ in range(limit):
        nxt = Qt @ p
        mass = float(nxt.sum())
        if mass <= 0.0:
            raise ValueError("start: the attack-free CUSUM alarms surely; no stationary regime exists")
        nxt /= mass
        if float(np.abs(nxt - p).sum()) < tol:
            return np.asarray(nxt)
        p = nxt
    raise ValueError("start: the attack-free CUSUM's law given no alarm did not settle")


def _renewal_start(process: FlagProcess, Y: int, m: int) -> FloatArray:
    p = np.zeros(process.n_states * Y * m)
    p[np.arange(process.n_states) * m] = process.initial  # y = 1, W = 0
    return p


def _stationary_start(
    null: FlagProcess, attacked: FlagProcess, inc: CusumIncrements, h: float, m: int, rounding: str
) -> FloatArray:
    Y = inc.length
    Q0 = _chain((null.D0, null.D1), inc, h, m, rounding)
    qs = _quasi_stationary(Q0, _renewal_start(null, Y, m)).reshape(Y, null.n_states, m)
    M = _attack_map(null, attacked)
    return np.asarray(np.einsum("yem,ef->yfm", qs, M.toarray()).ravel())


def cusum_run_length(
    channel: ChannelLike,
    design: OnlineDesign,
    cusum: CusumTest,
    attack: object = None,
    start: str = "renewal",
    *,
    bins: int | None = None,
    rtol: float = 0.01,
    authenticated: bool = False,
    max_states: int = MAX_CHAIN_STATES,
    runs: int | None = None,
    seed: int | None = None,
    max_steps: int | None = None,
) -> CusumRunLength | SimulatedRunLength:
    r"""The mean number of steps until a flag-ACK CUSUM alarms: ARL0 without attack, the mean
    detection delay under one.

    The Markov chain of (automaton state e, gap y, statistic W) of Brook and Evans over the exact
    engine's automaton (the module docstring), so any attack the engine takes (periodic, masks,
    forging with any ``min_gap``, :class:`fakeack.MimicryAttack`, an
    :class:`fakeack.AttackerAutomaton`) has its exact flag process. The grid of W is refined
    (doubled) until the estimate moves by less than ``rtol`` of itself, or the chain would pass
    ``max_states`` (then a ``UserWarning`` says so); the rigorous but slowly closing bracket of
    the two one-sided roundings is reported beside it.

    A filter CUSUM (``likelihood="filter"``) carries a continuous belief that no finite chain
    holds: its mean run length is estimated from ``runs`` simulated runs of the attack's flag
    process (from the paper's initial condition) beside the two forward filters, with its
    standard error (``fakeack.detection.cusum_filter``). Only the renewal start is simulated.

    Parameters
    ----------
    channel : Channel or float
        The true channel (a float: the paper's channel).
    design : OnlineDesign
        The online schedule.
    cusum : CusumTest
        The statistic and its threshold.
    attack : optional
        The attack present from the start (None: the mean time to a false alarm, ARL0).
    start : {"renewal", "stationary"}
        ``"renewal"``: W = 0 just after a delivered flag-ACK (the paper's initial condition, the
        attacker in its start state). ``"stationary"``: the attack begins in the long-run regime
        without attack (the automaton's stationary law, W in its law given no alarm yet, the
        attacker at its start): the steady-state delay.
    bins : int, optional
        Grid points of W to start from (default 25 per unit of threshold, at least 50); the
        first comparison is with twice as many.
    rtol : float, optional
        Target relative accuracy of the estimate (default 0.01; the renewal statistic only).
    authenticated : bool, optional
        Whether the sensor rejects forged flag-ACKs (only the attack's blocking part acts).
    max_states : int, optional
        Largest chain built (default 10^6; the sparse LU of the largest takes a few GB).
    runs : int, optional
        A filter CUSUM only: runs simulated (default 2000).
    seed : int
        A filter CUSUM only, required: the seed of the draws.
    max_steps : int, optional
        A filter CUSUM only: refuse (``ValueError`` naming it) if some run has not alarmed by
        then (default 10^6 steps).

    Returns
    -------
    CusumRunLength or SimulatedRunLength
        ``mean`` and its ``error``, the bracket ``lower``/``upper``, the grid and the chain's
        size; for a filter CUSUM, ``mean`` over the runs and its standard error ``error``.

    Raises
    ------
    TypeError, ValueError
        For bad arguments (naming them); ``start="stationary"`` where the attack cannot begin in
        its start state from some attack-free state, or for a filter CUSUM; ``bins``, ``runs``,
        ``seed`` or ``max_steps`` given to the statistic that does not take them.

    Examples
    --------
    >>> import fakeack as fa
    >>> test = fa.CusumTest(fa.RandomBlocking(0.5), 3.0)
    >>> arl0 = fa.cusum_run_length(0.5, fa.OnlineDesign(2), test)
    >>> arl1 = fa.cusum_run_length(0.5, fa.OnlineDesign(2), test, fa.RandomBlocking(0.5))
    >>> arl1.mean < arl0.mean
    True
    """
    ch = as_channel(channel, "channel")
    if not isinstance(design, OnlineDesign):
        raise TypeError(f"design must be a fakeack.OnlineDesign, got {type(design).__name__}")
    if not isinstance(cusum, CusumTest):
        raise TypeError(f"cusum must be a fakeack.CusumTest, got {type(cusum).__name__}")
    if start not in _STARTS:
        raise ValueError(f"start must be 'renewal' or 'stationary', got {start!r}")
    tol = as_real("rtol", rtol)
    if not 0.0 < tol < 1.0:
        raise ValueError(f"rtol must lie in (0, 1), got {tol}")
    if not isinstance(authenticated, bool):
        raise TypeError(f"authenticated must be True or False, got {authenticated!r}")
    cap = as_int("max_states", max_states, minimum=1)
    h = cusum.threshold
    m = as_int("bins", bins, minimum=2) if bins is not None else max(50, int(math.ceil(25 * h)))
    if authenticated and attack is not None:
        attack = discard_forgeries(attack, channel=ch, design=design)
    if cusum.likelihood == "filter":
        if start != "renewal":
            raise ValueError("start: the filter CUSUM's run length is simulated from the renewal start only")
        if bins is not None:
            raise ValueError("bins: the filter CUSUM's run length is simulated, on no grid")
        n, s, limit = _check_runs(
            2000 if runs is None else runs, seed, 10**6 if max_steps is None else max_steps
        )
        process = flag_process(ch, design, attack)
        _, key = cusum._key(ch, design)
        times = _simulate_passage_times(process, ch, design, key, np.array([h]), n, s, limit)
        return _summarise(times[:, 0], n, s)
    for name, value in (("runs", runs), ("seed", seed), ("max_steps", max_steps)):
        if value is not None:
            raise ValueError(f"{name}: only a filter CUSUM's run length is simulated")
    inc = cusum.increments(ch, design)
    null = flag_process(ch, design)
    process = flag_process(ch, design, attack) if attack is not None else null
    Y = inc.length
    _check_size(process.n_states, Y, m, cap)

    def estimate(bins: int, rounding: str) -> float:
        p0 = (
            _renewal_start(process, Y, bins)
            if start == "renewal" or attack is None
            else _stationary_start(null, process, inc, h, bins, rounding)
        )
        return run_length_bounds(process, inc, h, p0, bins, rounding)

    previous = estimate(m, "split")
    while True:
        _check_size(process.n_states, Y, 2 * m, cap)
        m *= 2
        current = estimate(m, "split")
        error = abs(current - previous)
        if error <= tol * current or process.n_states * Y * 2 * m > cap:
            break
        previous = current
    lo, hi = estimate(m, "up"), estimate(m, "down")
    size = process.n_states * Y * m
    best = CusumRunLength(current, error, min(lo, current), max(hi, current), m, size, start)
    if error > tol * current:
        warnings.warn(
            f"cusum_run_length: the estimate {current:.6g} at {m} bins moved by {error:.3g} from half as "
            f"many bins, more than rtol = {tol}; raise max_states for more bins",
            UserWarning,
            stacklevel=2,
        )
    return best


def cusum_threshold(
    channel: ChannelLike,
    design: OnlineDesign,
    alternative: object,
    arl0: float,
    *,
    rtol: float = 0.02,
    likelihood: str = "renewal",
    runs: int = 2000,
    seed: int | None = None,
    max_steps: int = 10**6,
) -> float:
    r"""The CUSUM threshold h whose mean time to a false alarm (ARL0, renewal start) is ``arl0``.

    ARL0 grows with h; the root of :math:`\mathrm{ARL}_0(h) = ` ``arl0`` is found by Brent's
    method on the estimate of :func:`cusum_run_length` (to a relative 1e-4 in ARL0, each value
    within ``rtol``). For the filter CUSUM (``likelihood="filter"``) one simulation of ``runs``
    attack-free runs gives the mean first passage of W over a grid of levels, the ARL0 of every
    threshold on the same draws, and h is interpolated where it meets ``arl0``: the ARL0 of the
    result carries the simulation's relative standard error, about 1/sqrt(``runs``).

    Parameters
    ----------
    channel : Channel or float
        The channel.
    design : OnlineDesign
        The online schedule.
    alternative : RandomBlocking, FlagInjection or array_like
        As in :class:`fakeack.CusumTest`.
    arl0 : float
        The mean number of steps to a false alarm, > 1.
    rtol : float, optional
        As in :func:`cusum_run_length` (the renewal statistic only).
    likelihood : {"renewal", "filter"}, optional
        The statistic (:class:`fakeack.CusumTest`).
    runs, seed, max_steps : int, optional
        The filter statistic's simulation (:func:`cusum_run_length`); ``seed`` is required there.

    Returns
    -------
    float
        The threshold.

    Examples
    --------
    >>> import fakeack as fa
    >>> h = fa.cusum_threshold(0.5, fa.OnlineDesign(2), fa.RandomBlocking(0.5), 1000)
    >>> test = fa.CusumTest(fa.RandomBlocking(0.5), h)
    >>> round(fa.cusum_run_length(0.5, fa.OnlineDesign(2), test).mean, -1)
    1000.0
    """
    target = as_real("arl0", arl0)
    if target <= 1.0:
        raise ValueError(f"arl0 must be > 1, got {target}")
    test = CusumTest(alternative, 1.0, likelihood=likelihood)  # validates both, naming them
    if likelihood == "filter":
        n, s, limit = _check_runs(runs, seed, max_steps)
        ch, key = test._key(channel, design)
        return _passage_threshold(ch, design, key, target, n, s, limit)

    def gap(log_h: float) -> float:
        test = CusumTest(alternative, math.exp(log_h))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            arl = cusum_run_length(channel, design, test, rtol=rtol).mean
        return math.log(arl) - math.log(target)

    lo, hi = math.log(1e-3), math.log(2.0)
    while gap(hi) < 0.0:
        lo, hi = hi, hi + math.log(2.0)
        if hi > math.log(1e3):
            raise ValueError(f"arl0 = {target}: no threshold up to 1000 reaches it")
    if gap(lo) > 0.0:
        raise ValueError(f"arl0 = {target}: even the threshold 0.001 gives a longer mean run")
    return float(math.exp(brentq(gap, lo, hi, rtol=1e-6, xtol=1e-6)))
