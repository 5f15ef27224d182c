"""The system that ``sweep`` and ``simulate`` work on: from --A/--C/--Q/--R/--lam/--ratio/--channel
or --config."""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from fractions import Fraction

from .._internal.validate import as_fraction, as_ratio
from ..config.analyze import Config, load_config
from ..config.channel import parse_channel_option
from ..model.channels import BernoulliChannel, Channel
from ..model.system import LinearSystem
from ..studies.report import PAPER_LAM, PAPER_RATIO, PAPER_SYSTEM

__all__ = ["SYSTEM_FLAGS", "SystemInputs", "option_channel", "resolve_system"]

#: The options that describe the system (each defaults to the paper's value).
SYSTEM_FLAGS = ("A", "C", "Q", "R", "lam", "ratio")


@dataclass(frozen=True)
class SystemInputs:
    """The system, its channel and budget, and the config they came from (if any).

    ``lam`` is the paper's arrival probability, or for another ``channel`` its mean low-power
    arrival probability; ``channel`` is None on the paper's channel.
    """

    system: LinearSystem
    lam: float
    ratio: Fraction
    config: Config | None
    channel: Channel | None = None

    @property
    def channel_arg(self) -> float | Channel:
        """The channel as the analysis functions take it (the float ``lam`` on the paper's)."""
        return self.lam if self.channel is None else self.channel


def _ratio(text: str) -> Fraction:
    """``--ratio`` read by :func:`fakeack._validate.as_ratio`, the message naming the flag."""
    try:
        value = as_fraction("--ratio", text)
    except ValueError:
        raise ValueError(f"--ratio: cannot read {text!r} as a fraction p/q (e.g. 1/7)") from None
    return as_ratio("--ratio", value)


def option_channel(args: argparse.Namespace) -> Channel | None:
    """``--channel``, read by :func:`fakeack.config.channel.parse_channel_option` (None if absent)."""
    text = getattr(args, "channel", None)
    return None if text is None else parse_channel_option(text)


def resolve_system(args: argparse.Namespace) -> SystemInputs:
    """The system of the command line: ``--config`` or the system flags, not both.

    ``--channel`` goes with either: it replaces the config's channel (``[system] lam`` or
    ``[channel]``; a designed online schedule is designed for it), or the paper's lam; with
    ``--lam`` it is an error.
    """
    given = [f"--{k.replace('_', '-')}" for k in SYSTEM_FLAGS if getattr(args, k) is not None]
    channel = option_channel(args)
    if channel is not None and args.lam is not None:
        raise ValueError("give either --channel or --lam, not both (--channel bernoulli:LAM is --lam LAM)")
    if args.config:
        if given:
            raise ValueError(f"give either --config or {', '.join(given)}, not both")
        cfg = load_config(args.config, channel=channel)
        if channel is not None:
            cfg = replace(cfg, source=f"{cfg.source} with --channel {args.channel}")
        return SystemInputs(cfg.system, cfg.lam, cfg.ratio, cfg, cfg.channel)
    matrices = {k: (PAPER_SYSTEM[k] if getattr(args, k) is None else getattr(args, k)) for k in "ACQR"}
    ratio = PAPER_RATIO if args.ratio is None else _ratio(args.ratio)
    system = LinearSystem(matrices["A"], matrices["C"], matrices["Q"], matrices["R"])
    if isinstance(channel, BernoulliChannel):
        return SystemInputs(system, channel.lam, ratio, None)
    if channel is not None:
        return SystemInputs(system, channel.mean_low, ratio, None, channel)
    lam = PAPER_LAM if args.lam is None else args.lam
    # Validate lam here so the message names the flag.
    if not 0 < lam < 1:
        raise ValueError(f"--lam must lie in (0, 1), got {lam}")
    return SystemInputs(system, lam, ratio, None)
