"""The system that ``sweep`` and ``simulate`` work on: from --A/--C/--Q/--R/--lam/--ratio or --config."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from fractions import Fraction

from .._internal.validate import as_fraction, as_ratio
from ..config.analyze import Config, load_config
from ..model.system import LinearSystem
from ..studies.report import PAPER_LAM, PAPER_RATIO, PAPER_SYSTEM

__all__ = ["SYSTEM_FLAGS", "SystemInputs", "resolve_system"]

#: The options that describe the system (each defaults to the paper's value).
SYSTEM_FLAGS = ("A", "C", "Q", "R", "lam", "ratio")


@dataclass(frozen=True)
class SystemInputs:
    """The system, its arrival probability and budget, and the config they came from (if any)."""

    system: LinearSystem
    lam: float
    ratio: Fraction
    config: Config | None


def _ratio(text: str) -> Fraction:
    """``--ratio`` read by :func:`fakeack._validate.as_ratio`, the message naming the flag."""
    try:
        value = as_fraction("--ratio", text)
    except ValueError:
        raise ValueError(f"--ratio: cannot read {text!r} as a fraction p/q (e.g. 1/7)") from None
    return as_ratio("--ratio", value)


def resolve_system(args: argparse.Namespace) -> SystemInputs:
    """The system of the command line: ``--config`` or the system flags, not both."""
    given = [f"--{k.replace('_', '-')}" for k in SYSTEM_FLAGS if getattr(args, k) is not None]
    if args.config:
        if given:
            raise ValueError(f"give either --config or {', '.join(given)}, not both")
        cfg = load_config(args.config)
        return SystemInputs(cfg.system, cfg.lam, cfg.ratio, cfg)
    matrices = {k: (PAPER_SYSTEM[k] if getattr(args, k) is None else getattr(args, k)) for k in "ACQR"}
    lam = PAPER_LAM if args.lam is None else args.lam
    ratio = PAPER_RATIO if args.ratio is None else _ratio(args.ratio)
    # Validate lam here so the message names the flag.
    if not 0 < lam < 1:
        raise ValueError(f"--lam must lie in (0, 1), got {lam}")
    return SystemInputs(
        LinearSystem(matrices["A"], matrices["C"], matrices["Q"], matrices["R"]), lam, ratio, None
    )
