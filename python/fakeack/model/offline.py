r"""The best offline pattern of a given density under a channel: an exhaustive search over
necklaces, and a stated local search beyond.

On the paper's channel Theorem 3.1 settles the offline problem: of all patterns with p high-power
steps in q, the evenly spread one (:func:`fakeack.offline_schedule`) has the least J. Under a
channel with memory it need not: on the cyclic channel of the example in :func:`offline_search`
``101000`` beats ``100``. :func:`offline_search` looks for the best periodic pattern with high
fraction p/q and period at most a bound, evaluating each candidate with the exact engine
(``fakeack.model.exact``, the computation of :class:`fakeack.Scenario`).

**What is searched.** A periodic 0/1 sequence with high fraction p/q (lowest terms) and period
L has ``L p / q`` ones, so q divides its least period: the candidates are the patterns of length
L = kq with kp ones, k = 1, 2, ..., ``max_period // q``.

**Rotations (proved).** J is a long-run average: a rotation of the pattern is the same sequence
started at another step, so its J is the same (the engine's J of the rotations agree to rounding,
a check the tests make). A sequence is therefore counted once, by its least period and its
necklace. Writing a pattern as its ones, each followed by a gap of g_i zeros, the necklaces of
aperiodic patterns of length L with w ones are the Lyndon words among the compositions
(g_1, ..., g_w) of L - w: enumerated directly (Fredricksen-Kessler-Maiorana with a fixed sum),
:math:`\frac1L\sum_{d \mid \gcd(L, w)} \mu(d)\binom{L/d}{w/d}` of them.

**Reversals (proved, reversible channels only).** If the channel's chain is reversible (two
states, or any birth-death chain: :math:`\pi_i P_{ij} = \pi_j P_{ji}`), the stationary channel
run backwards has the law of the channel, and arrivals depend only on the current state and
power, so the arrival sequence of the reversed pattern has the law of the reversed arrival
sequence. A gap of g steps between arrivals costs :math:`\sum_{t<g} \mathrm{tr}_t` whether the
time since the last arrival is read forwards or backwards, and reversing a sequence keeps its
gaps, so the reversed pattern has the same J: one of each pair is evaluated. On other channels
it is not so (the tests show a pattern and its reversal with different J), and both are.

**Beyond the budget (not exhaustive).** Periods whose necklaces would bring the count past
``max_patterns`` (those of a ``max_period`` given beyond it, or q itself when its necklaces
alone exceed it; the default ``max_period`` stops before) are searched locally: steepest
descent from the best pattern so far (repeated to the period when it divides it, else the
evenly spread pattern), moving one high-power step one place left or right while that lowers J,
at most ``fakeack.model.offline.MAX_DESCENT_ROUNDS`` rounds. The result says which periods were exhaustive
(``exhaustive_period``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .. import _fakeack
from .._internal.types import IntArray, RatioLike
from .._internal.validate import as_int, as_ratio
from .channels import Channel, ChannelLike
from .exact import MAX_STATES, channel_of, engine
from .system import LinearSystem, compiled

__all__ = [
    "OfflineSearch",
    "offline_search",
    "lyndon_count",
    "necklaces",
    "DEFAULT_MAX_PATTERNS",
    "TIE_RTOL",
    "MAX_DESCENT_ROUNDS",
    "STEPS_PER_PATTERN",
]

#: Necklaces :func:`offline_search` evaluates exhaustively by default (about 40 us each).
DEFAULT_MAX_PATTERNS = 5_000
#: A pattern beats the best so far only if its J is lower by more than this relative amount
#: (rotations of one pattern agree to about 1e-15): ties go to the evenly spread pattern.
TIE_RTOL = 1e-11
#: The default period also keeps the necklaces' total length within this many steps per pattern
#: of ``max_patterns``.
STEPS_PER_PATTERN = 100
#: Largest number of improving moves of the local search at one period.
MAX_DESCENT_ROUNDS = 1_000
#: Beyond this many ones or zeros a period's necklaces outnumber any budget (C(130, 65)/130 > 2^62).
_HUGE = 64


def lyndon_count(n: int, w: int) -> int:
    r"""The number of aperiodic binary necklaces (Lyndon words) of length n with w ones.

    :math:`\frac1n\sum_{d \mid \gcd(n, w)} \mu(d)\binom{n/d}{w/d}` (Moebius inversion of the
    necklaces by their least period).
    """
    g = math.gcd(n, w)
    total = 0
    for d in range(1, g + 1):
        if g % d == 0:
            total += _moebius(d) * math.comb(n // d, w // d)
    return total // n


def _moebius(d: int) -> int:
    out, m, f = 1, d, 2
    while f * f <= m:
        if m % f == 0:
            m //= f
            if m % f == 0:
                return 0
            out = -out
        f += 1
    return -out if m > 1 else out


def necklaces(zeros: int, ones: int) -> Iterator[tuple[int, ...]]:
    """The gap compositions (g_1..g_w) of ``zeros`` into ``ones`` parts that are Lyndon words.

    Each is the lexicographically least of its rotations and differs from all of them, so each
    aperiodic pattern ``1 0^g_1 1 0^g_2 ...`` of that length and weight appears once up to
    rotation. Fredricksen-Kessler-Maiorana generation, pruned by the fixed sum (every part is at
    least the first, the least).
    """
    w, Z = ones, zeros
    if w == 1:
        yield (Z,)
        return
    a = [0] * w

    def rec(t: int, p: int, s: int) -> Iterator[tuple[int, ...]]:
        if t == w - 1:
            v = Z - s
            if v > a[t - p]:  # a new maximal period: the word is Lyndon
                a[t] = v
                yield tuple(a)
            return
        top = Z - s - (w - 1 - t) * a[0]
        for v in range(a[t - p], top + 1):
            a[t] = v
            yield from rec(t + 1, p if v == a[t - p] else t + 1, s + v)

    for first in range(Z // w + 1):
        a[0] = first
        yield from rec(1, 1, first)


def _least_rotation(g: tuple[int, ...]) -> tuple[int, ...]:
    return min(g[i:] + g[:i] for i in range(len(g)))


def _pattern(gaps: tuple[int, ...]) -> list[int]:
    out: list[int] = []
    for g in gaps:
        out.append(1)
        out.extend([0] * g)
    return out


def _gaps(pattern: list[int]) -> tuple[int, ...]:
    ones = [i for i, x in enumerate(pattern) if x]
    n = len(pattern)
    return tuple((ones[(k + 1) % len(ones)] - ones[k] - 1) % n for k in range(len(ones)))


def _canonical(pattern: list[int]) -> list[int]:
    """The least period of ``pattern``, written from its least gap rotation."""
    n = len(pattern)
    for d in range(1, n + 1):
        if n % d == 0 and pattern[:d] * (n // d) == pattern:
            return _pattern(_least_rotation(_gaps(pattern[:d])))
    raise AssertionError("unreachable")


def _reversible(ch: Channel) -> bool:
    """Two states or a birth-death chain: reversible, whatever the entries (proved, not tested)."""
    P = ch.P
    k = ch.n_states
    return k <= 2 or all(P[i, j] == 0.0 for i in range(k) for j in range(k) if abs(i - j) > 1)


def _better(j: float, ref: float) -> bool:
    if math.isinf(ref):
        return j < ref
    return j < ref - TIE_RTOL * abs(ref)


@dataclass(frozen=True, eq=False)
class OfflineSearch:
    """The best periodic offline pattern of a density found by :func:`offline_search`."""

    ratio: Fraction
    """The high fraction p/q every candidate has."""
    pattern: IntArray
    """One period of the best pattern (``int64`` 0/1, 1 = high power), its least period; the
    evenly spread pattern of Theorem 3.1 when nothing beats it."""
    j: float
    """Its J under the channel (``inf`` if even the best is unstable)."""
    j_even: float
    """J of the evenly spread pattern :func:`fakeack.offline_schedule` ``(ratio)``."""
    even_is_optimal: bool
    """No searched pattern has a J lower than ``j_even`` by more than ``fakeack.model.offline.TIE_RTOL``."""
    max_period: int
    """The largest period searched, a multiple of q."""
    exhaustive_period: int
    """Every pattern with period up to this (a multiple of q, 0 if none) was compared."""
    n_searched: int
    """The number of patterns evaluated."""

    @property
    def exhaustive(self) -> bool:
        """Whether every period up to ``max_period`` was searched exhaustively."""
        return self.exhaustive_period == self.max_period

    def __repr__(self) -> str:
        pat = "".join(map(str, self.pattern.tolist()))
        if len(pat) > 64:
            pat = f"<{int(self.pattern.sum())} high of {len(pat)} steps>"
        return (
            f"OfflineSearch(ratio={self.ratio}, pattern={pat!r}, j={self.j:.6g}, j_even={self.j_even:.6g}, "
            f"even_is_optimal={self.even_is_optimal}, max_period={self.max_period}, "
            f"exhaustive_period={self.exhaustive_period}, n_searched={self.n_searched})"
        )

    def _repr_html_(self) -> str:
        from .._internal import html as _html

        pat = "".join(map(str, self.pattern.tolist()))
        kind = "exhaustive" if self.exhaustive else f"exhaustive up to {self.exhaustive_period}, local beyond"
        return _html.key_values(
            "OfflineSearch: the best offline pattern",
            [
                ("high fraction", self.ratio),
                ("best pattern", pat if len(pat) <= 64 else f"{len(pat)} steps"),
                ("J", self.j),
                ("J of the evenly spread pattern", self.j_even),
                ("evenly spread is optimal", "yes" if self.even_is_optimal else "no"),
                ("periods searched", f"up to {self.max_period} ({kind})"),
                ("patterns evaluated", self.n_searched),
            ],
            "Among periodic patterns of this high fraction with period up to the bound.",
        )


def _periods(q: int, p: int, n_states: int, max_period: int | None, budget: int) -> tuple[int, int]:
    """(k_max, k_exhaustive): periods kq searched, and those within the necklace budget."""
    if max_period is None:
        k_max = None
    else:
        mp = as_int("max_period", max_period, minimum=q)
        k_max = mp // q
        if k_max * q * n_states > MAX_STATES:
            raise ValueError(
                f"max_period: a period of {k_max * q} steps on {n_states} channel states exceeds the "
                f"engine's {MAX_STATES} states"
            )
    k, total, steps, k_exh = 0, 0, 0, 0
    while k_max is None or k < k_max:
        L, w = (k + 1) * q, (k + 1) * p
        c = lyndon_count(L, w) if min(w, L - w) <= _HUGE else budget + 1
        if total + c > budget or L * n_states > MAX_STATES:
            break
        if k_max is None and k > 0 and steps + c * L > STEPS_PER_PATTERN * budget:
            break  # by default, also bound the work (an evaluation costs about its period)
        k, total, steps = k + 1, total + c, steps + c * L
        k_exh = k
    return (k_max if k_max is not None else max(k_exh, 1)), k_exh


def offline_search(
    system: LinearSystem,
    channel: ChannelLike,
    ratio: RatioLike,
    *,
    max_period: int | None = None,
    max_patterns: int = DEFAULT_MAX_PATTERNS,
) -> OfflineSearch:
    r"""The best periodic offline pattern with high fraction ``ratio`` under ``channel``.

    Candidates are the patterns of period L = kq with kp ones (``ratio`` = p/q, the fraction of
    steps at high power, as in Theorem 3.1 and :func:`fakeack.offline_schedule`), L up to
    ``max_period``, each sequence counted once by its least period and its necklace (rotations
    have the same J), and once per reversal pair on a reversible channel (module docstring:
    both prunings are proved). Each is evaluated by the exact engine: J of
    ``fakeack.Scenario(system, channel, fakeack.OfflineSchedule(pattern=...))``. Periods are
    exhaustive while the number of necklaces stays within ``max_patterns``; beyond, a local
    search (module docstring), and ``exhaustive_period`` says where that starts.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor (the patterns are ranked by its J).
    channel : Channel or float
        Any channel; a float is the paper's channel, where Theorem 3.1 says the evenly spread
        pattern wins (the search confirms it).
    ratio : Fraction, int/int string or float
        The high fraction p/q in (0, 1).
    max_period : int, keyword-only, optional
        Longest period searched (at least q; the periods are its multiples of q). Default: the
        longest that keeps the search exhaustive within ``max_patterns`` necklaces of total
        length at most ``fakeack.model.offline.STEPS_PER_PATTERN`` times ``max_patterns`` steps, at least q.
    max_patterns : int, keyword-only, optional
        Necklaces evaluated exhaustively at most (default ``fakeack.model.offline.DEFAULT_MAX_PATTERNS``).

    Returns
    -------
    OfflineSearch
        The best pattern, its J, the evenly spread pattern's J, whether that is optimal among
        the candidates, the periods searched and the number of patterns evaluated.

    Raises
    ------
    TypeError, ValueError
        Naming ``channel``, ``ratio``, ``max_period`` or ``max_patterns``.

    Examples
    --------
    >>> s = LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> cyc = MarkovChannel([[0.05, 0.9, 0.05], [0.05, 0.05, 0.9], [0.9, 0.05, 0.05]],
    ...                     low=[0.9, 0.0, 0.0], high=[1.0, 0.2, 1.0])
    >>> res = offline_search(s, cyc, "1/3", max_period=9)
    >>> "".join(map(str, res.pattern)), res.even_is_optimal, round(res.j_even, 4), round(res.j, 4)
    ('101000', False, 2.3188, 2.2891)
    """
    core = compiled(system)
    ch, _ = channel_of(channel, None, "offline_search")
    r = as_ratio("ratio", ratio)
    budget = as_int("max_patterns", max_patterns, minimum=1)
    p, q = r.numerator, r.denominator
    k_max, k_exh = _periods(q, p, ch.n_states, max_period, budget)
    counter = [0]

    def evaluate(pattern: list[int]) -> float:
        counter[0] += 1
        return float(engine(ch, pattern=pattern).cost(core))

    even = [int(x) for x in _fakeack.offline_schedule(p, q)]
    j_even = evaluate(even)
    best, best_j = even, j_even
    pairs = _reversible(ch)
    for k in range(1, k_max + 1):
        L, w = k * q, k * p
        if k <= k_exh:
            for gaps in necklaces(L - w, w):
                if pairs and _least_rotation(gaps[::-1]) < gaps:
                    continue  # its reversal, with the same J, comes (or came) as the canonical one
                pat = _pattern(gaps)
                j = evaluate(pat)
                if _better(j, best_j):
                    best, best_j = pat, j
        else:
            tiled = L % len(best) == 0  # the same sequence, so the same J; else start evenly
            start, j0 = (best * (L // len(best)), best_j) if tiled else (even * k, j_even)
            best_l, j_l = _descend(start, j0, evaluate)
            if _better(j_l, best_j):
                best, best_j = _canonical(best_l), j_l
    out = np.array(best, dtype=np.int64)
    out.flags.writeable = False
    return OfflineSearch(
        ratio=r,
        pattern=out,
        j=best_j,
        j_even=j_even,
        even_is_optimal=best is even,
        max_period=k_max * q,
        exhaustive_period=k_exh * q,
        n_searched=counter[0],
    )


def _descend(start: list[int], j0: float, evaluate: Callable[[list[int]], float]) -> tuple[list[int], float]:
    """Steepest descent from ``start`` (of J ``j0``), moving one high-power step one place."""
    cur, jc = list(start), j0
    L = len(cur)
    for _ in range(MAX_DESCENT_ROUNDS):
        move: list[int] | None = None
        jm = jc
        for i in range(L):
            if not cur[i]:
                continue
            for t in ((i - 1) % L, (i + 1) % L):
                if cur[t]:
                    continue
                cand = list(cur)
                cand[i], cand[t] = 0, 1
                j = evaluate(cand)
                if _better(j, jm):
                    move, jm = cand, j
        if move is None:
            break
        cur, jc = move, jm
    return cur, jc
