r"""Scenarios under a jamming pattern (:class:`fakeack.Jamming`): the automaton E written out here.

A pattern of period L makes the channel the Markov chain of :math:`c'_k = (c_k, (k-1) \bmod L)`
whose arrival probabilities vanish in the jammed phases. The built-in engine starts a channel in
its stationary law, which would draw the phase at random; here the phase is 0 at step 1, so the
automaton is written out with that start and solved as an automaton given as :math:`K_0` and
:math:`K_1`. Its state before step k is the engine's: :math:`(c'_k, z, p)`, z the detector's zero
count after step k - 1 and p the power of step k (online), or :math:`(c'_k, m)` with m the
offline phase. One step (the engine's order, docs page "The exact engine"): the packet arrives
with :math:`\lambda_p(c'_k)`; the detector's count restarts at an arrival, else grows to z + 1,
and a flag-ACK is sent surely at :math:`z + 1 > z_0` and with probability :math:`\mu` at
:math:`z + 1 = z_0` (the count then restarts), making the next step high-power; the channel
moves by P and the phase by one.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from .._internal.types import FloatArray
from ..attacks.jamming import Jamming
from ..model.channels import Channel
from ..model.schedules import OfflineSchedule, OnlineDesign
from .chains import ScenarioChain

__all__ = ["csr", "jammed_chain"]


def csr(coo: tuple[Any, Any, Any], n: int) -> sp.csr_array:
    """An engine's (rows, cols, vals) as an ``(n, n)`` CSR array."""
    rows, cols, vals = (np.asarray(x) for x in coo)
    return sp.csr_array((vals.astype(np.float64), (rows, cols)), shape=(n, n))


def _jammed_parts(channel: Channel, jam: Jamming) -> tuple[sp.coo_array, FloatArray, FloatArray]:
    """P, low and high of the channel of (c, phase), state ``c * L + phase`` (P sparse)."""
    period = jam.period
    shift = sp.csr_array((np.ones(period), (np.arange(period), (np.arange(period) + 1) % period)))
    P = sp.coo_array(sp.kron(sp.csr_array(np.asarray(channel.P)), shift))
    free = 1.0 - jam.jammed.astype(np.float64)
    low = np.kron(np.asarray(channel.low), free).astype(np.float64)
    return P, low, np.kron(np.asarray(channel.high), free).astype(np.float64)


def jammed_chain(
    channel: Channel, schedule: OnlineDesign | OfflineSchedule, jam: Jamming, max_states: int
) -> ScenarioChain:
    """The automaton E of ``schedule`` on ``channel`` under ``jam``, from phase 0 at step 1.

    Initial law: :math:`c_1` stationary at phase 0, high power and the count at 0 (online), the
    offline phase 0. Per state: the step's power and its flag-ACKs (sent = delivered, none
    forged: the jammer leaves the flag-ACKs alone; none for an offline sensor).
    """
    P, low, high = _jammed_parts(channel, jam)
    kc = P.shape[0]
    online = isinstance(schedule, OnlineDesign)
    z0, mu = 0, 1.0
    if isinstance(schedule, OnlineDesign):
        z0, mu = int(schedule.z0), float(schedule.mu)
        n_x, power = 2 * (z0 + 1), np.tile([0, 1], z0 + 1)  # x = 2 z + p
        count = np.repeat(np.arange(z0 + 1), 2)
    else:
        pattern = np.asarray(schedule.pattern, dtype=np.int64)
        n_x, power = pattern.size, pattern
    n = kc * n_x
    if n > max_states:
        raise ValueError(
            f"max_states: the jammed automaton has {n} states (channel {channel.n_states} x jamming "
            f"period {jam.period} x {n_x}), more than {max_states}; refused before allocating"
        )
    arrive = np.where(power[None, :] == 1, high[:, None], low[:, None])  # (kc, n_x)
    lose = 1.0 - arrive
    rows0: list[Any] = []
    cols0: list[Any] = []
    vals0: list[Any] = []
    rows1: list[Any] = []
    cols1: list[Any] = []
    vals1: list[Any] = []
    c_from, c_to, move = np.asarray(P.row), np.asarray(P.col), np.asarray(P.data)
    sent = np.zeros((kc, n_x))
    if not online:  # every phase moves to the next, whatever the packet did
        phases = np.arange(n_x)
        src = (c_from[:, None] * n_x + phases).ravel()
        dst = (c_to[:, None] * n_x + (phases + 1) % n_x).ravel()
        rows0 += [src]
        rows1 += [src]
        cols0 += [dst]
        cols1 += [dst]
        vals0 += [(move[:, None] * lose[c_from]).ravel()]
        vals1 += [(move[:, None] * arrive[c_from]).ravel()]
    for x in range(n_x if online else 0):
        from_x = c_from * n_x + x
        z1 = int(count[x]) + 1
        if z1 > z0:
            lost_to = [(1.0, 1)]  # a flag-ACK: count 0, high power
        elif z1 == z0:
            lost_to = [(mu, 1), (1.0 - mu, 2 * z0)]
        else:
            lost_to = [(1.0, 2 * z1)]
        sent[:, x] = lose[:, x] * sum(w for w, to in lost_to if to == 1)
        rows1.append(from_x)
        cols1.append(c_to * n_x)  # an arrival: count 0, low power
        vals1.append(move * arrive[c_from, x])
        for w, to in lost_to:
            if w > 0.0:
                rows0.append(from_x)
                cols0.append(c_to * n_x + to)
                vals0.append(move * lose[c_from, x] * w)

    def build(r: list[Any], c: list[Any], v: list[Any]) -> sp.csr_array:
        m = sp.csr_array((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(n, n))
        m.eliminate_zeros()
        return m

    init = np.zeros(n)
    start = 1 if online else 0  # x of count 0 and high power, or offline phase 0
    init[np.arange(channel.n_states) * jam.period * n_x + start] = channel.stationary
    labels = [
        f"c={c // jam.period} jam={c % jam.period} "
        + (f"z={count[x]} power={'high' if power[x] else 'low'}" if online else f"phase={x}")
        for c in range(kc)
        for x in range(n_x)
    ]
    high_step = np.tile(power.astype(np.float64), kc)
    flags = (sent.ravel(), sent.ravel(), np.zeros(n))
    return ScenarioChain(
        build(rows0, cols0, vals0),
        build(rows1, cols1, vals1),
        init,
        labels,
        None,
        high=high_step,
        flags=flags,
    )
