"""The one way the figure functions get a figure, and the one way figures are written to disk.

A new figure is a :class:`matplotlib.figure.Figure` with its own Agg canvas, never one from
``pyplot``: nothing is registered in pyplot's list of open figures (so nothing has to be closed),
no GUI backend is selected, and the caller's own pyplot figures are never touched.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._internal.files import atomic_write

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["file_stem", "given_axes", "new_figure", "save_figure"]


def new_figure(
    figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **subplot_kw: Any
) -> tuple[Figure, Any]:
    """A new Figure on an Agg canvas (constrained layout) and its grid of Axes.

    Parameters
    ----------
    figsize : tuple of float
        Width and height in inches.
    nrows, ncols : int, optional
        The grid of Axes.
    **subplot_kw
        Passed on to :meth:`matplotlib.figure.Figure.subplots` (``sharex``, ``sharey``,
        ``squeeze``, ...).

    Returns
    -------
    fig : matplotlib.figure.Figure
        The new figure.
    axes : matplotlib.axes.Axes or numpy.ndarray of Axes
        As :meth:`~matplotlib.figure.Figure.subplots` returns them (one Axes for a 1 x 1 grid).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)  # attached to this figure only: no global backend switch
    return fig, fig.subplots(nrows, ncols, **subplot_kw)


def file_stem(name: str) -> str:
    """``name`` (a system's, say) as part of a file name: letters, digits, ``-_.``, else ``_``."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def figure_of(ax: Axes) -> Figure:
    """The Figure that ``ax`` is drawn on (the top-level one when ``ax`` sits in a SubFigure)."""
    from matplotlib.figure import Figure

    fig = ax.figure
    return fig if isinstance(fig, Figure) else fig.figure


def given_axes(ax: Axes | Sequence[Axes] | Any, count: int, what: str) -> list[Axes]:
    """``ax`` (one Axes or any sequence or array of them) as a flat list of ``count`` Axes.

    Parameters
    ----------
    ax : matplotlib.axes.Axes or sequence of Axes
        What the caller passed as ``ax``.
    count : int
        How many panels the figure has.
    what : str
        The panels, for the error message (e.g. ``"one per test"``).

    Returns
    -------
    list of matplotlib.axes.Axes

    Raises
    ------
    ValueError
        If there are not exactly ``count`` Axes.
    """
    axes = list(np.ravel(np.asarray(ax, dtype=object)))
    if len(axes) != count:
        raise ValueError(f"ax must be {count} Axes ({what}), got {len(axes)}")
    return axes


def save_figure(fig: Figure, outdir: str | os.PathLike[str], stem: str) -> list[Path]:
    """Write ``stem.png`` and ``stem.svg`` atomically, with no date or software stamp.

    Without the stamps (and with a fixed SVG id salt) the same figure gives the same bytes on
    every run, so written figures can be compared and kept under version control.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, e.g. as returned by a ``plot_*`` function.
    outdir : str or os.PathLike
        The directory (created if missing).
    stem : str
        The file name without its extension.

    Returns
    -------
    list of pathlib.Path
        The PNG (150 dpi) and the SVG, in that order.
    """
    import matplotlib

    written = []
    for ext in ("png", "svg"):
        buf = io.BytesIO()
        meta = {"Software": None} if ext == "png" else {"Date": None}
        with matplotlib.rc_context({"svg.hashsalt": "fakeack"}):
            fig.savefig(buf, format=ext, dpi=150, metadata=meta)
        written.append(atomic_write(Path(outdir) / f"{stem}.{ext}", buf.getvalue()))
    return written
