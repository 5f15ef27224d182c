"""Exact finite-horizon curves: E Tr P_k and J_k from the paper's initial condition, the curves the
Monte Carlo of the protocol estimates."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .._internal.types import FloatArray, IntArray
from .._internal.validate import as_int, as_probability
from ..attacks.kinds import Attack, AttackLike, MaskBlocking, as_attack, core_attack
from ..model.schedules import OfflineSchedule, OnlineDesign
from ..model.system import LinearSystem, compiled

__all__ = [
    "TraceCurve",
    "expected_trace_curve",
]


def _schedule_and_attack(
    sched: OfflineSchedule | OnlineDesign, attack: AttackLike
) -> tuple[OfflineSchedule | OnlineDesign, Attack | None]:
    """Validated schedule and attack (None: no attacker); offline schedules take none."""
    if not isinstance(sched, (OfflineSchedule, OnlineDesign)):
        raise TypeError(
            f"sched must be a fakeack.OfflineSchedule or fakeack.OnlineSchedule, got {type(sched).__name__}"
        )
    if isinstance(sched, OfflineSchedule) and sched.ratio is None:
        raise ValueError(
            "sched: an offline schedule given by its pattern is computed by fakeack.Scenario; "
            "this route takes OfflineSchedule(ratio)"
        )
    att = as_attack(attack)
    if isinstance(sched, OfflineSchedule) and att is not None:
        raise ValueError("attack: an offline schedule ignores ACKs, so an attack has no effect")
    return sched, att


@dataclass(frozen=True)
class TraceCurve:
    """Exact :math:`\\mathbb E[\\mathrm{Tr}\\,P_k]` and :math:`J_k` for k = 1..horizon."""

    k: IntArray
    trace: FloatArray
    """E[Tr P_k]."""
    j_k: FloatArray
    """J_k = (1/k) Σ_{i<=k} E[Tr P_i] (the paper's Sec. V quantity)."""

    # Array-like: np.asarray(curve) and curve[k-1] give E[Tr P_k].
    def __array__(
        self, dtype: npt.DTypeLike | None = None, copy: bool | None = None
    ) -> npt.NDArray[np.generic]:
        return np.asarray(self.trace, dtype=dtype)

    def __len__(self) -> int:
        return len(self.trace)

    def __getitem__(self, index: int | slice) -> float | FloatArray:
        return self.trace[index]


def expected_trace_curve(
    system: LinearSystem,
    lam: float,
    sched: OfflineSchedule | OnlineDesign,
    horizon: int = 200,
    attack: AttackLike = None,
) -> TraceCurve:
    r"""Exact finite-horizon curve :math:`\mathbb E[\mathrm{Tr}\,P_k]`, k = 1..horizon (no sampling).

    Propagates the law of the protocol's state (holding time, memory zeros, attacker counter) from
    the paper's initial condition (high power at k = 1, memory all ones, counter 0), so the
    transient of the paper's Figs. 3-4 appears without Monte Carlo noise. As k grows, ``j_k``
    tends to the stationary J (:func:`fakeack.j_offline`, :func:`fakeack.j_online`,
    :func:`fakeack.j_attack`).

    Parameters
    ----------
    system : LinearSystem
    lam : float
        Arrival probability at low power.
    sched : OfflineSchedule or OnlineSchedule
    horizon : int, optional
        Number of steps (default 200).
    attack : None, PeriodicBlocking, MaskBlocking or (r, t), optional
        The attack; online schedules only (an offline schedule ignores ACKs).

    Returns
    -------
    TraceCurve
        Entries are ``inf`` (never NaN) past the double range. The curve weights the plain traces
        :math:`\mathrm{Tr}\,h^\tau(\bar P)` by probabilities, so where
        :math:`(1-\lambda)\rho(A)^2 \ge 1` an entry is ``inf`` as soon as a reachable holding time
        passes the overflow of its trace (τ ≈ 1950 for the paper's system), even where
        E[Tr P_k] itself would still fit in a double.
    """
    core = compiled(system)
    lam = as_probability("lam", lam)
    sched, att = _schedule_and_attack(sched, attack)
    horizon = as_int("horizon", horizon, minimum=1)
    if isinstance(sched, OfflineSchedule):
        r = sched.ratio
        assert r is not None  # _schedule_and_attack refuses a schedule given by its pattern
        trace = core.curve_offline(lam, r.numerator, r.denominator, horizon)
    else:
        if isinstance(att, MaskBlocking) and all(att.mask):
            raise ValueError("attack blocks every flag-ACK: the state space is unbounded")
        trace = core.curve_online(lam, sched.z0, sched.mu, core_attack(att), horizon)
    k = np.arange(1, horizon + 1)
    with np.errstate(over="ignore"):  # a running sum past the double range is inf, as documented
        j_k = np.cumsum(trace) / k
    return TraceCurve(k, trace, j_k)
