"""Studies: the complete report on one system (:mod:`fakeack.studies.report`) and parameter studies
over grids of systems, loss probabilities (or bursty channels) and energy ratios
(:func:`fakeack.study_grid`), and the sweep along a channel's memory (:func:`fakeack.memory_sweep`)."""

from .grid import study_grid
from .memory import MemorySweep, memory_channel, memory_sweep

__all__ = ["MemorySweep", "memory_channel", "memory_sweep", "study_grid"]
