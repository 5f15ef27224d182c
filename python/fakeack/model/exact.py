r"""The exact engine's routes for the attack-free schedules on any channel.

Where a channel is not the paper's (one state, a high-power packet always arrives), the costs
and rates of the model layer come from the exact engine (``fakeack._fakeack.Engine``, the
computation behind :class:`fakeack.Scenario`, docs page "The exact engine"): the automaton E of
the channel state, the detector's count and the sensor's next power (or offline phase), and the
coupled Stein equations :math:`Z_e = \bar P + (w_e - 1) Q + \sum_f K_0[e, f] A Z_f A'`. This
module builds the engine directly, below :mod:`fakeack.engine.scenario` in the import graph, so
that the model, attack and detection layers can use it.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import _fakeack
from .channels import Channel, channel_argument
from .system import LinearSystem, compiled

__all__ = [
    "channel_of",
    "engine",
    "online_cost",
    "online_rate",
    "pattern_cost",
    "MAX_STATES",
]

#: Largest automaton E built here (the default of :class:`fakeack.Scenario`).
MAX_STATES = 1_000_000


def channel_of(channel: object, lam: object, function: str) -> tuple[Channel, str]:
    """:func:`fakeack.model.channels.channel_argument`, with a number given as ``channel`` named
    ``lam`` in errors: a number is the paper's lam, and the analyses named it so before channels."""
    if lam is None and isinstance(channel, (numbers.Real, np.floating)) and not isinstance(channel, bool):
        return channel_argument(None, channel, function)
    return channel_argument(channel, lam, function)


def engine(
    channel: Channel,
    z0: int = 1,
    mu: float = 1.0,
    pattern: Sequence[int] | None = None,
    attack: _fakeack.Attack | None = None,
    min_gap: int = 1,
    mimicry: Any = None,
    automaton: Any = None,
) -> _fakeack.Engine:
    """The compiled engine of a validated channel, schedule and (core) attack.

    Online with ``(z0, mu)`` unless ``pattern`` (one period of 0/1) is given; the arguments after
    ``pattern`` are those of :class:`fakeack.Scenario`'s binding (an offline pattern takes none).
    """
    offline = None if pattern is None else [bool(x) for x in pattern]
    return _fakeack.Engine(
        channel.P.tolist(),
        channel.low.tolist(),
        channel.high.tolist(),
        z0,
        mu,
        offline,
        attack,
        min_gap,
        mimicry,
        automaton,
        MAX_STATES,
    )


def online_cost(system: LinearSystem, channel: Channel, z0: int, mu: float) -> float:
    """J of the attack-free online schedule (z0, mu) on ``channel``, by the engine."""
    return float(engine(channel, z0, mu).cost(compiled(system)))


def online_rate(channel: Channel, z0: int, mu: float) -> float:
    """High-power rate of the attack-free online schedule (z0, mu) on ``channel``, by the engine."""
    return float(engine(channel, z0, mu).high_power_rate())


def pattern_cost(system: LinearSystem, channel: Channel, pattern: Sequence[int]) -> float:
    """J of the offline schedule repeating ``pattern`` on ``channel``, by the engine."""
    return float(engine(channel, pattern=pattern).cost(compiled(system)))
