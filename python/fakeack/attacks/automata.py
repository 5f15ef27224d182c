r"""Attackers as finite automata, for the exact engine (:class:`fakeack.Scenario`).

At every step the attacker sees one event, whether the remote detector sent a genuine flag-ACK
(``"flag"``) or not (``"quiet"``), and from its state ``s`` draws one of the transitions listed for
that event, ``(probability, deliver, next_state)``: ``deliver`` says whether the sensor receives a
flag-ACK at the end of the step (a genuine one let through, or a forged one on a quiet step).
Every built-in attack is such an automaton (:func:`as_automaton`), and so is the mimicry attacker,
which runs a virtual copy of the attack-free system and delivers its flag-ACKs.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TypeAlias, cast

import numpy as np

from ..model.channels import Channel, as_channel
from ..model.schedules import OnlineDesign
from .kinds import (
    Attack,
    AttackLike,
    EngineOnlyAttack,
    FlagInjection,
    MaskBlocking,
    PeriodicBlocking,
    RandomBlocking,
    as_attack,
)

__all__ = [
    "Transition",
    "AttackerAutomaton",
    "MimicryAttack",
    "as_automaton",
    "discard_forgeries",
    "SUM_TOL",
]

#: One transition of an event: ``(probability, deliver, next_state)``.
Transition: TypeAlias = tuple[float, bool, int]
Event: TypeAlias = tuple[Transition, ...]

#: Largest deviation from 1 of the probabilities listed for one (state, event).
SUM_TOL = 1e-12
#: Automata with at most this many states print their transitions in full.
_REPR_STATES = 4
EVENTS = ("flag", "quiet")


def _event(where: str, value: object, n: int) -> Event:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) == 0:
        raise TypeError(f"{where} must be a non-empty list of (probability, deliver, next_state)")
    out: list[Transition] = []
    for i, tr in enumerate(value):
        w = f"{where}[{i}]"
        if isinstance(tr, (str, bytes)) or not isinstance(tr, Sequence) or len(tr) != 3:
            raise TypeError(f"{w} must be a triple (probability, deliver, next_state), got {tr!r}")
        p, d, nxt = tr
        if isinstance(p, (bool, np.bool_)) or not isinstance(p, (numbers.Real, np.integer, np.floating)):
            raise TypeError(f"{w}: the probability must be a number, got {type(p).__name__}")
        pf = float(p)
        if not (math.isfinite(pf) and 0.0 <= pf <= 1.0):
            raise ValueError(f"{w}: the probability must lie in [0, 1], got {pf}")
        if isinstance(d, (bool, np.bool_)):
            db = bool(d)
        elif isinstance(d, (int, np.integer)) and int(d) in (0, 1):
            db = bool(d)
        else:
            raise TypeError(f"{w}: deliver must be a bool (or 0/1), got {d!r}")
        if isinstance(nxt, (bool, np.bool_)) or not isinstance(nxt, (int, np.integer)):
            raise TypeError(f"{w}: next_state must be an integer, got {type(nxt).__name__}")
        if not 0 <= int(nxt) < n:
            raise ValueError(f"{w}: next_state {int(nxt)} is not a state (0..{n - 1})")
        out.append((pf, db, int(nxt)))
    total = math.fsum(t[0] for t in out)
    if abs(total - 1.0) > SUM_TOL:
        raise ValueError(f"{where}: the probabilities must sum to 1, got {total!r}")
    return tuple(out)


def _state_entry(where: str, entry: object) -> tuple[object, object]:
    if isinstance(entry, Mapping):
        if set(entry) != set(EVENTS):
            raise ValueError(
                f"{where} must have exactly the keys 'flag' and 'quiet', got {sorted(map(str, entry))}"
            )
        return entry["flag"], entry["quiet"]
    if isinstance(entry, Sequence) and not isinstance(entry, (str, bytes)) and len(entry) == 2:
        return entry[0], entry[1]
    raise TypeError(f"{where} must be a mapping {{'flag': [...], 'quiet': [...]}} or a pair (flag, quiet)")


def _entries(transitions: object) -> list[object]:
    if isinstance(transitions, Mapping):
        keys = list(transitions)
        if any(isinstance(k, bool) or not isinstance(k, (int, np.integer)) for k in keys):
            raise TypeError("transitions: the states (keys) must be integers 0..n-1")
        if sorted(int(k) for k in keys) != list(range(len(keys))):
            raise ValueError(f"transitions: the states (keys) must be 0..{len(keys) - 1}, got {sorted(keys)}")
        return [transitions[k] for k in sorted(keys)]
    if isinstance(transitions, (str, bytes)) or not isinstance(transitions, Sequence):
        raise TypeError(
            "transitions must be a sequence over the states 0..n-1 or a mapping {state: {'flag': [...], "
            f"'quiet': [...]}}, got {type(transitions).__name__}"
        )
    return list(transitions)


@dataclass(frozen=True, init=False, repr=False)
class AttackerAutomaton(EngineOnlyAttack):
    r"""An attacker given as a finite automaton on the events ``"flag"`` and ``"quiet"``.

    In state ``s`` on event ``e`` the attacker takes transition ``(p, deliver, next)`` with
    probability ``p``: the sensor receives a flag-ACK at the end of the step iff ``deliver``
    (blocking is ``deliver = False`` on ``"flag"``; forging is ``deliver = True`` on ``"quiet"``),
    and the attacker moves to ``next``.

    Parameters
    ----------
    transitions : sequence or mapping
        Per state ``0..n-1``, either ``{"flag": [...], "quiet": [...]}`` or a pair
        ``(flag, quiet)``; each event a non-empty list of ``(probability, deliver, next_state)``
        with probabilities in [0, 1] summing to 1 within 1e-12. A mapping is keyed by the states.
    start : int, optional
        The state at step 1 (default 0). Every state must be reachable from it.

    Raises
    ------
    TypeError, ValueError
        Naming ``transitions`` (with the state, the event and the entry) or ``start``.

    Examples
    --------
    An on/off attacker that blocks every flag-ACK while "on" and switches on a flag-ACK:

    >>> onoff = AttackerAutomaton({
    ...     0: {"flag": [(0.5, True, 0), (0.5, False, 1)], "quiet": [(1.0, False, 0)]},
    ...     1: {"flag": [(1.0, False, 1)], "quiet": [(0.9, False, 1), (0.1, False, 0)]},
    ... })
    >>> onoff.n_states, onoff.flag[1]
    (2, ((1.0, False, 1),))
    """

    flag: tuple[Event, ...]
    """Per state, the transitions on a genuine flag-ACK."""
    quiet: tuple[Event, ...]
    """Per state, the transitions on a step without a genuine flag-ACK."""
    start: int
    """The state at step 1."""

    def __init__(self, transitions: object, start: object = 0) -> None:
        entries = _entries(transitions)
        n = len(entries)
        if n == 0:
            raise ValueError("transitions must list at least one state")
        if isinstance(start, (bool, np.bool_)) or not isinstance(start, (int, np.integer)):
            raise TypeError(f"start must be an integer, got {type(start).__name__}")
        if not 0 <= int(start) < n:
            raise ValueError(f"start must be a state (0..{n - 1}), got {int(start)}")
        flag, quiet = [], []
        for s, entry in enumerate(entries):
            f, q = _state_entry(f"transitions[{s}]", entry)
            flag.append(_event(f"transitions[{s}]['flag']", f, n))
            quiet.append(_event(f"transitions[{s}]['quiet']", q, n))
        seen = {int(start)}
        todo = [int(start)]
        while todo:
            s = todo.pop()
            for p, _, nxt in flag[s] + quiet[s]:
                if p > 0.0 and nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        if len(seen) < n:
            missing = sorted(set(range(n)) - seen)
            raise ValueError(f"transitions: states {missing[:10]} are not reachable from start {int(start)}")
        object.__setattr__(self, "flag", tuple(flag))
        object.__setattr__(self, "quiet", tuple(quiet))
        object.__setattr__(self, "start", int(start))

    @property
    def n_states(self) -> int:
        """The number of attacker states."""
        return len(self.flag)

    @property
    def transitions(self) -> dict[int, dict[str, list[Transition]]]:
        """The mapping form ``{state: {"flag": [...], "quiet": [...]}}`` (it rebuilds the automaton)."""
        return {s: {"flag": list(self.flag[s]), "quiet": list(self.quiet[s])} for s in range(self.n_states)}

    @property
    def label(self) -> str:
        """``"automaton:n"`` with n the number of states."""
        return f"automaton:{self.n_states}"

    def __repr__(self) -> str:
        if self.n_states > _REPR_STATES:
            return f"AttackerAutomaton(<{self.n_states} states>, start={self.start})"
        return f"AttackerAutomaton({self.transitions!r}, start={self.start})"

    def __str__(self) -> str:
        return f"attacker automaton with {self.n_states} states"


@dataclass(frozen=True, init=False, repr=False)
class MimicryAttack(EngineOnlyAttack):
    r"""The mimicry attacker: it ignores the genuine flag-ACKs and delivers those of a virtual
    attack-free system that it runs itself.

    The attacker simulates a channel and the remote detector of ``design`` driven by its own
    virtual sensor, and at every step delivers a flag-ACK exactly when the virtual detector sends
    one. When the virtual channel has the real channel's law, the flag-ACKs the sensor receives
    have exactly the attack-free law, so no test on the flag-ACKs' timing can see the attack,
    while the real detector's flag-ACKs (the ones that follow real losses) are all dropped.

    Parameters
    ----------
    channel : Channel, float or None, optional
        The virtual channel; ``None`` (default) means the scenario's.
    design : OnlineDesign or (z0, mu), optional
        The virtual detector; ``None`` (default) means the scenario's (an offline scenario has
        none, so it must then be given).

    Examples
    --------
    >>> MimicryAttack()
    MimicryAttack()
    >>> MimicryAttack(design=(2, 1.0))
    MimicryAttack(design=OnlineDesign(z0=2, mu=1.0))
    """

    channel: Channel | None
    """The virtual channel (``None``: the scenario's)."""
    design: OnlineDesign | None
    """The virtual detector (``None``: the scenario's)."""

    def __init__(self, channel: object = None, design: object = None) -> None:
        object.__setattr__(self, "channel", None if channel is None else as_channel(channel, "channel"))
        object.__setattr__(self, "design", None if design is None else _design(design))

    @property
    def label(self) -> str:
        """``"mimicry"``."""
        return "mimicry"

    def __repr__(self) -> str:
        parts = [
            f"{k}={v!r}" for k, v in (("channel", self.channel), ("design", self.design)) if v is not None
        ]
        return f"MimicryAttack({', '.join(parts)})"

    def __str__(self) -> str:
        return "deliver the flag-ACKs of a virtual attack-free system"


def _design(design: object) -> OnlineDesign:
    if isinstance(design, OnlineDesign):
        return design
    if isinstance(design, tuple) and len(design) == 2:
        return OnlineDesign(*design)
    raise TypeError(f"design must be a fakeack.OnlineDesign or a pair (z0, mu), got {type(design).__name__}")


def _from_lists(
    flag: list[list[Transition]], quiet: list[list[Transition]], start: int = 0
) -> AttackerAutomaton:
    def clean(ev: list[Transition]) -> list[Transition]:
        merged: dict[tuple[bool, int], float] = {}
        for p, d, nxt in ev:
            if p > 0.0:
                merged[(d, nxt)] = merged.get((d, nxt), 0.0) + p
        return [(p, d, nxt) for (d, nxt), p in merged.items()]

    return AttackerAutomaton([(clean(f), clean(q)) for f, q in zip(flag, quiet, strict=True)], start)


def _blocking(attack: PeriodicBlocking | MaskBlocking | RandomBlocking | None) -> AttackerAutomaton:
    if attack is None:  # every genuine flag-ACK goes through
        return _from_lists([[(1.0, True, 0)]], [[(1.0, False, 0)]])
    if isinstance(attack, RandomBlocking):
        b = attack.beta
        return _from_lists([[(b, False, 0), (1.0 - b, True, 0)]], [[(1.0, False, 0)]])
    mask = attack.mask
    t = len(mask)
    return _from_lists(
        [[(1.0, not mask[s], (s + 1) % t)] for s in range(t)], [[(1.0, False, s)] for s in range(t)]
    )


def _injection(attack: FlagInjection) -> AttackerAutomaton:
    """State b * m + g: b the blocking part's state, g = min(k - k_last, m) - 1 at the next step."""
    block, m, gamma = _blocking(attack.block), attack.min_gap, attack.gamma
    flag: list[list[Transition]] = []
    quiet: list[list[Transition]] = []
    for b in range(block.n_states):
        for g in range(m):
            after = min(g + 1, m - 1)
            flag.append([(p, d, nb * m + (0 if d else after)) for p, d, nb in block.flag[b]])
            if g == m - 1:
                quiet.append([(gamma, True, b * m), (1.0 - gamma, False, b * m + g)])
            else:
                quiet.append([(1.0, False, b * m + after)])
    return _from_lists(flag, quiet)


def _mimicry(channel: Channel, design: OnlineDesign) -> AttackerAutomaton:
    """State 0 is the virtual start (c_1 stationary, high power, memory all ones); the others are
    (c, z, h): the virtual channel state of the next step, the zero count, the next power level."""
    P, low, high, pi = channel.P, channel.low, channel.high, channel.stationary
    z0, mu = design.z0, design.mu
    index: dict[tuple[int, int, int] | None, int] = {None: 0}
    order: list[tuple[int, int, int] | None] = [None]
    events: list[list[Transition]] = []
    i = 0
    while i < len(order):
        state = order[i]
        start = [(c, float(pi[c])) for c in range(len(pi))] if state is None else [(state[0], 1.0)]
        z, h = (0, 1) if state is None else state[1:]
        out: list[tuple[float, bool, tuple[int, int, int]]] = []
        for c, w in start:
            p_arr = float(high[c] if h else low[c])
            for arrive, pa in ((True, p_arr), (False, 1.0 - p_arr)):
                z1 = 0 if arrive else z + 1
                flags = (
                    [(1.0, True)]
                    if z1 > z0
                    else [(mu, True), (1.0 - mu, False)]
                    if z1 == z0
                    else [(1.0, False)]
                )
                for pf, fl in flags:
                    for c2 in np.flatnonzero(P[c] > 0.0):
                        out.append((w * pa * pf * float(P[c, c2]), fl, (int(c2), 0 if fl else z1, int(fl))))
        ev: list[Transition] = []
        for p, d, nxt in out:
            if p > 0.0:
                if nxt not in index:
                    index[nxt] = len(order)
                    order.append(nxt)
                ev.append((p, d, index[nxt]))
        events.append(ev)
        i += 1
    return _from_lists(events, [list(e) for e in events])


def as_automaton(attack: object, *, channel: object = None, design: object = None) -> AttackerAutomaton:
    r"""Any attack written as an :class:`AttackerAutomaton`.

    * ``None`` (no attack): one state that delivers every genuine flag-ACK and forges none.
    * :class:`fakeack.PeriodicBlocking`, :class:`fakeack.MaskBlocking`: the counter of genuine
      flag-ACKs modulo the period, blocking where the mask says.
    * :class:`fakeack.RandomBlocking`: one state.
    * :class:`fakeack.FlagInjection` ``(gamma, block, min_gap)``: the blocking part's states times
      ``min_gap`` counters of the steps since the last delivered flag-ACK (state ``b * min_gap + g``).
    * :class:`MimicryAttack`: a start state and the states (c, z, h) of the virtual system
      reachable from it (virtual channel state, zero count, next power level); its
      ``"flag"`` and ``"quiet"`` transitions are the same.
    * :class:`AttackerAutomaton`: returned as it is.

    Parameters
    ----------
    attack : attack, str or None
        Any attack (built-in spellings such as ``"1/5"`` are read by ``as_attack``).
    channel : Channel or float, optional
        The virtual channel of a :class:`MimicryAttack` whose own ``channel`` is None.
    design : OnlineDesign or (z0, mu), optional
        The virtual detector of a :class:`MimicryAttack` whose own ``design`` is None.

    Returns
    -------
    AttackerAutomaton
        Zero-probability transitions dropped, equal ones merged.

    Examples
    --------
    >>> as_automaton(PeriodicBlocking(1, 3)).flag
    (((1.0, False, 1),), ((1.0, True, 2),), ((1.0, True, 0),))
    >>> as_automaton(FlagInjection(0.2, min_gap=2)).quiet
    (((1.0, False, 1),), ((0.2, True, 0), (0.8, False, 1)))
    """
    if isinstance(attack, AttackerAutomaton):
        return attack
    if isinstance(attack, MimicryAttack):
        ch = attack.channel if attack.channel is not None else channel
        ds = attack.design if attack.design is not None else design
        if ch is None:
            raise ValueError("channel: a MimicryAttack without its own channel needs channel=")
        if ds is None:
            raise ValueError("design: a MimicryAttack without its own design needs design=")
        return _mimicry(as_channel(ch, "channel"), _design(ds))
    att: Attack | None = as_attack(cast("AttackLike", attack))  # as_attack validates any object
    if isinstance(att, FlagInjection):
        return _injection(att)
    return _blocking(att)


def discard_forgeries(
    attack: object, *, channel: object = None, design: object = None
) -> Attack | AttackerAutomaton | None:
    r"""The attack as a sensor with authenticated flag-ACKs meets it: every forged flag-ACK is
    rejected, so only its blocking part acts.

    :class:`fakeack.FlagInjection` becomes its ``block`` (None without one); a
    :class:`MimicryAttack` or :class:`AttackerAutomaton` keeps its states and moves, with
    ``deliver`` false on every ``"quiet"`` transition (the attacker still runs its strategy; the
    sensor discards what it forges); blocking attacks and None are unchanged.

    Parameters
    ----------
    attack : attack, str or None
        Any attack.
    channel, design : optional
        The virtual channel and detector of a :class:`MimicryAttack` that has none of its own.

    Returns
    -------
    attack or None
    """
    if attack is None:
        return None
    if isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        auto = as_automaton(attack, channel=channel, design=design)
        states = [
            {"flag": list(flag), "quiet": [(p, False, nxt) for p, _, nxt in quiet]}
            for flag, quiet in zip(auto.flag, auto.quiet, strict=True)
        ]
        return AttackerAutomaton(states, start=auto.start)
    att = as_attack(cast("AttackLike", attack))
    if isinstance(att, FlagInjection):
        return att.block
    return att
