"""Power schedules without attack: optimal offline (Theorem 3.1) and ACK-based online (Thm 4.5)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, NamedTuple

import numpy as np

from .. import _fakeack
from .._internal.types import IntArray, RatioLike
from .._internal.validate import as_fraction, as_int, as_probability, as_ratio
from .channels import Channel, ChannelLike, is_paper_channel
from .design import design_paper, design_under_channel
from .exact import channel_of, online_cost, pattern_cost
from .offline import offline_search
from .system import LinearSystem, compiled

__all__ = [
    "energy_ratio",
    "offline_schedule",
    "j_offline",
    "j_online",
    "OnlineDesign",
    "design_online",
    "j_max",
    "OfflineSchedule",
    "OnlineSchedule",
]


def energy_ratio(Psi: RatioLike, Delta: RatioLike, delta: RatioLike) -> Fraction:
    r"""The fraction of high-power steps the budget allows, :math:`p/q = (\Psi-\delta)/(\Delta-\delta)`.

    Parameters
    ----------
    Psi : rational
        Average energy budget per step :math:`\Psi` (Problem 2.1).
    Delta : rational
        High transmit energy :math:`\Delta` (packet always arrives).
    delta : rational
        Low transmit energy :math:`\delta` (packet arrives with probability :math:`\lambda`).

    Returns
    -------
    fractions.Fraction
        :math:`p/q` in lowest terms, exact for int, Fraction and decimal-string inputs (floats are
        read as the simplest fraction that rounds to them, so 0.1 is 1/10).

    Raises
    ------
    ValueError
        Unless :math:`0 \le \delta < \Psi < \Delta` (Remark 2.1).

    Examples
    --------
    >>> from fractions import Fraction
    >>> energy_ratio(Fraction(1, 7) * 10 + Fraction(6, 7) * 3, 10, 3)
    Fraction(1, 7)
    """
    psi, hi, lo = as_fraction("Psi", Psi), as_fraction("Delta", Delta), as_fraction("delta", delta)
    if lo < 0:
        raise ValueError(f"delta must be non-negative, got {lo}")
    if not lo < hi:
        raise ValueError(f"Delta must exceed delta, got Delta={hi}, delta={lo}")
    if not lo < psi < hi:
        raise ValueError(f"Psi must lie strictly between delta={lo} and Delta={hi}, got {psi}")
    return (psi - lo) / (hi - lo)


def offline_schedule(
    ratio: RatioLike,
    channel: ChannelLike | None = None,
    *,
    system: LinearSystem | None = None,
    max_period: int | None = None,
) -> IntArray:
    r"""One period of the optimal offline schedule :math:`\theta^\star_{\mathrm{off}}` (Theorem 3.1).

    With :math:`s_0 = \lfloor q/p \rfloor - 1`, the period holds :math:`m = q - p(s_0+1)` blocks
    ``1 0...0`` of length :math:`s_0+2` followed by :math:`n = p(s_0+2) - q` blocks of length
    :math:`s_0+1` (Model note 1: the printed pattern swaps m and n). Under a channel other than
    the paper's the best pattern of that density depends on the system and need not be this
    one: give ``channel`` and ``system`` for the pattern of :func:`fakeack.offline_search`.

    Parameters
    ----------
    ratio : Fraction, int/int string or float
        Energy ratio :math:`p/q \in (0, 1)` (the fraction of high-power steps), e.g. from
        :func:`energy_ratio`.
    channel : Channel or float, optional
        None or the paper's channel (a float): Theorem 3.1's pattern. Another channel needs
        ``system``.
    system : LinearSystem, keyword-only, optional
        The system the patterns are ranked by (only with a channel).
    max_period : int, keyword-only, optional
        As in :func:`fakeack.offline_search` (ignored on the paper's channel).

    Returns
    -------
    numpy.ndarray
        ``int64`` array of length q (a multiple of q under a channel) with a fraction p/q of ones
        (1 = high power :math:`\Delta`).

    Examples
    --------
    >>> offline_schedule(Fraction(1, 7)).tolist()
    [1, 0, 0, 0, 0, 0, 0]
    """
    r = as_ratio("ratio", ratio)
    ch = None if channel is None else channel_of(channel, None, "offline_schedule")[0]
    if ch is None and (system is not None or max_period is not None):
        raise TypeError("channel: system and max_period are used only with a channel")
    if ch is None or is_paper_channel(ch):
        return _fakeack.offline_schedule(r.numerator, r.denominator)
    if system is None:
        raise TypeError("system: the best pattern under this channel depends on the system")
    return offline_search(system, ch, r, max_period=max_period).pattern


def j_offline(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    ratio: RatioLike | None = None,
    *,
    pattern: str | Sequence[int] | None = None,
    lam: float | None = None,
    max_period: int | None = None,
) -> float:
    r"""Cost J of the optimal offline schedule (Proposition 3.1, with m and n as corrected), or of
    a given pattern.

    On the paper's channel, with :math:`a = 1-\lambda` and :math:`\mathrm{tr}_i = \mathrm{Tr}\,h^i(\bar P)`,

    .. math::
       J = \frac{1}{q}\Big[m\sum_{i=0}^{s_0+1}\big(1+\lambda(s_0+1-i)\big)a^i\,\mathrm{tr}_i
           + n\sum_{i=0}^{s_0}\big(1+\lambda(s_0-i)\big)a^i\,\mathrm{tr}_i\Big].

    Under another channel, J of the best pattern of :func:`fakeack.offline_search`; with
    ``pattern``, J of that pattern on any channel. Both by the exact engine.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The channel; a float is the paper's, with arrival probability :math:`\lambda \in (0, 1)`
        at low power.
    ratio : Fraction
        Energy ratio :math:`p/q \in (0, 1)`. Give exactly one of ``ratio`` and ``pattern``.
    pattern : str or sequence of 0/1, keyword-only, optional
        One period of power levels, as in :class:`OfflineSchedule`.
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float).
    max_period : int, keyword-only, optional
        Longest period of :func:`fakeack.offline_search` (with ``ratio``; ignored on the paper's
        channel, where Theorem 3.1 needs no search).

    Returns
    -------
    float
        :math:`\lim \frac1T\sum_{k\le T}\mathrm{Tr}\,\mathbb E[P_k]`. On the paper's channel
        ``math.inf`` (never NaN) when this finite value lies beyond the double range (about
        1.8e308): an IEEE overflow, which a long period reaches where
        :math:`(1-\lambda)\rho(A)^2 \ge 1` (e.g. the paper's system at ``lam = 0.25``,
        ``ratio = 1/16384``). By the engine, ``inf`` where the cost diverges.
    """
    core = compiled(system)
    ch, name = channel_of(channel, lam, "j_offline")
    if (ratio is None) == (pattern is None):
        raise TypeError("give exactly one of ratio and pattern")
    if pattern is not None:
        if max_period is not None:
            raise TypeError("max_period: a given pattern is evaluated, not searched")
        return pattern_cost(system, ch, as_pattern(pattern))
    if is_paper_channel(ch):  # Theorem 3.1: the evenly spread pattern, whatever max_period
        lam_v = as_probability(name, ch.low[0])
        r = as_ratio("ratio", ratio)
        return core.j_offline(lam_v, r.numerator, r.denominator)
    return offline_search(system, ch, as_ratio("ratio", ratio), max_period=max_period).j


def check_online(lam: float, z0: int, mu: float) -> tuple[float, OnlineDesign]:
    """``lam`` and the online design ``(z0, mu)``, validated in that order."""
    return as_probability("lam", lam), OnlineDesign(z0, mu)


def j_online(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    z0: int | None = None,
    mu: float = 1.0,
    *,
    lam: float | None = None,
) -> float:
    r"""Cost J of the ACK-based online schedule :math:`\theta_{\mathrm{on}}` (Theorem 4.5).

    On the paper's channel, Theorem 4.5 of the paper, after the online schedule of Han et al.
    [1]_, corrected as in Model note 2, with :math:`a = 1-\lambda`:

    .. math::
       J = \frac{\lambda\big[\sum_{i=0}^{z_0} a^i\,\mathrm{tr}_i + (1-\mu)\,a^{z_0+1}
           \mathrm{tr}_{z_0+1}\big]}{1 - \mu a^{z_0+1} - (1-\mu) a^{z_0+2}}.

    Under another channel, the exact engine (:class:`fakeack.Scenario` without attack).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The channel; a float is the paper's, with arrival probability :math:`\lambda \in (0, 1)`
        at low power.
    z0 : int
        Memory length :math:`z_0 \ge 1`: a flag-ACK after :math:`z_0` consecutive losses.
    mu : float, optional
        Probability :math:`\mu \in [0, 1]` that the detector uses the :math:`z_0`-bit memory at a
        step (:math:`z_0+1` bits otherwise). Default 1 (fixed length).
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float).

    Returns
    -------
    float
        ``math.inf`` (never NaN) when this finite cost lies beyond the double range (a memory of
        thousands of steps where :math:`(1-\lambda)\rho(A)^2 \ge 1`); unlike :func:`j_max`'s
        ``inf``, not a divergence. By the engine, ``inf`` where the cost diverges.

    References
    ----------
    .. [1] D. Han, P. Cheng, J. Chen, L. Shi, "An online sensor power schedule for remote state
       estimation with communication energy constraint", IEEE TAC, 2014.
    """
    core = compiled(system)
    ch, name = channel_of(channel, lam, "j_online")
    if not is_paper_channel(ch):
        design = OnlineDesign(_required("z0", z0, "j_online"), mu)
        return online_cost(system, ch, design.z0, design.mu)
    lam_v, design = check_online_channel(ch, name, z0, mu, "j_online")
    return core.j_online(lam_v, design.z0, design.mu)


def _required(name: str, value: int | None, function: str) -> int:
    if value is None:
        raise TypeError(f"{function}() missing {name}")
    return value


def check_online_channel(
    ch: Channel, name: str, z0: int | None, mu: float, function: str
) -> tuple[float, OnlineDesign]:
    """The paper channel's ``lam`` (named ``name``) and the design, validated in that order."""
    return as_probability(name, ch.low[0]), OnlineDesign(_required("z0", z0, function), mu)


class _Design(NamedTuple):
    z0: int
    """Memory length."""
    mu: float
    """Probability of the z0-bit memory at each step (1.0: fixed length z0)."""


class OnlineDesign(_Design):
    """The ACK-based online schedule :math:`\theta_{\\mathrm{on}}`: a flag-ACK after z0 losses (z0+1 with
    probability 1-mu).

    One type for the pair (z0, mu) everywhere: :func:`design_online` returns it, the simulation
    takes it as its schedule, and it unpacks as ``z0, mu = design``. ``fakeack.OnlineSchedule`` is
    the same class.

    Parameters
    ----------
    z0 : int
        Memory length of the event detector, at least 1.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1: a fixed memory of z0).

    Examples
    --------
    >>> OnlineDesign(2)
    OnlineDesign(z0=2, mu=1.0)
    >>> z0, mu = OnlineDesign.design(0.5, "1/7"); (z0, mu)
    (2, 1.0)
    >>> str(OnlineDesign(3, 0.25))
    'online z0=3, mu=0.25'
    """

    __slots__ = ()

    def __new__(cls, z0: int, mu: float = 1.0) -> OnlineDesign:
        return super().__new__(cls, as_int("z0", z0, minimum=1), as_probability("mu", mu, closed=True))

    @classmethod
    def design(
        cls,
        channel: ChannelLike | Fraction | None = None,
        ratio: RatioLike | None = None,
        *,
        lam: float | None = None,
    ) -> OnlineDesign:
        """The schedule that spends the energy ratio exactly (:func:`fakeack.design_online`)."""
        return design_online(channel, ratio, lam=lam)

    def __str__(self) -> str:
        return f"online z0={self.z0}" + ("" if self.mu == 1.0 else f", mu={self.mu:.6g}")


OnlineSchedule = OnlineDesign
"""The online schedule as the simulation's schedule: the same class as :class:`OnlineDesign`."""


def design_online(
    channel: ChannelLike | Fraction | None = None, ratio: RatioLike | None = None, *, lam: float | None = None
) -> OnlineDesign:
    r"""The online schedule :math:`(z_0, \mu)` whose high-power rate equals the energy ratio.

    The rate :math:`f(z_0, \mu)` of :func:`fakeack.high_power_rate` without attack has
    :math:`f(z_0, 0) = f(z_0+1, 1)`, so the budget fixes :math:`z_0` (the bracket with
    :math:`f(z_0+1,1) < p/q \le f(z_0,1)`, by comparing the rates with p/q) and then :math:`\mu`.
    On the paper's channel f falls in both, :math:`\mu` has a closed form and all arithmetic is
    exact (:class:`fractions.Fraction`; a float ``lam`` is taken at its exact binary value unless
    a short fraction rounds to it). Under another channel f is the exact engine's rate, not
    linear-fractional in :math:`\mu`, and :math:`\mu` is the root of :math:`f(z_0, \mu) = p/q`
    by bracketing bisection to a width of 1e-15 (``fakeack.model.design.design_under_channel``).

    Parameters
    ----------
    channel : Channel, float or Fraction
        The channel; a number is the paper's, with arrival probability :math:`\lambda \in (0, 1)`
        at low power (a Fraction is used exactly).
    ratio : Fraction
        Energy ratio :math:`p/q`, from :func:`energy_ratio`.
    lam : float or Fraction, keyword-only, optional
        The former name of ``channel`` (a number).

    Returns
    -------
    OnlineDesign
        ``(z0, mu)``; ``mu == 1.0`` exactly when a fixed memory length meets the budget with
        equality (the paper's example: ``lam = 0.5``, ``ratio = 1/7`` gives ``(2, 1.0)``).

    Raises
    ------
    ValueError
        Naming ``ratio`` if no online schedule meets the budget: above :math:`f(1, 1)` (on the
        paper's channel :math:`a/(1+a)`), the most any online schedule with :math:`z_0 \ge 1` can
        spend (the sensor should then simply transmit more often at high power), or so small
        that the memory would be too long.
    """
    ch, name = channel_of(channel, lam, "design_online")
    if ratio is None:
        raise TypeError("design_online() missing ratio")
    if not is_paper_channel(ch):
        return OnlineDesign(*design_under_channel(ch, as_ratio("ratio", ratio)))
    given = lam if lam is not None else channel  # a number as given: a Fraction stays exact
    lam_v = given if isinstance(given, (int, float, Fraction)) else ch.low[0]
    return OnlineDesign(*design_paper(lam_v, ratio, name))


def j_max(system: LinearSystem, channel: ChannelLike | None = None, *, lam: float | None = None) -> float:
    r"""Cost with every flag-ACK blocked (Sec. IV-C): :math:`\sum_{i\ge0}\lambda a^i\,\mathrm{tr}_i`.

    On the paper's channel, :math:`\mathrm{Tr}\,X` with :math:`X = aAXA' + \lambda\bar P + aQ` (a
    Stein equation solved by doubling), not by truncating the series. The sensor then always
    transmits at low power, so under another channel this is J of the offline pattern ``"0"`` by
    the exact engine (on ``GilbertElliott(p, q, 1, 0)``,
    :math:`\frac{q}{p+q}[\mathrm{tr}_0 + p\sum_{t\ge1}(1-q)^{t-1}\mathrm{tr}_t]`).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The channel; a float is the paper's, with arrival probability :math:`\lambda \in (0, 1)`
        at low power.
    lam : float, keyword-only, optional
        The former name of ``channel`` (a float).

    Returns
    -------
    float
        ``math.inf`` when the cost diverges: on the paper's channel when
        :math:`(1-\lambda)\rho(A)^2 \ge 1` (Model note 5: the printed condition
        :math:`(1-\lambda)\rho(A) < 1` is wrong), by the engine when
        :math:`\rho(K_0)\rho(A)^2 \ge 1`; the other costs of the paper's channel return ``inf``
        only for a finite value beyond the double range.
    """
    core = compiled(system)
    ch, name = channel_of(channel, lam, "j_max")
    if not is_paper_channel(ch):
        return pattern_cost(system, ch, [0])
    return core.j_max(as_probability(name, ch.low[0]))


@dataclass(frozen=True, init=False, repr=False)
class OfflineSchedule:
    r"""An offline schedule: the optimal one for an energy ratio (Theorem 3.1), or any periodic
    pattern of power levels.

    Give exactly one of ``ratio`` and ``pattern``. A pattern is one period, first symbol = step 1
    (``"1000000"`` uses high power at steps 1, 8, 15, ...); an all-zero pattern is the sensor that
    always transmits at low power. The sensor follows it whatever the flag-ACKs say.

    Parameters
    ----------
    ratio : Fraction, int/int string or float, optional
        Energy ratio :math:`p/q \in (0, 1)`: the period is :func:`offline_schedule` ``(ratio)``.
    pattern : str or sequence of 0/1, keyword-only, optional
        One period of power levels (1 = high power :math:`\Delta`), a string of ``0``/``1`` or a
        sequence of 0/1 or booleans.

    Examples
    --------
    >>> OfflineSchedule(Fraction(1, 7))
    OfflineSchedule(ratio=Fraction(1, 7))
    >>> str(OfflineSchedule("1/7"))
    'offline 1/7: 1000000'
    >>> OfflineSchedule(pattern="0110")
    OfflineSchedule(pattern='0110')
    >>> OfflineSchedule(pattern=[1, 0, 0]).pattern.tolist(), OfflineSchedule(pattern="10").ratio
    ([1, 0, 0], None)
    """

    ratio: Fraction | None
    """The energy ratio, or ``None`` for a schedule given by its pattern."""
    _given: tuple[int, ...] | None

    def __init__(self, ratio: RatioLike | None = None, *, pattern: str | Sequence[int] | None = None) -> None:
        if (ratio is None) == (pattern is None):
            raise TypeError("give exactly one of ratio and pattern")
        if ratio is not None:
            object.__setattr__(self, "ratio", as_ratio("ratio", ratio))
            object.__setattr__(self, "_given", None)
        else:
            object.__setattr__(self, "ratio", None)
            object.__setattr__(self, "_given", as_pattern(pattern))

    @property
    def pattern(self) -> IntArray:
        """One period as an ``int64`` array of 0/1, 1 = high power, first entry = step 1."""
        if self._given is not None:
            return np.array(self._given, dtype=np.int64)
        assert self.ratio is not None
        return offline_schedule(self.ratio)

    @property
    def high_fraction(self) -> Fraction:
        """The fraction of steps at high power: the ratio, or the pattern's share of ones."""
        if self._given is not None:
            return Fraction(sum(self._given), len(self._given))
        assert self.ratio is not None
        return self.ratio

    def __repr__(self) -> str:
        if self._given is None:
            return f"OfflineSchedule(ratio={self.ratio!r})"
        if len(self._given) <= MAX_PATTERN_REPR:
            return f"OfflineSchedule(pattern={''.join(map(str, self._given))!r})"
        return f"OfflineSchedule(pattern=<{sum(self._given)} high of {len(self._given)} steps>)"

    def __str__(self) -> str:
        pat = self.pattern
        body = "".join(map(str, pat.tolist())) if len(pat) <= 40 else f"{len(pat)} steps"
        if self.ratio is None:
            return f"offline pattern: {body}"
        return f"offline {self.ratio}: {body}"


#: Longest pattern a repr writes out.
MAX_PATTERN_REPR = 64
#: Longest offline pattern accepted (symbols per period).
MAX_PATTERN = 10_000_000


def as_pattern(pattern: Any) -> tuple[int, ...]:
    """A non-empty 0/1 pattern (an offline schedule's, a jammer's) from a string of 0/1 or a
    sequence of 0/1 or booleans; errors name ``pattern``."""
    if isinstance(pattern, str):
        if not pattern or set(pattern) - {"0", "1"}:
            raise ValueError(f"pattern must be a non-empty string of 0 and 1, got {pattern!r}")
        return tuple(int(c) for c in pattern)
    if pattern is None or isinstance(pattern, (bytes, bool, np.bool_, int, float)):
        raise TypeError(f"pattern must be a string or a sequence of 0/1, got {type(pattern).__name__}")
    try:
        arr = np.asarray(pattern)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"pattern: cannot be read as a sequence of 0/1 ({exc})") from None
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"pattern must be a non-empty 1-D sequence of 0/1, got shape {arr.shape}")
    if arr.size > MAX_PATTERN:
        raise ValueError(f"pattern: longer than {MAX_PATTERN} steps")
    if arr.dtype.kind not in "biuf":
        raise TypeError(f"pattern must hold 0/1 or booleans, got dtype {arr.dtype}")
    if not np.all(np.isin(arr, (0, 1))):
        raise ValueError("pattern must hold only 0 and 1")
    return tuple(int(x) for x in arr)
