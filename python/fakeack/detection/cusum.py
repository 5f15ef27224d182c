r"""The CUSUM of the flag-ACK stream: a sequential test for the onset of an attack.

The sensor sees one bit per step, whether a flag-ACK reached it. Let :math:`y` be the steps since
the last one (:math:`y = 1` on the step after it) and :math:`h(y) = P(G = y \mid G \ge y)` the
hazard of the gap law G between flag-ACKs. Under a law with i.i.d. gaps the log-likelihood of
the stream is the sum over steps of :math:`\log h(y)` on a step with a flag-ACK and
:math:`\log(1 - h(y))` on a silent one, so the CUSUM of the log-likelihood ratio between an
alternative :math:`h_a` and the attack-free :math:`h_0` is

.. math:: W_k = \max\bigl(0,\; W_{k-1} + \ell_k\bigr), \qquad
   \ell_k = \begin{cases} \log\bigl(h_a(y)/h_0(y)\bigr) & \text{flag-ACK at step } k,\\
   \log\bigl((1 - h_a(y))/(1 - h_0(y))\bigr) & \text{silent step,}\end{cases}

with an alarm once :math:`W_k \ge` the threshold (Page's CUSUM). A flag-ACK where
:math:`h_0(y) = 0` is impossible without attack and sets :math:`W = +\infty` (the support check);
a long silence raises W as a short gap does.

The gap laws are the Palm laws of the flag process (:func:`fakeack.flag_process`): from the law
:math:`\alpha \propto \pi D_1` of the automaton just after a delivery, the conditional law of the
state given no delivery yet, :math:`v_{y+1} = v_y D_0 / (v_y D_0 \mathbf 1)`, gives
:math:`h(y) = v_y D_1 \mathbf 1` (a forward filter, stable where the survival function
underflows). On the paper's channel the gaps are i.i.d. without attack and under the families
:class:`CusumTest` takes, so the statistic is the exact log-likelihood ratio. On a Markov channel
successive gaps are correlated; the statistic then uses the same Palm hazards, a renewal
likelihood that is a well-defined detector whose run lengths are still computed exactly
(:func:`fakeack.cusum_run_length`), but not the likelihood ratio of the whole stream. That one,
``CusumTest(..., likelihood="filter")``, replaces :math:`h(y)` by the forward filter's predictive
probability of a flag-ACK given every bit seen so far (``fakeack.detection.cusum_filter``); its
state is a continuous belief over the channel, which no finite chain holds, so its run lengths
are simulated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from .._internal.types import FloatArray
from .._internal.validate import as_real
from ..attacks.kinds import FlagInjection, RandomBlocking
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.schedules import OnlineDesign
from .cusum_filter import LIKELIHOODS, _filter_statistic, _log_ratio, _pmf_hazards
from .process import FlagProcess, flag_process

__all__ = [
    "CusumTest",
    "CusumIncrements",
    "gap_hazards",
]

#: Longest gap over which hazards are followed before they must have settled.
MAX_HAZARD_STEPS = 20_000
#: Hazards count as settled once the filter's law moves less than this in one step (L1).
SETTLED = 1e-13


def gap_hazards(process: FlagProcess) -> FloatArray:
    r"""The hazards :math:`h(y) = P(G = y \mid G \ge y)`, y = 1..Y, of the Palm gap law of a flag
    process; the last entry holds for every longer gap.

    Y is the first gap at which the conditional law of the automaton given no delivery has
    settled (moves less than 1e-13 in one step); from there on the hazard is constant to that
    accuracy. A process that never delivers has hazard 0 (Y = 1).

    Parameters
    ----------
    process : FlagProcess
        The delivered flag-ACKs (:func:`fakeack.flag_process`).

    Returns
    -------
    numpy.ndarray
        ``h[y - 1]`` for y = 1..Y, in [0, 1].

    Raises
    ------
    ValueError
        When the conditional law has not settled within 20,000 steps (a periodic silence).
    """
    d = np.asarray(process.D1.sum(axis=1)).ravel()
    alpha = process.stationary @ process.D1
    total = float(alpha.sum())
    if total <= 0.0:
        return np.zeros(1)
    v = np.asarray(alpha / total)
    D0t = process.D0.T.tocsr()
    hazards = []
    for _ in range(MAX_HAZARD_STEPS):
        h = float(v @ d)
        hazards.append(min(max(h, 0.0), 1.0))
        nxt = D0t @ v
        mass = float(nxt.sum())
        if mass <= 0.0:  # every gap has ended: the hazard is 1 here and nothing lies beyond
            return np.asarray(hazards)
        nxt /= mass
        settled = float(np.abs(nxt - v).sum()) < SETTLED
        v = nxt
        if settled:
            hazards.append(min(max(float(v @ d), 0.0), 1.0))
            return np.asarray(hazards)
    raise ValueError(
        f"the gap hazards of {process.attack or 'the attack-free process'} have not settled within "
        f"{MAX_HAZARD_STEPS} steps; the CUSUM needs gap laws with an aperiodic tail"
    )


def _as_alternative(alternative: object) -> RandomBlocking | FlagInjection | FloatArray:
    if isinstance(alternative, FlagInjection):
        if alternative.block is not None and not isinstance(alternative.block, RandomBlocking):
            raise TypeError(
                "alternative: a FlagInjection's block must be None or RandomBlocking for i.i.d. gaps, "
                f"got {type(alternative.block).__name__}"
            )
        return alternative
    if isinstance(alternative, RandomBlocking):
        return alternative
    if isinstance(alternative, (list, tuple, np.ndarray)):
        pmf = np.asarray(alternative, dtype=float)
        if pmf.ndim != 1 or pmf.size == 0:
            raise ValueError(f"alternative: a gap pmf must be a non-empty 1-D array, got shape {pmf.shape}")
        if not np.all(np.isfinite(pmf)) or np.any(pmf < 0.0):
            raise ValueError("alternative: a gap pmf must hold finite probabilities >= 0")
        if abs(float(pmf.sum()) - 1.0) > 1e-9:
            raise ValueError(f"alternative: a gap pmf must sum to 1, got {float(pmf.sum())!r}")
        pmf.setflags(write=False)
        return pmf
    raise TypeError(
        "alternative must be a fakeack.RandomBlocking, a fakeack.FlagInjection (block None or "
        f"RandomBlocking) or a gap pmf (1-D array, pmf[g - 1] = P(G = g)), got {type(alternative).__name__}"
    )


@dataclass(frozen=True)
class CusumIncrements:
    """The CUSUM's increments per gap length (see :meth:`CusumTest.increments`)."""

    flag: FloatArray
    r"""``flag[y - 1]`` = :math:`\log(h_a(y)/h_0(y))`, added on a step with a flag-ACK at gap y
    (``+inf`` where the attack-free hazard is 0, whatever the alternative: the support check;
    ``-inf`` where only the alternative cannot deliver: W restarts at 0)."""
    quiet: FloatArray
    r"""``quiet[y - 1]`` = :math:`\log((1 - h_a(y))/(1 - h_0(y)))`, added on a silent step (``+inf``
    where the attack-free law must deliver)."""
    h0: FloatArray = field(repr=False)
    """The attack-free hazards, same length."""
    ha: FloatArray = field(repr=False)
    """The alternative's hazards, same length."""

    @property
    def length(self) -> int:
        """Y: the last entry holds for every gap of Y steps or more."""
        return int(self.flag.size)


def _extend(h: FloatArray, n: int) -> FloatArray:
    return np.concatenate((h, np.full(n - h.size, h[-1]))) if h.size < n else h


@lru_cache(maxsize=64)
def _cached_increments(channel: Channel, design: OnlineDesign, alternative: Any) -> CusumIncrements:
    h0 = gap_hazards(flag_process(channel, design))
    if isinstance(alternative, tuple):  # a pmf, hashed as a tuple
        ha = _pmf_hazards(np.asarray(alternative))
        n = max(h0.size, ha.size + 1)
        h0 = _extend(h0, n)
        beyond = n - ha.size
        ha = np.concatenate((ha, np.zeros(beyond)))
        flag, quiet = _log_ratio(ha, h0), _log_ratio(1.0 - ha, 1.0 - h0)
        # Past the pmf's support the alternative is impossible: W restarts at 0 on every step.
        flag[-beyond:] = -math.inf
        quiet[-beyond:] = -math.inf
    else:
        ha = gap_hazards(flag_process(channel, design, alternative))
        n = max(h0.size, ha.size)
        h0, ha = _extend(h0, n), _extend(ha, n)
        flag, quiet = _log_ratio(ha, h0), _log_ratio(1.0 - ha, 1.0 - h0)
    for a in (flag, quiet, h0, ha):
        a.setflags(write=False)
    return CusumIncrements(flag, quiet, h0, ha)


@dataclass(frozen=True)
class CusumTest:
    r"""Page's CUSUM of the flag-ACK stream against an alternative with i.i.d. gaps.

    ``CusumTest(alternative, threshold)``: on each step add the log-likelihood ratio of what
    reached the sensor (a flag-ACK or silence, at the current gap y) between ``alternative``
    and the attack-free law, restart at 0 when the sum falls below it, and alarm once it reaches
    ``threshold`` (the module docstring has the increments). A flag-ACK sooner than any can
    come without attack alarms at once (the support check). Run lengths:
    :func:`fakeack.cusum_run_length`; the threshold of a given mean time to a false alarm:
    :func:`fakeack.cusum_threshold`.

    Parameters
    ----------
    alternative : RandomBlocking, FlagInjection or array_like
        The attack the statistic is tuned to: :class:`fakeack.RandomBlocking`,
        :class:`fakeack.FlagInjection` with ``block`` None or a :class:`fakeack.RandomBlocking`
        and any ``min_gap``, or a gap pmf (``pmf[g - 1] = P(G = g)``, summing to 1). Other
        attacks do not have i.i.d. gaps (TypeError).
    threshold : float
        The alarm level h > 0.
    likelihood : {"renewal", "filter"}, optional
        ``"renewal"`` (default): the increments use the Palm gap hazards :math:`h(y)`, the exact
        log-likelihood ratio where gaps are i.i.d. (the paper's channel), run lengths exact.
        ``"filter"``: they use the forward filters' predictive flag probabilities, the exact
        log-likelihood ratio of the whole stream on any channel
        (``fakeack.detection.cusum_filter``); run lengths simulated, and the closed-loop
        policy (:class:`fakeack.SensorPolicy`) cannot run it. Both start just after a delivered
        flag-ACK and agree on the paper's channel.

    Examples
    --------
    >>> import fakeack as fa
    >>> test = fa.CusumTest(fa.RandomBlocking(0.2), 4.0)
    >>> inc = test.increments(0.5, fa.OnlineDesign(2))
    >>> bool(inc.flag[0] == float("inf"))   # a flag-ACK one step after the last: never without attack
    True
    """

    alternative: RandomBlocking | FlagInjection | FloatArray
    threshold: float
    likelihood: str = "renewal"

    def __init__(self, alternative: object, threshold: float, *, likelihood: str = "renewal") -> None:
        object.__setattr__(self, "alternative", _as_alternative(alternative))
        h = as_real("threshold", threshold)
        if h <= 0.0:
            raise ValueError(f"threshold must be > 0, got {h}")
        object.__setattr__(self, "threshold", h)
        if likelihood not in LIKELIHOODS:
            raise ValueError(f"likelihood must be 'renewal' or 'filter', got {likelihood!r}")
        object.__setattr__(self, "likelihood", likelihood)

    def increments(self, channel: ChannelLike, design: OnlineDesign) -> CusumIncrements:
        r"""The increments :math:`\log(h_a/h_0)` and :math:`\log((1-h_a)/(1-h_0))` per gap.

        Parameters
        ----------
        channel : Channel or float
            The true channel of both laws (a float: the paper's channel).
        design : OnlineDesign
            The online schedule.

        Returns
        -------
        CusumIncrements
            Tables over y = 1..Y; the last entry holds for longer gaps. They are the renewal
            statistic's, whatever ``likelihood``.
        """
        ch, key = self._key(channel, design)
        return _cached_increments(ch, design, key)

    def _key(self, channel: ChannelLike, design: OnlineDesign) -> tuple[Channel, Any]:
        ch = as_channel(channel, "channel")
        if not isinstance(design, OnlineDesign):
            raise TypeError(f"design must be a fakeack.OnlineDesign, got {type(design).__name__}")
        alt = self.alternative
        return ch, (tuple(float(x) for x in alt) if isinstance(alt, np.ndarray) else alt)

    def statistic(self, channel: ChannelLike, design: OnlineDesign, delivered: object) -> FloatArray:
        r"""The path of W over given flag-ACK streams, from the renewal start.

        Step k adds the increment of the bit ``delivered[k]`` (a flag-ACK reached the sensor or
        not) and W restarts at 0 below it; nothing alarms or restarts at the threshold, so the
        run length is the first step with W >= ``threshold``. The first step is the one after a
        delivered flag-ACK (gap y = 1; the filters at their Palm laws). W = +inf (a stream the
        attack-free law cannot produce) stays +inf.

        Parameters
        ----------
        channel : Channel or float
            The true channel of both laws (a float: the paper's channel).
        design : OnlineDesign
            The online schedule.
        delivered : array_like of bool
            One stream (steps,) or a batch (runs, steps).

        Returns
        -------
        numpy.ndarray
            W after each step, the shape of ``delivered``.

        Raises
        ------
        TypeError, ValueError
            For a bad channel, design or stream, naming it.

        Examples
        --------
        >>> import fakeack as fa
        >>> test = fa.CusumTest(fa.RandomBlocking(0.5), 4.0, likelihood="filter")
        >>> w = test.statistic(0.5, fa.OnlineDesign(2), [0, 0, 0, 1, 0, 1])
        >>> bool(w[-1] == float("inf"))   # a gap of 2 steps: impossible without attack
        True
        """
        ch, key = self._key(channel, design)
        x = np.asarray(delivered)
        if x.dtype != np.bool_:
            if not np.issubdtype(x.dtype, np.integer) or not np.isin(x, (0, 1)).all():
                raise TypeError(f"delivered must hold booleans (or 0/1), got dtype {x.dtype}")
            x = x.astype(bool)
        if x.ndim not in (1, 2) or x.shape[-1] == 0:
            raise ValueError(f"delivered must have shape (steps,) or (runs, steps), got {x.shape}")
        batch = x.reshape(-1, x.shape[-1])
        if self.likelihood == "filter":
            return np.asarray(_filter_statistic(ch, design, key, batch).reshape(x.shape))
        inc = _cached_increments(ch, design, key)
        W = np.zeros(batch.shape[0])
        y = np.ones(batch.shape[0], dtype=np.int64)
        out = np.empty(batch.shape)
        for k in range(batch.shape[1]):
            at = np.minimum(y, inc.length) - 1
            with np.errstate(invalid="ignore"):  # inf - inf: W is +inf already and stays there
                new = np.maximum(0.0, W + np.where(batch[:, k], inc.flag[at], inc.quiet[at]))
            W = np.where(W == math.inf, math.inf, new)
            out[:, k] = W
            y = np.where(batch[:, k], 1, y + 1)
        return np.asarray(out.reshape(x.shape))

    def __str__(self) -> str:
        alt = self.alternative
        what = f"a gap pmf of {alt.size} steps" if isinstance(alt, np.ndarray) else str(alt)
        tail = ", filter likelihood" if self.likelihood == "filter" else ""
        return f"CUSUM against {what}, threshold {self.threshold:g}{tail}"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CusumTest):
            return NotImplemented
        a, b = self.alternative, other.alternative
        same = (
            np.array_equal(a, b)
            if isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
            else (not isinstance(a, np.ndarray) and not isinstance(b, np.ndarray) and a == b)
        )
        return same and self.threshold == other.threshold and self.likelihood == other.likelihood

    def __hash__(self) -> int:
        a = self.alternative
        return hash((tuple(a.tolist()) if isinstance(a, np.ndarray) else a, self.threshold, self.likelihood))
