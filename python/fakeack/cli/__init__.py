"""The ``fakeack`` command line.

Sub-commands, one module each: ``reproduce`` (the paper's Sec. V with exact and Monte Carlo values
and figures), ``analyze`` (a TOML config, see :mod:`fakeack.config`), ``sweep`` (the attacked cost
over every r/t) and ``simulate`` (one Monte Carlo run set against its exact finite-horizon value).
:mod:`fakeack.cli._parser` builds the argument parser.

Exit codes: 0 success, 1 a runtime failure (a file that cannot be read or written), 2 bad
arguments or config (``fakeack: error: ...``), 130 interrupted (Ctrl-C). Every output file is
written atomically (temporary file in the same directory, then ``os.replace``), so an interrupted
run never leaves a half-written file.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Sequence

from ..studies.report import DEFAULT_HORIZON, DEFAULT_RUNS
from ._io import atomic_write
from ._parser import build_parser

__all__ = ["DEFAULT_HORIZON", "DEFAULT_RUNS", "atomic_write", "build_parser", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``fakeack`` console script and of ``python -m fakeack``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code (0 ok, 1 runtime failure, 2 bad arguments or config, 130 interrupted).
        ``--help`` and ``--version`` return 0 instead of raising :class:`SystemExit`.
    """
    start = time.perf_counter()
    parser = build_parser()
    try:
        args = parser.parse_args(None if argv is None else list(argv))
    except SystemExit as exc:  # --help, --version, usage errors (argparse printed the message)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    args.start = start
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("fakeack: interrupted", file=sys.stderr)
        return 130
    except (ValueError, TypeError) as exc:
        print(f"fakeack: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `fakeack sweep | head`
        with contextlib.suppress(OSError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        return 0
    except OSError as exc:
        where = f"{exc.filename!s}: " if exc.filename else ""
        print(f"fakeack: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1
