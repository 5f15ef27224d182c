r"""Periodic blocking and the thresholds under a Markov channel (the routes of :mod:`.threshold`).

Where every high-power packet arrives, periodic and mask blocking use the renewal over the flag
counter with the channel state as a phase (``_fakeack.markov_*``: a K x K transfer per run of
blocked flag-ACKs, so a sweep costs :math:`O(K^3)` per fraction after an
:math:`O(t_{\max}^2 K^3)` set-up); otherwise each period goes through the exact engine
(:class:`fakeack.Scenario`), which bounds the sizes these functions accept. The large-period
limit mixes the unattacked and the all-blocked regimes by time,
:math:`J_\infty(\beta) = (\beta J_{\max}/f_{\mathrm{blk}} + (1-\beta) J_{\mathrm{on}}/f_{\mathrm{on}})
/ (\beta/f_{\mathrm{blk}} + (1-\beta)/f_{\mathrm{on}})`, with the four numbers from the engine:
the argument of the i.i.d. case holds for any ergodic channel, since each regime's time averages
converge and the switches between them cost O(1) per period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .. import _fakeack
from .._internal.types import FloatArray
from ..engine.scenario import Scenario
from ..model.channels import Channel
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem, compiled
from .kinds import MaskBlocking, PeriodicBlocking, RandomBlocking

#: Largest t_max (sweep) and t (mask search) the engine route takes when a high-power packet can
#: be lost: each fraction or mask is a solve of its own.
ENGINE_T_MAX = 200
ENGINE_MASK_T = 12


def renewal_applies(ch: Channel) -> bool:
    """Whether every high-power packet arrives (the renewal form's condition)."""
    return bool(np.all(ch.high == 1.0))


def _parts(ch: Channel) -> tuple[list[list[float]], list[float], list[float]]:
    return ch.P.tolist(), ch.low.tolist(), ch.high.tolist()


def sweep(
    system: LinearSystem, ch: Channel, design: OnlineDesign, t_max: int
) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint32], FloatArray, FloatArray]:
    """(r, t, beta, J) of "block the first r of every t" for every reduced r/t, t <= t_max."""
    z0, mu = design
    if renewal_applies(ch):
        return _fakeack.markov_beta_sweep(compiled(system), _parts(ch), z0, mu, t_max)
    if t_max > ENGINE_T_MAX:
        raise ValueError(
            f"t_max: at most {ENGINE_T_MAX} on a channel whose high-power packets can be lost "
            f"(each period is an exact engine solve), got {t_max}"
        )
    fr = [(r, t) for t in range(2, t_max + 1) for r in range(1, t) if math.gcd(r, t) == 1]
    fr.sort(key=lambda x: x[0] / x[1])
    j = np.array([Scenario(system, ch, design, PeriodicBlocking(r, t)).cost() for r, t in fr])
    rr = np.array([x[0] for x in fr], dtype=np.uint32)
    tt = np.array([x[1] for x in fr], dtype=np.uint32)
    return rr, tt, rr / tt, j


def mask_j(system: LinearSystem, ch: Channel, design: OnlineDesign, mask: list[bool]) -> float:
    """J of a blocking mask (not all blocked)."""
    if renewal_applies(ch):
        return _fakeack.markov_mask_j(compiled(system), _parts(ch), design.z0, design.mu, mask)
    return Scenario(system, ch, design, MaskBlocking(mask)).cost()


def worst_mask(
    system: LinearSystem, ch: Channel, design: OnlineDesign, t: int, blocked: int
) -> tuple[list[bool], float, float]:
    """(mask, J, J of the consecutive mask) of the most damaging mask."""
    if renewal_applies(ch):
        return _fakeack.markov_worst_mask(compiled(system), _parts(ch), design.z0, design.mu, t, blocked)
    if t > ENGINE_MASK_T:
        raise ValueError(
            f"t: at most {ENGINE_MASK_T} on a channel whose high-power packets can be lost "
            f"(each mask is an exact engine solve), got {t}"
        )
    consecutive = [i < blocked for i in range(t)]
    j_cons = mask_j(system, ch, design, consecutive)
    best, best_j = consecutive, j_cons
    for bits in range(1 << t):
        if bin(bits).count("1") == blocked:
            m = [bool(bits >> i & 1) for i in range(t)]
            j = mask_j(system, ch, design, m)
            if j > best_j * (1 + 1e-12):
                best, best_j = m, j
    return best, best_j, j_cons


@dataclass(frozen=True)
class Regimes:
    """The unattacked and the all-blocked regimes of a design under a channel."""

    j_on: float
    f_on: float
    """Flag-ACKs sent per step without attack."""
    j_max: float
    f_blk: float
    """Flag-ACKs sent per step when every one is blocked."""


def regimes(system: LinearSystem, ch: Channel, design: OnlineDesign) -> Regimes:
    """J and the flag-ACK rate without attack and with every flag-ACK blocked (engine)."""
    on = Scenario(system, ch, design)
    blk = Scenario(system, ch, design, RandomBlocking(1.0))
    return Regimes(on.cost(), on.flag_rates().sent, blk.cost(), blk.flag_rates().sent)


def j_limit(g: Regimes, beta: float) -> float:
    r""":math:`J_\infty(\beta)`, the time-weighted mix of the two regimes; ``inf`` for β > 0 when
    :math:`J_{\max}` is infinite."""
    if beta == 0.0 or g.f_on == 0.0 or g.f_blk == 0.0:  # no flag-ACK to block
        return g.j_on
    if math.isinf(g.j_max):
        return math.inf
    wb, wo = beta / g.f_blk, (1.0 - beta) / g.f_on
    return (wb * g.j_max + wo * g.j_on) / (wb + wo)


def beta_limit(g: Regimes, j_off: float) -> float:
    r"""The root of :math:`J_\infty(\beta) = J_{\mathrm{off}}`: :math:`G/(G+L)`,
    :math:`G = (J_{\mathrm{off}} - J_{\mathrm{on}})/f_{\mathrm{on}}`,
    :math:`L = (J_{\max} - J_{\mathrm{off}})/f_{\mathrm{blk}}`; 0 when the offline schedule is
    already better or :math:`J_{\max}` is infinite, 1 when blocking every flag-ACK does not reach
    :math:`J_{\mathrm{off}}` or :math:`J_{\mathrm{off}}` is infinite."""
    if g.f_on == 0.0 or g.f_blk == 0.0:
        return 1.0 if j_off > g.j_on else 0.0
    if math.isinf(j_off):  # an unstable offline schedule is never the better choice
        return 1.0
    gain = (j_off - g.j_on) / g.f_on
    if gain <= 0.0 or math.isinf(g.j_max):
        return 0.0
    loss = (g.j_max - j_off) / g.f_blk
    if loss <= 0.0:
        return 1.0
    return gain / (gain + loss)
