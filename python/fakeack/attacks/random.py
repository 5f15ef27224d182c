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
from ..model.channels import Channel, ChannelLike, channel_argument, is_paper_channel
from ..model.schedules import OnlineDesign, check_online, j_offline
from ..model.system import LinearSystem, compiled
from ._args import required
from .kinds import Attack, FlagInjection, RandomBlocking
from .threshold import _problem

__all__ = [
    "beta_bar_random",
    "RandomSweep",
    "random_blocking_sweep",
    "rate_matching_attack",
]


def beta_bar_random(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    ratio: RatioLike | None = None,
    z0: int | None = None,
    mu: float | None = None,
    *,
    lam: float | None = None,
) -> float:
    r"""The threshold against independent blocking: the root of
    :math:`J(\mathrm{RandomBlocking}(\beta)) = J_{\mathrm{off}}`.

    J under independent blocking increases with :math:`\beta` from :math:`J_{\mathrm{on}}` to
    :math:`J_{\max}`, so the root is unique; it is found by bisection to full precision.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float. Under a Markov channel every J and rate comes from the
        exact engine (:class:`fakeack.Scenario`).
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
    pb = _problem("beta_bar_random", channel, lam, ratio, z0, mu)
    if pb.lam is not None:
        return core.beta_bar_random(
            pb.lam, pb.ratio.numerator, pb.ratio.denominator, pb.design.z0, pb.design.mu
        )
    j_off = j_offline(system, pb.channel, pb.ratio)

    def j(b: float) -> float:
        return Scenario(system, pb.channel, pb.design, RandomBlocking(b)).cost()

    if j(0.0) >= j_off:
        return 0.0
    if j(1.0) < j_off:
        return 1.0
    # Bisection, not Brent: J may be inf near beta = 1 (past the growth condition).
    lo, hi = 0.0, 1.0
    while hi - lo > 4e-16 * hi:
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if j(mid) < j_off:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


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
    """The paper's lam, or a Markov channel's mean low-power arrival probability."""
    channel: Channel | None = None
    """The channel analysed."""


def random_blocking_sweep(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    z0: int | None = None,
    betas: npt.ArrayLike | None = None,
    mu: float = 1.0,
    gamma: float = 0.0,
    *,
    lam: float | None = None,
) -> RandomSweep:
    r"""J under :class:`fakeack.RandomBlocking` at many budgets, sharing the traces.

    Each J is the renewal sum of :func:`fakeack.j_attack`, :math:`O(\tau_{\max} z_0)` after the
    traces, so :math:`10^4` budgets on the paper's system take milliseconds.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float. Under a Markov channel every J and rate comes from the
        exact engine (:class:`fakeack.Scenario`).
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
    ch, name = channel_argument(channel, lam, "random_blocking_sweep")
    z0 = as_int("z0", required("random_blocking_sweep", "z0", z0), minimum=1)
    g = as_probability("gamma", gamma, closed=True)
    b = np.asarray(required("random_blocking_sweep", "betas", betas), dtype=np.float64)
    if b.ndim != 1 or b.size == 0:
        raise ValueError(f"betas must be a non-empty 1-D array, got shape {b.shape}")
    if not np.all(np.isfinite(b)) or np.any((b < 0) | (b > 1)):
        raise ValueError("betas must lie in [0, 1]")
    if is_paper_channel(ch):
        lam_f, design = check_online(float(ch.low[0]), z0, mu)
        j = core.j_random_sweep(lam_f, design.z0, design.mu, g, b.tolist())
        return RandomSweep(b, j, g, design.z0, design.mu, lam_f, ch)
    design = OnlineDesign(z0, as_probability("mu", mu, closed=True))

    def attack(x: float) -> Attack:
        return FlagInjection(g, RandomBlocking(x)) if g > 0 else RandomBlocking(x)

    j = np.array([Scenario(system, ch, design, attack(float(x))).cost() for x in b])
    return RandomSweep(b, j, g, design.z0, design.mu, ch.mean_low, ch)


def rate_matching_attack(
    channel: ChannelLike | None = None,
    z0: int | None = None,
    beta: float | Fraction | None = None,
    mu: float = 1.0,
    min_gap: int = 1,
    *,
    lam: float | None = None,
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
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float. Under a Markov channel every J and rate comes from the
        exact engine (:class:`fakeack.Scenario`).
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
    ch, name = channel_argument(channel, lam, "rate_matching_attack")
    paper = is_paper_channel(ch)
    z0_v = required("rate_matching_attack", "z0", z0)
    if paper:
        lam_f, design = check_online(float(ch.low[0]), z0_v, mu)
    else:
        design = OnlineDesign(as_int("z0", z0_v, minimum=1), as_probability("mu", mu, closed=True))
    z0, mu = design
    beta_v = required("rate_matching_attack", "beta", beta)
    b = as_probability("beta", float(as_fraction("beta", beta_v)), closed=True)
    gap = as_int("min_gap", min_gap, minimum=1)
    # Flag-ACK rates do not depend on the system.
    if paper:
        target = _fakeack.high_power_rate(lam_f, z0, mu)
    else:
        target = Scenario(any_system(), ch, design).flag_rates().delivered
    block = RandomBlocking(b)

    def excess(g: float) -> float:
        if gap > 1 or not paper:
            sc = Scenario(any_system(), ch, design, FlagInjection(g, block, gap))
            return sc.flag_rates().delivered - target
        att = _fakeack.Attack.injection(g, _fakeack.Attack.random(b))
        return _fakeack.flag_rates(lam_f, z0, mu, att)[1] - target

    if excess(0.0) >= 0.0:  # beta = 0: nothing to hide
        return FlagInjection(0.0, block, gap)
    if excess(1.0) < 0.0:
        raise ValueError(
            f"min_gap: with min_gap={gap}, forging at every allowed step still delivers fewer "
            "flag-ACKs than the attack-free rate"
        )
    gamma = brentq(excess, 0.0, 1.0, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return FlagInjection(gamma, block, gap)
