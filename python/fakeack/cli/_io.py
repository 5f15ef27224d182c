"""Output plumbing of the command line: atomic file writes, stdout-or-file, JSON."""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import tempfile
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["atomic_write", "emit", "to_json"]


def _default_mode(path: Path) -> int:
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def atomic_write(path: str | os.PathLike[str], data: bytes | str) -> Path:
    """Write a file atomically: a temporary file in the same directory, then ``os.replace``.

    Readers see either the old file or the complete new one; if writing fails or is interrupted
    (including ``KeyboardInterrupt``) the temporary file is removed and the target is untouched.

    Parameters
    ----------
    path : str or os.PathLike
        Destination. Missing parent directories are created.
    data : bytes or str
        Contents; text is encoded as UTF-8.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    p = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    parent = p.parent
    parent.mkdir(parents=True, exist_ok=True)
    mode = _default_mode(p)
    fd, tmp = tempfile.mkstemp(dir=parent, prefix=f".{p.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return p


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
