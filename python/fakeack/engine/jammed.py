r"""Scenarios under jamming of the data channel (:class:`fakeack.Jamming`,
:class:`fakeack.RandomJamming`).

Random jamming is the channel with every arrival probability times :math:`1 - r`, and the
built-in engine computes everything on it. A jamming pattern of period L is the channel of
:math:`(c_k, (k-1) \bmod L)` whose arrival probabilities vanish in the jammed phases; the
built-in engine starts a channel in its stationary law, a uniformly drawn phase, so the engine's
automaton on that channel is taken and started again at phase 0 (the state before step 1 with
:math:`c_1` stationary and phase 0), on the states that start reaches. Its long-run law may
depend on the phase at step 1 (an offline schedule whose period shares a factor with L, or an
online protocol that never forgets its start): the automaton given this way weighs each closed
class by the chance of ending in it from phase 0, and is exact there.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from .. import _fakeack
from ..attacks.jamming import Jamming
from ..model.channels import Channel
from .automaton import automaton_args
from .chains import closed_class_count, reachable

__all__ = ["csr", "phase_zero_engine"]


def csr(coo: tuple[Any, Any, Any], n: int) -> sp.csr_array:
    """An engine's (rows, cols, vals) as an ``(n, n)`` CSR array."""
    rows, cols, vals = (np.asarray(x) for x in coo)
    return sp.csr_array((vals.astype(np.float64), (rows, cols)), shape=(n, n))


def _named(label: str, period: int) -> str:
    """``c=5 ...`` of the jammed channel as ``c=2 jam=1 ...`` (the channel state and the jamming phase)."""
    head, _, rest = label.partition(" ")
    c, phase = divmod(int(head.removeprefix("c=")), period)
    return f"c={c} jam={phase} {rest}".rstrip()


def phase_zero_engine(
    base: Any, channel: Channel, jam: Jamming, online: bool, max_states: int
) -> tuple[Any, str | None]:
    """The engine of the automaton of ``base`` (built on ``jam.jammed_channel(channel)``) started at
    phase 0, and None when ``base``'s power and flag-ACK rates are those from phase 0, else the
    reason they are not.
    """
    labels, k0, k1 = base.automaton()
    n = len(labels)
    K0, K1 = csr(k0, n), csr(k1, n)
    period = jam.period
    jammed_pi = np.kron(np.asarray(channel.stationary), np.full(period, 1.0 / period))
    # The engine numbers its initial states first, one per channel state of positive
    # stationary mass, in the channel's order.
    init = np.zeros(n)
    for i, c in enumerate(np.flatnonzero(jammed_pi > 0.0)):
        if not labels[i].startswith(f"c={c} "):
            raise RuntimeError(f"attack: the engine's state {i} is {labels[i]!r}, not channel state {c}")
        if c % period == 0:
            init[i] = channel.stationary[c // period]
    init /= init.sum()
    keep = reachable(K0, K1, init)
    named = [_named(labels[i], period) for i in keep]
    args = automaton_args(K0[keep][:, keep], K1[keep][:, keep], init[keep], named, max_states)
    engine = _fakeack.Engine.from_automaton(*args)
    note = None
    if online and closed_class_count(K0, K1) > 1:
        note = (
            "attack: under this jamming pattern the online protocol's long run depends on the phase at "
            "step 1 (its automaton has several closed classes), and the power and flag-ACK rates are "
            "not computed from phase 0; cost, holding_time_law and cost_curve are"
        )
    return engine, note
