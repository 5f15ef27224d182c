"""Figures (optional: ``pip install fakeack[plot]``). matplotlib is imported only when a function
here is called."""

from .families import plot_attack_families
from .frontier import plot_frontiers
from .game import plot_game
from .grid import plot_beta_bar, plot_decision, write_heat_maps
from .paper import JkCurve, have_matplotlib, plot_beta_sweep, plot_jk, plot_stationary

__all__ = [
    "have_matplotlib",
    "JkCurve",
    "plot_jk",
    "plot_beta_sweep",
    "plot_stationary",
    "plot_attack_families",
    "plot_frontiers",
    "plot_game",
    "plot_beta_bar",
    "plot_decision",
    "write_heat_maps",
]
