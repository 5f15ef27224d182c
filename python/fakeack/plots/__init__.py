"""Figures (optional: ``pip install fakeack[plot]``). matplotlib is imported only when a function
here is called.

Every figure function follows one rule:

- it takes an optional ``ax``: one :class:`matplotlib.axes.Axes`, or a sequence of them (one per
  panel) for a figure with several panels, and draws there, leaving the rest of the caller's
  figure alone;
- without ``ax`` it draws on a new :class:`matplotlib.figure.Figure` with its own Agg canvas
  (constrained layout), made by one private helper;
- it returns the Figure it drew on.

Nothing here uses :mod:`matplotlib.pyplot`: no GUI backend is selected, no figure is registered
in pyplot's global list (so none needs closing), and the caller's pyplot figures and current Axes
are never touched, which keeps the functions safe on headless machines, in threads and inside
notebooks. A new figure shows in Jupyter as the value of a cell, or is written with
:func:`save_figure` (PNG and SVG, atomically, with reproducible bytes).
"""

from ._figure import save_figure
from .delay import plot_delay_frontier
from .detection import plot_detection_curves
from .effort import plot_attack_effort
from .families import plot_attack_families
from .frontier import plot_frontiers
from .game import plot_game
from .grid import plot_beta_bar, plot_decision, write_heat_maps
from .memory import plot_memory, write_memory_figures
from .paper import JkCurve, have_matplotlib, plot_beta_sweep, plot_jk, plot_stationary
from .stability import plot_stability_region

__all__ = [
    "have_matplotlib",
    "save_figure",
    "JkCurve",
    "plot_jk",
    "plot_beta_sweep",
    "plot_stationary",
    "plot_attack_families",
    "plot_attack_effort",
    "plot_frontiers",
    "plot_detection_curves",
    "plot_delay_frontier",
    "plot_game",
    "plot_beta_bar",
    "plot_decision",
    "write_heat_maps",
    "plot_stability_region",
    "plot_memory",
    "write_memory_figures",
]
