r"""Stability regions in the (p, q) plane of a Gilbert-Elliott channel (:func:`plot_stability_region`).

Each panel shows the engine's stability index :math:`\rho(K_0)\rho(A)^2` of one
:class:`fakeack.StabilityRegion` as a colour map (blue: J finite, red: J
infinite, white at the boundary 1), the boundary index = 1 as a black line and the i.i.d.
channels p + q = 1 as a dashed line. Points that were not evaluated (p = q = 0) are grey. It
follows the rule of :mod:`fakeack.plots`: an optional ``ax``, a new Figure on an Agg canvas
otherwise, never ``pyplot``; nothing is computed here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..engine.stability import StabilityRegion
from ..model.schedules import OfflineSchedule
from ._figure import figure_of, given_axes, new_figure
from .grid import _edges

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "plot_stability_region",
]

#: The colour scale of the index: 0 (deep blue) .. 1 (white) .. 2 and above (deep red).
_VMAX = 2.0


def _title(region: StabilityRegion) -> str:
    """The schedule, and for an online one the attack."""
    if isinstance(region.schedule, OfflineSchedule):
        return str(region.schedule)
    att = region.attack
    label = None if att is None else getattr(att, "label", str(att))  # policies have no label
    return f"{region.schedule}, " + ("no attack" if att is None else f"attack {label}")


def _panel(axis: Axes, region: StabilityRegion, title: str | None) -> Any:
    import matplotlib

    p, q = np.asarray(region.p), np.asarray(region.q)
    index = np.ma.MaskedArray(np.ma.getdata(region.index), mask=np.ma.getmaskarray(region.index)).T
    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="#bdbdbd", over="#67001f")
    mesh = axis.pcolormesh(_edges(p), _edges(q), index, cmap=cmap, vmin=0.0, vmax=_VMAX)
    data = np.ma.getdata(index)[~np.ma.getmaskarray(index)]
    if len(p) > 1 and len(q) > 1 and data.size and data.min() < 1.0 < data.max():
        axis.contour(p, q, index, levels=[1.0], colors="k", linewidths=1.2)
    axis.plot([0.0, 1.0], [1.0, 0.0], ls="--", color="0.15", lw=1.0, label="i.i.d. channels (p + q = 1)")
    axis.set_xlim(0.0, 1.0)
    axis.set_ylim(0.0, 1.0)
    axis.set_aspect("equal")
    axis.set_xlabel("p (good to bad)")
    axis.set_ylabel("q (bad to good)")
    head = _title(region) if title is None else title
    stable, evaluated = int(region.stable.sum()), int(region.evaluated.sum())
    axis.set_title(f"{head}\nJ finite at {stable} of {evaluated} points", fontsize=9)
    axis.legend(loc="upper right", fontsize=7)
    return mesh


def plot_stability_region(
    region: StabilityRegion | Sequence[StabilityRegion],
    ax: Axes | Sequence[Axes] | None = None,
    *,
    titles: Sequence[str] | None = None,
) -> Figure:
    r"""Where J is finite in the (p, q) plane: one panel per :class:`StabilityRegion`.

    The colour is the stability index :math:`\rho(K_0)\rho(A)^2` (J finite iff below 1; blue
    below, red above, saturated from 2), the black line its level 1, the dashed line the i.i.d.
    channels p + q = 1; grey cells were not evaluated (p = q = 0).

    Parameters
    ----------
    region : StabilityRegion or sequence of StabilityRegion
        From :func:`fakeack.stability_region`; several draw side by side.
    ax : matplotlib.axes.Axes or sequence of Axes, optional
        One Axes per region; a new row of panels by default.
    titles : sequence of str, optional
        One title per panel (default: the schedule and the attack).

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.

    Raises
    ------
    ValueError
        If ``ax`` or ``titles`` is not one per region.
    """
    regions = [region] if isinstance(region, StabilityRegion) else list(region)
    if not regions or not all(isinstance(r, StabilityRegion) for r in regions):
        raise TypeError("region must be a StabilityRegion or a non-empty sequence of them")
    if titles is not None and len(titles) != len(regions):
        raise ValueError(f"titles must be {len(regions)} strings (one per region), got {len(titles)}")
    if ax is None:
        fig, grid = new_figure((4.3 * len(regions) + 0.9, 4.4), 1, len(regions), squeeze=False)
        axes = list(grid[0])
    else:
        axes = given_axes(ax, len(regions), "one per region")
        fig = figure_of(axes[0])
    meshes = [
        _panel(axis, reg, None if titles is None else titles[k])
        for k, (axis, reg) in enumerate(zip(axes, regions, strict=True))
    ]
    fig.colorbar(
        meshes[0], ax=axes, label=r"stability index $\rho(K_0)\,\rho(A)^2$", extend="max", shrink=0.85
    )
    return fig
