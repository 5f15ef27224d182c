r"""The filter CUSUM: Page's CUSUM of the exact log-likelihood ratio of the whole flag-ACK stream
(``CusumTest(..., likelihood="filter")``), and its run lengths by simulation.

Under a law L with flag process :math:`(D_0, D_1)` (:func:`fakeack.flag_process`), let
:math:`\pi_k` be the forward filter: the law of L's automaton state given the bits seen before
step k. The predictive probability of a flag-ACK at step k is :math:`p_L(k) = \pi_k D_1\mathbf 1`,
and after the bit :math:`x_k`,

.. math:: \pi_{k+1} = \pi_k D_{x_k} / (\pi_k D_{x_k}\mathbf 1).

The log-likelihood of the stream is :math:`\sum_k \log p_L(k)` over the steps with a flag-ACK
plus :math:`\sum_k \log(1 - p_L(k))` over the silent ones, exactly, on any channel; the CUSUM adds
:math:`\log(p_a/p_0)` on a flag-ACK and :math:`\log((1 - p_a)/(1 - p_0))` on silence, with
:math:`p_0` the attack-free filter's and :math:`p_a` the alternative's (a gap pmf alternative:
its hazard at the gap y). A flag-ACK with :math:`p_0 = 0`, or silence with :math:`p_0 = 1`, sets
W to :math:`+\infty` (the support check). An outcome the alternative's law cannot produce gives
:math:`-\infty` (W restarts at 0) and restarts the alternative's filter from its long-run law given
that outcome, :math:`\pi_a D_x / (\pi_a D_x \mathbf 1)`.

**Start.** The statistic starts as the renewal CUSUM does, just after a delivered flag-ACK with
W = 0: each filter starts from the law of its automaton just after a delivery in the long run,
the Palm law :math:`\alpha \propto \pi D_1` (the law from which the renewal statistic's hazards
start). On the paper's i.i.d. channel a delivery fixes the automaton's state, the filters restart
at every flag-ACK, and the statistic equals the renewal one.

**Run lengths.** The filter is a continuous belief, so no finite chain holds the statistic;
its mean run length is estimated by simulating the flag process of the true automaton (the
attack's, from the paper's initial condition: high power, memory restarted, the attacker at its
start, as :func:`fakeack.cusum_run_length`'s renewal start) beside the two filters, a batch of
runs advancing together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.sparse as sp

from .._internal.types import FloatArray
from .._internal.validate import as_int
from ..model.channels import Channel
from ..model.schedules import OnlineDesign
from .process import FlagProcess, flag_process

__all__ = [
    "LIKELIHOODS",
    "SimulatedRunLength",
]

#: The CUSUM's likelihoods: the renewal (Palm gap hazards) and the forward filter's.
LIKELIHOODS = ("renewal", "filter")
#: Automata up to this many states are filtered with dense products (faster than sparse there).
MAX_DENSE = 256


def _pmf_hazards(pmf: FloatArray) -> FloatArray:
    """Hazards of a finite gap pmf (pmf[g - 1] = P(G = g)); 1 at the last gap of the support."""
    survival = 1.0 - np.concatenate(([0.0], np.cumsum(pmf)[:-1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(survival > 1e-15, pmf / np.maximum(survival, 1e-300), 1.0)
    last = int(np.flatnonzero(pmf)[-1])
    h = np.clip(h[: last + 1], 0.0, 1.0)
    h[last] = 1.0
    return np.asarray(h)


def _log_ratio(num: FloatArray, den: FloatArray) -> FloatArray:
    """log(num/den) of an alternative's and the attack-free probability of one step's outcome:
    +inf where the attack-free law cannot produce it (the support check, whatever the
    alternative says), -inf where only the alternative cannot."""
    out = np.full(num.shape, math.inf)
    possible = den > 0
    out[possible & (num <= 0)] = -math.inf
    both = possible & (num > 0)
    out[both] = np.log(num[both]) - np.log(den[both])
    return out


def _normalised(v: FloatArray, fallback: FloatArray) -> FloatArray:
    total = float(v.sum())
    return np.asarray(v / total) if total > 0.0 else fallback


class _Filter:
    """Forward filters of one flag process, a batch at once: column r of F is run r's law."""

    def __init__(self, process: FlagProcess) -> None:
        n = process.n_states
        M = sp.vstack([process.D0.T, process.D1.T]).tocsr()
        self.n = n
        self.M: Any = M.toarray() if n <= MAX_DENSE else M
        pi = process.stationary
        # The long-run law given one step's outcome: the restart after an impossible outcome.
        self.after = (_normalised(pi @ process.D0, pi), _normalised(pi @ process.D1, pi))
        self.start = self.after[1]  # the Palm law just after a delivery

    def begin(self, runs: int) -> FloatArray:
        return np.repeat(self.start[:, None], runs, axis=1)

    def predict(self, F: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(P(silence), P(flag), the stacked products F' D0 and F' D1) of each run."""
        AB = np.asarray(self.M @ F)
        return AB[: self.n].sum(axis=0), AB[self.n :].sum(axis=0), AB

    def update(self, AB: FloatArray, x: Any) -> FloatArray:
        new = np.where(x, AB[self.n :], AB[: self.n])
        mass = new.sum(axis=0)
        dead = mass <= 0.0
        new /= np.where(dead, 1.0, mass)
        if dead.any():
            new[:, dead] = np.where(x[dead], self.after[1][:, None], self.after[0][:, None])
        return np.asarray(new)


class _Hazards:
    """A gap pmf alternative: its hazard at the gap y; past its support nothing is possible."""

    def __init__(self, pmf: FloatArray) -> None:
        self.h = _pmf_hazards(pmf)

    def probabilities(self, y: Any) -> tuple[FloatArray, FloatArray]:
        inside = y <= self.h.size
        flag = np.where(inside, self.h[np.minimum(y, self.h.size) - 1], 0.0)
        return np.where(inside, 1.0 - flag, 0.0), flag


@lru_cache(maxsize=32)
def _models(channel: Channel, design: OnlineDesign, alternative: Any) -> tuple[_Filter, _Filter | _Hazards]:
    null = _Filter(flag_process(channel, design))
    if isinstance(alternative, tuple):  # a pmf, hashed as a tuple
        return null, _Hazards(np.asarray(alternative, dtype=float))
    return null, _Filter(flag_process(channel, design, alternative))


class _Statistic:
    """The filter CUSUM of a batch of runs, one step at a time."""

    def __init__(self, channel: Channel, design: OnlineDesign, alternative: Any, runs: int) -> None:
        self.null, self.alt = _models(channel, design, alternative)
        self.F0 = self.null.begin(runs)
        self.Fa = self.alt.begin(runs) if isinstance(self.alt, _Filter) else None
        self.y = np.ones(runs, dtype=np.int64)
        self.W = np.zeros(runs)

    def step(self, x: Any) -> FloatArray:
        q0, p0, AB0 = self.null.predict(self.F0)
        if self.Fa is not None:
            assert isinstance(self.alt, _Filter)
            qa, pa, ABa = self.alt.predict(self.Fa)
            self.Fa = self.alt.update(ABa, x)
        else:
            assert isinstance(self.alt, _Hazards)
            qa, pa = self.alt.probabilities(self.y)
        num, den = np.where(x, pa, qa), np.where(x, p0, q0)
        with np.errstate(divide="ignore", invalid="ignore"):
            # log 0 = -inf: an outcome only the alternative cannot produce gives -inf; one the
            # attack-free law cannot produce gives +inf whatever the alternative (the support
            # check); inf - inf below: W is already +inf and stays there.
            inc = np.where(den > 0.0, np.log(num) - np.log(den), math.inf)
            W = np.maximum(0.0, self.W + inc)
        self.W = np.where(self.W == math.inf, math.inf, W)
        self.F0 = self.null.update(AB0, x)
        self.y = np.where(x, 1, self.y + 1)
        return self.W

    def keep(self, which: Any) -> None:
        """Drop the runs not in ``which`` (a boolean mask)."""
        self.F0 = self.F0[:, which]
        if self.Fa is not None:
            self.Fa = self.Fa[:, which]
        self.y, self.W = self.y[which], self.W[which]


def _filter_statistic(channel: Channel, design: OnlineDesign, alternative: Any, delivered: Any) -> FloatArray:
    """The filter CUSUM's path over a batch of bit sequences (runs x steps, bool); see
    :meth:`fakeack.CusumTest.statistic`, which validates the arguments."""
    runs, steps = delivered.shape
    stat = _Statistic(channel, design, alternative, runs)
    out = np.empty((runs, steps))
    for k in range(steps):
        out[:, k] = stat.step(delivered[:, k])
    return out


class _Sampler:
    """Draws the true automaton's moves: row e of [D0 | D1] as one discrete law per state."""

    def __init__(self, process: FlagProcess) -> None:
        B = sp.hstack([process.D0, process.D1]).tocsr()
        B.sort_indices()
        self.n = process.n_states
        self.indptr, self.indices = B.indptr, B.indices
        self.cum = np.cumsum(B.data)
        self.base = np.concatenate(([0.0], self.cum))[B.indptr[:-1]]
        self.mass = np.asarray(B.sum(axis=1)).ravel()
        self.initial = process.initial

    def move(self, state: Any, u: FloatArray) -> tuple[Any, Any]:
        target = self.base[state] + u * self.mass[state]
        pos = np.searchsorted(self.cum, target, side="right")
        pos = np.clip(pos, self.indptr[state], self.indptr[state + 1] - 1)
        col = self.indices[pos]
        return col % self.n, col >= self.n


def _simulate_passage_times(
    true: FlagProcess,
    channel: Channel,
    design: OnlineDesign,
    alternative: Any,
    levels: FloatArray,
    runs: int,
    seed: int,
    max_steps: int,
) -> Any:
    """The first step at which each run's filter CUSUM reaches each level (runs x levels, int):
    the run lengths of the filter CUSUMs of those thresholds, on the same draws. A run stops
    once it reaches the highest level.

    Raises
    ------
    ValueError
        Naming ``max_steps`` when some run has not reached the highest level by then.
    """
    rng = np.random.default_rng(seed)
    sampler = _Sampler(true)
    stat = _Statistic(channel, design, alternative, runs)
    state = rng.choice(true.n_states, size=runs, p=true.initial)
    ids = np.arange(runs)
    passed = np.zeros(runs, dtype=np.int64)
    times = np.zeros((runs, levels.size), dtype=np.int64)
    top = levels.size
    for k in range(1, max_steps + 1):
        state, x = sampler.move(state, rng.random(ids.size))
        W = stat.step(x)
        reached = np.searchsorted(levels, W, side="right")
        for i in np.flatnonzero(reached > passed):
            times[ids[i], passed[i] : reached[i]] = k
        passed = np.maximum(passed, reached)
        done = passed == top
        if done.any():
            alive = ~done
            ids, passed, state = ids[alive], passed[alive], state[alive]
            stat.keep(alive)
            if ids.size == 0:
                return times
    raise ValueError(
        f"max_steps: {ids.size} of {runs} runs of the filter CUSUM had not alarmed after {max_steps} "
        "steps; raise max_steps (or the mean run length may be infinite)"
    )


@dataclass(frozen=True)
class SimulatedRunLength:
    """The mean run length of a filter CUSUM, estimated by simulation (see
    :func:`fakeack.cusum_run_length`)."""

    mean: float
    """The mean number of steps to the alarm over the runs (the alarm's step included)."""
    error: float
    """The standard error of ``mean``: the runs' standard deviation over the square root of
    their number (a 95% interval is about ``mean`` ± 2 ``error``)."""
    runs: int
    """Independent runs simulated."""
    seed: int
    """The seed of the draws (the result depends on it only)."""
    start: str
    """``"renewal"``: W = 0 and the filters at their Palm laws just after a delivered flag-ACK."""


def _check_runs(runs: object, seed: object, max_steps: object) -> tuple[int, int, int]:
    """The simulation's arguments, checked (a seed is required: results are reproducible)."""
    n = as_int("runs", runs, minimum=2)
    if seed is None:
        raise TypeError("seed: the simulated run length of a filter CUSUM needs a seed (an int >= 0)")
    s = as_int("seed", seed, minimum=0)
    if s >= 2**64:
        raise ValueError(f"seed must be below 2**64, got {s}")
    return n, s, as_int("max_steps", max_steps, minimum=1)


def _summarise(times: Any, runs: int, seed: int) -> SimulatedRunLength:
    """The mean of a column of run lengths and its standard error."""
    t = np.asarray(times, dtype=float)
    return SimulatedRunLength(
        float(t.mean()), float(t.std(ddof=1) / math.sqrt(t.size)), runs, seed, "renewal"
    )


def _passage_threshold(
    channel: Channel,
    design: OnlineDesign,
    alternative: Any,
    arl0: float,
    runs: int,
    seed: int,
    max_steps: int,
) -> float:
    r"""The filter CUSUM threshold whose simulated ARL0 is ``arl0``: the mean first passage of W
    over a grid of 400 levels from one simulation of ``runs`` runs (each followed until W reaches
    the top level), interpolated linearly in log ARL0 between the two levels that bracket
    ``arl0``.

    The top level is located first by a pilot of a tenth of the runs (raised by 0.5 from 1 until
    the pilot's mean passage there exceeds 1.3 ``arl0``), then raised by 0.5 until the full
    simulation's does.
    """
    null = flag_process(channel, design)

    def passages(top: float, n: int) -> tuple[FloatArray, FloatArray]:
        levels = np.linspace(top / 400, top, 400)
        times = _simulate_passage_times(null, channel, design, alternative, levels, n, seed, max_steps)
        return levels, np.asarray(times.mean(axis=0))

    top, pilot = 1.0, max(runs // 10, 20)
    while passages(top, pilot)[1][-1] < 1.3 * arl0:
        top += 0.5
        if top > 200.0:
            raise ValueError(f"arl0 = {arl0}: no threshold up to 200 reaches it")
    for _ in range(20):
        levels, mean = passages(top, runs)
        if mean[0] > arl0:
            raise ValueError(f"arl0 = {arl0}: even the threshold {levels[0]:.3g} gives a longer mean run")
        if mean[-1] >= arl0:
            j = int(np.searchsorted(mean, arl0))  # mean[j - 1] < arl0 <= mean[j]
            lo, hi = math.log(mean[j - 1]), math.log(mean[j])
            t = 1.0 if hi == lo else (math.log(arl0) - lo) / (hi - lo)
            return float(levels[j - 1] + t * (levels[j] - levels[j - 1]))
        top += 0.5
    raise ValueError(f"arl0 = {arl0}: no threshold up to {top:.3g} reaches it")
