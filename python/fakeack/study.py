"""Deprecated module path: the one-system report lives in :mod:`fakeack.studies.report`."""

import warnings

from .studies.report import *  # noqa: F403
from .studies.report import PAPER_ATTACKS, PAPER_PRINTED, analyse  # noqa: F401

warnings.warn(
    "fakeack.study is deprecated; import from fakeack.studies.report", DeprecationWarning, stacklevel=2
)
