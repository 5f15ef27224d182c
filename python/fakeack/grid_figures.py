"""Deprecated module path: the heat maps of a parameter study live in :mod:`fakeack.plots.grid`."""

import warnings

from .plots.grid import *  # noqa: F403
from .plots.grid import plot_beta_bar, plot_decision, write_heat_maps  # noqa: F401

warnings.warn(
    "fakeack.grid_figures is deprecated; import from fakeack.plots.grid", DeprecationWarning, stacklevel=2
)
