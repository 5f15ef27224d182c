"""Heat maps of a parameter study (:func:`fakeack.study_grid`) over (lam, energy ratio), per system.

:func:`plot_beta_bar` draws the large-period threshold β̄ (the finite one's crossing r/t is in the
dataset); :func:`plot_decision` the sensor's schedule against each budget β, one panel per β.
Cells whose ``status`` is not "ok" are hatched grey where their value is NaN. Figures are built on
an Agg canvas without ``pyplot`` (see :mod:`fakeack.plots`); :func:`write_heat_maps` writes both
figures of every system as PNG and SVG.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "plot_beta_bar",
    "plot_decision",
    "write_heat_maps",
]



def _figure(ncols: int) -> tuple[Any, list[Any]]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.6 * ncols + 0.8, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    return fig, list(axes)


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


def plot_beta_bar(ds: Any, system: str | None = None) -> Any:
    """Heat map of ``beta_bar_limit`` over (lam, ratio) for one system.

    Parameters
    ----------
    ds : xarray.Dataset
        A study from :func:`fakeack.study_grid`.
    system : str, optional
        The system's name (default: the first).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    name = str(ds["system"].values[0]) if system is None else system
    sel = ds.sel(system=name)
    x, y, z = _grid(ds, name, np.asarray(sel["beta_bar_limit"].values, dtype=float))
    fig, (ax,) = _figure(1)
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


def plot_decision(ds: Any, system: str | None = None) -> Any:
    """The sensor's decision over (lam, ratio) at each budget β, one panel per β.

    Parameters
    ----------
    ds : xarray.Dataset
        A study from :func:`fakeack.study_grid` with a ``beta`` dimension.
    system : str, optional
        The system's name (default: the first).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    name = str(ds["system"].values[0]) if system is None else system
    sel = ds.sel(system=name)
    betas = [str(b) for b in ds["beta_fraction"].values]
    fig, axes = _figure(len(betas))
    cmap = ListedColormap(["#d9d9d9", "#e66101", "#5e3c99"])  # n/a, offline, online
    for k, (ax, label) in enumerate(zip(axes, betas, strict=True)):
        dec = np.asarray(sel["decision"].values[..., k]).astype(str)
        code = np.where(dec == "online", 2.0, np.where(dec == "offline", 1.0, 0.0))
        x, y, z = _grid(ds, name, code)
        ax.pcolormesh(x, y, z, cmap=cmap, vmin=-0.5, vmax=2.5)
        _axes_labels(ax)
        ax.set_title(f"{name}: " + r"$\beta$" + f" = {label}", fontsize=9)
    legend = [
        Patch(color="#5e3c99", label="online"),
        Patch(color="#e66101", label="offline"),
        Patch(color="#d9d9d9", label="n/a"),
    ]
    fig.legend(handles=legend, loc="outside lower center", ncols=3, fontsize=8)
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
    from ..cli._figures import save_figure

    out = Path(outdir)
    written: list[Path] = []
    for name in (str(s) for s in ds["system"].values):
        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
        written += save_figure(plot_beta_bar(ds, name), out, f"beta_bar_{safe}")
        if "decision" in ds:
            written += save_figure(plot_decision(ds, name), out, f"decision_{safe}")
    return written
