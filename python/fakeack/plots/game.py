"""The payoff matrix of the sensor-attacker game (:func:`fakeack.solve_game`) as a heat map.

The payoff itself (the renewal-reward average over windows, and the two fall-back rules) is
explained in :mod:`fakeack.game.payoff`. The figure follows the rule of :mod:`fakeack.plots`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..attacks.kinds import FlagInjection
from ..game.solve import GameSolution
from ._figure import figure_of, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_game"]


def plot_game(
    solution: GameSolution, ax: Axes | None = None, max_rows: int = 40, max_cols: int = 40
) -> Figure:
    """The payoff matrix J(policy, attack) as a heat map, with the equilibrium's supports and the
    Stackelberg cell marked.

    Rows are the sensor's policies and columns the attacks, each labelled with its probability in
    the optimal mixed strategy when it has one; red frames mark both supports, white dots the
    attacker's best response to each policy, and a star the Stackelberg pair. Rows and columns
    are shown in the order of ``solution`` when they fit; larger games keep the rows and columns
    in either optimal strategy's support, the Stackelberg pair and the best responses to them, up
    to ``max_rows`` x ``max_cols``.

    Parameters
    ----------
    solution : GameSolution
        From :func:`solve_game`.
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new figure sized to the matrix by default.
    max_rows, max_cols : int, optional
        Largest matrix drawn.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.
    """
    from matplotlib.patches import Rectangle

    A = solution.payoff
    rows = list(range(A.shape[0]))
    cols = list(range(A.shape[1]))
    st_row = solution.policies.index(solution.stackelberg.policy)
    st_col = next(j for j, a in enumerate(solution.attacks) if a == solution.stackelberg.attack)
    if len(rows) > max_rows:
        keep = {int(i) for i in np.flatnonzero(solution.sensor_strategy > 1e-9)} | {0, 1, st_row}
        keep |= {int(i) for i in solution.best_policy[np.flatnonzero(solution.attacker_strategy > 1e-9)]}
        rest = [i for i in rows if i not in keep]
        rows = sorted(keep | set(rest[: max(0, max_rows - len(keep))]))
    if len(cols) > max_cols:
        keep = {int(j) for j in np.flatnonzero(solution.attacker_strategy > 1e-9)} | {st_col}
        keep |= {int(j) for j in solution.best_attack[rows]}
        rest = [j for j in cols if j not in keep]
        cols = sorted(keep | set(rest[: max(0, max_cols - len(keep))]))
    sub = A[np.ix_(rows, cols)]
    if ax is None:
        fig, ax = new_figure((min(7 + 0.35 * len(cols), 20), min(3 + 0.3 * len(rows), 14)))
    else:
        fig = figure_of(ax)
    im = ax.imshow(sub, aspect="auto", cmap="viridis")
    fig.colorbar(im, ax=ax, label="J (long-run mean Tr P)")

    def row_label(i: int) -> str:
        p = solution.sensor_strategy[i]
        return (f"[{p:.2f}] " if p > 1e-9 else "") + str(solution.policies[i])

    def col_label(j: int) -> str:
        p = solution.attacker_strategy[j]
        return _short(solution.attacks[j]) + (f" [{p:.2f}]" if p > 1e-9 else "")

    ax.set_yticks(range(len(rows)), [row_label(i) for i in rows], fontsize=6)
    ax.set_xticks(range(len(cols)), [col_label(j) for j in cols], fontsize=6, rotation=90)
    for c, j in enumerate(cols):
        if solution.attacker_strategy[j] > 1e-9:
            ax.add_patch(Rectangle((c - 0.5, -0.5), 1, len(rows), fill=False, ec="C3", lw=1.2))
    for r, i in enumerate(rows):
        if solution.sensor_strategy[i] > 1e-9:
            ax.add_patch(Rectangle((-0.5, r - 0.5), len(cols), 1, fill=False, ec="C3", lw=1.2))
        best = solution.best_attack[i]
        if best in cols and np.ptp(A[i]) > 0:
            ax.plot([cols.index(best)], [r], "o", ms=3, color="white", mec="k", mew=0.5)
    if st_row in rows and st_col in cols:
        ax.plot([cols.index(st_col)], [rows.index(st_row)], marker="*", ms=14, color="white", mec="k")
    ax.set_title(
        f"Payoff J per (sensor policy, attack); value {solution.value:.4f}. Red frames and [p]: "
        "the optimal mixed strategies; dots: the attacker's best response to each policy; "
        "star: Stackelberg",
        fontsize=8,
    )
    return fig


def _short(attack: Any) -> str:
    """A tick label: the attack's own label, with the forged rate to 3 digits when it also blocks."""
    if attack is None:
        return "none"
    if isinstance(attack, FlagInjection) and attack.block is not None:
        return f"inject:{attack.gamma:.3g}+{attack.block.label}"
    return getattr(attack, "label", str(attack))
