"""A parameter study's definition, validated before any work starts, and its tiling into blocks.

:func:`spec` reads the arguments of :func:`fakeack.study_grid` into a :class:`Spec` or raises a
``ValueError``/``TypeError`` naming the argument: an empty axis, a lam outside (0, 1), a ratio
outside (0, 1), a budget outside [0, 1], a duplicate coordinate, an unknown family or Monte Carlo
key, and an axis value that fails in every cell (a ratio that no lam of the grid has an online
schedule for, or a lam with no ratio) are all refused here. :class:`Layout` tiles the
(system, lam, ratio) grid into blocks of at most ``block`` cells, one system and a rectangle of
(lam, ratio) each.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from ..._internal.types import RatioLike
from ..._internal.validate import MODES, PROTOCOLS, as_fraction, as_int, as_probability, as_ratio
from ...model.system import LinearSystem
from .cells import ChannelAxes, MonteCarlo
from .channel import channel_axes
from .design import design

#: The systems of a study: one, a list (named system0, system1, ...) or a dict by name.
SystemsLike: TypeAlias = LinearSystem | Sequence[LinearSystem] | Mapping[str, LinearSystem]
#: One exact value or a sequence of them (an axis of the grid).
RatioAxis: TypeAlias = RatioLike | Sequence[RatioLike]

__all__ = [
    "FAMILIES",
    "Spec",
    "spec",
    "Layout",
]


#: Attack families: the large-period worst case of periodic blocking, or independent blocking.
FAMILIES = ("periodic", "random")

#: Longest attack period the Monte Carlo's periodic attack at a budget r/t may need.
MAX_MC_PERIOD = 10_000_000

_MC_KEYS = ("runs", "horizon", "seed", "mode", "protocol")


@dataclass(frozen=True)
class Spec:
    """A validated study: names and systems, the axes and the settings. With ``channel`` the
    cells are (system, mean, memory, ratio) and ``lam`` is empty."""

    names: tuple[str, ...]
    systems: tuple[LinearSystem, ...]
    lam: tuple[float, ...]
    ratio: tuple[Fraction, ...]
    beta: tuple[Fraction, ...]
    family: str
    t_max: int
    montecarlo: MonteCarlo | None
    channel: ChannelAxes | None = None

    @property
    def shape(self) -> tuple[int, ...]:
        """(systems, lams, ratios), or (systems, means, memories, ratios) with ``channel``."""
        if self.channel is not None:
            return len(self.names), len(self.channel.mean), len(self.channel.memory), len(self.ratio)
        return len(self.names), len(self.lam), len(self.ratio)

    @property
    def n_cells(self) -> int:
        """Cells of the grid (the product of :attr:`shape`)."""
        return math.prod(self.shape)

    def fingerprint(self) -> str:
        """SHA-256 of everything that determines the results (a store of another study differs)."""
        doc = {
            "systems": [
                {
                    "name": n,
                    "matrices": [[float(x).hex() for x in m.ravel()] for m in s._matrices()],
                    "shapes": [list(m.shape) for m in s._matrices()],
                    "tol": float(s._tol).hex(),
                    "max_iter": s._max_iter,
                }
                for n, s in zip(self.names, self.systems, strict=True)
            ],
            "lam": [x.hex() for x in self.lam],
            "ratio": [str(r) for r in self.ratio],
            "beta": [str(b) for b in self.beta],
            "family": self.family,
            "t_max": self.t_max,
            "montecarlo": None if self.montecarlo is None else vars(self.montecarlo),
        }
        if self.channel is not None:  # absent for lam grids, whose stores keep their fingerprint
            doc["channel"] = {
                "kind": self.channel.kind,
                "mean": [x.hex() for x in self.channel.mean],
                "memory": [x.hex() for x in self.channel.memory],
            }
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def _systems(systems: Any) -> tuple[tuple[str, ...], tuple[LinearSystem, ...]]:
    if isinstance(systems, LinearSystem):
        return ("system",), (systems,)
    if isinstance(systems, Mapping):
        items = [(str(k), v) for k, v in systems.items()]
    elif isinstance(systems, (list, tuple)):
        items = [(f"system{i}", v) for i, v in enumerate(systems)]
    else:
        raise TypeError(
            "systems must be a fakeack.LinearSystem, a list of them or a dict name -> LinearSystem, "
            f"got {type(systems).__name__}"
        )
    if not items:
        raise ValueError("systems: empty (give at least one fakeack.LinearSystem)")
    names = [n for n, _ in items]
    for name, s in items:
        if not isinstance(s, LinearSystem):
            raise TypeError(f"systems[{name!r}] must be a fakeack.LinearSystem, got {type(s).__name__}")
    _no_duplicates("systems", names)
    return tuple(names), tuple(s for _, s in items)


def _values(name: str, values: Any) -> list[Any]:
    if isinstance(values, (str, bytes)) or np.ndim(values) == 0:
        values = [values]
    out = list(np.asarray(values, dtype=object).ravel()) if not isinstance(values, list) else values
    if not out:
        raise ValueError(f"{name}: empty axis (give at least one value)")
    return out


def _no_duplicates(name: str, values: list[Any], shown: list[Any] | None = None) -> None:
    seen: dict[Any, int] = {}
    for i, v in enumerate(values):
        if v in seen:
            a, b = (shown or values)[seen[v]], (shown or values)[i]
            same = f"{a!r} and {b!r} are the same value" if repr(a) != repr(b) else f"{a!r} appears twice"
            raise ValueError(f"{name}: duplicate coordinate ({same})")
        seen[v] = i


def _lam_axis(lam: Any) -> tuple[float, ...]:
    raw = _values("lam", lam)
    out = [as_probability(f"lam[{i}]", x) for i, x in enumerate(raw)]
    _no_duplicates("lam", out, raw)
    return tuple(out)


def _ratio_axis(ratio: Any) -> tuple[Fraction, ...]:
    raw = _values("ratio", ratio)
    out = [as_ratio(f"ratio[{i}]", x) for i, x in enumerate(raw)]
    _no_duplicates("ratio", out, raw)
    return tuple(out)


def _beta_axis(beta: Any) -> tuple[Fraction, ...]:
    if beta is None:
        return ()
    raw = _values("beta", beta)
    out = []
    for i, x in enumerate(raw):
        f = as_fraction(f"beta[{i}]", x)
        if not 0 <= f <= 1:
            raise ValueError(f"beta[{i}] must lie in [0, 1], got {x!r}")
        out.append(f)
    _no_duplicates("beta", out, raw)
    return tuple(out)


def _montecarlo(mc: Any, beta: tuple[Fraction, ...], family: str) -> MonteCarlo | None:
    if mc is None:
        return None
    if isinstance(mc, MonteCarlo):
        mc = vars(mc)
    if not isinstance(mc, Mapping):
        raise TypeError(
            f"montecarlo must be None or a dict(runs=..., horizon=..., seed=...), got {type(mc).__name__}"
        )
    unknown = sorted(set(mc) - set(_MC_KEYS))
    if unknown:
        raise ValueError(f"montecarlo: unknown key {unknown[0]!r} (expected {', '.join(_MC_KEYS)})")
    for key in ("runs", "horizon"):
        if key not in mc:
            raise ValueError(f"montecarlo: missing {key!r}")
    out = MonteCarlo(
        runs=as_int("montecarlo runs", mc["runs"], minimum=2),
        horizon=as_int("montecarlo horizon", mc["horizon"], minimum=1),
        seed=as_int("montecarlo seed", mc.get("seed", 1), minimum=0, maximum=2**63 - 1),
        mode=mc.get("mode", "covariance"),
        protocol=mc.get("protocol", "B"),
    )
    if out.mode not in MODES:
        raise ValueError(f"montecarlo mode must be 'covariance' or 'state', got {out.mode!r}")
    if out.protocol not in PROTOCOLS:
        raise ValueError(f"montecarlo protocol must be 'A' or 'B', got {out.protocol!r}")
    if not beta:
        raise ValueError(
            "montecarlo: the check simulates the online schedule at each beta; give beta (0 for no attack)"
        )
    if family == "periodic":
        for b in beta:
            if b.denominator > MAX_MC_PERIOD:
                raise ValueError(
                    f"beta {b}: the Monte Carlo's periodic attack r/t = beta would have a period of "
                    f"{b.denominator} flag-ACKs (at most {MAX_MC_PERIOD}); give beta as a simple fraction"
                )
    return out


def _check_family(family: Any) -> str:
    if family not in FAMILIES:
        raise ValueError(f"family must be 'periodic' or 'random', got {family!r}")
    return family


def _check_axes_meet(lam: tuple[float, ...], ratio: tuple[Fraction, ...]) -> None:
    """Every ratio has an online schedule at some lam of the grid, and every lam for some ratio."""
    ok = np.zeros((len(lam), len(ratio)), dtype=bool)
    first_error: dict[int, str] = {}
    for j, r in enumerate(ratio):
        for i in sorted(range(len(lam)), key=lambda i: lam[i]):
            try:
                design(lam[i], r)
            except ValueError as exc:
                first_error.setdefault(j, f"at lam={lam[i]}: {exc}")
                continue
            ok[i, j] = True
            break
        if not ok[:, j].any():
            raise ValueError(
                f"ratio {r}: no lam of the grid has an online schedule that spends this budget "
                f"({first_error[j]}); drop it from the grid"
            )
    for i, x in enumerate(lam):
        if ok[i].any():
            continue
        for r in ratio:
            try:
                design(x, r)
                break
            except ValueError:
                continue
        else:
            raise ValueError(
                f"lam {x}: no ratio of the grid has an online schedule at this lam; drop it from the grid"
            )


def spec(
    systems: SystemsLike,
    lam: npt.ArrayLike | None,
    ratio: RatioAxis | None,
    beta: RatioAxis | None,
    family: str,
    t_max: int,
    montecarlo: Mapping[str, object] | None,
    channel: Mapping[str, object] | None = None,
) -> Spec:
    """The validated study (see :func:`fakeack.study_grid` for the arguments)."""
    names, systems_ = _systems(systems)
    if channel is not None and lam is not None:
        raise ValueError(
            "lam: give either a lam axis (the i.i.d. channel) or channel=dict(kind=..., mean=..., "
            "memory=...), not both (memory 0 is the i.i.d. channel of lam = mean)"
        )
    if channel is None and lam is None:
        raise ValueError("lam: missing (give a lam axis, or channel=dict(kind=..., mean=..., memory=...))")
    if ratio is None:
        raise ValueError("ratio: missing (give the energy ratios p/q)")
    axes = channel_axes(channel, _values)
    lam_ = () if lam is None else _lam_axis(lam)
    ratio_ = _ratio_axis(ratio)
    beta_ = _beta_axis(beta)
    family_ = _check_family(family)
    t_max_ = as_int("t_max", t_max, minimum=2, maximum=2**32 - 1)
    mc = _montecarlo(montecarlo, beta_, family_)
    if axes is None:
        # Under a channel each cell designs its own schedule (the engine's bisection, about a
        # millisecond): a cell without one says so in ``status`` rather than in an upfront check.
        _check_axes_meet(lam_, ratio_)
    return Spec(names, systems_, lam_, ratio_, beta_, family_, t_max_, mc, axes)


@dataclass(frozen=True)
class Layout:
    """The grid tiled into blocks: one system and a rectangle of the other axes each.

    ``shape`` is (systems, lams, ratios), or (systems, means, memories, ratios) under a channel;
    ``tile`` is the block's extent along every axis but the first.
    """

    shape: tuple[int, ...]
    tile: tuple[int, ...]

    @classmethod
    def for_spec(cls, sp: Spec, block: int | None, workers: int) -> Layout:
        """Tiles of at most ``block`` cells (None: a size that keeps scheduling overhead small),
        filled from the last axis (ratio) backwards."""
        if block is None:
            cells = _default_block(sp, workers)
        else:
            cells = as_int("block", block, minimum=1)
        tile: list[int] = []
        for n in reversed(sp.shape[1:]):
            t = max(1, min(n, cells))
            tile.insert(0, t)
            cells = max(1, cells // t)
        return cls(sp.shape, tuple(tile))

    @property
    def counts(self) -> tuple[int, ...]:
        """Blocks along each axis."""
        return (self.shape[0], *(-(-n // t) for n, t in zip(self.shape[1:], self.tile, strict=True)))

    @property
    def n_blocks(self) -> int:
        """Number of blocks."""
        return math.prod(self.counts)

    def region(self, index: int) -> tuple[slice, ...]:
        """The slices of block ``index`` along every axis (C order over the block grid)."""
        pos = np.unravel_index(index, self.counts)
        tiles = (1, *self.tile)
        return tuple(
            slice(int(i) * t, min((int(i) + 1) * t, n))
            for i, t, n in zip(pos, tiles, self.shape, strict=True)
        )

    def cells(self, index: int) -> int:
        """Cells of block ``index``."""
        return math.prod(r.stop - r.start for r in self.region(index))


def _default_block(sp: Spec, workers: int) -> int:
    """About 8 tasks per worker, each 256-8192 analytic cells (one second of Monte Carlo at most);
    under a channel a cell takes tens of milliseconds, so 1-16 cells."""
    if sp.channel is not None:
        cells = min(16, max(1, -(-sp.n_cells // (8 * max(1, workers)))))
    else:
        cells = min(8192, max(256, -(-sp.n_cells // (8 * max(1, workers)))))
    if sp.montecarlo is not None:
        steps = sp.montecarlo.runs * sp.montecarlo.horizon * max(1, len(sp.beta))
        cells = min(cells, max(1, int(2e9 // steps)))
    return cells
