r"""The delay frontier: what an attack of a family costs the estimate against how soon a sequential
detector with a given mean time to a false alarm sees it, beside the windowed count test at the
same false-alarm rate."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .._internal.progress import Progress
from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_int, as_real
from ..attacks.automata import MimicryAttack
from ..attacks.chain import j_attack
from ..attacks.kinds import Attack, PeriodicBlocking, RandomBlocking
from ..attacks.random import rate_matching_attack
from ..detection.cusum import CusumTest
from ..detection.flags import flag_interval_moments
from ..detection.interval_test import MIN_EXPECTED_FLAGS
from ..detection.probability import detection_probability
from ..detection.run_length import cusum_run_length, cusum_threshold
from ..model.schedules import OnlineDesign, design_online, j_offline, j_online
from ..model.system import LinearSystem

__all__ = [
    "DELAY_FAMILIES",
    "DelayFrontier",
    "delay_frontier",
]

#: The attack families of :func:`delay_frontier`.
DELAY_FAMILIES = ("random", "careful", "periodic", "mimicry")
#: Blocking patterns (r, t) of the periodic family: the paper's consecutive blocking.
_PERIODIC = ((1, 10), (1, 5), (1, 3), (1, 2), (2, 3), (4, 5))


@dataclass(frozen=True)
class DelayFrontier:
    """One family's costs and detection delays (see :func:`delay_frontier`)."""

    family: str
    attacks: list[Attack | MimicryAttack]
    """The family's attacks, in order."""
    j: FloatArray
    """Each attack's J (stationary, online, never detected)."""
    cusum_delay: FloatArray
    """Mean steps from the attack's onset to the CUSUM's alarm (onset just after a delivered
    flag-ACK with W = 0: the CUSUM's worst case)."""
    cusum_error: FloatArray
    """The stated accuracy of each ``cusum_delay`` (:attr:`fakeack.CusumRunLength.error`)."""
    window_detection: FloatArray
    """The count test's detection probability per window (with the support check)."""
    window_delay: FloatArray
    """The count test's mean delay, ``window / 2 + window / detection``: the onset uniform in a
    window, detection from the first whole attacked window on (``inf`` where never)."""
    interval_detection: FloatArray
    """The interval test's detection probability per window (with the support check); NaN for
    a window too short for it (fewer than 100 expected flag-ACKs, where its normal law fails)."""
    interval_delay: FloatArray
    """The interval test's mean delay, as ``window_delay``."""
    cusum: CusumTest
    """The CUSUM, its threshold set for ``arl0``."""
    arl0: float
    """Mean steps to a false alarm of both detectors."""
    window: int
    alpha: float
    """The count test's level, ``window / arl0``."""
    j_online: float
    j_offline: float


def _family(family: str, lam: float, design: OnlineDesign, grid: int) -> list[Attack | MimicryAttack]:
    if family == "mimicry":
        return [MimicryAttack()]
    if family == "periodic":
        return [PeriodicBlocking(r, t) for r, t in _PERIODIC]
    betas = np.linspace(0.1, 0.9, grid)
    if family == "random":
        return [RandomBlocking(float(b)) for b in betas]
    out: list[Attack | MimicryAttack] = []
    for b in betas:
        try:  # the careful forger cannot match the rate at every beta
            out.append(rate_matching_attack(lam, design.z0, float(b), design.mu, min_gap=design.z0 + 1))
        except ValueError:
            continue
    return out


def delay_frontier(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    arl0: float = 1e5,
    family: str = "random",
    *,
    alternative: object = None,
    window: int = 1000,
    grid: int = 5,
    progress: bool | None = None,
) -> DelayFrontier:
    r"""J against the mean detection delay for the attacks of one family, for the flag-ACK CUSUM
    and for the windowed tests at the same mean time to a false alarm.

    The CUSUM (:class:`fakeack.CusumTest` against ``alternative``) gets the threshold of
    :func:`fakeack.cusum_threshold` for ``arl0``; each attack's delay is
    :func:`fakeack.cusum_run_length` from the renewal start. The count test of ``window`` steps
    at level :math:`\alpha = ` ``window / arl0`` has the same mean time to a false alarm
    (``window / alpha`` steps); its delay is ``window / 2 + window / d`` with d its detection
    probability per window (:func:`fakeack.detection_probability`, with the support check); the
    interval test likewise.
    Families: ``"random"`` (:class:`fakeack.RandomBlocking` at ``grid`` budgets in [0.1, 0.9]),
    ``"careful"`` (:func:`fakeack.rate_matching_attack` with ``min_gap = z0 + 1`` at those
    budgets, where a rate-matching forger exists), ``"periodic"`` (the paper's consecutive
    blocking at r/t = 1/10, 1/5, 1/3, 1/2, 2/3, 4/5) and ``"mimicry"``.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Low-power arrival probability of the paper's channel.
    ratio : Fraction
        Energy ratio; the online schedule is :func:`fakeack.design_online` ``(lam, ratio)``.
    arl0 : float, optional
        Mean steps to a false alarm (default 1e5, so ``alpha = 0.01`` at 1000-step windows).
    family : {"random", "careful", "periodic", "mimicry"}
        The attack family.
    alternative : optional
        The CUSUM's alternative (default ``RandomBlocking(0.5)``).
    window : int, optional
        The count test's window (default 1000 steps); ``window < arl0``.
    grid : int, optional
        Budgets of the random and careful families (default 5).
    progress : bool, optional
        A progress bar over the attacks (default: when run interactively and longer than a
        second; needs tqdm).

    Returns
    -------
    DelayFrontier
    """
    if family not in DELAY_FAMILIES:
        raise ValueError(f"family must be one of {DELAY_FAMILIES}, got {family!r}")
    a0 = as_real("arl0", arl0)
    n = as_int("window", window, minimum=1)
    if not n < a0:
        raise ValueError(f"window must be shorter than arl0 = {a0}, got {n}")
    points = as_int("grid", grid, minimum=1, maximum=100)
    z0, mu = design_online(lam, ratio)
    design = OnlineDesign(z0, mu)
    alt = RandomBlocking(0.5) if alternative is None else alternative
    cusum = CusumTest(alt, cusum_threshold(lam, design, alt, a0))
    alpha = n / a0
    m, _ = flag_interval_moments(lam, z0, mu)
    interval = n / m >= MIN_EXPECTED_FLAGS  # else the interval test's normal law does not hold
    attacks = _family(family, lam, design, points)
    j, delay, err, d, di = (np.empty(len(attacks)) for _ in range(5))
    bar = Progress(len(attacks), progress, desc="fakeack delay_frontier", unit="attack")
    for k, attack in enumerate(attacks):
        bar(k)
        j[k] = j_attack(system, lam, z0, attack=attack, mu=mu)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # the accuracy is reported beside it
            run = cusum_run_length(lam, design, cusum, attack)
        delay[k], err[k] = run.mean, run.error
        d[k] = detection_probability(lam, z0, attack, n, alpha, "count", mu=mu)
        di[k] = detection_probability(lam, z0, attack, n, alpha, "interval", mu=mu) if interval else math.nan
    bar(len(attacks))
    bar.close()
    with np.errstate(divide="ignore"):
        window_delay, interval_delay = n / 2 + n / d, n / 2 + n / di
    return DelayFrontier(
        family,
        attacks,
        j,
        delay,
        err,
        d,
        window_delay,
        di,
        interval_delay,
        cusum,
        a0,
        n,
        alpha,
        j_online(system, lam, z0, mu),
        j_offline(system, lam, ratio),
    )
