"""The stealthy frontier: the most damaging attack of a family that a test sees rarely enough."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "plot_frontiers",
]



def plot_frontiers(frontiers: Any, j_offline: Any = None, ax: Any = None) -> Any:
    """J against detection probability per window for several frontiers (one line each).

    Parameters
    ----------
    frontiers : sequence of StealthyFrontier
        From :func:`stealthy_frontier`; one panel per test, one line per family.
    j_offline : float, optional
        Drawn as a horizontal reference.
    ax : sequence of matplotlib Axes, optional
        One per test; a new figure by default.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    tests = sorted({f.test for f in frontiers})
    if ax is None:
        fig, axes = plt.subplots(1, len(tests), figsize=(6 * len(tests), 4.5), sharey=True, squeeze=False)
        axes = list(axes[0])
    else:
        axes = list(np.atleast_1d(ax))
        fig = axes[0].figure
    styles = {"periodic": ("C0", "-"), "random": ("C1", "--"), "random+inject": ("C2", "-.")}
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
    fig.suptitle("Stealthy frontiers: the largest J an attack family reaches at each detection probability")
    fig.tight_layout()
    return fig
