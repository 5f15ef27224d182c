r"""Packet channels: whether a packet arrives, given the transmit power and the channel's state.

A channel is a finite Markov chain :math:`c_k` on states :math:`0..K-1` with row-stochastic
:math:`P` (:math:`P_{ij} = \Pr[c_{k+1} = j \mid c_k = i]`) and, per state, the arrival
probability of a low-power packet (``low``) and of a high-power packet (``high``). The paper's
channel is :class:`BernoulliChannel`: one state, ``low = lam``, ``high = 1``. The first state
:math:`c_1` has the stationary law (the exact engine's convention, docs page "The exact engine").
"""

from __future__ import annotations

import math
import numbers
from typing import TypeAlias

import numpy as np
import numpy.typing as npt
from scipy.sparse import csr_array
from scipy.sparse.csgraph import connected_components

__all__ = [
    "Channel",
    "BernoulliChannel",
    "MarkovChannel",
    "GilbertElliott",
    "ChannelLike",
    "as_channel",
    "channel_argument",
    "is_paper_channel",
    "ROW_SUM_TOL",
]

FloatArray: TypeAlias = npt.NDArray[np.float64]

#: Largest deviation of a row sum of P from 1 that is accepted (and then renormalised away).
ROW_SUM_TOL = 1e-12
#: Channels with at most this many states print their matrices in full.
_REPR_STATES = 4


def _frozen(values: npt.ArrayLike) -> FloatArray:
    out = np.array(values, dtype=np.float64, copy=True)
    out.flags.writeable = False
    return out


def _real_array(name: str, x: object, ndim: int) -> FloatArray:
    """A finite float64 array of ``ndim`` dimensions read from ``x`` (TypeError/ValueError naming it)."""
    if x is None or isinstance(x, (str, bytes, bool, np.bool_)):
        raise TypeError(f"{name} must be an array of real numbers, got {type(x).__name__}")
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError) as exc:  # ragged lists
        raise ValueError(f"{name}: cannot be read as an array ({exc})") from None
    if arr.dtype == object or arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got {arr.ndim}-D (shape {arr.shape})")
    if arr.size == 0:
        raise ValueError(f"{name} must not be empty")
    out = np.array(arr, dtype=np.float64)
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{name} contains NaN or inf")
    if np.any((out < 0.0) | (out > 1.0)):
        raise ValueError(f"{name}: probabilities must lie in [0, 1]")
    return out


def _probability(name: str, x: object) -> float:
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (numbers.Real, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number in [0, 1], got {type(x).__name__}")
    v = float(x)
    if not (math.isfinite(v) and 0.0 <= v <= 1.0):
        raise ValueError(f"{name} must lie in [0, 1], got {v}")
    return v


#: Channels up to this many states find their classes by a dense closure.
_DENSE_CLASSES = 64


def closed_classes(P: FloatArray) -> list[npt.NDArray[np.intp]]:
    """The closed communicating classes of the transition graph of ``P`` (edges where P > 0).

    A strongly connected component is closed when no positive entry of its rows leaves it.
    """
    n = P.shape[0]
    if n <= _DENSE_CLASSES:
        # Small channels (every channel in practice) by a dense transitive closure: csgraph's
        # set-up alone costs a few hundred microseconds, most of a scenario's construction.
        reach = (P > 0.0) | np.eye(n, dtype=bool)
        for _ in range(max(1, math.ceil(math.log2(n)))):
            reach = (reach.astype(np.int64) @ reach.astype(np.int64)) > 0
        closed = [i for i in range(n) if np.all(reach[reach[i], i])]  # all it reaches reach it back
        out: list[npt.NDArray[np.intp]] = []
        seen: set[int] = set()
        for i in closed:
            if i not in seen:
                cls = np.flatnonzero(reach[i])
                seen.update(int(j) for j in cls)
                out.append(cls)
        return out
    graph = csr_array((P > 0.0).astype(np.float64))
    n_comp, label = connected_components(graph, directed=True, connection="strong")
    rows, cols = graph.nonzero()
    leaves = np.zeros(n_comp, dtype=bool)
    leaves[label[rows][label[rows] != label[cols]]] = True
    return [np.flatnonzero(label == c) for c in range(n_comp) if not leaves[c]]


def gth_stationary(P: FloatArray) -> FloatArray:
    r"""Stationary law of a row-stochastic matrix with one closed class, by GTH state reduction.

    Grassmann-Taksar-Heyman elimination on the closed class (no subtractions, so small entries
    keep their relative accuracy); states outside it get 0. Solves :math:`\pi P = \pi`,
    :math:`\sum\pi = 1`.
    """
    (cls,) = closed_classes(P)
    A = np.array(P[np.ix_(cls, cls)], dtype=np.float64)
    n = len(cls)
    for k in range(n - 1, 0, -1):
        s = A[k, :k].sum()
        A[:k, k] /= s
        A[:k, :k] += np.outer(A[:k, k], A[k, :k])
    x = np.zeros(n)
    x[0] = 1.0
    for k in range(1, n):
        x[k] = x[:k] @ A[:k, k]
    pi = np.zeros(P.shape[0])
    pi[cls] = x / x.sum()
    return pi


class Channel:
    """A packet channel: a finite Markov chain with a low- and a high-power arrival probability
    per state (the common base of :class:`BernoulliChannel`, :class:`MarkovChannel` and
    :class:`GilbertElliott`).

    Two channels are equal when their ``P``, ``low`` and ``high`` are equal, whatever their
    class: ``GilbertElliott(p, q, g, b) == MarkovChannel([[1-p, p], [q, 1-q]], [g, b], [1, 1])``.
    """

    __slots__ = ("_P", "_low", "_high", "_stationary")

    _P: FloatArray
    _low: FloatArray
    _high: FloatArray
    _stationary: FloatArray

    def _set(self, P: FloatArray, low: FloatArray, high: FloatArray) -> None:
        object.__setattr__(self, "_P", _frozen(P))
        object.__setattr__(self, "_low", _frozen(low))
        object.__setattr__(self, "_high", _frozen(high))
        object.__setattr__(self, "_stationary", _frozen(gth_stationary(self._P)))

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    @property
    def P(self) -> FloatArray:
        """``(K, K)`` transition matrix, ``P[i, j] = P(c_{k+1} = j | c_k = i)`` (read-only)."""
        return self._P

    @property
    def low(self) -> FloatArray:
        """``(K,)`` arrival probability of a low-power packet in each state (read-only)."""
        return self._low

    @property
    def high(self) -> FloatArray:
        """``(K,)`` arrival probability of a high-power packet in each state (read-only)."""
        return self._high

    @property
    def stationary(self) -> FloatArray:
        r"""``(K,)`` the stationary law :math:`\pi P = \pi` (0 on transient states; read-only)."""
        return self._stationary

    @property
    def n_states(self) -> int:
        """The number of channel states K."""
        return int(self._P.shape[0])

    @property
    def mean_low(self) -> float:
        r"""Long-run arrival probability of a low-power packet, :math:`\sum_i \pi_i\,\mathrm{low}_i`."""
        return float(self._stationary @ self._low)

    @property
    def mean_high(self) -> float:
        r"""Long-run arrival probability of a high-power packet, :math:`\sum_i \pi_i\,\mathrm{high}_i`."""
        return float(self._stationary @ self._high)

    def _key(self) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        return (tuple(self._P.ravel().tolist()), tuple(self._low.tolist()), tuple(self._high.tolist()))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Channel):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __reduce__(self) -> tuple[object, tuple[object, ...]]:
        return (MarkovChannel, (self._P.tolist(), self._low.tolist(), self._high.tolist()))


class BernoulliChannel(Channel):
    r"""The paper's channel: a low-power packet arrives with probability ``lam``, independently
    at every step, a high-power packet always.

    One state: ``P = [[1]]``, ``low = [lam]``, ``high = [1]``. Wherever a channel is accepted, a
    float ``lam`` means ``BernoulliChannel(lam)``.

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in [0, 1]` of a low-power packet.

    Examples
    --------
    >>> BernoulliChannel(0.5)
    BernoulliChannel(lam=0.5)
    >>> BernoulliChannel(0.5).stationary.tolist(), BernoulliChannel(0.5).mean_low
    ([1.0], 0.5)
    """

    __slots__ = ()

    def __init__(self, lam: float) -> None:
        v = _probability("lam", lam)
        self._set(np.ones((1, 1)), np.array([v]), np.ones(1))

    @property
    def lam(self) -> float:
        """The low-power arrival probability."""
        return float(self._low[0])

    def __reduce__(self) -> tuple[object, tuple[object, ...]]:
        return (BernoulliChannel, (self.lam,))

    def __repr__(self) -> str:
        return f"BernoulliChannel(lam={self.lam!r})"


def _list(x: FloatArray) -> str:
    return "[" + ", ".join(repr(float(v)) for v in x) + "]"


class MarkovChannel(Channel):
    r"""A finite-state Markov channel (Gilbert-Elliott and beyond).

    The state moves :math:`c_k \to c_{k+1}` by ``P`` after step k's packet; in state i a
    low-power packet arrives with probability ``low[i]`` and a high-power one with ``high[i]``.

    Parameters
    ----------
    P : array_like, shape (K, K)
        Row-stochastic (rows sum to 1 within 1e-12, then renormalised), entries in [0, 1],
        :math:`P_{ij} = \Pr[c_{k+1} = j \mid c_k = i]`, with exactly one closed class (so the
        stationary law is unique; transient states are allowed).
    low, high : array_like, shape (K,)
        Arrival probabilities in [0, 1] of a low- and a high-power packet in each state. ``high``
        is not required to exceed ``low``.

    Raises
    ------
    TypeError
        For non-numeric input (the message names ``P``, ``low`` or ``high``).
    ValueError
        For a shape, range, row-sum or closed-class violation (naming the argument).

    Examples
    --------
    >>> ch = MarkovChannel([[0.9, 0.1], [0.3, 0.7]], [0.8, 0.2], [1.0, 0.9])
    >>> ch.stationary.round(6).tolist(), round(ch.mean_low, 6)
    ([0.75, 0.25], 0.65)
    """

    __slots__ = ()

    def __init__(self, P: npt.ArrayLike, low: npt.ArrayLike, high: npt.ArrayLike) -> None:
        Pm = _real_array("P", P, 2)
        if Pm.shape[0] != Pm.shape[1]:
            raise ValueError(f"P must be square, got shape {Pm.shape}")
        rows = Pm.sum(axis=1)
        if np.max(np.abs(rows - 1.0)) > ROW_SUM_TOL:
            i = int(np.argmax(np.abs(rows - 1.0)))
            raise ValueError(f"P must be row-stochastic: row {i} sums to {rows[i]!r}")
        Pm = Pm / rows[:, None]
        k = Pm.shape[0]
        lo, hi = _real_array("low", low, 1), _real_array("high", high, 1)
        if lo.shape != (k,):
            raise ValueError(f"low must have one entry per channel state ({k}), got {lo.size}")
        if hi.shape != (k,):
            raise ValueError(f"high must have one entry per channel state ({k}), got {hi.size}")
        n_closed = len(closed_classes(Pm))
        if n_closed != 1:
            raise ValueError(
                f"P must have exactly one closed class (a unique stationary law), got {n_closed}"
            )
        self._set(Pm, lo, hi)

    def __repr__(self) -> str:
        if self.n_states > _REPR_STATES:
            return f"MarkovChannel(<{self.n_states} states>, mean_low={self.mean_low:.6g})"
        P = "[" + ", ".join(_list(row) for row in self._P) + "]"
        return f"MarkovChannel(P={P}, low={_list(self._low)}, high={_list(self._high)})"


class GilbertElliott(MarkovChannel):
    r"""The Gilbert-Elliott channel: a good state 0 and a bad state 1.

    Exactly ``MarkovChannel([[1-p, p], [q, 1-q]], [lam_good, lam_bad], [high_good, high_bad])``,
    and equal to it (``==``, same hash); a subclass only for its parameters and its repr. The
    stationary law is :math:`\pi_{\mathrm{good}} = q/(p+q)`.

    Parameters
    ----------
    p : float
        Probability of going from good to bad at a step, in [0, 1].
    q : float
        Probability of going from bad to good, in [0, 1]; ``p = q = 0`` (two closed classes) is
        refused.
    lam_good, lam_bad : float
        Low-power arrival probabilities in the good and the bad state.
    high_good, high_bad : float, optional
        High-power arrival probabilities (default 1).

    Examples
    --------
    >>> ge = GilbertElliott(0.1, 0.3, 0.9, 0.2)
    >>> ge
    GilbertElliott(p=0.1, q=0.3, lam_good=0.9, lam_bad=0.2)
    >>> ge.stationary.round(12).tolist() == [0.75, 0.25]
    True
    >>> ge == MarkovChannel([[0.9, 0.1], [0.3, 0.7]], [0.9, 0.2], [1.0, 1.0])
    True
    """

    __slots__ = ("_params",)

    _params: tuple[float, float, float, float, float, float]

    def __init__(
        self,
        p: float,
        q: float,
        lam_good: float,
        lam_bad: float,
        high_good: float = 1.0,
        high_bad: float = 1.0,
    ) -> None:
        pp, qq = _probability("p", p), _probability("q", q)
        if pp == 0.0 and qq == 0.0:
            raise ValueError("p and q must not both be 0: the channel would never change state")
        params = (
            pp,
            qq,
            _probability("lam_good", lam_good),
            _probability("lam_bad", lam_bad),
            _probability("high_good", high_good),
            _probability("high_bad", high_bad),
        )
        super().__init__([[1.0 - pp, pp], [qq, 1.0 - qq]], params[2:4], params[4:6])
        object.__setattr__(self, "_params", params)

    @property
    def p(self) -> float:
        """Good-to-bad transition probability."""
        return self._params[0]

    @property
    def q(self) -> float:
        """Bad-to-good transition probability."""
        return self._params[1]

    @property
    def lam_good(self) -> float:
        """Low-power arrival probability in the good state."""
        return self._params[2]

    @property
    def lam_bad(self) -> float:
        """Low-power arrival probability in the bad state."""
        return self._params[3]

    @property
    def high_good(self) -> float:
        """High-power arrival probability in the good state."""
        return self._params[4]

    @property
    def high_bad(self) -> float:
        """High-power arrival probability in the bad state."""
        return self._params[5]

    def __reduce__(self) -> tuple[object, tuple[object, ...]]:
        return (GilbertElliott, self._params)

    def __repr__(self) -> str:
        p, q, g, b, hg, hb = self._params
        extra = "" if (hg, hb) == (1.0, 1.0) else f", high_good={hg!r}, high_bad={hb!r}"
        return f"GilbertElliott(p={p!r}, q={q!r}, lam_good={g!r}, lam_bad={b!r}{extra})"


#: What :func:`as_channel` reads: a channel, or a float ``lam`` (a :class:`BernoulliChannel`).
ChannelLike: TypeAlias = Channel | float


def as_channel(x: object, name: str = "channel") -> Channel:
    """A channel object, or a number ``lam`` as :class:`BernoulliChannel` ``(lam)``.

    Parameters
    ----------
    x : Channel or float
        The channel, or the low-power arrival probability of the paper's channel.
    name : str, optional
        The argument's name in error messages (default ``"channel"``).

    Returns
    -------
    Channel

    Raises
    ------
    TypeError
        For anything else (naming ``name``).
    ValueError
        For a number outside [0, 1] (naming ``name``).

    Examples
    --------
    >>> as_channel(0.25)
    BernoulliChannel(lam=0.25)
    """
    if isinstance(x, Channel):
        return x
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (numbers.Real, np.integer, np.floating)):
        raise TypeError(
            f"{name} must be a channel (fakeack.BernoulliChannel, MarkovChannel, GilbertElliott) or a "
            f"low-power arrival probability, got {type(x).__name__}"
        )
    return BernoulliChannel(_probability(name, x))


def channel_argument(channel: object, lam: object, function: str) -> tuple[Channel, str]:
    """The channel of ``function(system, channel)`` or of the old spelling ``function(system, lam=...)``.

    Parameters
    ----------
    channel : Channel, float or None
        The ``channel`` argument.
    lam : float or None
        The ``lam`` keyword (the parameter's name before channels existed).
    function : str
        The public function's name, for the error when neither is given.

    Returns
    -------
    (Channel, str)
        The channel and the argument name its errors use (``"channel"`` or ``"lam"``).

    Raises
    ------
    TypeError
        Both or neither given, or not a channel or a number.
    ValueError
        A number outside [0, 1].
    """
    if lam is not None:
        if channel is not None:
            raise TypeError("give either channel or lam (its old name), not both")
        return as_channel(lam, "lam"), "lam"
    if channel is None:
        raise TypeError(f"{function}() missing the channel: a fakeack channel or a float lam")
    return as_channel(channel, "channel"), "channel"


def is_paper_channel(ch: Channel) -> bool:
    """Whether ``ch`` is the paper's channel: one state, a high-power packet always arrives.

    On it every analysis keeps its structured i.i.d. route; its ``lam`` is ``ch.low[0]``.
    """
    return ch.n_states == 1 and float(ch.high[0]) == 1.0
