"""Figures of the paper's Sec. V and of the attack chain (optional: ``pip install fakeack[plot]``).

matplotlib is imported only when a function here is called. Each function follows the rule of
:mod:`fakeack.plots`: it takes its data and an optional :class:`matplotlib.axes.Axes`, draws on it
or on a new Figure with an Agg canvas (never ``pyplot``), and returns the
:class:`~matplotlib.figure.Figure` it drew on. Nothing is computed here beyond simple reshaping,
so the figures show exactly the numbers the command line prints.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ._figure import figure_of, new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..attacks.threshold import BetaBar, BetaSweep


__all__ = [
    "have_matplotlib",
    "JkCurve",
    "plot_jk",
    "plot_beta_sweep",
    "plot_stationary",
]


# Colour-blind-safe (Okabe-Ito) colours for the four curves of Fig. 3.
_COLOURS = ("#0072B2", "#009E73", "#E69F00", "#D55E00", "#CC79A7", "#56B4E9", "#000000")


def have_matplotlib() -> bool:
    """Whether matplotlib can be imported.

    Returns
    -------
    bool
        ``False`` when the optional ``plot`` extra is not installed.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def _new_axes(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    """The Figure of ``ax``, or a new Figure (Agg canvas, no pyplot) with one Axes."""
    if ax is not None:
        return figure_of(ax), ax
    return new_figure(figsize)


@dataclass(frozen=True)
class JkCurve:
    """One schedule's :math:`J_k` curves for :func:`plot_jk`.

    Attributes
    ----------
    label : str
        Legend text, e.g. ``"online, attack beta=1/5"``.
    k : numpy.ndarray
        Time steps ``1..H``.
    mc : numpy.ndarray or None
        Monte Carlo :math:`J_k` (``SimulationResult.j_k``), or None.
    exact : numpy.ndarray or None
        Exact finite-horizon :math:`J_k` (``TraceCurve.j_k``), or None.
    stationary : float or None
        The stationary cost J, drawn as a horizontal dotted line.
    """

    label: str
    k: np.ndarray
    mc: np.ndarray | None = None
    exact: np.ndarray | None = None
    stationary: float | None = None


def plot_jk(
    curves: Sequence[JkCurve],
    ax: Axes | None = None,
    *,
    title: str | None = None,
    mc_runs: int | None = None,
) -> Figure:
    r"""The paper's Fig. 3: :math:`J_k = \frac1k\sum_{i\le k}\mathrm{Tr}\,\mathbb E[P_i]` against k.

    Each schedule gets one colour: the Monte Carlo curve as a thin solid line, the exact
    finite-horizon curve dashed over it, and the stationary value as a dotted horizontal line.

    Parameters
    ----------
    curves : sequence of JkCurve
        One entry per schedule (offline, online, online under attack, ...).
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new 7 x 4.4 inch figure by default.
    title : str, optional
        Axes title.
    mc_runs : int, optional
        Number of Monte Carlo runs, quoted in the legend.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.
    """
    from matplotlib.lines import Line2D

    fig, ax = _new_axes(ax, (7.0, 4.4))
    handles: list[Any] = []
    any_mc = any_exact = any_stat = False
    kmax = 1
    for i, c in enumerate(curves):
        col = _COLOURS[i % len(_COLOURS)]
        k = np.asarray(c.k)
        kmax = max(kmax, int(k[-1]))
        if c.mc is not None:
            ax.plot(k, c.mc, color=col, lw=2.6, alpha=0.35, solid_capstyle="butt")
            any_mc = True
        if c.exact is not None:
            ax.plot(k, c.exact, color=col, lw=1.2, ls=(0, (4, 2)))
            any_exact = True
        if c.stationary is not None and np.isfinite(c.stationary):
            ax.axhline(c.stationary, color=col, lw=0.9, ls=":")
            any_stat = True
        text = c.label if c.stationary is None else f"{c.label}  (J = {c.stationary:.4f})"
        handles.append(Line2D([], [], color=col, lw=2.5, label=text))
    style: list[Any] = []
    if any_mc:
        runs = f", {mc_runs} runs" if mc_runs else ""
        style.append(Line2D([], [], color="0.3", lw=2.6, alpha=0.35, label=f"Monte Carlo{runs}"))
    if any_exact:
        style.append(Line2D([], [], color="0.3", lw=1.2, ls=(0, (4, 2)), label="exact finite horizon"))
    if any_stat:
        style.append(Line2D([], [], color="0.3", lw=0.9, ls=":", label="stationary J"))
    ax.set_xlim(1, kmax)
    ax.set_xlabel("time step $k$")
    ax.set_ylabel(r"$J_k = \frac{1}{k}\,\Sigma_{i=1}^{k}\,\mathrm{Tr}\,\mathbb{E}[P_i]$")
    ax.grid(True, lw=0.4, alpha=0.5)
    # The lower part of the plot is empty after the first steps (every J_k starts at Tr P-bar and
    # rises), so both legends go there, side by side.
    leg1 = ax.legend(handles=handles, loc="lower right", fontsize=8, title="schedule", title_fontsize=8)
    if style:
        ax.add_artist(leg1)
        ax.legend(
            handles=style,
            loc="lower left",
            fontsize=8,
            bbox_to_anchor=(0.12, 0.0),
            title="curve",
            title_fontsize=8,
        )
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def plot_beta_sweep(
    sweep: BetaSweep,
    bar: BetaBar | None = None,
    limit_beta: np.ndarray | None = None,
    limit_j: np.ndarray | None = None,
    ax: Axes | None = None,
    *,
    paper_beta_bar: float | None = None,
    title: str | None = None,
) -> Figure:
    r"""The paper's Fig. 4: the attacked cost against the attacker's budget :math:`\beta = r/t`.

    Draws every fraction of the sweep as a small marker coloured by its period t, the
    large-period limit :math:`J_\infty(\beta)` as a line, :math:`J_{\mathrm{off}}` and
    :math:`J_{\mathrm{on}}` as horizontal lines, and both thresholds :math:`\bar\beta`.

    Parameters
    ----------
    sweep : BetaSweep
        From :func:`fakeack.beta_sweep` (or any object with the same fields).
    bar : BetaBar, optional
        From :func:`fakeack.beta_bar`: ``bar.limit`` is drawn as a vertical line, ``bar.finite``
        (if any) as a star on its sweep point.
    limit_beta, limit_j : numpy.ndarray, optional
        A grid of budgets and :func:`fakeack.j_attack_limit` on it.
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new 7 x 4.6 inch figure by default.
    paper_beta_bar : float, optional
        A printed value of the threshold to show for comparison (the paper's 0.28).
    title : str, optional
        Axes title.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.
    """
    fig, ax = _new_axes(ax, (7.0, 4.6))
    beta = np.asarray(sweep.beta, dtype=float)
    j = np.asarray(sweep.j_attack, dtype=float)
    handles = _sweep_points(fig, ax, beta, j, np.asarray(sweep.t, dtype=float))
    if limit_beta is not None and limit_j is not None:
        handles += ax.plot(
            limit_beta,
            limit_j,
            color="black",
            lw=1.4,
            zorder=4,
            label=r"large-period limit $J_\infty(\beta)$",
        )
    handles += _cost_lines(ax, sweep)
    if bar is not None:
        handles += _threshold_marks(ax, bar, sweep, j)
    if paper_beta_bar is not None:
        handles.append(
            ax.axvline(
                paper_beta_bar,
                color="0.55",
                lw=1.0,
                ls=(0, (1, 2)),
                zorder=1,
                label=rf"paper: $\bar\beta \approx$ {paper_beta_bar:g} (read off a figure)",
            )
        )
    ax.set_xlim(0, 1)
    ax.set_ylim(*_cost_range(sweep, j, bar, limit_j))
    ax.set_xlabel(r"attacker budget $\beta = r/t$ (fraction of flag-ACKs blocked)")
    ax.set_ylabel(r"$J$ (stationary $\mathrm{Tr}\,\mathbb{E}[P_k]$)")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(handles=handles, loc="upper left", fontsize=7.5, framealpha=1.0)
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def _sweep_points(fig: Figure, ax: Axes, beta: np.ndarray, j: np.ndarray, t: np.ndarray) -> list[Any]:
    """Every r/t of the sweep as a dot coloured by its period t; returns the legend handle."""
    from matplotlib.lines import Line2D

    t_max = int(t.max()) if len(t) else 0
    scatter = ax.scatter(beta, j, c=t, s=5, cmap="viridis", lw=0, zorder=3)
    colorbar = fig.colorbar(scatter, ax=ax, pad=0.01)
    colorbar.set_label("attack period $t$ (flag-ACKs)")
    label = rf"$J(\tilde\theta_\mathrm{{on}})$, attack $r/t$ with $t \leq {t_max}$"
    return [Line2D([], [], ls="none", marker="o", ms=4, color=scatter.cmap(0.45), label=label)]


def _cost_lines(ax: Axes, sweep: BetaSweep) -> list[Any]:
    """J_offline and J_online (no attack) as horizontal lines."""
    off_label = rf"offline $J(\theta^\star_\mathrm{{off}})$ = {sweep.j_offline:.4f}"
    on_label = rf"online, no attack $J(\theta_\mathrm{{on}})$ = {sweep.j_online:.4f}"
    return [
        ax.axhline(sweep.j_offline, color="#D55E00", lw=1.3, ls="--", zorder=2, label=off_label),
        ax.axhline(sweep.j_online, color="#0072B2", lw=1.3, ls=":", zorder=2, label=on_label),
    ]


def _threshold_marks(ax: Axes, bar: BetaBar, sweep: BetaSweep, j: np.ndarray) -> list[Any]:
    """J_max at beta = 1, the limit threshold as a vertical line, the finite one as a star."""
    handles: list[Any] = []
    if np.isfinite(bar.j_max):
        # Every flag-ACK blocked: the end point beta = 1 of the limit curve.
        handles += ax.plot(
            1.0,
            bar.j_max,
            marker="D",
            ms=5,
            color="black",
            ls="none",
            zorder=5,
            clip_on=False,
            label=rf"all blocked ($\beta$ = 1): $J_\max$ = {bar.j_max:.4f}",
        )
    limit_label = rf"$\bar\beta$ (large-period limit) = {bar.limit:.4f}"
    handles.append(ax.axvline(bar.limit, color="#CC79A7", lw=1.3, ls="-.", zorder=2, label=limit_label))
    ax.annotate(
        rf"$\bar\beta$ = {bar.limit:.3f}",
        xy=(bar.limit, 0.075),
        xycoords=("data", "axes fraction"),
        xytext=(4, 0),
        textcoords="offset points",
        color="#CC79A7",
        fontsize=8,
        ha="left",
        va="bottom",
    )
    finite = bar.finite
    if finite is None:
        return handles
    match = (np.asarray(sweep.r) == finite.numerator) & (np.asarray(sweep.t) == finite.denominator)
    if match.any():
        label = rf"$\bar\beta$ ($t \leq {bar.t_max}$) = {finite} = {float(finite):.4f}"
        handles += ax.plot(
            float(finite),
            float(j[match][0]),
            marker="*",
            ms=12,
            color="#CC79A7",
            mec="black",
            mew=0.6,
            ls="none",
            zorder=5,
            label=label,
        )
    return handles


def _cost_range(
    sweep: BetaSweep, j: np.ndarray, bar: BetaBar | None, limit_j: np.ndarray | None
) -> tuple[float, float]:
    """The y-range: every drawn cost, with a 5% margin."""
    lo = min(float(np.min(j)) if len(j) else sweep.j_online, sweep.j_online)
    hi = float(np.max(j)) if len(j) else sweep.j_offline
    if limit_j is not None and len(limit_j):
        finite = np.asarray(limit_j)[np.isfinite(limit_j)]
        if len(finite):
            hi = max(hi, float(finite.max()))
    if bar is not None and np.isfinite(bar.j_max) and limit_j is None:
        hi = max(hi, bar.j_max)
    pad = 0.05 * (hi - lo if hi > lo else 1.0)
    return lo - pad, hi + pad


def plot_stationary(
    states: np.ndarray,
    pi: np.ndarray,
    ax: Axes | None = None,
    *,
    r: int | None = None,
    title: str | None = None,
) -> Figure:
    r"""Heat map of the stationary law :math:`\Pi^\star(\tau, \sigma)` of the attack chain.

    Parameters
    ----------
    states : numpy.ndarray
        ``(n, 2)`` array of ``[tau, sigma]`` from :func:`fakeack.attack_chain`.
    pi : numpy.ndarray
        Stationary probabilities aligned with ``states``
        (:func:`fakeack.stationary_distribution`).
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new figure sized to the grid by default.
    r : int, optional
        Number of blocked flag-ACKs per period; if given, a line separates the blocked counter
        levels :math:`\sigma < r` from the passing ones.
    title : str, optional
        Axes title.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``. Pairs :math:`(\tau, \sigma)` that are not states of the chain
        are left blank (hatched); the colour scale is logarithmic.
    """
    from matplotlib.colors import LogNorm

    st = np.asarray(states)
    p = np.asarray(pi, dtype=float)
    if st.ndim != 2 or st.shape[1] != 2 or len(st) != len(p):
        raise ValueError(f"states must be (n, 2) and pi (n,), got {st.shape} and {p.shape}")
    n_tau, n_sig = int(st[:, 0].max()) + 1, int(st[:, 1].max()) + 1
    grid = np.full((n_sig, n_tau), np.nan)
    grid[st[:, 1], st[:, 0]] = p
    masked = np.ma.masked_invalid(np.where(grid > 0, grid, np.nan))
    w = min(10.0, max(5.0, 0.45 * n_tau + 2.5))
    h = min(8.0, max(3.8, 0.4 * n_sig + 1.6))
    fig, ax = _new_axes(ax, (w, h))
    ax.set_facecolor("white")
    # Hatch the cells that are not states (the colour mesh leaves them transparent).
    ax.add_patch(_hatch_background(ax, n_tau, n_sig))
    vmin = float(masked.min()) if masked.count() else 1e-12
    vmax = float(masked.max()) if masked.count() else 1.0
    mesh = ax.pcolormesh(
        np.arange(n_tau + 1) - 0.5,
        np.arange(n_sig + 1) - 0.5,
        masked,
        norm=LogNorm(vmin=vmin, vmax=vmax),
        cmap="magma_r",
        edgecolors="white",
        linewidth=0.5,
    )
    cb = fig.colorbar(mesh, ax=ax, pad=0.02)
    cb.set_label(r"stationary probability $\Pi^\star(\tau, \sigma)$ (log scale)")
    ylabels = [str(v) for v in range(n_sig)]
    ylabel = r"attacker's counter $\sigma$"
    if r is not None and 0 < r < n_sig:
        ax.axhline(r - 0.5, color="#0072B2", lw=1.6)
        # The tick says what happens to the next flag-ACK at this counter value.
        ylabels = [f"{v}: {'block' if v < r else 'pass'}" for v in range(n_sig)]
    from matplotlib.patches import Patch

    ax.legend(
        handles=[Patch(facecolor="white", edgecolor="0.6", hatch="///", label="not a state")],
        **_key_location(grid),
        fontsize=8,
        framealpha=1.0,
    )
    ax.set_xlim(-0.5, n_tau - 0.5)
    ax.set_ylim(-0.5, n_sig - 0.5)
    ax.set_xticks(np.arange(n_tau))
    ax.set_yticks(np.arange(n_sig), ylabels)
    ax.set_xlabel(r"holding time $\tau$ (steps since the last arrival)")
    ax.set_ylabel(ylabel)
    ax.tick_params(length=0)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def _key_location(grid: np.ndarray) -> dict[str, Any]:
    """Where the heat map's key goes: a corner made of non-states, else below the axes.

    The paper's chains leave the low-counter, long-tau corner empty.
    """
    k = min(3, grid.shape[1])
    if np.all(np.isnan(grid[0, -k:])):
        return {"loc": "lower right"}
    if np.all(np.isnan(grid[-1, -k:])):
        return {"loc": "upper right"}
    return {"loc": "upper right", "bbox_to_anchor": (1.0, -0.14)}


def _hatch_background(ax: Axes, n_tau: int, n_sig: int) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle(
        (-0.5, -0.5), n_tau, n_sig, facecolor="none", edgecolor="0.85", hatch="///", lw=0, zorder=0
    )
