"""Names for the kinds of value the public API takes and returns (annotations only)."""

from fractions import Fraction
from typing import TypeAlias

import numpy as np
import numpy.typing as npt

__all__ = [
    "RatioLike",
    "FloatArray",
    "IntArray",
    "BoolArray",
]

#: An exact rational input, read by ``as_fraction``: a float becomes the simplest fraction that
#: rounds to it, a string such as ``"1/7"`` is parsed.
RatioLike: TypeAlias = Fraction | int | float | str

FloatArray: TypeAlias = npt.NDArray[np.float64]
IntArray: TypeAlias = npt.NDArray[np.int64]
BoolArray: TypeAlias = npt.NDArray[np.bool_]
