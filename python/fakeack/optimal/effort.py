r"""Which attack to buy: the long-run cost J each kind of attack reaches per unit of attacker energy.

The sensor runs the online schedule that spends the energy ratio p/q (:func:`fakeack.design_online`).
The attacker pays per action: ``jam_cost`` per jammed step, ``block_cost`` per blocked flag-ACK,
``forge_cost`` per forged flag-ACK. Its effort e is its energy per step in the long run. For each
effort and each kind of attack, :func:`attack_effort` finds the most damaging attack of that kind
whose energy per step is e (or, once the kind is saturated, less), evaluates its J exactly with
:class:`fakeack.Scenario`, and names the kind that does most damage.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
from scipy.optimize import brentq

from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_probability, as_ratio, as_real
from ..attacks.jamming import RandomJamming
from ..engine.scenario import Scenario
from ..model.channels import Channel, ChannelLike, MarkovChannel, as_channel, is_paper_channel
from ..model.schedules import OfflineSchedule, OnlineDesign, design_online, offline_schedule
from ..model.system import LinearSystem, compiled
from .attack import worst_attack
from .state_policy import StatePolicy

__all__ = ["KINDS", "AttackOption", "AttackEffort", "attack_effort", "jam_high_channel"]

#: The kinds of attack :func:`attack_effort` compares, in the order ties are resolved.
KINDS = ("jam", "jam-high", "block", "forge")
#: Relative tolerance of the budget found for an effort (the energy spent is the effort to this).
_XTOL = 1e-12


def jam_high_channel(channel: ChannelLike, p: float) -> Channel:
    """The channel seen by a sensor whose high-power packets are each jammed with probability ``p``.

    A jammer that recognises a high-power transmission (it overhears the flag-ACK that triggers
    it, or the transmit power) and jams it with probability p leaves the low-power arrivals alone
    and multiplies the high-power ones by 1 - p, in every channel state.

    Parameters
    ----------
    channel : Channel or float
        The channel (a float: the paper's, high power always arriving).
    p : float
        The probability of jamming a high-power step, in [0, 1].

    Returns
    -------
    Channel
        The same state process with ``high`` scaled by ``1 - p``.

    Raises
    ------
    TypeError, ValueError
        Naming ``channel`` or ``p``.

    Examples
    --------
    >>> jam_high_channel(0.5, 0.25).high.tolist()
    [0.75]
    """
    ch = as_channel(channel, "channel")
    q = as_probability("p", p, closed=True)
    return MarkovChannel(ch.P, ch.low, ch.high * (1.0 - q))


@dataclass(frozen=True)
class AttackOption:
    """The most damaging attack of one kind found for one effort (see :func:`attack_effort`).

    ``fa.Scenario(system, option.channel, design, option.attack).cost()`` is ``option.j``.
    """

    kind: str
    """One of "jam", "jam-high", "block", "forge"."""
    effort: float
    """The effort asked for: the attacker's energy per step."""
    spent: float
    """The attacker's energy per step this attack spends: ``effort`` (to 1e-9 relative), or less
    when the kind is saturated (``budget`` at its largest value)."""
    budget: float
    """The kind's own budget: the jam rate r (``"jam"``), the probability of jamming a high-power
    step (``"jam-high"``), the blocked fraction beta or the forged fraction of quiet steps."""
    j: float
    """J of the online sensor under this attack (``inf`` when the attack makes it diverge)."""
    j_offline: float
    """J of the offline schedule of the same ratio under the same attack (the attack-free J_off for
    flag-ACK attacks, which the offline schedule does not read)."""
    channel: Channel
    """The channel of the scenario: the given one, or the high-power-jammed one (``"jam-high"``)."""
    attack: RandomJamming | StatePolicy | None
    """The scenario's attack: a :class:`fakeack.RandomJamming`, the worst attack's
    :class:`fakeack.StatePolicy`, or None (``"jam-high"``: the attack is in the channel)."""

    @property
    def j_fallback(self) -> float:
        """J of a sensor that detects the attack and runs the better of the two schedules."""
        return min(self.j, self.j_offline)


@dataclass(frozen=True, eq=False)
class AttackEffort:
    """J of each kind of attack against attacker effort (see :func:`attack_effort`)."""

    effort: FloatArray
    """``(n,)`` the efforts: attacker energy per step, increasing."""
    kinds: tuple[str, ...]
    """The kinds compared, a subset of ("jam", "jam-high", "block", "forge")."""
    j: FloatArray
    """``(len(kinds), n)`` J of the online sensor under the best attack of each kind."""
    j_fallback: FloatArray
    """``(len(kinds), n)`` the same attack against a sensor that falls back to the better of the
    online and the offline schedule (``min(j, j_offline)`` of each option)."""
    best: tuple[str, ...]
    """Per effort, the kind of greatest J against the online sensor (ties: the first in ``kinds``;
    ``"none"`` where no kind raises J above ``j_online`` by more than 1e-12 relative)."""
    best_fallback: tuple[str, ...]
    """Per effort, the kind of greatest ``j_fallback`` (``"none"`` as for ``best``)."""
    options: tuple[tuple[AttackOption, ...], ...]
    """``options[i][k]``: the attack of kind ``kinds[i]`` at effort ``effort[k]``."""
    design: OnlineDesign
    """The sensor's online schedule (:func:`fakeack.design_online` of the ratio)."""
    offline: OfflineSchedule
    """The offline schedule of the same ratio (the fall-back)."""
    j_online: float
    """J of the online schedule without attack."""
    j_offline: float
    """J of the offline schedule without attack."""
    costs: tuple[float, float, float]
    """``(jam_cost, block_cost, forge_cost)``: attacker energy per jammed step, per blocked and per
    forged flag-ACK."""

    @property
    def j_best(self) -> FloatArray:
        """``(n,)`` J of the best attack at each effort (online sensor)."""
        return np.asarray(np.max(self.j, axis=0), dtype=np.float64)

    @property
    def j_best_fallback(self) -> FloatArray:
        """``(n,)`` J of the best attack at each effort against the fall-back sensor."""
        return np.asarray(np.max(self.j_fallback, axis=0), dtype=np.float64)


def attack_effort(
    system: LinearSystem,
    channel: ChannelLike,
    ratio: RatioLike,
    efforts: Sequence[float] | npt.ArrayLike | None = None,
    *,
    jam_cost: float = 1.0,
    block_cost: float = 1.0,
    forge_cost: float = 1.0,
    kinds: Sequence[str] = KINDS,
) -> AttackEffort:
    r"""Which attack raises the sensor's J most for a given attacker energy per step.

    The sensor runs :func:`fakeack.design_online` of ``ratio``. At effort e (energy per step),
    for each kind:

    * ``"jam"``, blind jamming of the data channel: every step jammed independently with
      probability :math:`r = \min(1, e/c_\mathrm{jam})` (:class:`fakeack.RandomJamming`; energy
      :math:`r c_\mathrm{jam}` per step). A jammed step loses the packet at any power, and the
      remote detector counts it as a loss (at r = 1 no packet arrives: J is
      :math:`\mathrm{Tr}\,X_\infty`, :math:`X_\infty = A X_\infty A' + Q`, if
      :math:`\rho(A) < 1`, else infinite).
    * ``"jam-high"``, reactive jamming: each high-power step jammed with probability p
      (:func:`jam_high_channel`); energy :math:`p f_p c_\mathrm{jam}`, :math:`f_p` the
      high-power rate under that jamming (``Scenario.high_power_rate``), which grows with p.
    * ``"block"``: :func:`fakeack.worst_attack` with blocking budget beta (the worst attack over
      every attacker that sees the holding time and the detector's state and blocks at most a
      fraction beta of the genuine flag-ACKs); energy :math:`c_\mathrm{block}` times its blocked
      flag-ACKs per step (``Scenario.flag_rates().blocked`` under that attack: beta times the
      genuine flag rate *under the attack*, which exceeds the attack-free one).
    * ``"forge"``: :func:`fakeack.worst_attack` with beta = 0 and forge budget phi; energy
      :math:`c_\mathrm{forge}` times its forged flag-ACKs per step.

    The budget (r, p, beta or phi) is the one whose energy is e, found by Brent's method to 1e-12
    (the energy grows with the budget in every case computed in the tests and the docs, so it is
    the largest budget within e; ``spent`` reports the energy of the budget returned); when even
    the largest budget spends less than e the kind is saturated and its largest budget is used.
    For blocking and forging J grows with e (a larger budget admits every smaller attack); for
    the jamming families it does in every example of the tests, but it is not a theorem here: a
    jammed step also makes the detector send its flag-ACK sooner. The blocking and forging
    attacks are optimal for a *fraction* budget; an attacker bound only by energy per step could spread it
    otherwise, so their J is what that attacker reaches at least. Blind and reactive jamming are
    families, not optima: an attacker that jams knowing the holding time can do more (on an
    unstable process, holding the jam probability above :math:`1/\rho(A)^2` once the holding
    time is long makes J infinite at a vanishing rate, as :func:`fakeack.optimal_jamming` finds
    against a sensor at one power).

    **Fall-back.** ``j_fallback`` is J of a sensor that detects the attack and runs the better of
    the online and the offline schedule of the same ratio: an attack on the flag-ACKs cannot push
    it above the attack-free J_off, jamming hits the offline schedule too.

    Parameters
    ----------
    system : LinearSystem
        The process and its sensor.
    channel : Channel or float
        The packet channel (a float: the paper's, with that low-power arrival probability).
    ratio : Fraction, int/int string or float
        The sensor's energy ratio p/q.
    efforts : sequence of float, optional
        Attacker energies per step, non-negative (sorted on return, duplicates removed). Default:
        11 evenly spaced from 0 to the energy of blocking every flag-ACK.
    jam_cost, block_cost, forge_cost : float, keyword-only, optional
        Attacker energy per jammed step, per blocked and per forged flag-ACK (positive; default 1).
    kinds : sequence of str, keyword-only, optional
        The kinds to compare, from "jam", "jam-high", "block", "forge" (default all).

    Returns
    -------
    AttackEffort

    Raises
    ------
    TypeError, ValueError
        Naming the argument: ``efforts`` negative, empty or not finite, a cost not positive,
        ``kinds`` empty or unknown, and as :func:`fakeack.design_online` and
        :func:`fakeack.worst_attack` do.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> res = attack_effort(s, 0.5, "1/7", [0.0, 0.05], kinds=("jam", "block"))
    >>> res.best[1], [round(float(v), 4) for v in res.j[:, 1]]
    ('block', [1.8001, 2.1067])
    """
    compiled(system)
    ch = as_channel(channel, "channel")
    r = as_ratio("ratio", ratio)
    costs = tuple(
        _positive(n, v)
        for n, v in (("jam_cost", jam_cost), ("block_cost", block_cost), ("forge_cost", forge_cost))
    )
    ks = _kinds(kinds)
    # A number is passed on as given, so that design_online's arithmetic stays exact.
    design = design_online(channel if isinstance(channel, (int, float)) else ch, r)
    pattern = offline_schedule(r) if is_paper_channel(ch) else offline_schedule(r, ch, system=system)
    offline = OfflineSchedule(pattern=pattern.tolist())
    j_on = Scenario(system, ch, design).cost()
    j_off = Scenario(system, ch, offline).cost()
    kit = _Kit(system, ch, design, offline, j_off, (costs[0], costs[1], costs[2]))
    e = _efforts(efforts, kit)
    options = tuple(tuple(kit.option(k, float(v)) for v in e) for k in ks)
    j = np.array([[o.j for o in row] for row in options], dtype=np.float64)
    jf = np.array([[o.j_fallback for o in row] for row in options], dtype=np.float64)
    for a in (e, j, jf):
        a.flags.writeable = False
    return AttackEffort(
        e,
        ks,
        j,
        jf,
        _best(j, ks, j_on),
        _best(jf, ks, min(j_on, j_off)),
        options,
        design,
        offline,
        j_on,
        j_off,
        (costs[0], costs[1], costs[2]),
    )


class _Kit:
    """The fixed data of one :func:`attack_effort` call and the per-kind searches."""

    def __init__(
        self,
        system: LinearSystem,
        ch: Channel,
        design: OnlineDesign,
        offline: OfflineSchedule,
        j_off: float,
        costs: tuple[float, float, float],
    ) -> None:
        self.system, self.ch, self.design, self.offline, self.j_off = system, ch, design, offline, j_off
        self.jam_cost, self.block_cost, self.forge_cost = costs
        self._flag_cache: dict[tuple[float, float], tuple[StatePolicy, float]] = {}

    def flag_attack(self, beta: float, phi: float) -> tuple[StatePolicy, float, float]:
        """The worst attack's policy, its J and its energy per step (blocked and forged flag-ACKs)."""
        key = (beta, phi)
        if key not in self._flag_cache:
            w = worst_attack(self.system, self.ch, self.design, beta, forge_budget=phi)
            self._flag_cache[key] = (w.policy, w.j)
        policy, j = self._flag_cache[key]
        rates = Scenario(self.system, self.ch, self.design, policy).flag_rates()
        spent = self.block_cost * max(rates.blocked, 0.0) + self.forge_cost * rates.forged
        return policy, j, spent

    def jam_high(self, p: float) -> tuple[Channel, float, float]:
        """The high-power-jammed channel, the online J on it and the jammer's energy per step."""
        jc = jam_high_channel(self.ch, p)
        sc = Scenario(self.system, jc, self.design)
        return jc, sc.cost(), self.jam_cost * p * sc.high_power_rate()

    def option(self, kind: str, effort: float) -> AttackOption:
        if kind == "jam":
            rate = min(1.0, effort / self.jam_cost)
            jam = RandomJamming(rate)
            if rate == 1.0:  # no packet ever arrives, whatever the schedule
                j = j_off = _no_arrival_cost(self.system)
            else:
                j = Scenario(self.system, self.ch, self.design, jam).cost()
                j_off = Scenario(self.system, self.ch, self.offline, jam).cost()
            return AttackOption(kind, effort, rate * self.jam_cost, rate, j, j_off, self.ch, jam)
        if kind == "jam-high":
            p = _budget(lambda x: self.jam_high(x)[2], effort)
            jc, j, spent = self.jam_high(p)
            j_off = Scenario(self.system, jc, self.offline).cost()
            return AttackOption(kind, effort, spent, p, j, j_off, jc, None)
        blocking = kind == "block"
        x = _budget(
            lambda v: self.flag_attack(v, 0.0)[2] if blocking else self.flag_attack(0.0, v)[2], effort
        )
        policy, j, spent = self.flag_attack(x, 0.0) if blocking else self.flag_attack(0.0, x)
        return AttackOption(kind, effort, spent, x, j, self.j_off, self.ch, policy)

    def full_block_energy(self) -> float:
        """Energy per step of blocking every flag-ACK (the default largest effort)."""
        return self.flag_attack(1.0, 0.0)[2]


def _best(j: FloatArray, kinds: tuple[str, ...], j_free: float) -> tuple[str, ...]:
    """Per column, the kind of greatest J, ``"none"`` where none raises J above ``j_free``."""
    top = np.max(j, axis=0)
    return tuple(
        kinds[int(i)] if t > j_free * (1.0 + 1e-12) else "none"
        for i, t in zip(np.argmax(j, axis=0), top, strict=True)
    )


def _budget(spent: Callable[[float], float], effort: float) -> float:
    """The largest budget in [0, 1] whose energy ``spent(budget)`` is at most ``effort``."""
    if effort <= 0.0:
        return 0.0
    top = spent(1.0)
    if top <= effort:
        return 1.0
    root = float(brentq(lambda x: spent(x) - effort, 0.0, 1.0, xtol=_XTOL, rtol=4 * np.finfo(float).eps))
    return root


def _no_arrival_cost(system: LinearSystem) -> float:
    r"""J when no packet arrives: :math:`\lim_k \mathrm{Tr}\,h^k(\bar P) = \mathrm{Tr}\,X_\infty`,
    :math:`X_\infty = A X_\infty A' + Q`, if :math:`\rho(A) < 1`; else infinite."""
    if system.spectral_radius >= 1.0:
        return math.inf
    return float(np.trace(sla.solve_discrete_lyapunov(system.A, system.Q)))


def _positive(name: str, x: object) -> float:
    v = as_real(name, x)
    if v <= 0.0:
        raise ValueError(f"{name} must be positive, got {v}")
    return v


def _kinds(kinds: Sequence[str]) -> tuple[str, ...]:
    if isinstance(kinds, str) or not isinstance(kinds, Sequence):
        raise TypeError(f"kinds must be a sequence of names from {KINDS}, got {kinds!r}")
    out = tuple(dict.fromkeys(kinds))
    if not out:
        raise ValueError("kinds must name at least one kind of attack")
    for k in out:
        if k not in KINDS:
            raise ValueError(f"kinds: unknown kind {k!r}, expected one of {KINDS}")
    return out


def _efforts(efforts: Sequence[float] | npt.ArrayLike | None, kit: _Kit) -> FloatArray:
    if efforts is None:
        return np.linspace(0.0, kit.full_block_energy(), 11)
    try:
        e = np.asarray(efforts, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"efforts must be a sequence of numbers, got {efforts!r}") from exc
    if e.size == 0:
        raise ValueError("efforts must hold at least one effort")
    if not np.all(np.isfinite(e)) or np.any(e < 0.0):
        raise ValueError("efforts must be finite and non-negative")
    return np.unique(e)
