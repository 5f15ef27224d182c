"""Which attack to buy: J against the attacker's energy per step, one curve per kind of attack
(:func:`plot_attack_effort`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..optimal.effort import AttackEffort
from ._figure import figure_of, given_axes, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "plot_attack_effort",
]

#: Label and line style of each kind of attack.
_STYLES = {
    "jam": ("blind jamming (random steps)", "C0", "-"),
    "jam-high": ("reactive jamming (high-power steps)", "C3", "-"),
    "block": ("blocking flag-ACKs (worst attack)", "C1", "--"),
    "forge": ("forging flag-ACKs (worst attack)", "C2", "-."),
}


def plot_attack_effort(result: AttackEffort, ax: Axes | None = None, *, fallback: bool = False) -> Figure:
    """J against the attacker's energy per step, one curve per kind of attack.

    The attack-free online and offline costs are drawn as references. Points where an attack
    makes J infinite are left out of its curve.

    Parameters
    ----------
    result : AttackEffort
        From :func:`fakeack.attack_effort`.
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new figure by default.
    fallback : bool, keyword-only, optional
        Draw J of the sensor that falls back to the better of the online and the offline
        schedule (``result.j_fallback``) instead of the online sensor's J.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.

    Raises
    ------
    TypeError
        If ``result`` is not an AttackEffort.
    ValueError
        If ``ax`` is not one Axes.
    """
    if not isinstance(result, AttackEffort):
        raise TypeError(f"result must be an AttackEffort, got {type(result).__name__}")
    if ax is None:
        fig, axes = new_figure((7, 4.5))
    else:
        (axes,) = given_axes(ax, 1, "J against effort")
        fig = figure_of(axes)
    js = result.j_fallback if fallback else result.j
    for kind, j in zip(result.kinds, js, strict=True):
        label, color, ls = _STYLES[kind]
        axes.plot(
            result.effort, np.where(np.isfinite(j), j, np.nan), color=color, ls=ls, marker=".", label=label
        )
    axes.axhline(result.j_offline, color="0.3", lw=0.8, ls=":", label="offline schedule, no attack")
    axes.axhline(result.j_online, color="0.6", lw=0.8, ls=":", label="online, no attack")
    jam, block, forge = result.costs
    axes.set_xlabel(
        f"attacker energy per step (per jam {jam:g}, per blocked {block:g}, per forged {forge:g})"
    )
    axes.set_ylabel("J (long-run mean Tr P)")
    sensor = "sensor falling back to the better schedule" if fallback else "online sensor"
    axes.set_title(f"Which attack to buy against the {sensor} ({result.design})")
    axes.legend(fontsize=8)
    return fig
