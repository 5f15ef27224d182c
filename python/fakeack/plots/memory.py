r"""What a bursty channel's memory does at a fixed mean arrival (:func:`plot_memory`).

Two panels over the memory :math:`1 - p - q` of the on/off Gilbert-Elliott channel of one mean
(a :class:`fakeack.MemorySweep`): the costs J_online, J_offline and J under the attack, and the thresholds
:math:`\bar\beta` (the large-period limit and the finite one). The i.i.d. channel (memory 0) is
marked on every curve. Infinite costs (an unstable schedule) are left out of the curve and
listed in the title. It follows the rule of :mod:`fakeack.plots`: an optional ``ax``, a new
Figure on an Agg canvas otherwise, never ``pyplot``; nothing is computed here.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..studies.memory import MemorySweep
from ._figure import figure_of, file_stem, given_axes, new_figure, save_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "plot_memory",
    "write_memory_figures",
]

#: Most figures :func:`write_memory_figures` writes (one per system, mean and ratio).
MAX_FIGURES = 24


def _curve(axis: Axes, sweep: MemorySweep, values: np.ndarray, label: str, style: str) -> int:
    """One curve, its i.i.d. point marked; returns how many of its values are infinite."""
    x = sweep.memory
    finite = np.isfinite(values)
    (line,) = axis.plot(x[finite], values[finite], style, label=label, lw=1.6)
    i = sweep.iid
    if i is not None and finite[i]:
        axis.plot([x[i]], [values[i]], "o", color=line.get_color(), ms=7, mfc="white", mew=1.6)
    return int(np.isinf(values).sum())


def plot_memory(sweep: MemorySweep, ax: Axes | Sequence[Axes] | None = None) -> Figure:
    r"""J_online, J_offline, J under an attack and :math:`\bar\beta` against the channel's memory.

    Left: the costs; right: the large-period threshold :math:`\bar\beta` and the
    finite one (periods up to ``sweep.t_max``). Open circles mark memory 0, the i.i.d. channel of
    the same mean; a vertical dotted line goes through it.

    Parameters
    ----------
    sweep : MemorySweep
        From :func:`fakeack.memory_sweep`.
    ax : sequence of two matplotlib.axes.Axes, optional
        Where to draw the two panels; a new 10 x 4 inch figure by default.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding ``ax``.

    Raises
    ------
    TypeError
        If ``sweep`` is not a :class:`fakeack.MemorySweep`.
    ValueError
        If ``ax`` is not two Axes.
    """
    if not isinstance(sweep, MemorySweep):
        raise TypeError(f"sweep must be a fakeack.MemorySweep, got {type(sweep).__name__}")
    if ax is None:
        fig, grid = new_figure((10.0, 4.0), 1, 2, squeeze=False)
        left, right = grid[0]
    else:
        left, right = given_axes(ax, 2, "two panels: the costs and the thresholds")
        fig = figure_of(left)
    infinite = {
        "J_online": _curve(left, sweep, sweep.j_online, "$J_{on}$", "-"),
        "J_offline": _curve(left, sweep, sweep.j_offline, "$J_{off}$", "--"),
    }
    if sweep.j_attack is not None:
        what = "worst case" if sweep.family == "periodic" else "independent blocking"
        label = rf"$J$, attack $\beta$ = {sweep.beta} ({what})"
        infinite["J_attack"] = _curve(left, sweep, sweep.j_attack, label, "-.")
    left.set_ylabel("J (long-run mean of Tr P)")
    gone = ", ".join(f"{k} at {n}" for k, n in infinite.items() if n)
    title = f"mean arrival {sweep.mean:g}, energy ratio {sweep.ratio}"
    left.set_title(title + (f"\ninfinite (not drawn): {gone} points" if gone else ""), fontsize=9)
    _curve(right, sweep, sweep.beta_bar_limit, r"$\bar\beta$, large-period limit", "-")
    _curve(right, sweep, sweep.beta_bar_finite, rf"$\bar\beta$, periods $\leq$ {sweep.t_max}", "--")
    right.set_ylim(bottom=0.0)
    right.set_ylabel(r"threshold $\bar\beta$")
    right.set_title("the budget past which the sensor goes offline", fontsize=9)
    for axis in (left, right):
        axis.axvline(0.0, color="0.6", ls=":", lw=1.0)
        axis.set_xlabel("channel memory 1 - p - q  (0: i.i.d.)")
        axis.legend(fontsize=7, loc="best")
    return fig


def write_memory_figures(ds: Any, outdir: str | Path) -> list[Path]:
    """Write ``memory_<system>_mean<mean>_ratio<p>-<q>`` (PNG and SVG) for a study over channels.

    One figure per system, mean and ratio (at most :data:`MAX_FIGURES`, in that order), its
    attack at the study's first budget.

    Parameters
    ----------
    ds : xarray.Dataset
        A study from :func:`fakeack.study_grid` with ``channel=dict(kind="gilbert-elliott", ...)``.
    outdir : str or pathlib.Path
        The directory (created if missing).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    out = Path(outdir)
    beta = None if "beta" not in ds.dims else str(ds["beta_fraction"].values[0])
    written: list[Path] = []
    count = 0
    for name in (str(x) for x in ds["system"].values):
        safe = file_stem(name)
        for mean in (float(x) for x in ds["mean"].values):
            for ratio in (str(r) for r in ds["ratio"].values):
                if count == MAX_FIGURES:
                    return written
                sweep = MemorySweep.from_dataset(ds, name, mean, ratio, beta)
                stem = f"memory_{safe}_mean{mean:g}_ratio{ratio.replace('/', '-')}"
                written += save_figure(plot_memory(sweep), out, stem)
                count += 1
    return written
