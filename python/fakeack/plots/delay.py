"""The delay frontiers in one figure: J against the mean detection delay, the CUSUM beside the
windowed count test at the same mean time to a false alarm (:func:`plot_delay_frontier`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ._figure import figure_of, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..game.delay import DelayFrontier

__all__ = [
    "plot_delay_frontier",
]


def plot_delay_frontier(frontiers: Sequence[DelayFrontier], ax: Axes | None = None) -> Figure:
    """J against the mean detection delay of each attack family's attacks.

    One colour per family; solid lines and dots for the CUSUM, dashed lines and crosses for the
    count test, dotted lines and plus signs for the interval test, both at the same mean time to
    a false alarm; dotted lines at that time (ARL0), at the
    unattacked online cost and at the offline schedule's cost.

    Parameters
    ----------
    frontiers : sequence of DelayFrontier
        From :func:`fakeack.delay_frontier`, one per family (one ARL0).
    ax : matplotlib.axes.Axes, optional
        Where to draw (a new figure by default).

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.
    """
    if ax is None:
        fig, grid = new_figure((7, 4.5), 1, 1, squeeze=False)
        axes = grid[0][0]
    else:
        axes, fig = ax, figure_of(ax)
    for k, f in enumerate(frontiers):
        color = f"C{k}"
        axes.plot(f.cusum_delay, f.j, "o-", color=color, ms=4, label=f"{f.family}: CUSUM")
        axes.plot(f.window_delay, f.j, "x--", color=color, ms=5, label=f"{f.family}: count test")
        axes.plot(f.interval_delay, f.j, "+:", color=color, ms=6, label=f"{f.family}: interval test")
    ref = frontiers[0]
    axes.axvline(ref.arl0, color="0.5", lw=0.8, ls=":", label=f"mean time to a false alarm {ref.arl0:g}")
    axes.axhline(ref.j_online, color="0.6", lw=0.8, ls=":", label="online, no attack")
    axes.axhline(ref.j_offline, color="0.3", lw=0.8, ls="--", label="offline schedule")
    axes.set_xscale("log")
    axes.set_xlabel("mean detection delay (steps)")
    axes.set_ylabel("J (long-run mean Tr P)")
    axes.legend(fontsize=7, loc="best")
    return fig
