"""Any periodic blocking pattern: its cost, and the search for the most damaging one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .._internal.types import IntArray
from .._internal.validate import as_int, as_probability
from ..model.channels import ChannelLike
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem, compiled
from . import _markov
from ._args import channel_and_lam, required
from .chain import j_attack
from .kinds import MaskBlocking

__all__ = ["j_attack_pattern", "MaskSearch", "worst_mask"]


def j_attack_pattern(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    z0: int | None = None,
    mask: npt.ArrayLike | None = None,
    mu: float = 1.0,
    *,
    lam: float | None = None,
) -> float:
    r"""Cost under any periodic blocking pattern of the attacker's flag counter.

    Generalises Algorithm 1: ``mask[sigma] == 1`` blocks the flag-ACK counted ``sigma`` in each
    period of ``len(mask)`` flags (``[1]*r + [0]*(t-r)`` is the paper's "first r of t").

    The renewal form: after each arrival the memory walk flags before the next arrival with
    probability :math:`u = a^{z_0}(\mu + (1-\mu)a)`; k blocked flags in a row put it in segment k.
    Balancing the flag rate over counter levels gives
    :math:`J = \sum_\sigma\sum_k \tilde c_{\sigma-k} W_k / \sum_\sigma\sum_k \tilde c_{\sigma-k} M_k`,
    where :math:`\tilde c_j = 1-u` if the flag before level j is blocked, else 1, and
    :math:`W_k` (:math:`M_k`) sums :math:`a^\tau\mathrm{Tr}\,h^\tau(\bar P)` (:math:`a^\tau`) over
    segment k (README, model notes). Checked against :func:`fakeack.general_attack_chain`.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\lambda`; ``lam=`` (its old
        name) is the same as a float.
    z0 : int
        Memory length.
    mask : sequence of 0/1
        One period of the blocking pattern; not all ones (that is :func:`fakeack.j_max`).
    mu : float, optional
        Probability of the z0-bit memory at each step.

    Notes
    -----
    Under a Markov channel whose high-power packets always arrive, the renewal runs over the
    same counter levels with the channel state as a phase: a run of b blocked flag-ACKs then a
    delivered one moves the phase by a K x K matrix :math:`B_b`, and J is a ratio of sums over the
    cycle of runs at the stationary phase of :math:`\prod_i B_{b_i}` (docs page "Bursty
    channels"); checked against the exact engine. Otherwise the engine solves it.
    """
    ch, lam_f = channel_and_lam(channel, lam, "j_attack_pattern")
    z0 = as_int("z0", required("j_attack_pattern", "z0", z0), minimum=1)
    if mask is None:
        raise TypeError("j_attack_pattern() missing required argument: 'mask'")
    m = MaskBlocking(mask)
    if lam_f is not None:
        return j_attack(system, lam_f, z0, mu=mu, attack=m)
    mu = as_probability("mu", mu, closed=True)
    if all(m.mask):
        raise ValueError("mask blocks every flag-ACK; its cost is fakeack.j_max(system, channel)")
    return _markov.mask_j(system, ch, OnlineDesign(z0, mu), list(m.mask))


@dataclass(frozen=True)
class MaskSearch:
    """Result of :func:`worst_mask`."""

    mask: IntArray
    """The most damaging blocking pattern found (0/1, length t)."""
    j: float
    j_consecutive: float
    """Cost of the consecutive pattern (the paper's "first r of t")."""
    consecutive_is_worst: bool


def worst_mask(
    system: LinearSystem,
    channel: ChannelLike | None = None,
    z0: int | None = None,
    t: int | None = None,
    blocked: int | None = None,
    mu: float = 1.0,
    *,
    lam: float | None = None,
) -> MaskSearch:
    """Exhaustive search for the most damaging mask with ``blocked`` of ``t`` flags blocked.

    Tests whether blocking consecutively, the paper's choice after the optimal-DoS result it cites,
    is the worst pattern for this system. ``t <= 24`` (all :math:`\\binom{t}{blocked}` masks).
    Under a Markov channel rotations of a mask share J, so the :math:`\\binom{t-1}{blocked}`
    masks whose last flag-ACK is delivered are searched with :func:`j_attack_pattern`'s renewal
    (``t <= 12`` through the engine when high-power packets can be lost); the mask returned is
    then a rotation ending on a delivered flag-ACK.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    channel : Channel or float
        The packet channel (:class:`fakeack.GilbertElliott`, :class:`fakeack.MarkovChannel`,
        ...) or the paper's low-power arrival probability :math:`\\lambda`; ``lam=`` (its old
        name) is the same as a float.
    z0 : int
        Memory length.
    t : int
        Mask length (flag-ACKs per period), at most 24.
    blocked : int
        Blocked flag-ACKs per period, ``0 <= blocked < t``.
    mu : float, optional
        Probability of the z0-bit memory at each step.
    """
    core = compiled(system)
    ch, lam_f = channel_and_lam(channel, lam, "worst_mask")
    z0 = as_int("z0", required("worst_mask", "z0", z0), minimum=1)
    t = as_int("t", required("worst_mask", "t", t), minimum=1)
    if t > 24:
        raise ValueError(f"t must be at most 24 for an exhaustive search, got {t}")
    blocked = as_int("blocked", required("worst_mask", "blocked", blocked), minimum=0)
    if blocked >= t:
        raise ValueError(f"blocked must be smaller than t = {t}, got {blocked}")
    mu = as_probability("mu", mu, closed=True)
    if lam_f is not None:
        mask, j, jc = core.worst_mask(lam_f, z0, mu, t, blocked)
    else:
        mask, j, jc = _markov.worst_mask(system, ch, OnlineDesign(z0, mu), t, blocked)
    return MaskSearch(np.array(mask, dtype=np.int64), j, jc, j <= jc * (1 + 1e-12))
