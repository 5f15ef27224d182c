"""Files written atomically: readers see the old file or the complete new one, never half of it."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write"]


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
