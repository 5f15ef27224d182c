"""Heat maps of a parameter study (:func:`fakeack.study_grid`) over (lam, energy ratio), per system.

:func:`plot_beta_bar` draws the large-period threshold β̄ (the finite one's crossing r/t is in the
dataset); :func:`plot_decision` the sensor's schedule against each budget β, one panel per β.
Cells without a value (no online schedule, or a cell whose ``status`` is not "ok") are grey.
Both follow the rule of :mod:`fakeack.plots` (an optional ``ax``, a new Figure on an Agg canvas
otherwise, never ``pyplot``); :func:`write_heat_maps` writes both figures of every system as PNG
and SVG.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ._figure import figure_of, file_stem, given_axes, new_figure, save_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "plot_beta_bar",
    "plot_decision",
    "write_heat_maps",
]


def _panels(ax: Axes | Sequence[Axes] | None, ncols: int) -> tuple[Figure, list[Axes]]:
    """The given Axes (one per panel) and their Figure, or a new row of ``ncols`` panels."""
    if ax is not None:
        axes = given_axes(ax, ncols, "one per panel")
        return figure_of(axes[0]), axes
    fig, grid = new_figure((4.6 * ncols + 0.8, 4.2), 1, ncols, squeeze=False)
    return fig, list(grid[0])


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (pcolormesh), half a spacing beyond the ends."""
    v = np.asarray(v, dtype=float)
    if len(v) == 1:
        return np.array([v[0] - 0.5 * abs(v[0] or 1) * 0.1, v[0] + 0.5 * abs(v[0] or 1) * 0.1])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate(([v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]))


def _grid(ds: Any, system: str, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ratio edges, lam edges, values[lam, ratio]) sorted by lam and ratio."""
    lam = np.asarray(ds["lam"].values, dtype=float)
    ratio = np.asarray(ds["ratio_value"].values, dtype=float)
    li, ri = np.argsort(lam), np.argsort(ratio)
    return _edges(ratio[ri]), _edges(lam[li]), values[np.ix_(li, ri)]


def _axes_labels(ax: Any) -> None:
    ax.set_xlabel("energy ratio p/q")
    ax.set_ylabel(r"$\lambda$")


def plot_beta_bar(ds: Any, system: str | None = None, ax: Axes | None = None) -> Figure:
    r"""Heat map of the large-period threshold :math:`\bar\beta` (``beta_bar_limit``) over
    (lam, energy ratio) for one system.

    Cells without an online schedule (no threshold) are grey; the colour bar starts at 0.

    Parameters
    ----------
    ds : xarray.Dataset
        A study from :func:`fakeack.study_grid`.
    system : str, optional
        The system's name (default: the first).
    ax : matplotlib.axes.Axes, optional
        Where to draw; a new 5.4 x 4.2 inch figure by default.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.
    """
    import matplotlib

    name = str(ds["system"].values[0]) if system is None else system
    sel = ds.sel(system=name)
    x, y, z = _grid(ds, name, np.asarray(sel["beta_bar_limit"].values, dtype=float))
    fig, (ax,) = _panels(ax, 1)
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="#d9d9d9")
    mesh = ax.pcolormesh(
        x,
        y,
        np.ma.masked_invalid(z),
        cmap=cmap,
        vmin=0.0,
        vmax=max(1e-9, np.nanmax(z)) if np.isfinite(z).any() else 1.0,
    )
    fig.colorbar(mesh, ax=ax, label=r"$\bar\beta$ (large-period limit)")
    _axes_labels(ax)
    ax.set_title(f"{name}: attacker threshold " + r"$\bar\beta$" + " (grey: no online schedule)", fontsize=9)
    return fig


def plot_decision(ds: Any, system: str | None = None, ax: Axes | Sequence[Axes] | None = None) -> Figure:
    """The sensor's decision (online, offline or n/a) over (lam, energy ratio) at each budget β,
    one panel per β.

    Parameters
    ----------
    ds : xarray.Dataset
        A study from :func:`fakeack.study_grid` with a ``beta`` dimension.
    system : str, optional
        The system's name (default: the first).
    ax : sequence of matplotlib.axes.Axes, optional
        One per budget of ``ds`` (a single Axes when it has one); a new row of panels by
        default.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.

    Raises
    ------
    ValueError
        If ``ax`` does not hold one Axes per budget.
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    name = str(ds["system"].values[0]) if system is None else system
    sel = ds.sel(system=name)
    betas = [str(b) for b in ds["beta_fraction"].values]
    own_figure = ax is None
    fig, axes = _panels(ax, len(betas))
    cmap = ListedColormap(["#d9d9d9", "#e66101", "#5e3c99"])  # n/a, offline, online
    for k, (panel, label) in enumerate(zip(axes, betas, strict=True)):
        dec = np.asarray(sel["decision"].values[..., k]).astype(str)
        code = np.where(dec == "online", 2.0, np.where(dec == "offline", 1.0, 0.0))
        x, y, z = _grid(ds, name, code)
        panel.pcolormesh(x, y, z, cmap=cmap, vmin=-0.5, vmax=2.5)
        _axes_labels(panel)
        panel.set_title(f"{name}: " + r"$\beta$" + f" = {label}", fontsize=9)
    legend = [
        Patch(color="#5e3c99", label="online"),
        Patch(color="#e66101", label="offline"),
        Patch(color="#d9d9d9", label="n/a"),
    ]
    if own_figure:
        fig.legend(handles=legend, loc="outside lower center", ncols=3, fontsize=8)
    else:
        # The caller's figure may hold other panels and another layout: keep the key beside ours.
        axes[-1].legend(handles=legend, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)
    return fig


def write_heat_maps(ds: Any, outdir: str | Path) -> list[Path]:
    """Write ``beta_bar_<system>`` and (with budgets) ``decision_<system>`` as PNG and SVG.

    Parameters
    ----------
    ds : xarray.Dataset
        A study from :func:`fakeack.study_grid`.
    outdir : str or pathlib.Path
        The directory (created if missing).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    out = Path(outdir)
    written: list[Path] = []
    for name in (str(s) for s in ds["system"].values):
        safe = file_stem(name)
        written += save_figure(plot_beta_bar(ds, name), out, f"beta_bar_{safe}")
        if "decision" in ds:
            written += save_figure(plot_decision(ds, name), out, f"decision_{safe}")
    return written
