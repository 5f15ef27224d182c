"""The game's payoff: the sensor's long-run cost and energy, and the attacker's, for each pair of a
sensor policy and an attack, from the exact costs and the detection probabilities per window."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from fractions import Fraction
from typing import TypeAlias, cast

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_int, as_probability, as_ratio, as_real
from ..attacks.automata import AttackerAutomaton, MimicryAttack, discard_forgeries
from ..attacks.chain import j_attack
from ..attacks.kinds import Attack, AttackLike, FlagInjection, PeriodicBlocking, as_attack
from ..attacks.rates import design_high_power_rate
from ..attacks.threshold import choose_schedule
from ..detection.belief import count_alarm_probability, count_moments
from ..detection.count import (
    alarm_bounds,
    exact_alarm_probability,
    exact_count_law,
    harmful_bound,
    uses_exact_law,
)
from ..detection.cusum import CusumTest
from ..detection.interval_power import AttackForm, interval_batch, interval_support_probability, sum_tails
from ..detection.interval_test import IntervalTest, cached_interval_test
from ..detection.likelihood import LikelihoodRatioTest
from ..detection.probability import forges
from ..detection.process import FlagProcess, flag_process
from ..detection.run_length import cusum_run_length
from ..model.channels import as_channel
from ..model.schedules import OnlineDesign, design_online, j_offline
from ..model.system import LinearSystem, compiled
from .policies import SensorPolicy

__all__ = [
    "Payoff",
    "game_payoff",
]


#: What the game's attacker may play: a built-in attack, mimicry or any attacker automaton.
GameAttack: TypeAlias = Attack | MimicryAttack | AttackerAutomaton | None


def _careful(attack: GameAttack) -> bool:
    """A forger with a minimum gap: the renewal routes take min_gap = 1, the engine the rest."""
    return isinstance(attack, FlagInjection) and attack.min_gap > 1


def _built_in(attack: GameAttack) -> Attack | None:
    assert attack is None or isinstance(attack, Attack)  # checked by the caller
    return attack


@dataclass
class _Setting:
    """The game's fixed data: system, schedules, window, the sensor's β̄."""

    system: LinearSystem
    lam: float
    ratio: Fraction
    design: OnlineDesign
    n: int
    beta_bar: float
    j_off: float
    hp_off: float
    # Keyed by what was computed and for which attack (or policy's alpha and alternative).
    _cache: dict[tuple[object, ...], object] = field(default_factory=dict)

    @classmethod
    def make(
        cls, system: LinearSystem, lam: float, ratio: RatioLike, n_steps: int, beta_bar: float | None
    ) -> _Setting:
        compiled(system)
        lam_f = as_probability("lam", lam)
        r = as_ratio("ratio", ratio)
        n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
        design = design_online(lam_f, r)
        if beta_bar is None:
            bb = choose_schedule(system, lam_f, r, 0, z0=design.z0, mu=design.mu).beta_bar
        else:
            bb = as_real("beta_bar", beta_bar)
        return cls(system, lam_f, r, design, n, bb, j_offline(system, lam_f, r), float(r))

    def attack_costs(self, attack: GameAttack) -> tuple[float, float]:
        """(J, high-power rate) online under the attack (stationary)."""
        key = ("cost", attack)
        if key not in self._cache:
            online = PeriodicBlocking(0, 1) if attack is None else attack
            j = j_attack(self.system, self.lam, self.design.z0, mu=self.design.mu, attack=online)
            if attack is None or (isinstance(attack, Attack) and not _careful(attack)):
                hp = design_high_power_rate(self.lam, self.design, attack)
            else:  # the sensor is at high power the step after each delivered flag-ACK
                hp = self._process(attack).rate
            self._cache[key] = (j, hp)
        return cast(tuple[float, float], self._cache[key])

    def harm(self, policy: SensorPolicy) -> int | None:
        """The harmful rule's count bound (None for rule "any")."""
        if policy.rule != "harmful":
            return None
        key = ("harm",)
        if key not in self._cache:
            self._cache[key] = harmful_bound(self.lam, self.design, self.n, self.beta_bar)
        return cast(int, self._cache[key])

    def detection(self, policy: SensorPolicy, attack: GameAttack) -> float:
        """d: probability that a stationary online window ends with a triggering alarm."""
        return float(self.detections(policy, [attack])[0])

    def detections(self, policy: SensorPolicy, attacks: list[GameAttack]) -> FloatArray:
        """d for each attack, as :func:`fakeack.detection_probability` gives it (with the support
        check when the policy has it; the tails of every built-in attack in one vectorised call)."""
        if policy.special:
            return np.zeros(len(attacks))
        timing = [self._as_timed(a) for a in attacks]
        if policy.test == "lr":  # its +inf increments are its support check
            lr = self._lr_test(policy)
            return np.array([lr.detection_probability(a) for a in timing])
        harm = self.harm(policy)
        d = self._test_alone(policy, timing, harm)
        if not policy.support:
            return d
        for i, a in enumerate(timing):
            if not forges(a, False):
                continue  # only forgery makes a gap shorter than the attack-free minimum
            process = self._process(a)
            if policy.test == "count":
                d[i] = process.window_alarm_probability(self.n, self.min_gap, self._bounds(policy), harm)
            else:
                test = cached_interval_test(self.lam, self.design, self.n, cast(float, policy.alpha))
                d[i] = interval_support_probability(test, process, self.min_gap, harm, float(d[i]))
        return d

    def _test_alone(self, policy: SensorPolicy, attacks: list[GameAttack], harm: int | None) -> FloatArray:
        """d of the policy's test without the support check."""
        if policy.test == "count":
            bounds = self._bounds(policy)
            return np.array([self._count_any(bounds, a, harm) for a in attacks])
        test = cached_interval_test(self.lam, self.design, self.n, cast(float, policy.alpha))
        return sum_tails([interval_batch(test, self._form(test, a), harm) for a in attacks])

    def _count_any(self, bounds: tuple[int, int], attack: GameAttack, harm: int | None) -> float:
        """The count test under any attack, from the exact count law of the engine's automaton."""
        if attack is None or (isinstance(attack, Attack) and not _careful(attack)):
            attack = _built_in(attack)
            if uses_exact_law(self.n, self.lam, self.design):
                law = exact_count_law(self.n, self.lam, self.design, attack)
                return exact_alarm_probability(bounds, law, harm)
            return count_alarm_probability(bounds, self.n, self._moments(attack), harm)
        return self._process(attack).window_alarm_probability(self.n, 1, bounds, harm)

    def _lr_test(self, policy: SensorPolicy) -> LikelihoodRatioTest:
        """The policy's likelihood-ratio test (cached by :func:`likelihood_ratio_test` itself)."""
        return policy.lr_test(self.lam, self.design, self.n)

    def _bounds(self, policy: SensorPolicy) -> tuple[int, int]:
        key = ("bounds", policy.alpha, policy.alternative)
        if key not in self._cache:
            self._cache[key] = alarm_bounds(
                self.lam, self.design, self.n, cast(float, policy.alpha), policy.alternative
            )
        return cast(tuple[int, int], self._cache[key])

    def _as_timed(self, attack: GameAttack) -> GameAttack:
        """The attack as the flag-timing tests see it: mimicry of this game's own channel and
        detector delivers the attack-free flag process, so it is tested as no attack."""
        if isinstance(attack, MimicryAttack) and attack.channel in (None, as_channel(self.lam)):
            if attack.design in (None, self.design):
                return None
        return attack

    @property
    def min_gap(self) -> int:
        """The support check's shortest attack-free gap."""
        return self._process(None).min_gap

    def _process(self, attack: GameAttack) -> FlagProcess:
        key = ("process", attack)
        if key not in self._cache:
            self._cache[key] = flag_process(self.lam, self.design, attack)
        return cast(FlagProcess, self._cache[key])

    def _moments(self, attack: Attack | None) -> tuple[float, float]:
        key = ("moments", attack)
        if key not in self._cache:
            self._cache[key] = count_moments(self.lam, self.design, self.n, attack)
        return cast(tuple[float, float], self._cache[key])

    def _form(self, test: IntervalTest, attack: GameAttack) -> AttackForm:
        key = ("form", attack)  # the bins depend on n only, not on alpha
        if key not in self._cache:
            self._cache[key] = AttackForm(test, attack)
        return cast(AttackForm, self._cache[key])


@dataclass(frozen=True)
class Payoff:
    """The payoff of one (policy, attack) pair (see :func:`game_payoff`)."""

    j: float
    """Long-run average of Tr E[P_k]: (J_att + d K J_off) / (1 + d K)."""
    high_power: float
    """Long-run fraction of steps at high power (the energy is δ + (Δ - δ) times this)."""
    detection: float
    """d, the probability that a stationary online window ends with a triggering alarm (for a
    CUSUM policy: the window length over the mean online steps between alarms)."""
    online: float
    """Long-run fraction of windows run online: 1 / (1 + d K) (for a CUSUM policy
    :math:`T_{on}/(T_{on} + K n)`, :math:`T_{on}` the mean online steps between alarms)."""
    j_attack: float
    """Stationary online cost under the attack."""
    j_offline: float


def as_game_attack(attack: object, name: str = "attack") -> GameAttack:
    """A built-in attack (any spelling :func:`fakeack.attacks.as_attack` reads), mimicry or an
    attacker automaton."""
    if isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        return attack
    return as_attack(cast(AttackLike, attack), name)


def played_attack(setting: _Setting, attack: GameAttack, authenticated: bool) -> GameAttack:
    """The attack as the sensor meets it: without its forgeries when flag-ACKs are authenticated."""
    if not isinstance(authenticated, bool):
        raise TypeError(f"authenticated must be True or False, got {authenticated!r}")
    if not authenticated:
        return attack
    return discard_forgeries(attack, channel=setting.lam, design=setting.design)


def _cusum_online_steps(setting: _Setting, policy: SensorPolicy, attack: GameAttack) -> float:
    r"""Mean online steps between two fall-backs under a CUSUM policy: the wait for the first
    flag-ACK after the return (from the stationary state, :math:`\pi (I - D_0)^{-1}\mathbf 1`)
    and the run length from the renewal start (:func:`fakeack.cusum_run_length`)."""
    key = ("cusum", policy.cusum, attack)
    if key not in setting._cache:
        test = policy.cusum
        if not isinstance(test, CusumTest):
            raise TypeError(f"policy: the payoff needs a fakeack.CusumTest, got {type(test).__name__}")
        process = setting._process(attack)
        n = process.n_states
        wait = splu(sp.csc_array(sp.identity(n, format="csc") - process.D0)).solve(np.ones(n))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # its accuracy is far below the formula's
            run = cusum_run_length(setting.lam, setting.design, test, attack)
        setting._cache[key] = float(process.stationary @ wait) + run.mean
    return cast(float, setting._cache[key])


def _payoff(setting: _Setting, policy: SensorPolicy, attack: GameAttack, d: float | None = None) -> Payoff:
    j_att, hp_att = setting.attack_costs(attack)
    if policy.test == "cusum":
        steps = _cusum_online_steps(setting, policy, attack)
        offline = cast(int, policy.fallback) * setting.n
        online = steps / (steps + offline)
        j = online * j_att + (1.0 - online) * setting.j_off
        hp = online * hp_att + (1.0 - online) * setting.hp_off
        return Payoff(j, hp, min(1.0, setting.n / steps), online, j_att, setting.j_off)
    if policy.test == "offline":
        return Payoff(setting.j_off, setting.hp_off, 0.0, 0.0, j_att, setting.j_off)
    if d is None:
        d = setting.detection(policy, attack)
    k = 0 if policy.special or policy.fallback is None else policy.fallback  # a test policy has one
    online = 1.0 / (1.0 + d * k)
    off = 1.0 - online
    j = j_att if off == 0.0 else online * j_att + off * setting.j_off
    return Payoff(j, online * hp_att + off * setting.hp_off, d, online, j_att, setting.j_off)


def game_payoff(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    policy: SensorPolicy,
    attack: AttackLike | MimicryAttack | AttackerAutomaton,
    n_steps: int,
    *,
    beta_bar: float | None = None,
    authenticated: bool = False,
) -> Payoff:
    r"""The payoff of a (policy, attack) pair: the renewal average over online and fall-back windows.

    :math:`J = (J_{att} + d K J_{off}) / (1 + d K)` with d from :func:`fakeack.detection_probability`
    (with ``beta_bar`` for the harmful rule, and with the support check when the policy has it,
    as it does by default); the module docstring derives it and states what it neglects. The
    online schedule is :func:`fakeack.design_online` ``(lam, ratio)``.

    A CUSUM policy (``SensorPolicy("cusum", fallback=K, cusum=fa.CusumTest(...))``) alarms
    after :math:`T_{on}` online steps on average: the wait for the first flag-ACK after a return
    and the run length of :func:`fakeack.cusum_run_length` from the renewal start; then
    :math:`J = (T_{on} J_{att} + K n J_{off}) / (T_{on} + K n)`, the same renewal average with
    the CUSUM's cycle in place of the windows'.

    The likelihood-ratio test's d is :meth:`fakeack.LikelihoodRatioTest.detection_probability`
    (its support check included). The count test's d is exact or normal as in
    :func:`fakeack.detection_probability`, and
    exact with the support check against a forger; the interval test's combination with the
    support check is P(short gap) plus P(no short gap) times the test's alarm probability given
    none, as there. Mimicry of the game's own channel and detector delivers the attack-free
    flag process, so every test sees it at its false-alarm rate; the interval test's law under a
    forger with ``min_gap > 1`` or any other attacker automaton comes from the flag process of
    the engine's automaton (``fakeack.detection.gap_bins``).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio p/q.
    policy : SensorPolicy
        The sensor's policy.
    attack : None, attack, MimicryAttack or AttackerAutomaton
        The attack.
    n_steps : int
        Window length in steps.
    beta_bar : float, optional
        The sensor's threshold for the harmful rule (default: the large-period β̄ of
        :func:`fakeack.choose_schedule`).
    authenticated : bool, optional
        Whether the sensor authenticates flag-ACKs, rejecting forged ones (default False): the
        attack is then scored by its blocking part (``fakeack.attacks.discard_forgeries``), so a
        forger gains nothing from forging.
    """
    if not isinstance(policy, SensorPolicy):
        raise TypeError(f"policy must be a fakeack.SensorPolicy, got {type(policy).__name__}")
    setting = _Setting.make(system, lam, ratio, n_steps, beta_bar)
    return _payoff(setting, policy, played_attack(setting, as_game_attack(attack), authenticated))
