r"""The online design most robust to flag-ACK blocking: the least worst-case J within the energy budget.

The online schedule (z0, mu) spends, without attack, the high-power rate :math:`f(z_0, \mu)`,
which grows with mu at fixed z0 and falls with z0, with :math:`f(z_0, 0) = f(z_0 + 1, 1)`.
:func:`fakeack.design_online` picks the design that spends the ratio p/q exactly, the best one
without attack. Against an attacker that blocks a fraction beta of the genuine flag-ACKs, the
worst-case J of a design is :func:`fakeack.worst_attack`'s; :func:`robust_design` scans the
designs that spend at most p/q and returns the one of least worst-case J.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_int, as_probability, as_ratio
from ..engine.scenario import Scenario
from ..model.channels import ChannelLike, as_channel, is_paper_channel
from ..model.schedules import OfflineSchedule, OnlineDesign, design_online, offline_schedule
from ..model.system import LinearSystem, compiled
from .attack import worst_attack

__all__ = ["RobustDesign", "robust_design"]


@dataclass(frozen=True, eq=False)
class RobustDesign:
    """The online design of least worst-case J found by :func:`robust_design`, and its table."""

    design: OnlineDesign
    """The design of least worst-case J among those searched (ties: the one spending most)."""
    j_worst: float
    """Its worst-case J: :func:`fakeack.worst_attack`'s ``j`` at budget ``beta``."""
    nominal: OnlineDesign
    """:func:`fakeack.design_online`'s design, spending the ratio exactly (best without attack)."""
    j_nominal_worst: float
    """The nominal design's worst-case J."""
    j_offline: float
    """J of the offline schedule of the same ratio (which no flag-ACK attack reaches)."""
    beta: float
    """The blocking budget: the largest fraction of genuine flag-ACKs blocked."""
    designs: tuple[OnlineDesign, ...]
    """The designs searched, by memory z0 then decreasing mu."""
    high_power_rate: FloatArray
    """Per design, its attack-free high-power rate (at most the ratio)."""
    j_free: FloatArray
    """Per design, its attack-free J."""
    j_worst_all: FloatArray
    """Per design, its worst-case J."""
    j_lp: FloatArray
    """Per design, the worst-attack LP's bound (``j_worst <= j_lp``)."""


def robust_design(
    system: LinearSystem,
    channel: ChannelLike,
    ratio: RatioLike,
    beta: float,
    *,
    extra_memory: int = 2,
    mu_points: int = 5,
    tau_max: int | None = None,
) -> RobustDesign:
    r"""The online design (z0, mu) within the energy budget whose worst-case J under blocking is least.

    **Feasible designs.** Blocking only lowers the sensor's high-power rate, so a design meets the
    budget under every blocking attack when its attack-free rate :math:`f(z_0, \mu)` is at most
    the ratio p/q. With :math:`(z^\star, \mu^\star)` = :func:`fakeack.design_online` (the rate
    equal to p/q), these are :math:`(z^\star, \mu)` with :math:`\mu \le \mu^\star` and every
    design of a longer memory (:math:`z_0 > z^\star`; :math:`(z_0, 0)` is :math:`(z_0 + 1, 1)`).

    **Search.** For :math:`z_0 = z^\star, \dots, z^\star +` ``extra_memory``, ``mu_points``
    values of mu evenly spaced on :math:`(0, \mu_{\max}]` (:math:`\mu_{\max} = \mu^\star` at
    :math:`z^\star`, else 1), both ends of each memory's range thus included. Each design's
    worst-case J is :func:`fakeack.worst_attack` at ``beta`` (the worst over every attacker that
    sees the holding time and the detector's state and blocks at most a fraction beta of the
    genuine flag-ACKs). The result is the best design *of those searched*; with ``beta = 0`` it is
    the nominal design (J falls with the energy spent).

    Parameters
    ----------
    system : LinearSystem
        The process and its sensor.
    channel : Channel or float
        The packet channel (a float: the paper's, with that low-power arrival probability).
    ratio : Fraction, int/int string or float
        The energy ratio p/q the sensor may spend.
    beta : float
        The blocking budget, in [0, 1].
    extra_memory : int, keyword-only, optional
        How many memories beyond :math:`z^\star` to search (0 to 20; default 2).
    mu_points : int, keyword-only, optional
        Values of mu per memory (1 to 50; default 5; 1: the largest only).
    tau_max : int, keyword-only, optional
        Passed to :func:`fakeack.worst_attack` (None: its automatic truncation).

    Returns
    -------
    RobustDesign

    Raises
    ------
    TypeError, ValueError
        Naming the argument, and as :func:`fakeack.design_online` and
        :func:`fakeack.worst_attack` do.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> r = robust_design(s, 0.5, "1/10", 0.5, extra_memory=1, mu_points=2)
    >>> r.nominal, r.design
    (OnlineDesign(z0=2, mu=0.45454545454545453), OnlineDesign(z0=3, mu=1.0))
    >>> bool(r.j_worst < r.j_nominal_worst)
    True
    """
    compiled(system)
    ch = as_channel(channel, "channel")
    r = as_ratio("ratio", ratio)
    b = as_probability("beta", beta, closed=True)
    extra = as_int("extra_memory", extra_memory, minimum=0, maximum=20)
    points = as_int("mu_points", mu_points, minimum=1, maximum=50)
    # A number is passed on as given, so that design_online's arithmetic stays exact.
    nominal = design_online(channel if isinstance(channel, (int, float)) else ch, r)
    designs: list[OnlineDesign] = []
    for z0 in range(nominal.z0, nominal.z0 + extra + 1):
        top = nominal.mu if z0 == nominal.z0 else 1.0
        mus = [top] if points == 1 else np.linspace(top, top / points, points).tolist()
        designs.extend(nominal if (z0 == nominal.z0 and m == top) else OnlineDesign(z0, m) for m in mus)
    rows = []
    for d in designs:
        free = Scenario(system, ch, d)
        w = worst_attack(system, ch, d, b, tau_max=tau_max)
        rows.append((free.high_power_rate(), free.cost(), w.j, w.j_lp))
    table = np.array(rows, dtype=np.float64).reshape(-1, 4)
    # Least worst-case J; among equals (to 1e-12), the earliest: the one spending most.
    worst = table[:, 2]
    best = int(np.flatnonzero(worst <= worst.min() * (1 + 1e-12))[0])
    pattern = offline_schedule(r) if is_paper_channel(ch) else offline_schedule(r, ch, system=system)
    j_off = Scenario(system, ch, OfflineSchedule(pattern=pattern.tolist())).cost()
    cols = [_frozen(table[:, i]) for i in range(4)]
    return RobustDesign(
        designs[best],
        float(worst[best]),
        nominal,
        float(worst[0]),
        j_off,
        b,
        tuple(designs),
        cols[0],
        cols[1],
        cols[2],
        cols[3],
    )


def _frozen(a: FloatArray) -> FloatArray:
    out = np.array(a, dtype=np.float64)
    out.flags.writeable = False
    return out
