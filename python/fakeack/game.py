r"""The repeated game between the sensor and an attacker who must not be seen.

Time is cut into windows of n steps. The sensor runs the online schedule and tests each window's
flag-ACKs (:mod:`fakeack.detectors`); after an alarm that triggers its fall-back it runs the
offline schedule for K windows, then returns online. The attacker picks one attack from a list and
keeps it. The payoff is the long-run average of Tr E[P_k] (zero-sum: the sensor minimises it,
the attacker maximises it).

**The payoff formula.** With J_att the stationary online cost under the attack, J_off the offline
cost and d the probability that a stationary online window ends with a triggering alarm, the
sequence of windows is a renewal process whose cycle is one online window followed, with
probability d, by K offline windows. By the renewal-reward theorem the long-run average cost is
the expected cost per cycle over the expected cycle length:

.. math::
   J = \frac{n J_{att} + d K n J_{off}}{n + d K n} = \frac{J_{att} + d K J_{off}}{1 + d K},

and the high-power rate (hence the energy) is the same average of the online rate under attack
and the offline one p/q. It neglects (i) transients at switches: the first online window after a
fall-back starts from the state the offline windows left (detector memory, attacker counter), not
the stationary one, so its cost and its alarm probability differ; (ii) dependence between
consecutive windows' alarms (the state at a window's end carries over, e.g. a long-period
attacker's phase); (iii) the normal approximations behind d. All three fade as windows grow;
:func:`simulate_game` measures the real protocol with the detector in the loop.

**Why two fall-back rules.** J rises with d when J_att < J_off, so an attacker too weak to make
online worse than offline (or one who only forges flags) *wants* to trip a sensor that falls back
on any alarm. A rational sensor falls back only from harmful attacks: rule ``"harmful"`` acts on
an alarm only when the budget estimated from the window's count (:func:`fakeack.estimate_beta`)
exceeds β̄, the threshold past which online is worse than offline.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _fakeack
from ._validate import as_int, as_probability, as_ratio, as_real
from .attack import j_attack
from .attacks import FlagInjection, PeriodicBlocking, as_attack, core_attack
from .detectors import (
    _count_alarm,
    _count_moments,
    _Form,
    _interval_batch,
    _interval_test,
    _sum_tails,
    check_alternative,
    count_alarm_bounds,
    harmful_count_bound,
)
from .montecarlo import _Progress
from .other_attacks import high_power_rate
from .schedules import design_online, j_offline
from .system import _core
from .threshold import choose_schedule

__all__ = [
    "GameSimulation",
    "GameSolution",
    "Payoff",
    "SensorPolicy",
    "Stackelberg",
    "game_payoff",
    "simulate_game",
    "solve_game",
]

RULES = ("any", "harmful")
_SPECIAL = {"offline": "always offline", "never": "online, never test"}


@dataclass(frozen=True)
class SensorPolicy:
    """The sensor's policy in the repeated game.

    ``SensorPolicy(test, alpha, fallback, rule)``: run online and apply ``test`` ("count" or
    "interval") at level ``alpha`` to every online window; after an alarm run the offline schedule
    for ``fallback`` windows, then return online. With ``rule="any"`` every alarm triggers the
    fall-back, with ``"harmful"`` only an alarm whose estimated budget
    (:func:`fakeack.estimate_beta` of the window's count) exceeds β̄. Two special policies:
    ``SensorPolicy("offline")`` (always offline) and ``SensorPolicy("never")`` (online, never
    test).

    Parameters
    ----------
    test : {"count", "interval", "offline", "never"}
        The test, or a special policy.
    alpha : float
        False-alarm level per window, in (0, 1) (tests only).
    fallback : int
        Offline windows after a triggering alarm, >= 0 (tests only).
    rule : {"any", "harmful"}, optional
        Which alarms trigger the fall-back (default "any").
    alternative : {"two-sided", "less", "greater"}, optional
        The count test's alternative (default two-sided; the interval test is two-sided).

    Examples
    --------
    >>> str(SensorPolicy("count", 0.01, 2, "harmful"))
    'count test at alpha=0.01, 2 windows offline after a harmful alarm'
    >>> str(SensorPolicy("offline"))
    'always offline'
    """

    test: str
    alpha: float | None = None
    fallback: int | None = None
    rule: str = "any"
    alternative: str = "two-sided"

    def __init__(self, test: Any, alpha: Any = None, fallback: Any = None, rule: Any = "any",
                 alternative: Any = "two-sided"):
        if test in _SPECIAL:
            if alpha is not None or fallback is not None:
                raise ValueError(f"test: the special policy {test!r} takes no alpha or fallback")
            object.__setattr__(self, "test", test)
            object.__setattr__(self, "alpha", None)
            object.__setattr__(self, "fallback", None)
            object.__setattr__(self, "rule", "any")
            object.__setattr__(self, "alternative", "two-sided")
            return
        if test not in ("count", "interval"):
            raise ValueError(f"test must be 'count', 'interval', 'offline' or 'never', got {test!r}")
        if alpha is None or fallback is None:
            raise TypeError(f"test {test!r} needs alpha and fallback")
        if rule not in RULES:
            raise ValueError(f"rule must be one of {RULES}, got {rule!r}")
        alternative = check_alternative(alternative)
        if test == "interval" and alternative != "two-sided":
            raise ValueError("alternative: the interval test is two-sided by construction")
        object.__setattr__(self, "test", test)
        object.__setattr__(self, "alpha", as_probability("alpha", alpha))
        object.__setattr__(self, "fallback", as_int("fallback", fallback, minimum=0))
        object.__setattr__(self, "rule", rule)
        object.__setattr__(self, "alternative", alternative)

    @property
    def special(self) -> bool:
        """True for ``"offline"`` and ``"never"``."""
        return self.test in _SPECIAL

    def __str__(self) -> str:
        if self.special:
            return _SPECIAL[self.test]
        side = "" if self.test == "interval" or self.alternative == "two-sided" else f" ({self.alternative})"
        windows = "window" if self.fallback == 1 else "windows"
        after = "any alarm" if self.rule == "any" else "a harmful alarm"
        return (f"{self.test} test{side} at alpha={self.alpha:g}, {self.fallback} {windows} offline "
                f"after {after}")


def _policies(tests: Any, alphas: Any, fallbacks: Any, rules: Any, alternative: str) -> list[SensorPolicy]:
    def listed(name: str, x: Any) -> list:
        if isinstance(x, (str, bytes)) or not hasattr(x, "__iter__"):
            x = [x]
        out = list(x)
        if not out:
            raise ValueError(f"{name} must not be empty")
        return out

    tests, alphas = listed("tests", tests), listed("alphas", alphas)
    fallbacks, rules = listed("fallbacks", fallbacks), listed("rules", rules)
    for a in alphas:
        as_probability("alphas", a)
    for k in fallbacks:
        as_int("fallbacks", k, minimum=0)
    for t in tests:
        if t not in ("count", "interval"):
            raise ValueError(f"tests: each must be 'count' or 'interval', got {t!r}")
    for r in rules:
        if r not in RULES:
            raise ValueError(f"rules: each must be one of {RULES}, got {r!r}")
    out = [SensorPolicy("offline"), SensorPolicy("never")]
    for t in tests:
        for a in alphas:
            for k in fallbacks:
                for r in rules:
                    alt = alternative if t == "count" else "two-sided"
                    p = SensorPolicy(t, a, k, r, alt)
                    if p not in out:
                        out.append(p)
    return out


@dataclass
class _Setting:
    """The game's fixed data: system, schedules, window, the sensor's β̄."""

    system: Any
    lam: float
    ratio: Any
    z0: int
    mu: float
    n: int
    beta_bar: float
    j_off: float
    hp_off: float
    _cache: dict = field(default_factory=dict)

    @classmethod
    def make(cls, system: Any, lam: Any, ratio: Any, n_steps: Any, beta_bar: Any) -> _Setting:
        _core(system)
        lam_f = as_probability("lam", lam)
        r = as_ratio("ratio", ratio)
        n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
        z0, mu = design_online(lam_f, r)
        if beta_bar is None:
            bb = choose_schedule(system, lam_f, r, 0, z0=z0, mu=mu).beta_bar
        else:
            bb = as_real("beta_bar", beta_bar)
        return cls(system, lam_f, r, z0, mu, n, bb, j_offline(system, lam_f, r), float(r))

    def attack_costs(self, attack: Any) -> tuple[float, float]:
        """(J, high-power rate) online under the attack (stationary)."""
        key = ("cost", attack)
        if key not in self._cache:
            online = PeriodicBlocking(0, 1) if attack is None else attack
            j = j_attack(self.system, self.lam, self.z0, mu=self.mu, attack=online)
            self._cache[key] = (j, high_power_rate(self.lam, self.z0, attack, self.mu))
        return self._cache[key]

    def harm(self, policy: SensorPolicy) -> int | None:
        """The harmful rule's count bound (None for rule "any")."""
        if policy.rule != "harmful":
            return None
        key = ("harm",)
        if key not in self._cache:
            self._cache[key] = harmful_count_bound(self.lam, self.z0, self.n, self.beta_bar, self.mu)
        return self._cache[key]

    def detection(self, policy: SensorPolicy, attack: Any) -> float:
        """d: probability that a stationary online window ends with a triggering alarm."""
        return float(self.detections(policy, [attack])[0])

    def detections(self, policy: SensorPolicy, attacks: list) -> np.ndarray:
        """d for each attack (tails of every attack computed in one vectorised call)."""
        if policy.special:
            return np.zeros(len(attacks))
        harm = self.harm(policy)
        if policy.test == "count":
            bkey = ("bounds", policy.alpha, policy.alternative)
            if bkey not in self._cache:
                self._cache[bkey] = count_alarm_bounds(self.lam, self.z0, self.n, policy.alpha,
                                                       policy.alternative, self.mu)
            bounds = self._cache[bkey]
            return np.array([_count_alarm(bounds, self.n, self._moments(a), harm) for a in attacks])
        test = _interval_test(self.lam, self.z0, self.mu, self.n, policy.alpha)
        return _sum_tails([_interval_batch(test, self._form(test, a), harm) for a in attacks])

    def _moments(self, attack: Any) -> tuple[float, float]:
        key = ("moments", attack)
        if key not in self._cache:
            self._cache[key] = _count_moments(self.lam, self.z0, self.mu, self.n, attack)
        return self._cache[key]

    def _form(self, test: Any, attack: Any) -> _Form:
        key = ("form", attack)  # the bins depend on n only, not on alpha
        if key not in self._cache:
            self._cache[key] = _Form(test, attack)
        return self._cache[key]


@dataclass(frozen=True)
class Payoff:
    """The payoff of one (policy, attack) pair (see :func:`game_payoff`)."""

    j: float
    """Long-run average of Tr E[P_k]: (J_att + d K J_off) / (1 + d K)."""
    high_power: float
    """Long-run fraction of steps at high power (the energy is δ + (Δ - δ) times this)."""
    detection: float
    """d, the probability that a stationary online window ends with a triggering alarm."""
    online: float
    """Long-run fraction of windows run online: 1 / (1 + d K)."""
    j_attack: float
    """Stationary online cost under the attack."""
    j_offline: float


def _payoff(setting: _Setting, policy: SensorPolicy, attack: Any, d: float | None = None) -> Payoff:
    j_att, hp_att = setting.attack_costs(attack)
    if policy.test == "offline":
        return Payoff(setting.j_off, setting.hp_off, 0.0, 0.0, j_att, setting.j_off)
    if d is None:
        d = setting.detection(policy, attack)
    k = 0 if policy.special else policy.fallback
    online = 1.0 / (1.0 + d * k)
    off = 1.0 - online
    j = j_att if off == 0.0 else online * j_att + off * setting.j_off
    return Payoff(j, online * hp_att + off * setting.hp_off, d, online, j_att, setting.j_off)


def game_payoff(
    system: Any, lam: Any, ratio: Any, policy: Any, attack: Any, n_steps: Any, *, beta_bar: Any = None
) -> Payoff:
    r"""The payoff of a (policy, attack) pair: the renewal average over online and fall-back windows.

    :math:`J = (J_{att} + d K J_{off}) / (1 + d K)` with d from :func:`fakeack.detection_probability`
    (with ``beta_bar`` for the harmful rule); the module docstring derives it and states what it
    neglects. The online schedule is :func:`fakeack.design_online` ``(lam, ratio)``.

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
    attack : None or attack
        The attack.
    n_steps : int
        Window length in steps.
    beta_bar : float, optional
        The sensor's threshold for the harmful rule (default: the large-period β̄ of
        :func:`fakeack.choose_schedule`).
    """
    if not isinstance(policy, SensorPolicy):
        raise TypeError(f"policy must be a fakeack.SensorPolicy, got {type(policy).__name__}")
    setting = _Setting.make(system, lam, ratio, n_steps, beta_bar)
    return _payoff(setting, policy, as_attack(attack))


@dataclass(frozen=True)
class Stackelberg:
    """The sensor commits to a pure policy first; the attacker best-responds."""

    policy: SensorPolicy
    attack: Any
    """The attacker's best response."""
    payoff: float
    """The committed policy's worst-case payoff."""


@dataclass(frozen=True)
class GameSolution:
    """The solved game (see :func:`solve_game`)."""

    payoff: np.ndarray
    """J for each (policy, attack): rows are ``policies``, columns ``attacks``."""
    high_power: np.ndarray
    """Fraction of steps at high power for each pair (energy = δ + (Δ - δ) times this)."""
    detection: np.ndarray
    """d for each pair."""
    policies: list
    attacks: list
    value: float
    """The value of the zero-sum game (mixed strategies)."""
    sensor_strategy: np.ndarray
    """The sensor's optimal mixed strategy over ``policies``."""
    attacker_strategy: np.ndarray
    """The attacker's optimal mixed strategy over ``attacks``."""
    best_attack: np.ndarray
    """For each policy, the index of the attacker's best response."""
    best_policy: np.ndarray
    """For each attack, the index of the sensor's best response."""
    stackelberg: Stackelberg
    j_offline: float
    j_online: float
    n_steps: int
    beta_bar: float

    def summary(self, top: int = 5) -> str:
        """A few lines: the value, the support of both strategies, the Stackelberg outcome."""
        lines = [f"value of the game: J = {self.value:.6f} (J_on = {self.j_online:.6f}, "
                 f"J_off = {self.j_offline:.6f}; windows of {self.n_steps} steps)"]
        for who, strat, items in (("sensor", self.sensor_strategy, self.policies),
                                  ("attacker", self.attacker_strategy, self.attacks)):
            order = np.argsort(-strat)
            lines.append(f"{who}'s optimal strategy:")
            for i in order[:top]:
                if strat[i] > 1e-9:
                    lines.append(f"  {strat[i]:.4f}  {_name(items[i])}")
        st = self.stackelberg
        row = self.payoff[self.policies.index(st.policy)]
        answer = "any attack (all cost the same)" if np.ptp(row) == 0 else _name(st.attack)
        lines.append(f"Stackelberg (sensor commits to a pure policy): {st.policy}; the attacker "
                     f"answers {answer}; J = {st.payoff:.6f}")
        return "\n".join(lines)


def _name(attack: Any) -> str:
    return "no attack" if attack is None else str(attack)


def _attack_list(attacks: Any) -> list:
    if isinstance(attacks, (str, bytes)) or not hasattr(attacks, "__iter__"):
        raise TypeError("attacks must be a list of attacks (None for no attack)")
    out = [as_attack(a, "attacks") for a in attacks]
    if not out:
        raise ValueError("attacks must not be empty")
    return out


def solve_game(
    system: Any,
    lam: Any,
    ratio: Any,
    n_steps: Any,
    alphas: Any,
    fallbacks: Any,
    attacks: Any,
    tests: Any = ("count", "interval"),
    rules: Any = ("any", "harmful"),
    *,
    alternative: str = "two-sided",
    beta_bar: Any = None,
) -> GameSolution:
    r"""Solve the zero-sum game between the sensor's policies and a list of attacks.

    The rows are the two special policies (always offline; online, never test) and one
    :class:`SensorPolicy` per (test, alpha, fallback, rule); the columns are ``attacks``. Each
    entry is :func:`game_payoff`. The value and both optimal mixed strategies come from the two
    linear programs of the matrix game (``scipy.optimize.linprog``, HiGHS): the sensor minimises
    v subject to :math:`A^\top x \le v\mathbf 1`, the attacker maximises u subject to
    :math:`A y \ge u\mathbf 1`, over probability vectors x, y. Also reported: each pure strategy's
    best response and the Stackelberg outcome when the sensor commits to a pure policy first
    (the row with the smallest worst case; the attacker then plays its best response).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio p/q; the online schedule is :func:`fakeack.design_online` ``(lam, ratio)``.
    n_steps : int
        Window length in steps.
    alphas : sequence of float
        False-alarm levels, each in (0, 1).
    fallbacks : sequence of int
        Offline windows after a triggering alarm, each >= 0.
    attacks : sequence
        The attacker's choices: ``None`` (no attack) or any attack object.
    tests : sequence of {"count", "interval"}, optional
        The tests (default both).
    rules : sequence of {"any", "harmful"}, optional
        The fall-back rules (default both).
    alternative : str, optional
        The count test's alternative (default two-sided).
    beta_bar : float, optional
        The harmful rule's threshold (default: the large-period β̄ of :func:`fakeack.choose_schedule`).

    Returns
    -------
    GameSolution
    """
    from scipy.optimize import linprog

    alternative = check_alternative(alternative)
    policies = _policies(tests, alphas, fallbacks, rules, alternative)
    attack_list = _attack_list(attacks)
    setting = _Setting.make(system, lam, ratio, n_steps, beta_bar)
    payoffs = []
    for p in policies:
        d = setting.detections(p, attack_list)
        payoffs.append([_payoff(setting, p, a, float(x)) for a, x in zip(attack_list, d, strict=True)])
    A = np.array([[x.j for x in row] for row in payoffs])
    H = np.array([[x.high_power for x in row] for row in payoffs])
    D = np.array([[x.detection for x in row] for row in payoffs])
    if not np.all(np.isfinite(A)):
        j, a = np.argwhere(~np.isfinite(A))[0]
        raise ValueError(f"attacks: {_name(attack_list[a])} makes J infinite under {policies[j]}")
    m, k = A.shape
    # Sensor: min v  s.t.  A' x - v <= 0, sum x = 1, x >= 0.
    sen = linprog(np.r_[np.zeros(m), 1.0], A_ub=np.c_[A.T, -np.ones(k)], b_ub=np.zeros(k),
                  A_eq=np.r_[np.ones(m), 0.0][None], b_eq=[1.0],
                  bounds=[(0, None)] * m + [(None, None)], method="highs")
    # Attacker: max u  s.t.  -A y + u <= 0, sum y = 1, y >= 0.
    att = linprog(np.r_[np.zeros(k), -1.0], A_ub=np.c_[-A, np.ones(m)], b_ub=np.zeros(m),
                  A_eq=np.r_[np.ones(k), 0.0][None], b_eq=[1.0],
                  bounds=[(0, None)] * k + [(None, None)], method="highs")
    if not (sen.success and att.success):
        raise RuntimeError(f"linprog failed: {sen.message} / {att.message}")
    x = np.clip(sen.x[:m], 0.0, None)
    y = np.clip(att.x[:k], 0.0, None)
    worst = A.max(axis=1)
    i = int(np.argmin(worst))
    jbest = int(np.argmax(A[i]))
    return GameSolution(
        payoff=A, high_power=H, detection=D, policies=policies, attacks=attack_list,
        value=float(sen.x[m]), sensor_strategy=x / x.sum(), attacker_strategy=y / y.sum(),
        best_attack=A.argmax(axis=1), best_policy=A.argmin(axis=0),
        stackelberg=Stackelberg(policies[i], attack_list[jbest], float(worst[i])),
        j_offline=setting.j_off, j_online=setting.attack_costs(None)[0], n_steps=setting.n,
        beta_bar=setting.beta_bar,
    )


# ---------------------------------------------------------------------------------------------
# The closed loop.


@dataclass(frozen=True)
class GameSimulation:
    """Closed-loop Monte Carlo of one (policy, attack) pair (see :func:`simulate_game`)."""

    j: float
    """Mean over runs of each run's average Tr P_k."""
    stderr: float
    high_power: float
    """Fraction of steps at high power."""
    high_power_stderr: float
    online: float
    """Fraction of steps run online."""
    alarm_rate: float
    """Alarms per tested window."""
    alarm_stderr: float
    fallback_rate: float
    """Triggering alarms per tested window: the simulated d."""
    fallback_stderr: float
    runs: int
    horizon: int
    n_steps: int
    seed: int
    delivered_per_run: np.ndarray = field(repr=False)
    """Flag-ACKs that reached the sensor in each run's measured horizon."""


def _ratio_se(num: np.ndarray, den: np.ndarray) -> tuple[float, float]:
    """Ratio estimator Σnum/Σden over runs and its standard error (delta method)."""
    total = den.sum()
    if total == 0:
        return math.nan, math.nan
    r = num.sum() / total
    if len(num) < 2:
        return float(r), math.inf
    resid = num - r * den
    se = math.sqrt(resid.var(ddof=1) * len(num)) / total
    return float(r), float(se)


def simulate_game(
    system: Any,
    lam: Any,
    ratio: Any,
    policy: Any,
    attack: Any,
    horizon: Any,
    runs: Any,
    seed: Any,
    *,
    n_steps: Any = 1000,
    burn_in: Any = 0,
    beta_bar: Any = None,
    progress: bool | None = None,
) -> GameSimulation:
    r"""Closed-loop Monte Carlo of the game: the real protocol with the sensor's test and fall-back.

    Each run plays ``burn_in + horizon`` steps of the protocol (sensor, lossy channel, remote
    estimator, event detector, attacker) from the paper's initial condition, cut into windows of
    ``n_steps`` from the first step; the sensor tests every online window with its policy's test
    (the same statistic and critical value as :func:`fakeack.detect_attack` /
    :func:`fakeack.detect_intervals`), and a triggering alarm sends it offline for ``fallback``
    windows. Costs, rates and alarms are measured after the burn-in. Nothing here uses the payoff
    formula, so it checks :func:`game_payoff` including what the formula neglects (transients at
    switches, dependence between windows).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    ratio : Fraction
        Energy ratio p/q (the offline schedule, and the online one via :func:`fakeack.design_online`).
    policy : SensorPolicy
        The sensor's policy.
    attack : None or attack
        The attack, kept throughout.
    horizon : int
        Measured steps per run.
    runs : int
        Independent runs.
    seed : int
        The results depend on the seed only (not on threads).
    n_steps : int, optional
        Window length (default 1000).
    burn_in : int, optional
        Steps played (with the policy in the loop) before the measurement starts (default 0); a few
        fall-back cycles put the measured horizon in the game's stationary regime, which the
        payoff formula describes.
    beta_bar : float, optional
        The harmful rule's threshold (default as :func:`solve_game`).
    progress : bool or None
        Show a progress bar for runs over a second (default: only on a terminal).

    Returns
    -------
    GameSimulation

    Notes
    -----
    Runs in parallel with the GIL released; Ctrl-C raises ``KeyboardInterrupt`` promptly.
    """
    if not isinstance(policy, SensorPolicy):
        raise TypeError(f"policy must be a fakeack.SensorPolicy, got {type(policy).__name__}")
    setting = _Setting.make(system, lam, ratio, n_steps, beta_bar)
    att = as_attack(attack)
    horizon = as_int("horizon", horizon, minimum=1)
    runs = as_int("runs", runs, minimum=1)
    seed = as_int("seed", seed, minimum=0)
    if seed >= 2**64:
        raise ValueError(f"seed must be below 2**64, got {seed}")
    burn_in = as_int("burn_in", burn_in, minimum=0)
    args = _kernel_policy(setting, policy)
    bar = _Progress(runs, progress)
    r = setting.ratio
    try:
        out = _fakeack.simulate_game(
            _core(system), setting.lam, r.numerator, r.denominator, setting.z0, setting.mu,
            core_attack(att), *args, setting.n, horizon, burn_in, runs, seed, bar,
        )
    finally:
        bar.close()
    cost, hp = out["cost"], out["high_power"]
    tested = out["tested"].astype(float)
    alarm, alarm_se = _ratio_se(out["alarms"].astype(float), tested)
    fb, fb_se = _ratio_se(out["fallbacks"].astype(float), tested)

    def sd(x: np.ndarray) -> float:
        return float(x.std(ddof=1) / math.sqrt(len(x))) if len(x) > 1 else math.inf

    return GameSimulation(
        float(cost.mean()), sd(cost), float(hp.mean()), sd(hp), float(out["online"].mean()),
        alarm, alarm_se, fb, fb_se, runs, horizon, setting.n, seed, out["delivered"],
    )


def _kernel_policy(setting: _Setting, policy: SensorPolicy) -> tuple:
    """The compiled kernel's arguments for a policy."""
    none = (-1, 0, [], [], 0.0, None, 0)
    if policy.test == "offline":
        return ("offline", *none)
    if policy.test == "never":
        return ("online", *none)
    harm = harmful_count_bound(setting.lam, setting.z0, setting.n, setting.beta_bar, setting.mu) \
        if policy.rule == "harmful" else None
    if policy.test == "count":
        lo, hi = count_alarm_bounds(setting.lam, setting.z0, setting.n, policy.alpha, policy.alternative,
                                    setting.mu)
        return ("count", lo, hi, [], [], 0.0, harm, policy.fallback)
    t = _interval_test(setting.lam, setting.z0, setting.mu, setting.n, policy.alpha)
    return ("interval", -1, 0, [int(e) for e in t.edges], [float(e) for e in t.expected], float(t.critical),
            harm, policy.fallback)


def plot_game(solution: GameSolution, ax: Any = None, max_rows: int = 40, max_cols: int = 40) -> Any:
    """The payoff matrix as a heat map, with the equilibrium's supports and the Stackelberg cell marked.

    Rows (policies) and columns (attacks) are shown in the order of ``solution`` when they fit;
    larger games keep the rows and columns in either optimal strategy's support, the Stackelberg
    pair and the best responses to them, up to ``max_rows`` x ``max_cols``.

    Parameters
    ----------
    solution : GameSolution
        From :func:`solve_game`.
    ax : matplotlib Axes, optional
        Where to draw; a new figure by default.
    max_rows, max_cols : int, optional
        Largest matrix drawn.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    A = solution.payoff
    rows = list(range(A.shape[0]))
    cols = list(range(A.shape[1]))
    st_row = solution.policies.index(solution.stackelberg.policy)
    st_col = next(j for j, a in enumerate(solution.attacks) if a == solution.stackelberg.attack)
    if len(rows) > max_rows:
        keep = set(np.flatnonzero(solution.sensor_strategy > 1e-9)) | {0, 1, st_row}
        keep |= set(solution.best_policy[np.flatnonzero(solution.attacker_strategy > 1e-9)])
        rest = [i for i in rows if i not in keep]
        rows = sorted(keep | set(rest[: max(0, max_rows - len(keep))]))
    if len(cols) > max_cols:
        keep = set(np.flatnonzero(solution.attacker_strategy > 1e-9)) | {st_col}
        keep |= set(solution.best_attack[rows])
        rest = [j for j in cols if j not in keep]
        cols = sorted(keep | set(rest[: max(0, max_cols - len(keep))]))
    sub = A[np.ix_(rows, cols)]
    if ax is None:
        fig, ax = plt.subplots(figsize=(min(7 + 0.35 * len(cols), 20), min(3 + 0.3 * len(rows), 14)),
                               layout="constrained")
    else:
        fig = ax.figure
    im = ax.imshow(sub, aspect="auto", cmap="viridis")
    fig.colorbar(im, ax=ax, label="J (long-run mean Tr P)")

    def row_label(i: int) -> str:
        p = solution.sensor_strategy[i]
        return (f"[{p:.2f}] " if p > 1e-9 else "") + str(solution.policies[i])

    def col_label(j: int) -> str:
        p = solution.attacker_strategy[j]
        return _short(solution.attacks[j]) + (f" [{p:.2f}]" if p > 1e-9 else "")

    ax.set_yticks(range(len(rows)), [row_label(i) for i in rows], fontsize=6)
    ax.set_xticks(range(len(cols)), [col_label(j) for j in cols], fontsize=6, rotation=90)
    for c, j in enumerate(cols):
        if solution.attacker_strategy[j] > 1e-9:
            ax.add_patch(plt.Rectangle((c - 0.5, -0.5), 1, len(rows), fill=False, ec="C3", lw=1.2))
    for r, i in enumerate(rows):
        if solution.sensor_strategy[i] > 1e-9:
            ax.add_patch(plt.Rectangle((-0.5, r - 0.5), len(cols), 1, fill=False, ec="C3", lw=1.2))
        best = solution.best_attack[i]
        if best in cols and np.ptp(A[i]) > 0:
            ax.plot([cols.index(best)], [r], "o", ms=3, color="white", mec="k", mew=0.5)
    if st_row in rows and st_col in cols:
        ax.plot([cols.index(st_col)], [rows.index(st_row)], marker="*", ms=14, color="white", mec="k")
    ax.set_title(f"Payoff J per (sensor policy, attack); value {solution.value:.4f}. Red frames and [p]: "
                 "the optimal mixed strategies; dots: the attacker's best response to each policy; "
                 "star: Stackelberg", fontsize=8)
    return fig


def _short(attack: Any) -> str:
    if attack is None:
        return "none"
    if isinstance(attack, FlagInjection) and attack.block is not None:
        return f"inject:{attack.gamma:.3g}+{attack.block.label}"
    return getattr(attack, "label", str(attack))
