"""Output plumbing of the command line: atomic file writes, stdout-or-file, JSON."""

from __future__ import annotations

import json
import math
import sys
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from .._internal.files import atomic_write

__all__ = ["atomic_write", "emit", "to_json"]


def emit(text: str, out: str | None) -> None:
    """Print ``text`` or write it atomically to ``out``."""
    if out is None:
        sys.stdout.write(text if text.endswith("\n") else text + "\n")
        sys.stdout.flush()
    else:
        atomic_write(out, text if text.endswith("\n") else text + "\n")
        print(f"wrote {out}", file=sys.stderr)


def _jsonable(x: Any) -> Any:
    """Replace non-finite floats (not valid JSON) by None; numpy and Fractions by plain types."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, Fraction):
        return str(x)
    if isinstance(x, Path):
        return str(x)
    return x


def to_json(obj: Any) -> str:
    """``obj`` as indented JSON (numpy values as plain numbers, inf and NaN as null, "p/q" fractions)."""
    return json.dumps(_jsonable(obj), indent=2, allow_nan=False)
