"""Studies: the complete report on one system (:mod:`fakeack.studies.report`) and parameter studies
over grids of systems, loss probabilities and energy ratios (:func:`fakeack.study_grid`)."""

from .grid import study_grid

__all__ = ["study_grid"]
