"""The repeated game between the sensor and an attacker who must not be seen.

Time is cut into windows of n steps. The sensor runs the online schedule and tests each window's
flag-ACKs (:mod:`fakeack.detectors`); after an alarm that triggers its fall-back it runs the
offline schedule for K windows, then returns online. The attacker picks one attack from a list and
keeps it. The payoff is the long-run average of Tr E[P_k] (zero-sum: the sensor minimises it,
the attacker maximises it).

**The payoff formula.** With J_att the stationary online cost under the attack, J_off the offline
cost and d the probability that a stationary online window ends with a triggering alarm, the
sequence of windows is a renewal process whose cycle is one online window followed, with
probability d, by K offline windows. By the renewal-reward theorem the long-run average cost is
the expected cost per cycle over the expected cycle length:

.. math::
   J = \frac{n J_{att} + d K n J_{off}}{n + d K n} = \frac{J_{att} + d K J_{off}}{1 + d K},

and the high-power rate (hence the energy) is the same average of the online rate under attack
and the offline one p/q. It neglects (i) transients at switches: the first online window after a
fall-back starts from the state the offline windows left (detector memory, attacker counter), not
the stationary one, so its cost and its alarm probability differ; (ii) dependence between
consecutive windows' alarms (the state at a window's end carries over, e.g. a long-period
attacker's phase); (iii) the normal approximations behind d. All three fade as windows grow;
:func:`simulate_game` measures the real protocol with the detector in the loop.

**Why two fall-back rules.** J rises with d when J_att < J_off, so an attacker too weak to make
online worse than offline (or one who only forges flags) *wants* to trip a sensor that falls back
on any alarm. A rational sensor falls back only from harmful attacks: rule ``"harmful"`` acts on
an alarm only when the budget estimated from the window's count (:func:`fakeack.estimate_beta`)
exceeds β̄, the threshold past which online is worse than offline.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..attacks.kinds import FlagInjection
from ..game.solve import GameSolution


def plot_game(solution: GameSolution, ax: Any = None, max_rows: int = 40, max_cols: int = 40) -> Any:
    """The payoff matrix as a heat map, with the equilibrium's supports and the Stackelberg cell marked.

    Rows (policies) and columns (attacks) are shown in the order of ``solution`` when they fit;
    larger games keep the rows and columns in either optimal strategy's support, the Stackelberg
    pair and the best responses to them, up to ``max_rows`` x ``max_cols``.

    Parameters
    ----------
    solution : GameSolution
        From :func:`solve_game`.
    ax : matplotlib Axes, optional
        Where to draw; a new figure by default.
    max_rows, max_cols : int, optional
        Largest matrix drawn.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    A = solution.payoff
    rows = list(range(A.shape[0]))
    cols = list(range(A.shape[1]))
    st_row = solution.policies.index(solution.stackelberg.policy)
    st_col = next(j for j, a in enumerate(solution.attacks) if a == solution.stackelberg.attack)
    if len(rows) > max_rows:
        keep = set(np.flatnonzero(solution.sensor_strategy > 1e-9)) | {0, 1, st_row}
        keep |= set(solution.best_policy[np.flatnonzero(solution.attacker_strategy > 1e-9)])
        rest = [i for i in rows if i not in keep]
        rows = sorted(keep | set(rest[: max(0, max_rows - len(keep))]))
    if len(cols) > max_cols:
        keep = set(np.flatnonzero(solution.attacker_strategy > 1e-9)) | {st_col}
        keep |= set(solution.best_attack[rows])
        rest = [j for j in cols if j not in keep]
        cols = sorted(keep | set(rest[: max(0, max_cols - len(keep))]))
    sub = A[np.ix_(rows, cols)]
    if ax is None:
        fig, ax = plt.subplots(figsize=(min(7 + 0.35 * len(cols), 20), min(3 + 0.3 * len(rows), 14)),
                               layout="constrained")
    else:
        fig = ax.figure
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
            ax.add_patch(plt.Rectangle((c - 0.5, -0.5), 1, len(rows), fill=False, ec="C3", lw=1.2))
    for r, i in enumerate(rows):
        if solution.sensor_strategy[i] > 1e-9:
            ax.add_patch(plt.Rectangle((-0.5, r - 0.5), len(cols), 1, fill=False, ec="C3", lw=1.2))
        best = solution.best_attack[i]
        if best in cols and np.ptp(A[i]) > 0:
            ax.plot([cols.index(best)], [r], "o", ms=3, color="white", mec="k", mew=0.5)
    if st_row in rows and st_col in cols:
        ax.plot([cols.index(st_col)], [rows.index(st_row)], marker="*", ms=14, color="white", mec="k")
    ax.set_title(f"Payoff J per (sensor policy, attack); value {solution.value:.4f}. Red frames and [p]: "
                 "the optimal mixed strategies; dots: the attacker's best response to each policy; "
                 "star: Stackelberg", fontsize=8)
    return fig


def _short(attack: Any) -> str:
    if attack is None:
        return "none"
    if isinstance(attack, FlagInjection) and attack.block is not None:
        return f"inject:{attack.gamma:.3g}+{attack.block.label}"
    return getattr(attack, "label", str(attack))
