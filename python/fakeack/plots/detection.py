"""Detection probability against the window length, a panel per test (:func:`plot_detection_curves`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ._figure import figure_of, given_axes, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..detection.curves import DetectionCurves

__all__ = [
    "plot_detection_curves",
]

_TITLES = {
    "count": "count test",
    "interval": "interval test",
    "support": "support check alone",
    "lr": "likelihood-ratio test",
}


def plot_detection_curves(
    curves: DetectionCurves,
    labels: Sequence[str] | None = None,
    ax: Axes | Sequence[Axes] | None = None,
) -> Figure:
    """The detection probability per window against the window length, one line per attack.

    One panel per test of ``curves``, log-scaled window axis, with the false-alarm level dotted;
    the interval test's points below 100 expected flag-ACKs per window are absent (it refuses
    them).

    Parameters
    ----------
    curves : DetectionCurves
        From :func:`fakeack.detection_curves`.
    labels : sequence of str, optional
        One legend label per attack (default ``str`` of each, "no attack" for ``None``).
    ax : matplotlib.axes.Axes or sequence of Axes, optional
        One per test, in the order of ``curves.tests``; a new row of panels sharing the
        probability axis by default.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.

    Raises
    ------
    ValueError
        If ``labels`` or ``ax`` do not match ``curves``.
    """
    names = (
        [("no attack" if a is None else str(a)) for a in curves.attacks] if labels is None else list(labels)
    )
    if len(names) != len(curves.attacks):
        raise ValueError(f"labels: one per attack ({len(curves.attacks)}), got {len(names)}")
    k = len(curves.tests)
    if ax is None:
        fig, grid = new_figure((4.8 * k, 4.2), 1, k, sharey=True, squeeze=False)
        axes = list(grid[0])
        what = "with the support check" if curves.support else "alone"
        fig.suptitle(f"Detection probability per window (count and interval tests {what})")
    else:
        axes = given_axes(ax, k, "one per test")
        fig = figure_of(axes[0])
    markers = "os^vDPX*<>"
    for a, (i, test) in zip(axes, enumerate(curves.tests), strict=True):
        for j, name in enumerate(names):
            y = curves.probability[i, j]
            keep = np.isfinite(y)
            a.plot(curves.n_steps[keep], y[keep], marker=markers[j % len(markers)], ms=4, lw=1.2, label=name)
        if test != "support":
            a.axhline(curves.alpha, color="0.5", lw=0.8, ls=":", label=f"false-alarm level {curves.alpha:g}")
        a.set_xscale("log")
        a.set_ylim(-0.02, 1.02)
        a.set_xlabel("window length (steps)")
        a.set_title(_TITLES[test])
    axes[0].set_ylabel("detection probability per window")
    axes[-1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))
    return fig
