r"""Attackers that see the holding time and the attack-free state: :class:`StatePolicy`.

At the end of step k the remote detector has seen step k's packet (lost or arrived) and decided
whether to send a genuine flag-ACK; the attacker then decides what the sensor receives. A
:class:`StatePolicy` reads :math:`t = \min(\tau_k, \tau_{\max})` and the state the attack-free
protocol would move to, :math:`e = (c_k, n, \text{flag})`: the channel state, the detector's
zero count after the step (0 after a flag-ACK, which restarts it) and whether a genuine
flag-ACK was sent (the sensor's next power without attack). On a flag it blocks with
probability ``block[t, c]``; on a quiet step it forges a flag-ACK with probability
``forge[t, c, n]``. A policy may also read the steps d since the last flag-ACK the sensor
received, capped at G (a last axis of ``block`` and ``forge``): what a stealthy attacker must
track to keep the received gaps looking attack-free. The triple (t, e, d) is a Markov chain
under such a policy, and its loss / arrival split is an automaton of the exact engine
(:meth:`fakeack.Scenario.from_automaton`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import breadth_first_order

from .._internal.types import FloatArray
from ..attacks.automata import AttackerAutomaton, Transition
from ..engine.chains import ScenarioChain
from ..engine.scenario import Scenario
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem

__all__ = ["StatePolicy", "StateAutomaton", "Steps", "protocol_steps"]


class Steps(NamedTuple):
    r"""One step of the protocol between decision states ``e = c * (z0 + 2) + slot`` (slot n < z0 + 1:
    quiet with zero count n; slot z0 + 1: a genuine flag-ACK), for each next power."""

    loss: FloatArray
    """``(2, E, E)``: from e, next power a (0 low, 1 high), the next step's packet is lost and the
    next decision state is the column."""
    arrival: FloatArray
    """``(2, E, E)``: the same with the packet arriving (the column is a quiet state with count 0)."""
    n_states: int
    """K, the channel's states."""
    slots: int
    """z0 + 2 decision slots per channel state."""


def protocol_steps(channel: Channel, design: OnlineDesign) -> Steps:
    r"""The transitions of (c, n, flag) given the next power (the protocol's steps 5, 1-3 of
    :mod:`fakeack.engine`'s order): the channel moves :math:`c \to c'` by P, the packet arrives
    with ``high[c']`` or ``low[c']``; on a loss the zero count grows to n + 1 (from 0 after a
    flag-ACK), a flag-ACK is sent surely at z0 + 1 and with probability mu at z0."""
    z0, mu = int(design.z0), float(design.mu)
    P, low, high = np.asarray(channel.P), np.asarray(channel.low), np.asarray(channel.high)
    K, S = P.shape[0], z0 + 2
    E = K * S
    loss = np.zeros((2, E, E))
    arrival = np.zeros((2, E, E))
    for a, lam in enumerate((low, high)):
        for c in range(K):
            for slot in range(S):
                e = c * S + slot
                n = 0 if slot == z0 + 1 else slot
                z = n + 1
                for c2 in range(K):
                    move = P[c, c2]
                    arrival[a, e, c2 * S] += move * lam[c2]
                    lost = move * (1.0 - lam[c2])
                    if z >= z0 + 1:
                        loss[a, e, c2 * S + z0 + 1] += lost
                    elif z == z0:
                        loss[a, e, c2 * S + z0 + 1] += lost * mu
                        loss[a, e, c2 * S + z0] += lost * (1.0 - mu)
                    else:
                        loss[a, e, c2 * S + z] += lost
    return Steps(loss, arrival, K, S)


class StateAutomaton(NamedTuple):
    r"""A :class:`StatePolicy` on a channel and design: the engine's automaton over the decision
    states (t, e, d), index ``(t * E + e) * G + d - 1``."""

    K0: sp.csr_array
    """Steps whose packet is lost (:math:`\\tau \\to \\tau + 1`)."""
    K1: sp.csr_array
    """Steps whose packet arrives (:math:`\\tau \\to 0`)."""
    stationary: FloatArray
    """The long-run law of (t, e)."""
    blocked_fraction: float
    """Long-run blocked genuine flag-ACKs over genuine flag-ACKs sent (0 when none are sent)."""
    forged_fraction: float
    """Long-run forged flag-ACKs over quiet steps."""
    closed: npt.NDArray[np.intp]
    """The states of the closed class the chain settles in (the others have no long-run mass)."""
    received_gaps: FloatArray
    """``(G,)``: the law of the gaps between the flag-ACKs the sensor receives, d = 1..G - 1 and
    d >= G last (the steps since the previous one when one is received; ``[1.0]`` when G = 1)."""


def _table(name: str, x: npt.ArrayLike, ndim: int) -> FloatArray:
    if isinstance(x, (str, bytes)):
        raise TypeError(f"{name} must be an array of probabilities")
    try:
        arr = np.array(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be an array of probabilities") from None
    if not 1 <= arr.ndim <= ndim or arr.shape[0] == 0 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty array of 1 to {ndim} dimensions, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any((arr < 0.0) | (arr > 1.0)):
        raise ValueError(f"{name}: probabilities must lie in [0, 1]")
    arr = arr.reshape(arr.shape + (1,) * (ndim - arr.ndim))
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False, init=False)
class StatePolicy:
    r"""An attacker that blocks and forges flag-ACKs knowing :math:`\min(\tau_k, \tau_{\max})` and
    the attack-free state (module docstring).

    Parameters
    ----------
    block : array_like, shape (T + 1,), (T + 1, K) or (T + 1, K, G)
        Probability of blocking a genuine flag-ACK sent at holding time :math:`\tau_k = t`
        (channel state c, d = 1..G steps since the last flag-ACK received, the last entry for
        every d >= G); the row t = T = ``tau_max`` holds for every :math:`\tau_k \ge T`.
    forge : array_like, optional
        Probability of forging a flag-ACK on a quiet step, shape (T + 1,), (T + 1, K),
        (T + 1, K, z0 + 1) (the third axis: the detector's zero count) or
        (T + 1, K, z0 + 1, G); default: never.

    Raises
    ------
    TypeError, ValueError
        Naming ``block`` or ``forge`` for a probability outside [0, 1] or mismatched rows.

    Examples
    --------
    Blocking every genuine flag-ACK with probability 1/2 is ``fa.RandomBlocking(0.5)``:

    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> pol = StatePolicy([0.5])
    >>> j = pol.cost(s, 0.5, fa.OnlineDesign(2))
    >>> abs(j - fa.j_attack(s, 0.5, 2, attack=fa.RandomBlocking(0.5))) < 1e-10
    True
    """

    block: FloatArray
    """``(tau_max + 1, K or 1, G or 1)`` blocking probabilities (read-only)."""
    forge: FloatArray
    """``(tau_max + 1, K or 1, z0 + 1 or 1, G or 1)`` forging probabilities (read-only)."""

    def __init__(self, block: npt.ArrayLike, forge: npt.ArrayLike | None = None) -> None:
        b = _table("block", block, 3)
        f = _table("forge", np.zeros(b.shape[0]) if forge is None else forge, 4)
        if f.shape[0] != b.shape[0]:
            raise ValueError(
                f"forge must have {b.shape[0]} rows (tau 0..tau_max) like block, got {f.shape[0]}"
            )
        if b.shape[2] > 1 and f.shape[3] > 1 and b.shape[2] != f.shape[3]:
            raise ValueError(f"forge: {f.shape[3]} gap entries, block has {b.shape[2]}")
        object.__setattr__(self, "block", b)
        object.__setattr__(self, "forge", f)

    @property
    def gap_max(self) -> int:
        """G: the policy reads the steps since the last flag-ACK received, capped at G (1: not at all)."""
        return max(int(self.block.shape[2]), int(self.forge.shape[3]))

    @property
    def tau_max(self) -> int:
        r""":math:`\tau_{\max}`: the last row holds from there on."""
        return int(self.block.shape[0]) - 1

    @property
    def forges(self) -> bool:
        """Whether the policy ever forges a flag-ACK."""
        return bool(np.any(self.forge > 0.0))

    def high_probability(self, channel: Channel, design: OnlineDesign) -> FloatArray:
        """``(tau_max + 1, E, G)``: the probability that the sensor's next power is high in each
        decision state (1 - block on a flag, forge on a quiet step)."""
        K, z0 = channel.n_states, int(design.z0)
        for name, arr, axis, want in (
            ("block", self.block, 1, K),
            ("forge", self.forge, 1, K),
            ("forge", self.forge, 2, z0 + 1),
        ):
            if arr.shape[axis] not in (1, want):
                raise ValueError(f"{name}: {arr.shape[axis]} entries on axis {axis}, expected 1 or {want}")
        n_t, G = self.tau_max + 1, self.gap_max
        b = np.broadcast_to(self.block, (n_t, K, G))
        f = np.broadcast_to(self.forge, (n_t, K, z0 + 1, G))
        return np.concatenate([f, 1.0 - b[:, :, None, :]], axis=2).reshape(n_t, K * (z0 + 2), G)

    def automaton(self, channel: ChannelLike, design: OnlineDesign) -> StateAutomaton:
        r"""The product automaton over :math:`(\min(\tau_k, \tau_{\max}), e, d)`.

        From (t, e, d) the sensor's next power is high with the policy's probability (then a
        flag-ACK is received and d restarts at 1, else d grows, capped at G); the next step is
        ``protocol_steps``, and t moves to 0 on an arrival (``K1``) or to
        :math:`\min(t + 1, \tau_{\max})` on a loss (``K0``).

        Parameters
        ----------
        channel : Channel or float
            The packet channel.
        design : OnlineDesign
            The remote detector's (z0, mu).

        Returns
        -------
        StateAutomaton
        """
        ch = as_channel(channel, "channel")
        if not isinstance(design, OnlineDesign):
            raise TypeError(f"design must be an OnlineDesign, got {type(design).__name__}")
        steps = protocol_steps(ch, design)
        hi = self.high_probability(ch, design)
        n_t, E, G = hi.shape
        n = n_t * E * G
        gap = np.arange(G)
        rows: list[npt.NDArray[np.intp]] = []
        cols: list[npt.NDArray[np.intp]] = []
        v0: list[FloatArray] = []
        v1: list[FloatArray] = []
        for a, p in enumerate((1.0 - hi, hi)):
            nxt_gap = np.zeros(G, dtype=np.intp) if a else np.minimum(gap + 1, G - 1)  # d -> 1 on delivery
            for kernel, t_to, out in (
                (steps.loss[a], np.minimum(np.arange(n_t) + 1, n_t - 1), v0),
                (steps.arrival[a], np.zeros(n_t, dtype=np.intp), v1),
            ):
                e, f = np.nonzero(kernel)
                t = np.arange(n_t)[:, None, None]
                src = (t * E + e[None, :, None]) * G + gap[None, None, :]
                dst = (t_to[:, None, None] * E + f[None, :, None]) * G + nxt_gap[None, None, :]
                val = p[:, e, :] * kernel[e, f][None, :, None]
                keep = val > 0.0
                rows.append(src[keep])
                cols.append(np.broadcast_to(dst, val.shape)[keep])
                out.append(val[keep])
                (v1 if out is v0 else v0).append(np.zeros(int(keep.sum())))
        r, c = np.concatenate(rows), np.concatenate(cols)
        K0 = sp.csr_array((np.concatenate(v0), (r, c)), shape=(n, n))
        K1 = sp.csr_array((np.concatenate(v1), (r, c)), shape=(n, n))
        K0.eliminate_zeros()
        K1.eliminate_zeros()
        closed, law = _closed_class_law(sp.csr_array(K0 + K1), n_t * E)
        pi = np.zeros(n)
        pi[closed] = law
        pi = pi.reshape(n_t, steps.n_states, steps.slots, G)
        S = steps.slots
        hi4 = hi.reshape(n_t, steps.n_states, S, G)
        flag, quiet = pi[:, :, S - 1, :], pi[:, :, : S - 1, :]
        sent = float(flag.sum())
        blocked = float((flag * (1.0 - hi4[:, :, S - 1, :])).sum()) / sent if sent > 0.0 else 0.0
        q = float(quiet.sum())
        forged = float((quiet * hi4[:, :, : S - 1, :]).sum()) / q if q > 0.0 else 0.0
        received = (pi * hi4).sum(axis=(0, 1, 2))
        received = received / received.sum() if received.sum() > 0.0 else received
        return StateAutomaton(K0, K1, pi.ravel(), blocked, forged, closed, received)

    def scenario_chain(self, channel: ChannelLike, design: OnlineDesign) -> ScenarioChain:
        r"""This attacker as a :class:`fakeack.Scenario` attack: :meth:`automaton` and a start state
        for the paper's initial condition.

        The start state is the end of step 0: a flag-ACK reached the sensor (high power at step
        1, the detector's count at 0, d = 0), :math:`c_0` stationary; step 1 is then one step
        of ``protocol_steps`` at high power, without a decision of the attacker.
        ``fa.Scenario(system, channel, design, policy)`` solves the chain by the coupled Stein
        equations :math:`Z_e = \bar P + (w_e - 1) Q + \sum_f K_0[e, f] A Z_f A'`; its
        ``high_power_rate`` is :math:`\sum \pi(t, e, d)\,\Pr[\text{high} \mid t, e, d]` and
        its ``flag_rates`` count the genuine flag-ACKs (the flag slots), the delivered ones and
        the forged ones (delivered on a quiet step) per step.

        Parameters
        ----------
        channel : Channel or float
            The packet channel.
        design : OnlineDesign
            The remote detector's (z0, mu).

        Returns
        -------
        fakeack.engine.chains.ScenarioChain
            The states of :meth:`automaton`, then the start state.

        Examples
        --------
        >>> import fakeack as fa
        >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
        >>> sc = fa.Scenario(s, 0.5, fa.OnlineDesign(2), StatePolicy([0.5]))
        >>> ref = fa.Scenario(s, 0.5, fa.OnlineDesign(2), fa.RandomBlocking(0.5))
        >>> bool(abs(sc.cost() - ref.cost()) < 1e-12)
        True
        """
        ch = as_channel(channel, "channel")
        aut = self.automaton(ch, design)
        steps = protocol_steps(ch, design)
        hi = self.high_probability(ch, design)
        n_t, E, G = hi.shape
        n, S = n_t * E * G, steps.slots
        flag_slot = (np.arange(E) % S == S - 1)[None, :, None]
        from_flag = np.arange(steps.n_states) * S + S - 1  # (c, flag): the count restarts
        law = np.asarray(ch.stationary)
        start0 = np.zeros(n + 1)
        start1 = np.zeros(n + 1)
        t1 = min(1, n_t - 1)
        start0[(t1 * E + np.arange(E)) * G] = law @ steps.loss[1][from_flag]
        start1[np.arange(E) * G] = law @ steps.arrival[1][from_flag]

        def grow(m: sp.csr_array, row: FloatArray) -> sp.csr_array:
            edge = sp.csr_array((n, 1))
            return sp.csr_array(sp.vstack([sp.hstack([m, edge]), sp.csr_array(row[None, :])], format="csr"))

        init = np.zeros(n + 1)
        init[n] = 1.0
        sent = np.broadcast_to(flag_slot, hi.shape).astype(np.float64).ravel()
        high = hi.ravel()
        labels = [
            f"t={t} c={e // S} {'flag' if e % S == S - 1 else f'n={e % S}'} d={d + 1}"
            for t in range(n_t)
            for e in range(E)
            for d in range(G)
        ]

        def pad(v: FloatArray, last: float) -> FloatArray:
            return np.append(np.asarray(v, dtype=np.float64), last)

        return ScenarioChain(
            grow(aut.K0, start0),
            grow(aut.K1, start1),
            init,
            [*labels, "start"],
            pad(aut.stationary, 0.0),
            high=pad(high, 1.0),
            flags=(pad(sent, 0.0), pad(high, 1.0), pad(high * (1.0 - sent), 0.0)),
        )

    def cost(self, system: LinearSystem, channel: ChannelLike, design: OnlineDesign) -> float:
        """The exact long-run cost J under this attacker, by the engine on :meth:`automaton`
        (``inf`` when it is infinite)."""
        return automaton_cost(system, self.automaton(channel, design))

    def flag_automaton(self, design: OnlineDesign) -> AttackerAutomaton | None:
        r"""This policy as an attacker that sees only the genuine flag-ACKs, when one exists.

        With mu = 1 the count restarts after each flag-ACK and at each arrival, and a flag-ACK is
        sent exactly at the z0-th loss in a row after a restart. So a flag-ACK z0 steps after the
        previous one follows z0 more losses, :math:`\tau = \tau_{\mathrm{prev}} + z_0`; a later
        one follows an arrival and then z0 losses, :math:`\tau = z_0`: the gaps reveal
        :math:`\tau` at every flag-ACK. The automaton's state is (j, s): j the capped
        :math:`\tau` at the last flag-ACK (0 at the start, where :math:`\tau_0 = 0`), s the steps
        since it, capped at z0 + 1.

        Parameters
        ----------
        design : OnlineDesign
            The remote detector's (z0, mu).

        Returns
        -------
        AttackerAutomaton or None
            None when mu < 1 (a gap of z0 + 1 no longer tells whether an arrival came between),
            when the policy forges, or when its blocking depends on the channel state or the
            received gaps.
        """
        if not isinstance(design, OnlineDesign):
            raise TypeError(f"design must be an OnlineDesign, got {type(design).__name__}")
        if design.mu != 1.0 or self.forges or self.block.shape[1] > 1 or self.gap_max > 1:
            return None
        b = self.block[:, 0, 0]
        T, z0 = self.tau_max, int(design.z0)
        index: dict[tuple[int, int], int] = {(0, 0): 0}
        order = [(0, 0)]
        flag: list[list[Transition]] = []
        quiet: list[list[Transition]] = []

        def state(key: tuple[int, int]) -> int:
            if key not in index:
                index[key] = len(order)
                order.append(key)
            return index[key]

        i = 0
        while i < len(order):
            j, s = order[i]
            s2 = min(s + 1, z0 + 1)
            tau = min(j + z0, T) if s2 == z0 else min(z0, T)
            nxt = state((tau, 0))
            p = float(b[tau])
            flag.append([tr for tr in ((p, False, nxt), (1.0 - p, True, nxt)) if tr[0] > 0.0])
            quiet.append([(1.0, False, state((j, s2)))])
            i += 1
        return AttackerAutomaton({k: {"flag": flag[k], "quiet": quiet[k]} for k in range(len(order))})

    def __repr__(self) -> str:
        return f"StatePolicy(<block {self.block.shape}>, <forge {self.forge.shape}>)"

    def __str__(self) -> str:
        if self.gap_max > 1:
            return f"blocks and forges by tau, the detector's state and the received gap (G = {self.gap_max})"
        if self.block.shape[1] > 1:
            return "; ".join(f"state {c}: {_runs(self.block[:, c, 0])}" for c in range(self.block.shape[1]))
        text = _runs(self.block[:, 0, 0])
        return text + ("; forges" if self.forges else "")


def automaton_cost(system: LinearSystem, aut: StateAutomaton) -> float:
    """J of a :class:`StateAutomaton` by the engine on its closed class (``inf`` if infinite)."""
    keep = aut.closed
    sub0, sub1 = aut.K0[keep][:, keep], aut.K1[keep][:, keep]
    if sub1.sum() == 0.0:  # the closed class never arrives: tau grows without end
        return float("inf")
    init = aut.stationary[keep]
    return Scenario.from_automaton(system, sub0, sub1, init=init / init.sum()).cost()


def _closed_class_law(K: sp.csr_array, warm: int) -> tuple[npt.NDArray[np.intp], FloatArray]:
    r"""The closed class of a chain with one closed class, and its stationary law.

    A state of the class is found by running the chain from the uniform law for enough steps
    (``warm``, about the number of (t, e) pairs) that the transient states have lost most of
    their mass; the class is what it reaches, and :math:`\pi K = \pi` is solved there with that
    state's :math:`\pi` pinned to 1 (a sparse LU of :math:`I - K` without one row and column,
    with no dense normalisation row to fill it in), then normalised.
    """
    n = K.shape[0]
    v = np.full(n, 1.0 / n)
    KT = K.T.tocsr()
    for _ in range(warm):
        v = KT @ v
    root = int(np.argmax(v))
    keep = np.sort(breadth_first_order(K, root, directed=True, return_predecessors=False)).astype(np.intp)
    Kc = K[keep][:, keep]
    r = int(np.searchsorted(keep, root))
    m = keep.size
    if m == 1:
        return keep, np.ones(1)
    others = np.setdiff1d(np.arange(m), [r])
    M = (sp.identity(m, format="csr") - Kc).T.tocsr()[others][:, others]
    rhs = np.asarray(Kc[[r]][:, others].todense()).ravel()
    x = np.asarray(spla.spsolve(M.tocsc(), rhs), dtype=np.float64)
    if not np.all(np.isfinite(x)):
        raise ValueError("block: the policy's chain has no unique stationary law")
    law = np.empty(m)
    law[r] = 1.0
    law[others] = np.clip(x, 0.0, None)
    return keep, law / law.sum()


def _runs(b: FloatArray) -> str:
    """``flag at tau a-b: deliver | block | block p`` runs of equal entries (tau 0 never sees a flag)."""
    parts: list[str] = []
    last = b.size - 1
    start = 1 if b.size > 1 else 0
    for t in range(start + 1, b.size + 1):
        if t <= last and b[t] == b[start]:
            continue
        span = (
            f"tau >= {start}"
            if t - 1 == last
            else (f"tau {start}" if t - 1 == start else f"tau {start}-{t - 1}")
        )
        v = float(b[start])
        act = "deliver" if v == 0.0 else ("block" if v == 1.0 else f"block {v:.6g}")
        parts.append(f"{span}: {act}")
        start = t
    return "; ".join(parts)
