"""Parameter studies at scale: the grid's definition (:mod:`.spec`), its cells (:mod:`.cells`,
:mod:`.design`), its store (:mod:`.store`), the dataset (:mod:`.dataset`) and the run (:mod:`.run`)."""

from .run import RunInfo, run_study, study_grid
from .store import StoreError

__all__ = ["RunInfo", "StoreError", "run_study", "study_grid"]
