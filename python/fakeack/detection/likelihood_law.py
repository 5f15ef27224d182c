r"""The exact law of a window's log-likelihood ratio of the flag-ACK stream (:func:`likelihood_ratio_law`).

In a window of n steps the sensor sums the per-step increments of :class:`fakeack.CusumTest`
(:math:`\log(h_a(y)/h_0(y))` on a step with a flag-ACK at gap y, :math:`\log((1-h_a(y))/(1-h_0(y)))`
on a silent one; the last entry of the tables holds for longer gaps), without the CUSUM's
reflection at 0:

.. math:: \Lambda_n = \sum_{k=1}^n \ell_k .

The increment of a step is a function of the gap y before it and of whether a flag-ACK came, and
the deliveries are the Markov arrival process :math:`K = D_0 + D_1` of the exact engine's
automaton (:func:`fakeack.flag_process`), so (automaton state e, age a = y - 1 capped at Y - 1,
:math:`\Lambda`) is a Markov chain. The window starts in the long-run regime: (a, e) has the
stationary law :math:`P(a, e) = (\pi D_1 D_0^{a})_e` for a < Y - 1, the rest of :math:`\pi` at
the cap. :math:`\Lambda` moves on a grid of spacing :math:`\Delta`, centred on its exact mean
drift m (the mean increment under the stationary law), each new value split between its two grid
points in proportion to the distance: the split keeps the mean of :math:`\Lambda` exactly and adds
at most :math:`\Delta^2/4` of variance per step, against the statistic's own variance rate
:math:`\sigma^2` per step; the grid's spacing is a fixed fraction of :math:`\sigma`, so the
relative distortion does not grow with n. Where the attack-free law cannot produce a step's
outcome the increment is :math:`+\infty`: the window alarms (the support check); where only the
alternative cannot, :math:`-\infty` (kept apart, still watched for a later :math:`+\infty`).

The band of the grid holds :math:`m n \pm 8\sqrt{n\sigma^2}` (never more than the n steps can
reach), with :math:`\sigma^2` from the Poisson equation of the (a, e) chain; the mass that leaves
it is reported (``lost``; above the band it counts as a large value).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .._internal.types import FloatArray
from .cusum import CusumIncrements
from .process import FlagProcess, _poisson

__all__ = [
    "LikelihoodRatioLaw",
    "MAX_LAW_WORK",
    "law_of",
]

#: Largest (transitions x grid points x steps) of one law, about half a minute on one core.
MAX_LAW_WORK = 2 * 10**10
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
        r""":math:`P(\Lambda_n \ge` ``critical``) on the grid, with the infinite values and the mass
        above the band."""
        c = float(critical)
        if c == math.inf:
            return self.alarm
        # A relative 1e-9 of a grid step absorbs the rounding of a grid value equal to c.
        first = int(np.searchsorted(self.values, c - 1e-9 * self.step, side="left"))
        return float(min(1.0, self.probability[first:].sum() + self.above + self.alarm))


def _stationary_ages(process: FlagProcess, Y: int) -> FloatArray:
    """P(age a, state e), a = 0..Y-1 (age capped at Y - 1): (pi D1 D0^a)_e below the cap, the
    rest of pi at it."""
    D0t = process.D0.T.tocsr()
    f = np.zeros((Y, process.n_states))
    row = np.asarray(process.stationary @ process.D1).ravel()
    for a in range(Y - 1):
        f[a] = row
        row = D0t @ row
    f[Y - 1] = np.clip(process.stationary - f[: Y - 1].sum(axis=0), 0.0, None)
    return f


@dataclass(frozen=True)
class _Chain:
    """The (age, state) chain on the stationary support: its transitions and their increments."""

    start: FloatArray
    src: np.ndarray
    dst: np.ndarray
    weight: FloatArray
    inc: FloatArray


def _chain(process: FlagProcess, inc: CusumIncrements) -> _Chain:
    Y, n_e = inc.length, process.n_states
    f = _stationary_ages(process, Y)
    live = f.ravel() > 0.0
    index = np.full(Y * n_e, -1)
    index[live] = np.arange(int(live.sum()))
    parts = []
    for D, table, flag in ((process.D1, inc.flag, True), (process.D0, inc.quiet, False)):
        coo = D.tocoo()
        ages = np.arange(Y)
        src = (ages[:, None] * n_e + coo.row[None, :]).ravel()
        nxt = np.zeros(Y, dtype=np.int64) if flag else np.minimum(ages + 1, Y - 1)
        dst = (nxt[:, None] * n_e + coo.col[None, :]).ravel()
        w = np.broadcast_to(coo.data[None, :], (Y, coo.nnz)).ravel()
        x = np.broadcast_to(table[:, None], (Y, coo.nnz)).ravel()
        keep = live[src] & (w > 0.0)
        parts.append((index[src[keep]], index[dst[keep]], w[keep], x[keep]))
    src, dst, w, x = (np.concatenate([p[i] for p in parts]) for i in range(4))
    return _Chain(f.ravel()[live], src, dst, w, x)


def _moments(chain: _Chain) -> tuple[float, float]:
    """The mean increment per step and the variance rate of the finite increments (an infinite
    one counts as 0 here: it ends the statistic's finite life, and only sizes the grid)."""
    S = chain.start.size
    r = np.where(np.isfinite(chain.inc), chain.inc, 0.0)
    pi = chain.start
    flow = pi[chain.src] * chain.weight
    m = float(flow @ r)
    P = sp.csr_array((chain.weight, (chain.src, chain.dst)), shape=(S, S))
    rbar = np.bincount(chain.src, weights=chain.weight * r, minlength=S)
    g = _poisson(P, np.asarray(rbar - m, dtype=np.float64), pi)
    var = float(flow @ ((r - m) ** 2 + 2.0 * (r - m) * g[chain.dst]))
    return m, max(var, 0.0)


def law_of(process: FlagProcess, inc: CusumIncrements, n: int, resolution: float) -> LikelihoodRatioLaw:
    """The grid law of the window's statistic; ``resolution`` grid steps per standard deviation
    of one step's increment (:math:`\\Delta = \\sigma`/resolution)."""
    chain = _chain(process, inc)
    m, var = _moments(chain)
    finite = np.isfinite(chain.inc)
    spread = float(np.abs(chain.inc[finite] - m).max()) if finite.any() else 0.0
    sd = math.sqrt(var)
    if sd <= 1e-12 * max(spread, 1.0):  # a statistic without spread: any grid carries it exactly
        delta = max(spread, 1.0)
    else:
        delta = sd / resolution
    half = min(n * spread, BAND_SDS * math.sqrt(n * var) + 4.0 * spread) + 2.0 * delta
    J = int(math.ceil(half / delta))
    G, S = 2 * J + 1, chain.start.size
    T = int(chain.src.size)
    work = 2 * T * G * n
    if work > MAX_LAW_WORK:
        raise ValueError(
            f"n_steps = {n}: the law of the likelihood ratio needs about {work:.2g} operations "
            f"({T} transitions x {G} grid points x {n} steps), more than {MAX_LAW_WORK:.0e}; lower "
            "the resolution or the window"
        )
    M = _step_matrix(chain, m, delta, G)
    v: FloatArray = np.zeros(S * G + S + 3)
    v[np.arange(S) * G + J] = chain.start
    for _ in range(n):
        v = np.asarray(M @ v, dtype=np.float64)
    grid: FloatArray = np.asarray(v[: S * G].reshape(S, G).sum(axis=0), dtype=np.float64)
    top, bottom, alarm = (float(v[S * G + S + k]) for k in range(3))
    values = np.asarray(n * m + (np.arange(G) - J) * delta, dtype=np.float64)
    return LikelihoodRatioLaw(
        values,
        np.asarray(np.clip(grid, 0.0, None), dtype=np.float64),
        min(max(alarm, 0.0), 1.0),
        float(max(v[S * G : S * G + S].sum(), 0.0)),
        max(top, 0.0),
        max(bottom, 0.0),
        n * m,
        var,
        delta,
        n,
    )


def _step_matrix(chain: _Chain, m: float, delta: float, G: int) -> sp.csr_array:
    """One step over the vector [(state, grid point) ..., (state at -inf) ..., above, below,
    alarm]: each finite increment moves the grid point by (inc - m)/delta, split between the two
    neighbours; leaving the band lands in `above` or `below`; +inf lands in `alarm`."""
    S = chain.start.size
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
