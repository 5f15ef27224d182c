"""The attack families side by side in one figure: cost and energy of periodic blocking, independent
blocking and rate-matching injection (:func:`plot_attack_families`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..attacks.families import AttackFamilies
from ._figure import figure_of, given_axes, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "plot_attack_families",
]


def plot_attack_families(families: AttackFamilies, ax: Sequence[Axes] | None = None) -> Figure:
    """J (top panel) and energy per step (bottom panel) against the budget β for the three families.

    The top panel adds the offline and the unattacked online cost as references, the bottom one
    the sensor's energy budget Psi.

    Parameters
    ----------
    families : AttackFamilies
        From :func:`attack_families`.
    ax : pair of matplotlib.axes.Axes, optional
        The top and bottom panels; a new two-panel figure sharing the β axis by default.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.

    Raises
    ------
    ValueError
        If ``ax`` is not two Axes.
    """
    if ax is None:
        fig, (top, bottom) = new_figure((7, 6.5), 2, 1, sharex=True)
    else:
        top, bottom = given_axes(ax, 2, "cost and energy")
        fig = figure_of(top)
    f = families
    styles = [
        ("periodic, large period (worst)", "C0", "-"),
        ("random blocking", "C1", "--"),
        ("rate matching (random + forged)", "C2", "-."),
    ]
    for (label, color, ls), j, e in zip(
        styles,
        (f.j_periodic, f.j_random, f.j_rate_matching),
        (f.energy_periodic, f.energy_random, f.energy_rate_matching),
        strict=True,
    ):
        top.plot(f.beta, np.where(np.isfinite(j), j, np.nan), color=color, ls=ls, label=label)
        # Periodic (large period) and random blocking deliver flags at the same long-run rate, so
        # their energy curves coincide.
        bottom.plot(f.beta, e, color=color, ls=ls, label=label)
    top.axhline(f.j_offline, color="0.3", lw=0.8, ls=":", label="offline schedule")
    top.axhline(f.j_online, color="0.6", lw=0.8, ls=":", label="online, no attack")
    bottom.axhline(f.psi, color="0.3", lw=0.8, ls=":", label="budget Psi")
    bottom.text(
        0.5,
        0.05,
        "periodic and random blocking deliver flags at the same rate",
        transform=bottom.transAxes,
        ha="center",
        fontsize=8,
        color="0.3",
    )
    top.set_ylabel("J (long-run mean Tr P)")
    bottom.set_ylabel("energy per step")
    bottom.set_xlabel("attacker budget beta (fraction of genuine flag-ACKs blocked)")
    top.legend(fontsize=8)
    bottom.legend(fontsize=8)
    top.set_title("Attack families: estimation cost and the sensor's energy")
    return fig
