r"""Stability regions: where in the (p, q) plane of a Gilbert-Elliott channel the cost J is finite.

For every point of a grid of the channel's transition probabilities p (good to bad) and q (bad to
good) the exact engine builds the scenario's automaton E and decides its stability index
:math:`\rho(K_0)\,\rho(A)^2` (docs page "The exact engine", section Stability): J is finite iff
the index is below 1. :func:`stability_region` returns the index, the stable mask and the cost at
every point as a :class:`StabilityRegion`; :func:`fakeack.plots.stability.plot_stability_region` draws
it.

Two closed forms check the engine (tests/engine/test_stability_region.py). The always-low sensor
(``OfflineSchedule(pattern="0")``) on ``GilbertElliott(p, q, 1, 0)`` loses exactly the bad steps,
so :math:`K_0 = \mathrm{diag}(0, 1)\,P` has :math:`\rho(K_0) = 1 - q` and J is finite iff
:math:`(1-q)\rho(A)^2 < 1`, whatever p. The unattacked online sensor with high power always
arriving loses at most :math:`z_0` packets in a row (:math:`z_0 + 1` when :math:`\mu < 1`): the
next flag-ACK puts the sensor at high power. So :math:`K_0` is nilpotent, the index is 0 and J
is finite everywhere; with :math:`z_0 = 1` and :math:`\lambda_{good} = 1, \lambda_{bad} = 0`
the holding time is 1 exactly at the low-power bad steps, of stationary probability
:math:`p / ((p+q)(2-q))`.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from .._internal.html import key_values
from .._internal.types import BoolArray, FloatArray
from .._internal.validate import as_int
from ..model.channels import GilbertElliott
from ..model.schedules import OfflineSchedule, OnlineDesign
from ..model.system import LinearSystem, compiled
from .binding import AnyAttack, AnySchedule
from .scenario import DEFAULT_MAX_STATES, Scenario

__all__ = [
    "StabilityRegion",
    "stability_region",
    "DEFAULT_GRID",
]

#: The default grid of p and of q: 50 points 0.02, 0.04, ..., 1 (0 left out: p = q = 0 is no
#: channel, and q = 0 or p = 0 makes a state absorbing).
DEFAULT_GRID: FloatArray = np.linspace(0.02, 1.0, 50)
DEFAULT_GRID.flags.writeable = False

MaskedFloats: TypeAlias = "np.ma.MaskedArray[Any, np.dtype[np.float64]]"

#: The engine's refusal of a scenario with rho(K0) = 1 (some state never sees an arrival again).
_NO_ARRIVAL = "rho(K0) = 1"


def _grid(name: str, values: object) -> FloatArray:
    """A strictly increasing 1-D grid of probabilities in [0, 1] (a scalar: one point)."""
    if values is None:
        return np.array(DEFAULT_GRID)
    if isinstance(values, (str, bytes, bool, np.bool_)):
        raise TypeError(f"{name} must be an array of probabilities, got {type(values).__name__}")
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError) as exc:  # ragged lists
        raise ValueError(f"{name}: cannot be read as an array ({exc})") from None
    if arr.dtype == object or arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    arr = np.atleast_1d(np.array(arr, dtype=np.float64))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or inf")
    if np.any((arr < 0.0) | (arr > 1.0)):
        raise ValueError(f"{name}: probabilities must lie in [0, 1]")
    if np.any(np.diff(arr) <= 0.0):
        raise ValueError(f"{name} must be strictly increasing")
    return arr


class _Bar:
    """A tqdm bar over the grid points that appears only if the region takes over a second."""

    def __init__(self, total: int, enabled: bool | None) -> None:
        self.total, self.start = total, time.monotonic()
        self.bar: Any = None  # a tqdm bar once shown
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)

    def __call__(self, done: int) -> None:
        if not self.enabled:
            return
        if self.bar is None:
            if time.monotonic() - self.start < 1.0:
                return
            try:
                from tqdm.auto import tqdm
            except ImportError:  # the bar is optional (pip install fakeack[progress])
                self.enabled = False
                return
            self.bar = tqdm(total=self.total, unit="point", desc="fakeack stability_region")
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _frozen(x: npt.NDArray[Any]) -> npt.NDArray[Any]:
    x.flags.writeable = False
    return x


@dataclass(frozen=True, eq=False)
class StabilityRegion:
    r"""The stability index and the cost of one scenario over a grid of Gilbert-Elliott channels.

    Point ``[i, j]`` of every 2-D field is the channel ``GilbertElliott(p[i], q[j], lam_good,
    lam_bad, high_good, high_bad)`` (:meth:`channel`). A point whose channel does not exist
    (``p = q = 0``: two closed classes) is not evaluated: it is masked in :attr:`index` and
    :attr:`cost` (``numpy.ma``; the data under the mask is meaningless), ``False`` in
    :attr:`evaluated` and in :attr:`stable`. No field holds NaN.
    """

    p: FloatArray
    """The grid of p, good-to-bad probabilities (strictly increasing)."""
    q: FloatArray
    """The grid of q, bad-to-good probabilities (strictly increasing)."""
    index: MaskedFloats
    r"""``(len(p), len(q))``: the engine's :math:`\rho(K_0)\rho(A)^2`
    (:meth:`fakeack.Scenario.stability_index`); J is finite iff it is below 1. Where from some
    state no packet ever arrives again (the engine refuses the scenario) :math:`\rho(K_0) = 1`
    and the index is :math:`\rho(A)^2`."""
    stable: BoolArray
    """``index < 1`` at the evaluated points, ``False`` elsewhere."""
    cost: MaskedFloats
    r"""``(len(p), len(q))``: J (:meth:`fakeack.Scenario.cost`), ``inf`` where the index is at least 1.
    Also masked where :math:`\rho(K_0) = 1` and :math:`\rho(A) < 1` (J is then the limit of a
    holding time that grows without end, which the engine does not compute)."""
    schedule: AnySchedule
    """The sensor's schedule."""
    attack: AnyAttack | None
    """The attack (``None``: none)."""
    lam_good: float
    lam_bad: float
    high_good: float
    high_bad: float
    rho_a2: float
    r""":math:`\rho(A)^2`."""

    @property
    def evaluated(self) -> BoolArray:
        """Where the channel exists and the index was computed (everywhere but ``p = q = 0``)."""
        return np.asarray(~np.ma.getmaskarray(self.index))

    @property
    def shape(self) -> tuple[int, int]:
        """``(len(p), len(q))``."""
        return (len(self.p), len(self.q))

    def channel(self, i: int, j: int) -> GilbertElliott:
        """The channel of point ``[i, j]``: ``GilbertElliott(p[i], q[j], ...)``."""
        return GilbertElliott(
            float(self.p[i]), float(self.q[j]), self.lam_good, self.lam_bad, self.high_good, self.high_bad
        )

    def _repr_html_(self) -> str:
        ev = self.evaluated
        finite = np.ma.getdata(self.cost)[self.stable & ~np.ma.getmaskarray(self.cost)]
        idx = np.ma.getdata(self.index)[ev]
        items: list[tuple[str, Any]] = [
            (
                "channel",
                f"GilbertElliott(p, q, lam_good={self.lam_good:g}, lam_bad={self.lam_bad:g}, "
                f"high_good={self.high_good:g}, high_bad={self.high_bad:g})",
            ),
            ("schedule", str(self.schedule)),
            ("attack", "none" if self.attack is None else str(self.attack)),
            ("grid (p x q)", f"{len(self.p)} x {len(self.q)}"),
            ("points not evaluated (p = q = 0)", int((~ev).sum())),
            ("stable points", f"{int(self.stable.sum())} of {int(ev.sum())}"),
            ("rho(A)^2", self.rho_a2),
            ("index, smallest", float(idx.min()) if idx.size else None),
            ("index, largest", float(idx.max()) if idx.size else None),
            ("J over the stable points, smallest", float(finite.min()) if finite.size else None),
            ("J over the stable points, largest", float(finite.max()) if finite.size else None),
        ]
        return key_values("StabilityRegion", items, "J is finite iff the index rho(K0) rho(A)^2 is below 1.")


def stability_region(
    system: LinearSystem,
    schedule: OnlineDesign | OfflineSchedule,
    attack: object = None,
    *,
    p: npt.ArrayLike | None = None,
    q: npt.ArrayLike | None = None,
    lam_good: float = 1.0,
    lam_bad: float = 0.0,
    high_good: float = 1.0,
    high_bad: float = 1.0,
    progress: bool | None = None,
    max_states: int = DEFAULT_MAX_STATES,
) -> StabilityRegion:
    r"""Where in the (p, q) plane of a Gilbert-Elliott channel J stays finite, from the engine.

    At every grid point the exact engine (:class:`fakeack.Scenario`) builds the automaton E of
    the channel ``GilbertElliott(p, q, lam_good, lam_bad, high_good, high_bad)``, the schedule
    and the attack, and decides :math:`\rho(K_0)\,\rho(A)^2` by its M-matrix test (exact also
    for the cyclic :math:`K_0` of periodic attacks); J is finite iff it is below 1 (docs page
    "The exact engine", section Stability). The i.i.d. channels are the line p + q = 1, where
    the state is drawn afresh at every step.

    Parameters
    ----------
    system : LinearSystem
        The process and sensor (the engine uses :math:`A`, :math:`Q` and :math:`\bar P`).
    schedule : OnlineDesign or OfflineSchedule
        The sensor's schedule (any offline pattern too).
    attack : attack, MimicryAttack, AttackerAutomaton or None, optional
        Anything :class:`fakeack.Scenario` takes (online schedules only).
    p, q : array_like, keyword-only, optional
        Strictly increasing grids of probabilities in [0, 1] (a scalar is a grid of one point);
        by default ``fakeack.engine.DEFAULT_GRID``, 50 points 0.02, 0.04, ..., 1 each. The point
        ``p = q = 0`` is no channel: it is skipped and masked (see :class:`StabilityRegion`).
    lam_good, lam_bad : float, keyword-only, optional
        Low-power arrival probabilities in the good and the bad state (default 1 and 0).
    high_good, high_bad : float, keyword-only, optional
        High-power arrival probabilities (default 1).
    progress : bool or None, keyword-only
        Show a tqdm bar over the points for a region that takes over a second; ``None``
        (default) only on a terminal.
    max_states : int, keyword-only, optional
        Passed to :class:`fakeack.Scenario`.

    Returns
    -------
    StabilityRegion

    Raises
    ------
    TypeError, ValueError
        For a bad argument (naming it), before any point is computed.
    KeyboardInterrupt
        On Ctrl-C, between two points (one point is a few engine calls of microseconds to
        milliseconds, each holding the GIL).

    Examples
    --------
    >>> import fakeack as fa
    >>> from fakeack.engine.stability import stability_region
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> reg = stability_region(s, fa.OfflineSchedule(pattern="0"), p=[0.1, 0.5], q=[0.2, 0.4])
    >>> reg.stable.tolist()  # (1 - q) 1.44 < 1 iff q > 0.306
    [[False, True], [False, True]]
    """
    compiled(system)  # checks the system
    pg, qg = _grid("p", p), _grid("q", q)
    # The rates and the schedule and attack are checked once, on a valid channel, before the grid.
    GilbertElliott(0.5, 0.5, lam_good, lam_bad, high_good, high_bad)
    max_states = as_int("max_states", max_states, minimum=1)
    probe = _scenario(system, GilbertElliott(0.5, 0.5, 1.0, 1.0), schedule, attack, max_states)
    sched, att = probe.schedule, probe.attack
    assert sched is not None  # a scenario built from its parts has a schedule
    rho_a2 = float(system.spectral_radius) ** 2
    shape = (len(pg), len(qg))
    index, cost = np.zeros(shape), np.zeros(shape)
    index_mask, cost_mask = np.zeros(shape, dtype=bool), np.zeros(shape, dtype=bool)
    bar = _Bar(index.size, progress)
    try:
        for i, pi in enumerate(pg):
            for j, qj in enumerate(qg):
                bar(i * len(qg) + j)
                if pi == 0.0 and qj == 0.0:  # no channel: two closed classes
                    index_mask[i, j] = cost_mask[i, j] = True
                    continue
                ch = GilbertElliott(float(pi), float(qj), lam_good, lam_bad, high_good, high_bad)
                try:
                    sc = Scenario(system, ch, sched, att, max_states=max_states)
                except ValueError as exc:
                    if _NO_ARRIVAL not in str(exc):
                        raise
                    index[i, j] = rho_a2  # rho(K0) = 1 exactly: K0 is stochastic on a closed set
                    if rho_a2 >= 1.0:
                        cost[i, j] = math.inf
                    else:
                        cost_mask[i, j] = True
                    continue
                index[i, j] = sc.stability_index()
                cost[i, j] = sc.cost()
        bar(index.size)
    finally:
        bar.close()
    stable = (index < 1.0) & ~index_mask
    index[index_mask] = math.inf  # under the mask: never NaN, never read
    cost[cost_mask] = math.inf
    return StabilityRegion(
        p=_frozen(pg),
        q=_frozen(qg),
        index=np.ma.MaskedArray(_frozen(index), mask=index_mask, fill_value=math.inf),
        stable=_frozen(stable),
        cost=np.ma.MaskedArray(_frozen(cost), mask=cost_mask, fill_value=math.inf),
        schedule=sched,
        attack=att,
        lam_good=float(lam_good),
        lam_bad=float(lam_bad),
        high_good=float(high_good),
        high_bad=float(high_bad),
        rho_a2=rho_a2,
    )


def _scenario(
    system: LinearSystem, channel: GilbertElliott, schedule: object, attack: object, max_states: int
) -> Scenario:
    """The scenario at a channel where packets always arrive, which only checks the arguments."""
    return Scenario(system, channel, schedule, attack, max_states=max_states)  # type: ignore[arg-type]
