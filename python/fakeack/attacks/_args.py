"""Argument handling shared by the threshold, mask and random-blocking functions."""

from __future__ import annotations

from typing import TypeVar

from .._internal.validate import as_probability
from ..model.channels import Channel, channel_argument, is_paper_channel

T = TypeVar("T")


def required(function: str, name: str, value: T | None) -> T:
    """``value``, or the TypeError Python gives for a missing argument."""
    if value is None:
        raise TypeError(f"{function}() missing required argument: {name!r}")
    return value


def channel_and_lam(channel: object, lam: object, function: str) -> tuple[Channel, float | None]:
    """The channel and, on the paper's channel, its lam (checked in (0, 1) as before)."""
    ch, name = channel_argument(channel, lam, function)
    if not is_paper_channel(ch):
        return ch, None
    return ch, as_probability(name, float(ch.low[0]))
