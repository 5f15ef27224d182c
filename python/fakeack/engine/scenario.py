r"""One scenario of the exact engine: a system, a channel, a sensor schedule and an attacker.

The engine builds the finite automaton E of everything but the holding time :math:`\tau` (the
channel state, the detector's zero count, the sensor's next power level or offline phase, the
attacker's state), splits its transition matrix :math:`K = K_0 + K_1` by loss and arrival, and
solves the coupled Stein equations

.. math:: Z_e = \bar P + (w_e - 1) Q + \sum_f K_0[e, f]\, A Z_f A', \qquad
   J = \mathrm{Tr} \sum_e \nu_e Z_e,

with :math:`\nu = \pi_E K_1` and :math:`w = (I - K_0)^{-1}\mathbf 1` (docs page "The exact
engine"). An automaton built by hand, :math:`K_0` and :math:`K_1` only, is solved the same way
(:meth:`Scenario.from_automaton`). The computation is the compiled core's
(``fakeack._fakeack.Engine``); this module validates the objects and converts them.
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from .. import _fakeack
from .._internal.html import key_values
from .._internal.validate import as_int, as_real
from ..attacks.automata import discard_forgeries
from ..attacks.jamming import Jamming, JammingAttack, RandomJamming
from ..attacks.rates import FlagRates
from ..model.channels import Channel, as_channel
from ..model.schedules import OfflineSchedule, OnlineDesign
from ..model.system import LinearSystem, compiled
from ..montecarlo.trace import TraceCurve
from .automaton import automaton_args
from .binding import (
    AnyAttack,
    AnySchedule,
    EngineAutomaton,
    ScenarioSchedule,
    as_scenario_attack,
    as_schedule,
    binding_args,
)
from .chains import (
    AttackPolicy,
    ScenarioChain,
    SchedulePolicy,
    chain_flag_rates,
    chain_mean,
    has_chain,
    restricted,
)
from .jammed import csr, jammed_chain

__all__ = [
    "Scenario",
    "EngineAutomaton",
    "DEFAULT_MAX_STATES",
]

#: Largest automaton (states of E) a scenario builds unless told otherwise.
DEFAULT_MAX_STATES = 1_000_000


class Scenario:
    r"""A system, a channel, a sensor schedule and an attacker, computed exactly.

    Parameters
    ----------
    system : LinearSystem
        The process and its sensor (:math:`A, C, Q, R`; the engine uses :math:`A`, :math:`Q` and
        :math:`\bar P`).
    channel : Channel or float
        :class:`fakeack.BernoulliChannel`, :class:`fakeack.MarkovChannel`,
        :class:`fakeack.GilbertElliott`, or a float ``lam`` (the paper's channel).
    schedule : OnlineDesign, OfflineSchedule or sensor policy
        The ACK-based online schedule ``(z0, mu)``, or an offline one (by its ratio or any
        pattern). An offline sensor ignores flag-ACKs, so it takes no flag-ACK attack. Or a
        sensor policy that writes itself out as the engine's automaton
        (``scenario_chain(channel)``, ``fakeack.engine.chains.SchedulePolicy``), such as
        :class:`fakeack.HoldingTimePolicy`: its L power levels carry their own energies and
        arrival probabilities, the channel supplies only its state process ``P``, and it takes
        no attack (it reads per-packet ACKs, not flag-ACKs).
    attack : attack, MimicryAttack, AttackerAutomaton, attack policy, jamming or None, optional
        Any built-in attack (or a spelling ``as_attack`` reads, e.g. ``"1/5"``), including
        :class:`fakeack.FlagInjection` with ``min_gap``; :class:`fakeack.MimicryAttack`, whose
        ``None`` channel and design are this scenario's; any :class:`fakeack.AttackerAutomaton`;
        an attacker that writes itself out as the engine's automaton
        (``scenario_chain(channel, design)``, ``fakeack.engine.chains.AttackPolicy``), such
        as :class:`fakeack.StatePolicy`, with an online schedule; or jamming of the data
        channel, :class:`fakeack.Jamming` (step k jammed iff ``pattern[(k - 1) % L]``, phase 0
        at step 1) or :class:`fakeack.RandomJamming`, with an online or offline schedule. A
        jammed step is a loss the detector sees, so it also triggers flag-ACKs.
    max_states : int, keyword-only, optional
        Refuse (ValueError) an automaton E of more states than this, before allocating it
        (default 10^6).
    authenticated : bool, keyword-only, optional
        Whether the sensor authenticates flag-ACKs (default False): forged ones are rejected,
        so only the attack's blocking part acts (``fakeack.attacks.discard_forgeries``); the
        scenario's ``attack`` is then that part.

    Attributes
    ----------
    system, channel, schedule, attack, max_states, authenticated
        The arguments, as read; ``channel``, ``schedule`` and ``attack`` are None for a scenario
        built by :meth:`from_automaton`.

    Notes
    -----
    Every scenario's cost, :meth:`stability_index`, :meth:`holding_time_law`, :meth:`cost_curve`
    and :meth:`automaton` are exact. The rates need the protocol: :meth:`high_power_rate` and
    :meth:`flag_rates` raise ValueError for a sensor policy with L power levels (its
    :meth:`energy_per_step` takes no energies: the levels carry them). Under a jamming pattern
    the automaton is written out from phase 0 at step 1 and solved as one given by
    :math:`K_0` and :math:`K_1`; when its long run depends on the phase (several closed
    classes), every figure is the one from phase 0.

    Raises
    ------
    TypeError, ValueError
        For invalid arguments (naming them). Once the engine is built, ValueError naming the
        channel or the attack when from some state no arrival can ever happen
        (:math:`\rho(K_0) = 1`).

    Examples
    --------
    >>> import fakeack as fa
    >>> sc = fa.Scenario(fa.LinearSystem(1.2, 0.7, 0.8, 0.8), fa.GilbertElliott(0.1, 0.3, 0.9, 0.2),
    ...                  fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5))
    >>> sc  # doctest: +ELLIPSIS
    Scenario(system=LinearSystem(...), channel=GilbertElliott(...), schedule=OnlineDesign(...), attack=...)
    """

    def __init__(
        self,
        system: LinearSystem,
        channel: Channel | float,
        schedule: OnlineDesign | OfflineSchedule | SchedulePolicy,
        attack: object = None,
        *,
        max_states: int = DEFAULT_MAX_STATES,
        authenticated: bool = False,
    ) -> None:
        self._core_system = compiled(system)
        self.system = system
        ch, sched = as_channel(channel, "channel"), as_schedule(schedule)
        self.channel: Channel | None = ch
        self.schedule: AnySchedule | None = sched
        self.authenticated = bool(authenticated)
        self.max_states = as_int("max_states", max_states, minimum=1)
        self._chain: ScenarioChain | None = None
        if isinstance(attack, (Jamming, RandomJamming)):
            self.attack: AnyAttack | None = attack
            if not isinstance(sched, (OnlineDesign, OfflineSchedule)):
                raise TypeError(
                    "attack: jamming applies to an OnlineDesign or OfflineSchedule; a sensor policy's "
                    "levels carry their own arrival probabilities (scale them by the unjammed share)"
                )
            self._engine = self._jammed(ch, sched, attack)
            return
        if has_chain(sched):
            if attack is not None:
                raise ValueError("attack: a sensor policy reads per-packet ACKs and ignores flag-ACKs")
            self.attack = None
            self._engine = self._given(cast("SchedulePolicy", sched).scenario_chain(ch), "schedule")
            return
        assert isinstance(sched, (OnlineDesign, OfflineSchedule))
        if has_chain(attack):
            if self.authenticated:
                raise ValueError(
                    "authenticated: applies to the built-in attacks and automata; give the attack "
                    "policy without its forging instead"
                )
            if not isinstance(sched, OnlineDesign):
                raise ValueError("attack: an offline schedule ignores flag-ACKs, so an attack has no effect")
            self.attack = cast("AttackPolicy", attack)
            self._engine = self._given(self.attack.scenario_chain(ch, sched), "attack")
            return
        if self.authenticated and attack is not None:
            design = sched if isinstance(sched, OnlineDesign) else None
            attack = discard_forgeries(attack, channel=ch, design=design)
        self.attack = as_scenario_attack(attack)
        if isinstance(sched, OfflineSchedule) and self.attack is not None:
            raise ValueError("attack: an offline schedule ignores flag-ACKs, so an attack has no effect")
        self._engine = _fakeack.Engine(*binding_args(ch, sched, self.attack, self.max_states))

    def _given(self, chain: object, role: str) -> Any:
        """The engine of a policy's own automaton (:mod:`fakeack.engine.chains`)."""
        if not isinstance(chain, ScenarioChain):
            raise TypeError(
                f"{role}: scenario_chain must return a fakeack.engine.chains.ScenarioChain, "
                f"got {type(chain).__name__}"
            )
        self._chain = restricted(chain, role)
        c = self._chain
        args = automaton_args(c.K0, c.K1, c.init, c.labels, self.max_states)
        try:
            return _fakeack.Engine.from_automaton(*args)
        except ValueError as exc:  # no arrival from some state: the policy's doing
            raise ValueError(f"{role}: {exc}") from None

    def _jammed(self, ch: Channel, sched: ScenarioSchedule, jam: JammingAttack) -> Any:
        """The engine under jamming: random jamming on the jammed channel; a pattern's automaton
        written out from phase 0 (:mod:`fakeack.engine.jammed`)."""
        if isinstance(jam, RandomJamming):
            args = binding_args(jam.jammed_channel(ch), sched, None, self.max_states)
            try:
                return _fakeack.Engine(*args)
            except ValueError as exc:  # no arrival from some state: the jammer's doing
                raise ValueError(f"attack: {exc}") from None
        return self._given(jammed_chain(ch, sched, jam, self.max_states), "attack")

    @classmethod
    def from_automaton(
        cls,
        system: LinearSystem,
        K0: object,
        K1: object,
        *,
        init: npt.ArrayLike | None = None,
        labels: list[str] | None = None,
        max_states: int = DEFAULT_MAX_STATES,
    ) -> Scenario:
        r"""A scenario whose automaton E is given: :math:`K_0` (loss) and :math:`K_1` (arrival).

        For sensor policies, attackers and jammers the built-in parts do not cover: write the
        finite state e that holds everything but the holding time :math:`\tau`, and split each
        step's move by whether the packet is lost (:math:`K_0`, :math:`\tau \to \tau + 1`) or
        arrives (:math:`K_1`, :math:`\tau \to 0`). The cost is the one of the built-in scenarios,

        .. math:: Z_e = \bar P + (w_e - 1) Q + \sum_f K_0[e, f]\, A Z_f A', \qquad
           J = \mathrm{Tr} \sum_e \nu_e Z_e,

        with :math:`\nu = \pi_E K_1`, :math:`w = (I - K_0)^{-1}\mathbf 1` and :math:`\pi_E`
        the long-run law of :math:`K = K_0 + K_1` from ``init`` (with several closed classes,
        each weighted by the chance of ending in it); finite iff
        :math:`\rho(K_0)\rho(A)^2 < 1`. :meth:`cost`, :meth:`stability_index`,
        :meth:`holding_time_law`, :meth:`cost_curve` and :meth:`automaton` work as for any
        scenario. The matrices carry no power or flag-ACK information, so
        :meth:`high_power_rate`, :meth:`energy_per_step` and :meth:`flag_rates` raise
        ValueError; ``channel``, ``schedule`` and ``attack`` are None.

        Parameters
        ----------
        system : LinearSystem
            The process and its sensor (the engine uses :math:`A`, :math:`Q` and :math:`\bar P`).
        K0, K1 : scipy.sparse array or matrix, or 2-D array
            Square, of one shape (n, n), entries finite and :math:`\ge 0`, each row of
            :math:`K_0 + K_1` summing to 1 within 1e-12. ``K0[e, f]`` is the probability of
            moving from e to f with a lost packet, ``K1[e, f]`` with an arrival.
        init : array_like, keyword-only, optional
            The law of :math:`e_0`, the state before step 1 (:math:`\tau_0 = 0`), for
            :meth:`cost_curve` and to weigh closed classes; default: state 0 surely. Every state
            must be reachable from it.
        labels : list of str, keyword-only, optional
            One name per state (default: its index), shown by :meth:`automaton` and in errors.
        max_states : int, keyword-only, optional
            Refuse (ValueError) more than this many states, before allocating (default 10^6).

        Returns
        -------
        Scenario
            With ``channel``, ``schedule`` and ``attack`` None.

        Raises
        ------
        TypeError, ValueError
            Naming ``K0``, ``K1`` (``K0 + K1`` for a row sum), ``init``, ``labels`` or
            ``max_states``; ValueError naming ``K0`` when from some state no packet ever arrives
            again (:math:`\rho(K_0) = 1`).

        Examples
        --------
        One state in which each packet arrives with probability 0.6, so that
        :math:`J = (\lambda \bar P + (1 - \lambda) Q) / (1 - (1 - \lambda) A^2)`:

        >>> import fakeack as fa
        >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
        >>> sc = fa.Scenario.from_automaton(s, [[0.4]], [[0.6]])
        >>> pbar = float(s.pbar[0, 0])
        >>> abs(sc.cost() - (0.6 * pbar + 0.4 * 0.8) / (1 - 0.4 * 1.44)) < 1e-12
        True
        """
        self = cls.__new__(cls)
        self._core_system = compiled(system)
        self.system = system
        self.channel, self.schedule, self.attack = None, None, None
        self.authenticated = False
        self._chain = None
        args = automaton_args(K0, K1, init, labels, max_states)
        self.max_states = args[-1]
        self._engine = _fakeack.Engine.from_automaton(*args)
        return self

    # --- conversion ----------------------------------------------------------------------------

    def _rate_source(self, what: str) -> Any:
        """The engine or the policy's chain that knows the power and flag-ACK rates; ValueError
        saying why when the scenario does not know them."""
        if self.channel is None:
            raise ValueError(
                f"automaton: {what} needs a channel and a schedule; an automaton given as K0 and K1 "
                "carries no power or flag-ACK information"
            )
        if self._chain is not None:
            return self._chain
        return self._engine

    def _policy(self) -> str:
        """``"schedule: HoldingTimePolicy"``: the role and the type of the policy that gave the chain."""
        role, obj = ("attack", self.attack) if self.attack is not None else ("schedule", self.schedule)
        return f"{role}: {type(obj).__name__}"

    # --- results -------------------------------------------------------------------------------

    @property
    def n_states(self) -> int:
        """The number of states of the automaton E."""
        return int(self._engine.n_states)

    def cost(self) -> float:
        r"""The long-run average cost :math:`J = \lim \frac1T\sum_{k\le T}\mathrm{Tr}\,\mathbb E P_k`.

        Returns
        -------
        float
            :math:`\mathrm{Tr}\sum_e \nu_e Z_e` from the coupled Stein equations; ``inf`` when
            :math:`\rho(K_0)\rho(A)^2 \ge 1` (never NaN).
        """
        return float(self._engine.cost(self._core_system))

    def stability_index(self) -> float:
        r""":math:`\rho(K_0)\,\rho(A)^2`: the cost is finite iff it is below 1.

        Decided by an M-matrix test (the solution of :math:`(I - \rho(A)^2 K_0)x = \mathbf 1`
        exists and is positive), which is exact also for the cyclic :math:`K_0` of periodic
        attacks. With every flag-ACK blocked on the paper's channel it is
        :math:`(1-\lambda)\rho(A)^2` (Model note 5).
        """
        return float(self._engine.stability_index(self._core_system))

    def high_power_rate(self) -> float:
        """The long-run fraction of steps at high power (online: the rate of flag-ACKs received).

        Raises
        ------
        ValueError
            For a scenario built by :meth:`from_automaton`, which carries no power information;
            for a sensor policy of L power levels (not a high and a low one: see
            :meth:`energy_per_step`).
        """
        src = self._rate_source("high_power_rate")
        if isinstance(src, ScenarioChain):
            if src.high is None:
                raise ValueError(
                    f"{self._policy()} has power levels, not a high and a low one, so no high-power "
                    "rate; energy_per_step() gives the energy its levels spend"
                )
            return chain_mean(src, src.high)
        return float(src.high_power_rate())

    def energy_per_step(self, Delta: float | None = None, delta: float | None = None) -> float:
        r"""Long-run energy per step, :math:`\delta + (\Delta - \delta) f` with f :meth:`high_power_rate`.

        For a sensor policy with power levels (:class:`fakeack.HoldingTimePolicy`) the levels
        carry the energies: :math:`\sum_e \pi_e \sum_l p(l \mid e)\,e_l`, called without
        arguments.

        Parameters
        ----------
        Delta, delta : float
            Energy of a high- and a low-power transmission, :math:`\Delta > \delta \ge 0`
            (required, except for a sensor policy with power levels, which refuses them).

        Raises
        ------
        TypeError
            ``Delta`` and ``delta`` missing for a two-level schedule, or given for a policy's levels.
        ValueError
            For invalid energies, and where :meth:`high_power_rate` raises.
        """
        src = self._rate_source("energy_per_step")
        if isinstance(src, ScenarioChain) and src.energy is not None:
            if Delta is not None or delta is not None:
                raise TypeError(
                    "Delta and delta: the schedule's power levels carry their energies; call "
                    "energy_per_step() without them"
                )
            return chain_mean(src, src.energy)
        if Delta is None or delta is None:
            raise TypeError("Delta and delta are required: the energies of a high- and a low-power packet")
        hi, lo = as_real("Delta", Delta), as_real("delta", delta)
        if lo < 0:
            raise ValueError(f"delta must be non-negative, got {lo}")
        if not hi > lo:
            raise ValueError(f"Delta must exceed delta, got Delta={hi}, delta={lo}")
        return lo + (hi - lo) * self.high_power_rate()

    def flag_rates(self) -> FlagRates:
        """Long-run flag-ACKs per step: sent by the detector, reaching the sensor, forged.

        Returns
        -------
        FlagRates
            ``(sent, delivered, forged)``; ``.blocked`` is ``sent - (delivered - forged)``, the
            genuine flag-ACKs that did not reach the sensor.

        Raises
        ------
        ValueError
            For a scenario built by :meth:`from_automaton`, which carries no flag-ACK
            information; for a sensor policy on per-packet ACKs, which has no flag-ACKs.
        """
        src = self._rate_source("flag_rates")
        if isinstance(src, ScenarioChain):
            rates = chain_flag_rates(src)
            if rates is None:
                raise ValueError(f"{self._policy()} gives no flag-ACKs (its sensor reads per-packet ACKs)")
            return rates
        sent, delivered, forged = src.flag_rates()
        return FlagRates(float(sent), float(delivered), float(forged))

    def holding_time_law(self, n: int) -> npt.NDArray[np.float64]:
        r"""The stationary law of the holding time: :math:`P(\tau = 0..n-1)` and :math:`P(\tau \ge n)`.

        Parameters
        ----------
        n : int
            The number of point masses, at least 1.

        Returns
        -------
        numpy.ndarray
            ``(n + 1,)``, summing to 1.
        """
        n = as_int("n", n, minimum=1)
        return np.asarray(self._engine.holding_time_law(n), dtype=np.float64)

    def cost_curve(self, horizon: int = 200) -> TraceCurve:
        r""":math:`\mathbb E\,\mathrm{Tr}\,P_k` and :math:`J_k` for k = 1..horizon, exactly.

        From the paper's initial condition (high power at k = 1, memory all ones, the attacker in
        its start state, :math:`c_1` stationary; a jamming pattern at phase 0), or from ``init``
        for :meth:`from_automaton` and from a policy's own initial law (a
        :class:`fakeack.HoldingTimePolicy` sees :math:`\tau_0 = 0` at step 1); :math:`J_k` tends
        to :meth:`cost`.

        Parameters
        ----------
        horizon : int, optional
            Number of steps (default 200).
        """
        horizon = as_int("horizon", horizon, minimum=1)
        trace, j_k = self._engine.cost_curve(self._core_system, horizon)
        return TraceCurve(np.arange(1, horizon + 1), np.asarray(trace), np.asarray(j_k))

    def automaton(self) -> EngineAutomaton:
        """The automaton E: its state labels and :math:`K_0`, :math:`K_1` as ``scipy.sparse.csr_array``.

        ``K0 + K1`` is row-stochastic; ``K0[e, f]`` is the probability of moving from e to f
        with a lost packet, ``K1[e, f]`` with an arrival.
        """
        labels, k0, k1 = self._engine.automaton()
        n = len(labels)
        return EngineAutomaton(list(labels), csr(k0, n), csr(k1, n))

    # --- display -------------------------------------------------------------------------------

    def __repr__(self) -> str:
        if self.channel is None:
            return f"Scenario.from_automaton(system={self.system!r}, n_states={self.n_states})"
        att = "" if self.attack is None else f", attack={self.attack!r}"
        return f"Scenario(system={self.system!r}, channel={self.channel!r}, schedule={self.schedule!r}{att})"

    def _repr_html_(self) -> str:
        items: list[tuple[str, Any]] = (
            [("automaton", "given as K0 and K1")]
            if self.channel is None
            else [
                ("channel", repr(self.channel)),
                ("schedule", str(self.schedule)),
                ("attack", "none" if self.attack is None else str(self.attack)),
            ]
        )
        j = self.cost()
        items += [("states of E", self.n_states), ("J", j), ("stability index", self.stability_index())]
        if self.channel is not None:
            try:
                items.append(("high-power rate", self.high_power_rate()))
            except ValueError:
                pass  # a policy of power levels, or a phase-dependent jammed protocol
        note = "" if math.isfinite(j) else "J is infinite: rho(K0) rho(A)^2 >= 1."
        return key_values("Scenario", items, note)
