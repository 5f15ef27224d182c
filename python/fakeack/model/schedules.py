"""Power schedules without attack: optimal offline (Theorem 3.1) and ACK-based online (Thm 4.5)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, NamedTuple

import numpy as np

from .. import _fakeack
from .._internal.types import IntArray, RatioLike
from .._internal.validate import as_fraction, as_int, as_probability, as_ratio
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


def offline_schedule(ratio: RatioLike) -> IntArray:
    r"""One period of the optimal offline schedule :math:`\theta^\star_{\mathrm{off}}` (Theorem 3.1).

    With :math:`s_0 = \lfloor q/p \rfloor - 1`, the period holds :math:`m = q - p(s_0+1)` blocks
    ``1 0...0`` of length :math:`s_0+2` followed by :math:`n = p(s_0+2) - q` blocks of length
    :math:`s_0+1` (Model note 1: the printed pattern swaps m and n).

    Parameters
    ----------
    ratio : Fraction, int/int string or float
        Energy ratio :math:`p/q \in (0, 1)`, e.g. from :func:`energy_ratio`.

    Returns
    -------
    numpy.ndarray
        ``int64`` array of length q with exactly p ones (1 = high power :math:`\Delta`).

    Examples
    --------
    >>> offline_schedule(Fraction(1, 7)).tolist()
    [1, 0, 0, 0, 0, 0, 0]
    """
    r = as_ratio("ratio", ratio)
    return _fakeack.offline_schedule(r.numerator, r.denominator)


def j_offline(system: LinearSystem, lam: float, ratio: RatioLike) -> float:
    r"""Cost J of the optimal offline schedule (Proposition 3.1, with m and n as corrected).

    .. math::
       J = \frac{1}{q}\Big[m\sum_{i=0}^{s_0+1}\big(1+\lambda(s_0+1-i)\big)a^i\,\mathrm{tr}_i
           + n\sum_{i=0}^{s_0}\big(1+\lambda(s_0-i)\big)a^i\,\mathrm{tr}_i\Big],

    with :math:`a = 1-\lambda` and :math:`\mathrm{tr}_i = \mathrm{Tr}\,h^i(\bar P)`.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio :math:`p/q \in (0, 1)`.

    Returns
    -------
    float
        :math:`\lim \frac1T\sum_{k\le T}\mathrm{Tr}\,\mathbb E[P_k]` under
        :func:`offline_schedule`. ``math.inf`` (never NaN) when this finite value lies beyond the
        double range (about 1.8e308): an IEEE overflow, as numpy gives, which a long period
        reaches where :math:`(1-\lambda)\rho(A)^2 \ge 1` (e.g. the paper's system at
        ``lam = 0.25``, ``ratio = 1/16384``). :func:`j_max`'s ``inf`` means something else: that
        cost diverges.
    """
    core = compiled(system)
    lam = as_probability("lam", lam)
    r = as_ratio("ratio", ratio)
    return core.j_offline(lam, r.numerator, r.denominator)


def check_online(lam: float, z0: int, mu: float) -> tuple[float, OnlineDesign]:
    """``lam`` and the online design ``(z0, mu)``, validated in that order."""
    return as_probability("lam", lam), OnlineDesign(z0, mu)


def j_online(system: LinearSystem, lam: float, z0: int, mu: float = 1.0) -> float:
    r"""Cost J of the ACK-based online schedule :math:`\theta_{\mathrm{on}}` (Theorem 4.5).

    Theorem 4.5 of the paper, after the online schedule of Han et al. [1]_, corrected as in
    Model note 2, with :math:`a = 1-\lambda`:

    .. math::
       J = \frac{\lambda\big[\sum_{i=0}^{z_0} a^i\,\mathrm{tr}_i + (1-\mu)\,a^{z_0+1}
           \mathrm{tr}_{z_0+1}\big]}{1 - \mu a^{z_0+1} - (1-\mu) a^{z_0+2}}.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length :math:`z_0 \ge 1`: a flag-ACK after :math:`z_0` consecutive losses.
    mu : float, optional
        Probability :math:`\mu \in [0, 1]` that the detector uses the :math:`z_0`-bit memory at a
        step (:math:`z_0+1` bits otherwise). Default 1 (fixed length).

    Returns
    -------
    float
        ``math.inf`` (never NaN) when this finite cost lies beyond the double range (a memory of
        thousands of steps where :math:`(1-\lambda)\rho(A)^2 \ge 1`); unlike :func:`j_max`'s
        ``inf``, not a divergence.

    References
    ----------
    .. [1] D. Han, P. Cheng, J. Chen, L. Shi, "An online sensor power schedule for remote state
       estimation with communication energy constraint", IEEE TAC, 2014.
    """
    core = compiled(system)
    lam, design = check_online(lam, z0, mu)
    return core.j_online(lam, design.z0, design.mu)


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
    def design(cls, lam: float | Fraction, ratio: RatioLike) -> OnlineDesign:
        """The schedule that spends the energy ratio exactly (:func:`fakeack.design_online`)."""
        return design_online(lam, ratio)

    def __str__(self) -> str:
        return f"online z0={self.z0}" + ("" if self.mu == 1.0 else f", mu={self.mu:.6g}")


OnlineSchedule = OnlineDesign
"""The online schedule as the simulation's schedule: the same class as :class:`OnlineDesign`."""


def _rate_exact(lam: Fraction, z0: int, mu: Fraction) -> Fraction:
    a = 1 - lam
    return lam * a**z0 * (mu + (1 - mu) * a) / (1 - mu * a ** (z0 + 1) - (1 - mu) * a ** (z0 + 2))


def design_online(lam: float | Fraction, ratio: RatioLike) -> OnlineDesign:
    r"""The online schedule :math:`(z_0, \mu)` whose high-power rate equals the energy ratio.

    The rate :math:`f(z_0, \mu)` of :func:`online_high_power_rate` falls from :math:`f(z_0, 1)` to
    :math:`f(z_0, 0) = f(z_0+1, 1)` as :math:`\mu` goes from 1 to 0, so the budget fixes
    :math:`z_0` (the bracket with :math:`f(z_0+1,1) < p/q \le f(z_0,1)`) and then :math:`\mu` in
    closed form. All arithmetic is exact (:class:`fractions.Fraction`; a float ``lam`` is taken at
    its exact binary value unless a short fraction rounds to it).

    Parameters
    ----------
    lam : float or Fraction
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio :math:`p/q`, from :func:`energy_ratio`.

    Returns
    -------
    OnlineDesign
        ``(z0, mu)``; ``mu == 1.0`` exactly when a fixed memory length meets the budget with
        equality (the paper's example: ``lam = 0.5``, ``ratio = 1/7`` gives ``(2, 1.0)``).

    Raises
    ------
    ValueError
        If the budget exceeds :math:`f(1, 1) = a/(1+a)`, the most any online schedule with
        :math:`z_0 \ge 1` can spend: the sensor should then simply transmit more often at high power.
    """
    lam_f = as_probability("lam", lam)
    lam_q = as_fraction("lam", lam)
    rho = as_ratio("ratio", ratio)
    one = Fraction(1)
    top = _rate_exact(lam_q, 1, one)
    if rho > top:
        raise ValueError(
            f"ratio {rho} exceeds the largest high-power rate an online schedule with z0 >= 1 can "
            f"use at lam={lam_f} ({float(top):.6g} = (1-lam)/(2-lam))"
        )
    # f(z, 1) falls geometrically in z: bracket z0 in floats (bisection), then settle the boundary
    # exactly, where exact powers stay cheap.
    z0 = _largest_z_float(lam_f, float(rho))
    if z0 > MAX_DESIGN_Z0:
        raise ValueError(
            f"ratio {rho} is so small that the online schedule would need a memory of about {z0} "
            f"steps (more than {MAX_DESIGN_Z0})"
        )
    if z0 <= EXACT_DESIGN_Z0:
        z0 = max(1, z0 - 1)
        while _rate_exact(lam_q, z0 + 1, one) >= rho:
            z0 += 1
        # Now f(z0+1, 1) < rho <= f(z0, 1).
        if _rate_exact(lam_q, z0, one) == rho:
            return OnlineDesign(z0, 1.0)
        a = 1 - lam_q
        mu_q = (rho * (1 - a ** (z0 + 2)) - lam_q * a ** (z0 + 1)) / ((1 - a) * a**z0 * (lam_q + rho * a))
        return OnlineDesign(z0, float(mu_q))
    rf, ln_a = float(rho), math.log1p(-lam_f)
    apow = math.exp(z0 * ln_a)
    mu = (rf * -math.expm1((z0 + 2) * ln_a) - lam_f * apow * (1.0 - lam_f)) / (
        lam_f * apow * (lam_f + rf * (1.0 - lam_f))
    )
    return OnlineDesign(z0, min(max(mu, 0.0), 1.0))


#: Largest memory design_online returns, and the largest it settles in exact arithmetic.
MAX_DESIGN_Z0 = 1_000_000
EXACT_DESIGN_Z0 = 2_000


def _largest_z_float(lam: float, rho: float) -> int:
    """Largest z >= 1 with f(z, 1) >= rho in floating point (bisection; f falls in z)."""
    ln_a = math.log1p(-lam)

    def f(z: int) -> float:
        # 1 - a^(z+1) by expm1: for lam below 1e-16, 1 - lam rounds to 1.
        return lam * math.exp(z * ln_a) / -math.expm1((z + 1) * ln_a)

    lo, hi = 1, 2
    while f(hi) >= rho and hi < 2**40:
        lo, hi = hi, hi * 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if f(mid) >= rho:
            lo = mid
        else:
            hi = mid
    return lo


def j_max(system: LinearSystem, lam: float) -> float:
    r"""Cost with every flag-ACK blocked (Sec. IV-C): :math:`\sum_{i\ge0}\lambda a^i\,\mathrm{tr}_i`.

    Computed as :math:`\mathrm{Tr}\,X` with :math:`X = aAXA' + \lambda\bar P + aQ` (a Stein
    equation solved by doubling), not by truncating the series.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.

    Returns
    -------
    float
        ``math.inf`` when :math:`(1-\lambda)\rho(A)^2 \ge 1`: here ``inf`` means the series
        diverges (Model note 5: the printed condition :math:`(1-\lambda)\rho(A) < 1` is wrong),
        whereas the other costs return ``inf`` only for a finite value beyond the double range.
    """
    core = compiled(system)
    lam = as_probability("lam", lam)
    return core.j_max(lam)


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
            object.__setattr__(self, "_given", _as_pattern(pattern))

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


def _as_pattern(pattern: Any) -> tuple[int, ...]:
    """A non-empty 0/1 pattern from a string of 0/1 or a sequence of 0/1 or booleans."""
    if isinstance(pattern, str):
        if not pattern or set(pattern) - {"0", "1"}:
            raise ValueError(f"pattern must be a non-empty string of 0 and 1, got {pattern!r}")
        return tuple(int(c) for c in pattern)
    if isinstance(pattern, bytes):
        raise TypeError("pattern must be a string or a sequence of 0/1, got bytes")
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
