"""The arguments of :func:`fakeack.simulate` and its route to the automaton Monte Carlo.

The specialised kernels (``_fakeack.simulate``) take the paper's channel and, in covariance mode,
two-state Markov channels whose high-power packets always arrive, with ``OfflineSchedule(ratio)``
or an online design and the built-in attacks; everything else (another Markov channel, an
offline pattern, mimicry, an attacker automaton, an injection with ``min_gap > 1``, state mode
under a Markov channel) goes to the plain per-run Monte Carlo of any automaton
(``_fakeack.simulate_automaton``), in covariance or state mode. The closed-loop game kernel
(``_fakeack.simulate_game``) takes the same automaton tables (:func:`kernel_attack`).
"""

from __future__ import annotations

from typing import Any, cast

from .. import _fakeack
from ..attacks.automata import AttackerAutomaton, MimicryAttack, Transition, as_automaton
from ..attacks.kinds import Attack, AttackLike, FlagInjection, as_attack, core_attack
from ..model.channels import Channel, is_paper_channel
from ..model.schedules import OfflineSchedule, OnlineDesign

#: Longest offline period the automaton route passes to the core (as fakeack.Scenario).
MAX_OFFLINE_PERIOD = 10_000_000

SimAttack = Attack | MimicryAttack | AttackerAutomaton
#: An attacker automaton as the compiled kernels take it: per state the "flag" and the "quiet"
#: transitions, then the start state.
CoreAutomaton = tuple[list[list[Transition]], list[list[Transition]], int]


def core_automaton(att: SimAttack | None, ch: Channel, design: OnlineDesign | None) -> CoreAutomaton:
    """The compiled kernels' table of any attack; a mimicry attacker without its own channel or
    design runs ``ch`` and ``design``, the simulation's."""
    auto = as_automaton(att, channel=ch, design=design)
    return [list(ev) for ev in auto.flag], [list(ev) for ev in auto.quiet], auto.start


def kernel_attack(
    att: SimAttack | None, ch: Channel, design: OnlineDesign
) -> tuple[_fakeack.Attack | None, CoreAutomaton | None]:
    """The closed-loop game kernel's attack arguments ``(attack, automaton)``: a built-in attack
    as itself, and as an automaton table what only an automaton writes (mimicry, an
    :class:`fakeack.AttackerAutomaton`, an injection with ``min_gap > 1``)."""
    if isinstance(att, (MimicryAttack, AttackerAutomaton)) or (
        isinstance(att, FlagInjection) and att.min_gap > 1
    ):
        return None, core_automaton(att, ch, design)
    return core_attack(att), None


def schedule_argument(sched: object) -> OfflineSchedule | OnlineDesign:
    """The schedule, checked for its type."""
    if sched is None:
        raise TypeError("simulate() missing the schedule sched")
    if not isinstance(sched, (OfflineSchedule, OnlineDesign)):
        raise TypeError(
            f"sched must be a fakeack.OfflineSchedule or fakeack.OnlineSchedule, got {type(sched).__name__}"
        )
    return sched


def as_sim_attack(attack: object) -> SimAttack | None:
    """Any attack as an object (``None``: no attack): an automaton as it is, the rest by
    ``as_attack``, which validates any object."""
    if isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        return attack
    return as_attack(cast("AttackLike", attack))


def attack_argument(attack: object, sched: OfflineSchedule | OnlineDesign) -> SimAttack | None:
    """The attack as an object (``None``: no attack); an offline schedule takes none."""
    att = as_sim_attack(attack)
    if isinstance(sched, OfflineSchedule) and att is not None:
        raise ValueError("attack: an offline schedule ignores ACKs, so an attack has no effect")
    return att


def needs_automaton(ch: Channel, sched: OfflineSchedule | OnlineDesign, att: SimAttack | None) -> bool:
    """Whether only the automaton Monte Carlo simulates this: another channel than the paper's,
    an offline pattern, or an attack today's kernels do not take."""
    if not is_paper_channel(ch):
        return True
    if isinstance(sched, OfflineSchedule) and sched.ratio is None:
        return True
    if isinstance(att, (MimicryAttack, AttackerAutomaton)):
        return True
    return isinstance(att, FlagInjection) and att.min_gap > 1


def run_automaton(
    core: _fakeack.LinearSystem,
    ch: Channel,
    sched: OfflineSchedule | OnlineDesign,
    att: SimAttack | None,
    horizon: int,
    runs: int,
    seed: int,
    progress: Any,
    record_runs: bool,
    mode: str = "covariance",
) -> dict[str, Any]:
    """``_fakeack.simulate_automaton`` on the converted arguments (``mode`` already checked)."""
    offline: list[bool] | None = None
    if isinstance(sched, OfflineSchedule):
        pattern = sched.pattern
        if len(pattern) > MAX_OFFLINE_PERIOD:
            raise ValueError(f"sched: an offline period of {len(pattern)} steps exceeds {MAX_OFFLINE_PERIOD}")
        offline = [bool(x) for x in pattern]
        z0, mu = 1, 1.0
        flag, quiet, start = core_automaton(None, ch, None)
    else:
        z0, mu = sched.z0, sched.mu
        flag, quiet, start = core_automaton(att, ch, sched)
    return _fakeack.simulate_automaton(
        core,
        ch.P.tolist(),
        ch.low.tolist(),
        ch.high.tolist(),
        z0,
        mu,
        offline,
        flag,
        quiet,
        start,
        horizon,
        runs,
        seed,
        progress,
        record_runs,
        mode,
    )
