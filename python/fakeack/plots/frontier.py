"""The stealthy frontiers in one figure: J against the detection probability per window, a panel per
test (:func:`plot_frontiers`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ._figure import figure_of, given_axes, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..game.frontier import StealthyFrontier

__all__ = [
    "plot_frontiers",
]


def plot_frontiers(
    frontiers: Sequence[StealthyFrontier],
    j_offline: float | None = None,
    ax: Axes | Sequence[Axes] | None = None,
) -> Figure:
    """J against the detection probability per window along each stealthy frontier.

    One panel per test, one step line per attack family (its Pareto frontier: the largest J
    reached at each detection probability), a dot at the family's best admissible attack, and
    dotted lines at the false-alarm level, the detection bound and the unattacked online cost.

    Parameters
    ----------
    frontiers : sequence of StealthyFrontier
        From :func:`stealthy_frontier`; one panel per test, one line per family.
    j_offline : float, optional
        The offline schedule's cost, drawn as a dashed horizontal reference.
    ax : matplotlib.axes.Axes or sequence of Axes, optional
        One per test, in the sorted order of the tests' names; a new row of panels sharing the
        J axis by default.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.

    Raises
    ------
    ValueError
        If ``ax`` does not hold one Axes per test.
    """
    tests = sorted({f.test for f in frontiers})
    if ax is None:
        fig, grid = new_figure((6 * len(tests), 4.5), 1, len(tests), sharey=True, squeeze=False)
        axes = list(grid[0])
        # The figure is ours: its title can speak for every panel.
        fig.suptitle(
            "Stealthy frontiers: the largest J an attack family reaches at each detection probability"
        )
    else:
        axes = given_axes(ax, len(tests), "one per test")
        fig = figure_of(axes[0])
    styles = {
        "periodic": ("C0", "-"),
        "random": ("C1", "--"),
        "random+inject": ("C2", "-."),
        "careful": ("C3", ":"),
        "mimicry": ("C4", (0, (1, 3))),
    }
    for a, test in zip(axes, tests, strict=True):
        for f in (f for f in frontiers if f.test == test):
            color, ls = styles.get(f.family, ("C3", ":"))
            dd, jj = f.frontier
            a.step(np.r_[dd, 1.0], np.r_[jj, jj[-1]], where="post", color=color, ls=ls, label=f.family)
            if f.attack is not None:
                a.plot([f.detection], [f.j], "o", color=color, ms=5)
        ref = next(f for f in frontiers if f.test == test)
        a.axvline(ref.alpha, color="0.5", lw=0.8, ls=":", label=f"false-alarm level {ref.alpha:g}")
        a.axhline(ref.j_online, color="0.6", lw=0.8, ls=":", label="online, no attack")
        if j_offline is not None:
            a.axhline(float(j_offline), color="0.3", lw=0.8, ls="--", label="offline schedule")
        a.axvline(ref.max_detection, color="C3", lw=0.8, ls=":", label=f"bound {ref.max_detection:g} (dots)")
        a.set_xscale("log")
        a.set_xlim(ref.alpha / 2, 1.0)
        a.set_xlabel(f"detection probability per window of {ref.n_steps} steps")
        a.set_title(f"{test} test")
        a.legend(fontsize=8, loc="upper left")
    axes[0].set_ylabel("J (long-run mean Tr P)")
    return fig
