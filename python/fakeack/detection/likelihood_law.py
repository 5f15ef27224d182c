r"""The exact law of a window's log-likelihood ratio of the flag-ACK stream (:func:`likelihood_ratio_law`).

In a window of n steps the sensor sums the per-step increments of :class:`fakeack.CusumTest`
(:math:`\log(h_a(y)/h_0(y))` on a step with a flag-ACK at gap y, :math:`\log((1-h_a(y))/(1-h_0(y)))`
on a silent one; the last entry of the tables holds for longer gaps), without the CUSUM's
reflection at 0:

.. math:: \Lambda_n = \log\frac{P_a(y_0)}{P_0(y_0)} + \sum_{k=1}^n \ell_k ,

opened by the log-likelihood ratio of the gap :math:`y_0` already running at the window's start
under the two stationary age laws :math:`P(y_0 = y) = S(y)/m` (S the survival of the gap law, m its
mean; :func:`opening`).

The increment of a step is a function of the gap y before it and of whether a flag-ACK came, and
the deliveries are the Markov arrival process :math:`K = D_0 + D_1` of the exact engine's
automaton (:func:`fakeack.flag_process`), so (automaton state e, age a = y - 1 capped at Y - 1,
:math:`\Lambda`) is a Markov chain. The window starts in the long-run regime: the age and state
have the stationary law :math:`P(a, e) = (\pi D_1 D_0^{a})_e`, each age with its own opening
value (ages past the cap share the chain's state but not the opening). :math:`\Lambda` moves on
a grid of spacing :math:`\Delta`, centred on its exact mean drift m (the mean increment under the
stationary law), each new value split between its two grid points in proportion to the distance:
the split keeps the mean of :math:`\Lambda` exactly and adds at most :math:`\Delta^2/4` of
variance per step, against the statistic's own variance rate :math:`\sigma^2` per step; the
grid's spacing is a fixed fraction of :math:`\sigma`, so the
relative distortion does not grow with n. Where the attack-free law cannot produce a step's
outcome the increment is :math:`+\infty`: the window alarms (the support check); where only the
alternative cannot, :math:`-\infty` (kept apart, still watched for a later :math:`+\infty`).

The band of the grid holds :math:`m n \pm 8\sqrt{n\sigma^2}` (never more than the n steps can
reach), with :math:`\sigma^2` from the Poisson equation of the (a, e) chain; the mass that leaves
it is reported (``above``, ``below``; above the band it counts as a large value). The law is read
back through hat kernels (:meth:`fakeack.LikelihoodRatioLaw.tail`), the inverse of the split rounding,
which removes the first-order bias of counting whole grid cells; what remains shrinks between
first and second order in the spacing (the law of :math:`\Lambda_n` is itself a lattice-like
discrete law), so the error is stated by recomputing on a grid twice as coarse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from .._internal.types import FloatArray
from .cusum import CusumIncrements
from .process import FlagProcess, _poisson

__all__ = [
    "LikelihoodRatioLaw",
    "MAX_LAW_WORK",
    "law_of",
    "opening",
]

#: Largest (transitions x grid points x steps) of one law, about a minute on one core.
MAX_LAW_WORK = 6 * 10**10
#: Standard deviations of the final law on each side of its mean held by the grid's band.
BAND_SDS = 8.0


@dataclass(frozen=True)
class LikelihoodRatioLaw:
    r"""The law of :math:`\Lambda_n` in a stationary window (see :func:`fakeack.likelihood_ratio_law`)."""

    values: FloatArray = field(repr=False)
    r"""Grid values of :math:`\Lambda_n`, increasing, spacing ``step``."""
    probability: FloatArray = field(repr=False)
    """``probability[i]`` = P(the statistic on the grid is ``values[i]``)."""
    alarm: float
    r"""P(:math:`\Lambda_n = +\infty`): a step's outcome impossible without attack (the support check)."""
    minus_infinity: float
    r"""P(:math:`\Lambda_n = -\infty`): an outcome impossible under the alternative, no :math:`+\infty`."""
    above: float
    """Mass that left the band above it (counted as a value above every grid point)."""
    below: float
    """Mass that left the band below it."""
    mean: float
    r"""The exact mean of the finite part per step times n: :math:`E\Lambda_n` when no step is infinite."""
    variance_rate: float
    r""":math:`\lim_n \mathrm{Var}\,\Lambda_n / n` (the Poisson equation), which sets the grid."""
    step: float
    r"""The grid's spacing :math:`\Delta`."""
    n_steps: int

    def tail(self, critical: float) -> float:
        r""":math:`P(\Lambda_n \ge` ``critical``), with the infinite values and the mass above
        the band.

        Each grid point's mass is read as spread over the hat :math:`[v - \Delta, v + \Delta]`,
        the inverse of the split rounding (a point split between two grid points and read back
        this way keeps its mean): the tail is then continuous in the critical value and free of
        the first-order bias of counting whole grid cells.
        """
        c = float(critical)
        if c == math.inf:
            return self.alarm
        t = (self.values - c) / self.step
        inside = np.where(
            t >= 0.0, 1.0 - 0.5 * (1.0 - np.minimum(t, 1.0)) ** 2, 0.5 * (1.0 + np.maximum(t, -1.0)) ** 2
        )
        share = np.where(t >= 1.0, 1.0, np.where(t <= -1.0, 0.0, inside))
        return min(1.0, float(self.probability @ share) + self.above + self.alarm)

    def quantile(self, alpha: float) -> float:
        r"""The value c with :math:`P(\Lambda_n \ge c) = ` ``alpha`` on the law read as in
        :meth:`tail` (continuous, decreasing in c where the law has mass)."""
        base = self.above + self.alarm
        if base >= alpha:
            return math.inf
        lo, hi = float(self.values[0]) - self.step, float(self.values[-1]) + self.step
        for _ in range(200):  # bisection to a relative 1e-12 of a grid step
            mid = 0.5 * (lo + hi)
            if self.tail(mid) > alpha:
                lo = mid
            else:
                hi = mid
            if hi - lo < 1e-12 * self.step:
                break
        return hi


def opening(inc: CusumIncrements, y: npt.ArrayLike) -> FloatArray:
    r"""The log-likelihood ratio :math:`\log(P_a(y_0)/P_0(y_0))` of the gap :math:`y_0` already
    running at the window's start, under the stationary age laws :math:`P(y_0 = y) = S(y)/m` of
    the two renewal laws (S the survival, m the mean gap):
    :math:`\sum_{j<y} \text{quiet}_j + \log(m_0/m_a)`, the quiet table's last entry holding on."""
    q = inc.quiet
    Y = q.size
    m0, ma = _mean_gap(inc.h0), _mean_gap(inc.ha)
    if ma == math.inf:
        raise ValueError("alternative: a law that may never deliver a flag-ACK has no stationary gap")
    base = math.log(m0) - math.log(ma) if ma > 0.0 else -math.inf
    with np.errstate(invalid="ignore"):
        head = np.concatenate(([0.0], np.cumsum(q[:-1])))  # sum over j < y, y = 1..Y
    pos = np.concatenate(([False], np.cumsum(q[:-1] == math.inf) > 0))
    neg = np.concatenate(([False], np.cumsum(q[:-1] == -math.inf) > 0))
    head = np.where(pos, math.inf, np.where(neg, -math.inf, head))
    yy = np.asarray(y, dtype=np.int64)
    capped = np.minimum(yy, Y)
    out = head[capped - 1]
    beyond = yy > Y
    if beyond.any() and q[-1] != 0.0:  # the last entry holds on: y - Y more silent steps
        add = np.zeros(out.shape)
        add[beyond] = (yy[beyond] - Y) * q[-1]
        with np.errstate(invalid="ignore"):  # +inf and -inf meet only where out stays as it is
            out = np.where(beyond & np.isfinite(out), out + add, out)
    return np.asarray(out + base, dtype=np.float64)


def _mean_gap(h: FloatArray) -> float:
    """The mean gap of a renewal law from its hazards (the last one holding on)."""
    survival = np.concatenate(([1.0], np.cumprod(1.0 - h[:-1])))
    tail = survival[-1]
    if tail <= 0.0:
        return float(survival[:-1].sum() + tail)
    if h[-1] <= 0.0:
        return math.inf
    return float(survival[:-1].sum() + tail / h[-1])


def _stationary_ages(process: FlagProcess, limit: int = 100_000) -> FloatArray:
    """P(age a, state e), a = 0, 1, ... (age = y0 - 1): (pi D1 D0^a)_e until less than 1e-16 of
    the mass is left; the rest (a law that rarely delivers) at the last age."""
    D0t = process.D0.T.tocsr()
    rows = []
    row = np.asarray(process.stationary @ process.D1).ravel()
    left = 1.0
    for _ in range(limit):
        rows.append(row)
        left -= float(row.sum())
        if left <= 1e-16:
            break
        row = D0t @ row
    f = np.array(rows)
    f[-1] += np.clip(process.stationary - f.sum(axis=0), 0.0, None)
    return np.asarray(f, dtype=np.float64)


@dataclass(frozen=True)
class _Chain:
    """The (age, state) chain on the stationary support: its transitions and their increments,
    and the window's start: (state, opening value, mass)."""

    n_states: int
    src: np.ndarray
    dst: np.ndarray
    weight: FloatArray
    inc: FloatArray
    start_state: np.ndarray
    start_value: FloatArray
    start_mass: FloatArray

    def stationary(self) -> FloatArray:
        return np.asarray(np.bincount(self.start_state, self.start_mass, minlength=self.n_states))


def _chain(process: FlagProcess, inc: CusumIncrements) -> _Chain:
    Y, n_e = inc.length, process.n_states
    full = _stationary_ages(process)
    f = np.zeros((Y, n_e))
    f[: min(Y - 1, full.shape[0])] = full[: Y - 1]
    f[Y - 1] = full[Y - 1 :].sum(axis=0)
    edges = []
    for D, table, flag in ((process.D1, inc.flag, True), (process.D0, inc.quiet, False)):
        coo = D.tocoo()
        ages = np.arange(Y)
        src = (ages[:, None] * n_e + coo.row[None, :]).ravel()
        nxt = np.zeros(Y, dtype=np.int64) if flag else np.minimum(ages + 1, Y - 1)
        dst = (nxt[:, None] * n_e + coo.col[None, :]).ravel()
        w = np.broadcast_to(coo.data[None, :], (Y, coo.nnz)).ravel()
        x = np.broadcast_to(table[:, None], (Y, coo.nnz)).ravel()
        keep = w > 0.0
        edges.append((src[keep], dst[keep], w[keep], x[keep]))
    src, dst, w, x = (np.concatenate([p[i] for p in edges]) for i in range(4))
    # The states the window can visit: those of the start law (mass underflowing far out in the
    # age may leave some out) and all they lead to.
    live = f.ravel() > 0.0
    while True:
        reached = np.zeros_like(live)
        reached[dst[live[src]]] = True
        if not (reached & ~live).any():
            break
        live |= reached
    index = np.full(Y * n_e, -1)
    index[live] = np.arange(int(live.sum()))
    keep = live[src]
    src, dst, w, x = index[src[keep]], index[dst[keep]], w[keep], x[keep]
    a, e = np.nonzero(full > 0.0)
    state = index[np.minimum(a, Y - 1) * n_e + e]
    return _Chain(int(live.sum()), src, dst, w, x, state, opening(inc, a + 1), full[a, e])


def _moments(chain: _Chain) -> tuple[float, float]:
    """The mean increment per step and the variance rate of the finite increments (an infinite
    one counts as 0 here: it ends the statistic's finite life, and only sizes the grid)."""
    S = chain.n_states
    r = np.where(np.isfinite(chain.inc), chain.inc, 0.0)
    pi = chain.stationary()
    flow = pi[chain.src] * chain.weight
    m = float(flow @ r)
    P = sp.csr_array((chain.weight, (chain.src, chain.dst)), shape=(S, S))
    rbar = np.bincount(chain.src, weights=chain.weight * r, minlength=S)
    g = _poisson(P, np.asarray(rbar - m, dtype=np.float64), pi)
    var = float(flow @ ((r - m) ** 2 + 2.0 * (r - m) * g[chain.dst]))
    return m, max(var, 0.0)


def law_of(process: FlagProcess, inc: CusumIncrements, n: int, resolution: float) -> LikelihoodRatioLaw:
    r"""The grid law of the window's statistic; ``resolution`` grid steps per standard deviation
    of one step's increment (:math:`\Delta = \sigma`/resolution)."""
    chain = _chain(process, inc)
    m, var = _moments(chain)
    finite = np.isfinite(chain.inc)
    spread = float(np.abs(chain.inc[finite] - m).max()) if finite.any() else 0.0
    x0, p0 = chain.start_value, chain.start_mass
    ok0 = np.isfinite(x0)
    c0 = float(p0[ok0] @ x0[ok0] / max(p0[ok0].sum(), 1e-300)) if ok0.any() else 0.0
    var0 = float(p0[ok0] @ (x0[ok0] - c0) ** 2) if ok0.any() else 0.0
    reach0 = float(np.abs(x0[ok0] - c0).max()) if ok0.any() else 0.0
    sd = math.sqrt(var)
    if sd <= 1e-12 * max(spread, 1.0):  # a statistic without spread: any grid carries it exactly
        delta = max(spread, 1.0)
    else:
        delta = sd / resolution
    half = min(reach0 + n * spread, BAND_SDS * math.sqrt(n * var + var0) + 4.0 * spread) + 2.0 * delta
    J = int(math.ceil(half / delta))
    G, S = 2 * J + 1, chain.n_states
    T = int(chain.src.size)
    work = 2 * T * G * n
    if work > MAX_LAW_WORK:
        raise ValueError(
            f"n_steps = {n}: the law of the likelihood ratio needs about {work:.2g} operations "
            f"({T} transitions x {G} grid points x {n} steps), more than {MAX_LAW_WORK:.0e}; lower "
            "the resolution or the window"
        )
    M = _step_matrix(chain, m, delta, G)
    v: FloatArray = _start_vector(chain, c0, delta, G, J)
    for _ in range(n):
        v = np.asarray(M @ v, dtype=np.float64)
    grid = np.asarray(v[: S * G].reshape(S, G).sum(axis=0), dtype=np.float64)
    top, bottom, alarm = (float(v[S * G + S + k]) for k in range(3))
    values = np.asarray(c0 + n * m + (np.arange(G) - J) * delta, dtype=np.float64)
    return LikelihoodRatioLaw(
        values,
        np.asarray(np.clip(grid, 0.0, None), dtype=np.float64),
        min(max(alarm, 0.0), 1.0),
        float(max(v[S * G : S * G + S].sum(), 0.0)),
        max(top, 0.0),
        max(bottom, 0.0),
        c0 + n * m,
        var,
        delta,
        n,
    )


def _start_vector(chain: _Chain, c0: float, delta: float, G: int, J: int) -> FloatArray:
    """The window's first law on [(state, grid point) ..., (state at -inf) ..., above, below,
    alarm], the opening value split between its two grid points."""
    S = chain.n_states
    v = np.zeros(S * G + S + 3)
    s, x, p = chain.start_state, chain.start_value, chain.start_mass
    np.add.at(v, S * G + S + 2, p[x == math.inf].sum())
    np.add.at(v, S * G + s[x == -math.inf], p[x == -math.inf])
    ok = np.isfinite(x)
    pos = (x[ok] - c0) / delta + J
    lo = np.floor(pos)
    frac = pos - lo
    for k, share in ((lo, 1.0 - frac), (lo + 1.0, frac)):
        kk = k.astype(np.int64)
        where = np.where(
            kk >= G, S * G + S, np.where(kk < 0, S * G + S + 1, s[ok] * G + np.clip(kk, 0, G - 1))
        )
        np.add.at(v, where, p[ok] * share)
    return np.asarray(v, dtype=np.float64)


def _step_matrix(chain: _Chain, m: float, delta: float, G: int) -> sp.csr_array:
    """One step over the vector [(state, grid point) ..., (state at -inf) ..., above, below,
    alarm]: each finite increment moves the grid point by (inc - m)/delta, split between the two
    neighbours; leaving the band lands in `above` or `below`; +inf lands in `alarm`."""
    S = chain.n_states
    minus, above, below, alarm = S * G, S * G + S, S * G + S + 1, S * G + S + 2
    rows, cols, vals = [], [], []
    j = np.arange(G)
    for s, d, w, x in zip(chain.src, chain.dst, chain.weight, chain.inc, strict=True):
        if x == math.inf:  # from any grid point or -inf: an alarm
            rows.append(np.full(G + 1, alarm))
            cols.append(np.append(s * G + j, minus + s))
            vals.append(np.full(G + 1, w))
            continue
        rows.append(np.array([minus + d]))  # -inf stays -inf under a finite or -inf increment
        cols.append(np.array([minus + s]))
        vals.append(np.array([w]))
        if x == -math.inf:
            rows.append(np.full(G, minus + d))
            cols.append(s * G + j)
            vals.append(np.full(G, w))
            continue
        shift = (x - m) / delta
        lo = math.floor(shift + 1e-9)
        frac = min(max(shift - lo, 0.0), 1.0)
        for k, share in ((lo, 1.0 - frac), (lo + 1, frac)):
            if share <= 0.0:
                continue
            t = j + k
            r = np.where(t >= G, above, np.where(t < 0, below, d * G + np.clip(t, 0, G - 1)))
            rows.append(r)
            cols.append(s * G + j)
            vals.append(np.full(G, w * share))
    for k in (above, below, alarm):  # absorbing
        rows.append(np.array([k]))
        cols.append(np.array([k]))
        vals.append(np.array([1.0]))
    N = S * G + S + 3
    M = sp.coo_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N))
    return M.tocsr()
