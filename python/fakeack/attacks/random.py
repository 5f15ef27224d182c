"""Independent blocking and rate matching: the threshold against random blocking, its sweep over
beta, and the forger who keeps the flag count at the attack-free rate."""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq

from .. import _fakeack
from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_fraction, as_int, as_probability
from ..detection.flags import any_system
from ..engine.scenario import Scenario
from ..model.schedules import OnlineDesign, check_online
from ..model.system import LinearSystem, compiled
from .kinds import FlagInjection, RandomBlocking
from .threshold import _problem

__all__ = [
    "beta_bar_random",
    "RandomSweep",
    "random_blocking_sweep",
    "rate_matching_attack",
]


def beta_bar_random(
    system: LinearSystem, lam: float, ratio: RatioLike, z0: int | None = None, mu: float | None = None
) -> float:
    r"""The threshold against independent blocking: the root of
    :math:`J(\mathrm{RandomBlocking}(\beta)) = J_{\mathrm{off}}`.

    J under independent blocking increases with :math:`\beta` from :math:`J_{\mathrm{on}}` to
    :math:`J_{\max}`, so the root is unique; it is found by bisection to full precision.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio p/q.
    z0, mu : int and float, optional
        The online schedule; by default :func:`fakeack.design_online` ``(lam, ratio)``.

    Returns
    -------
    float
        0 when the online schedule does not beat the offline one even unattacked; 1 when even
        blocking every flag does not reach :math:`J_{\mathrm{off}}`.
    """
    core = compiled(system)
    pb = _problem(lam, ratio, z0, mu)
    return core.beta_bar_random(pb.lam, pb.ratio.numerator, pb.ratio.denominator, pb.design.z0, pb.design.mu)


@dataclass(frozen=True)
class RandomSweep:
    """J under independent blocking at each β (see :func:`random_blocking_sweep`)."""

    beta: FloatArray
    """The budgets."""
    j_attack: FloatArray
    """J at each budget (``inf`` past the growth condition)."""
    gamma: float
    """The forging probability of the sweep (0: blocking alone)."""
    z0: int
    mu: float
    lam: float


def random_blocking_sweep(
    system: LinearSystem, lam: float, z0: int, betas: npt.ArrayLike, mu: float = 1.0, gamma: float = 0.0
) -> RandomSweep:
    r"""J under :class:`fakeack.RandomBlocking` at many budgets, sharing the traces.

    Each J is the renewal sum of :func:`fakeack.j_attack`, :math:`O(\tau_{\max} z_0)` after the
    traces, so :math:`10^4` budgets on the paper's system take milliseconds.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    betas : array_like
        Budgets in [0, 1].
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    gamma : float, optional
        Also forge flag-ACKs with this probability (:class:`fakeack.FlagInjection` with a
        :class:`fakeack.RandomBlocking` block).
    """
    core = compiled(system)
    lam, design = check_online(lam, z0, mu)
    g = as_probability("gamma", gamma, closed=True)
    b = np.asarray(betas, dtype=np.float64)
    if b.ndim != 1 or b.size == 0:
        raise ValueError(f"betas must be a non-empty 1-D array, got shape {b.shape}")
    if not np.all(np.isfinite(b)) or np.any((b < 0) | (b > 1)):
        raise ValueError("betas must lie in [0, 1]")
    j = core.j_random_sweep(lam, design.z0, design.mu, g, b.tolist())
    return RandomSweep(b, j, g, design.z0, design.mu, lam)


def rate_matching_attack(
    lam: float, z0: int, beta: float | Fraction, mu: float = 1.0, min_gap: int = 1
) -> FlagInjection:
    r"""The injection that hides independent blocking from the flag count.

    Returns ``FlagInjection(gamma, block=RandomBlocking(beta), min_gap=min_gap)`` whose long-run
    rate of flag-ACKs reaching the sensor (genuine delivered plus forged) equals the attack-free
    rate, so a test of the flag count alone (:func:`fakeack.detect_attack`) sees nothing on
    average. With ``min_gap = 1`` a root always exists in [0, 1]: with :math:`\gamma = 0` at most
    the attack-free rate arrives, with :math:`\gamma = 1` one flag per step. Found by Brent's
    method to full precision.

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    beta : float
        The blocking probability to hide, in [0, 1].
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    min_gap : int, optional
        The injection's ``min_gap`` (default 1: forge on any quiet step). With ``min_gap > 1`` the
        rates come from the exact engine (:class:`fakeack.Scenario`); ``min_gap = z0 + 1`` also
        hides the attack from every test of impossible gaps between flag-ACKs.

    Raises
    ------
    ValueError
        Naming ``min_gap`` when even forging at every allowed step delivers fewer flag-ACKs than
        the attack-free rate.

    Examples
    --------
    >>> att = rate_matching_attack(0.5, 2, 0.2)
    >>> abs(high_power_rate(0.5, 2, att) - high_power_rate(0.5, 2)) < 1e-12
    True
    """
    lam, design = check_online(lam, z0, mu)
    z0, mu = design
    b = as_probability("beta", float(as_fraction("beta", beta)), closed=True)
    gap = as_int("min_gap", min_gap, minimum=1)
    target = _fakeack.high_power_rate(lam, z0, mu)
    block = RandomBlocking(b)

    def excess(g: float) -> float:
        if gap > 1:
            design = OnlineDesign(z0, mu)
            sc = Scenario(any_system(), lam, design, FlagInjection(g, block, gap))
            return sc.flag_rates().delivered - target
        att = _fakeack.Attack.injection(g, _fakeack.Attack.random(b))
        return _fakeack.flag_rates(lam, z0, mu, att)[1] - target

    if excess(0.0) >= 0.0:  # beta = 0: nothing to hide
        return FlagInjection(0.0, block, gap)
    if excess(1.0) < 0.0:
        raise ValueError(
            f"min_gap: with min_gap={gap}, forging at every allowed step still delivers fewer "
            "flag-ACKs than the attack-free rate"
        )
    gamma = brentq(excess, 0.0, 1.0, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return FlagInjection(gamma, block, gap)
