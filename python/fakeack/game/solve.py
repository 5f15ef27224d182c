"""Solving the game: the sensor's best policy against an attacker who best-responds (the Stackelberg
solution), and the mixed equilibrium of the payoff matrix."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_probability
from ..attacks.automata import AttackerAutomaton, MimicryAttack
from ..attacks.kinds import AttackLike
from ..detection.count import check_alternative
from ..model.system import LinearSystem
from .payoff import GameAttack, _payoff, _Setting, as_game_attack, played_attack
from .policies import SensorPolicy, _policies

__all__ = [
    "Stackelberg",
    "GameSolution",
    "solve_game",
]


@dataclass(frozen=True)
class Stackelberg:
    """The sensor commits to a pure policy first; the attacker best-responds."""

    policy: SensorPolicy
    attack: GameAttack
    """The attacker's best response."""
    payoff: float
    """The committed policy's worst-case payoff."""


@dataclass(frozen=True)
class GameSolution:
    """The solved game (see :func:`solve_game`)."""

    payoff: FloatArray
    """J for each (policy, attack): rows are ``policies``, columns ``attacks``."""
    high_power: FloatArray
    """Fraction of steps at high power for each pair (energy = δ + (Δ - δ) times this)."""
    detection: FloatArray
    """d for each pair."""
    policies: list[SensorPolicy]
    attacks: list[GameAttack]
    value: float
    """The value of the zero-sum game (mixed strategies)."""
    sensor_strategy: FloatArray
    """The sensor's optimal mixed strategy over ``policies``."""
    attacker_strategy: FloatArray
    """The attacker's optimal mixed strategy over ``attacks``."""
    best_attack: npt.NDArray[np.intp]
    """For each policy, the index of the attacker's best response."""
    best_policy: npt.NDArray[np.intp]
    """For each attack, the index of the sensor's best response."""
    stackelberg: Stackelberg
    j_offline: float
    j_online: float
    n_steps: int
    beta_bar: float
    attack_prior: float = 1.0
    """The probability that the attacker is present at all (see :func:`solve_game`)."""

    def summary(self, top: int = 5) -> str:
        """A few lines: the value, the support of both strategies, the Stackelberg outcome."""
        lines = [
            f"value of the game: J = {self.value:.6f} (J_on = {self.j_online:.6f}, "
            f"J_off = {self.j_offline:.6f}; windows of {self.n_steps} steps)"
        ]
        for who, strat, items in (
            ("sensor", self.sensor_strategy, self.policies),
            ("attacker", self.attacker_strategy, self.attacks),
        ):
            order = np.argsort(-strat)
            lines.append(f"{who}'s optimal strategy:")
            for i in order[:top]:
                if strat[i] > 1e-9:
                    lines.append(f"  {strat[i]:.4f}  {_name(items[i])}")
        st = self.stackelberg
        row = self.payoff[self.policies.index(st.policy)]
        answer = "any attack (all cost the same)" if np.ptp(row) == 0 else _name(st.attack)
        lines.append(
            f"Stackelberg (sensor commits to a pure policy): {st.policy}; the attacker "
            f"answers {answer}; J = {st.payoff:.6f}"
        )
        return "\n".join(lines)


def _mix(prior: float, attacked: FloatArray, clean: FloatArray) -> FloatArray:
    """prior * attacked + (1 - prior) * clean (one value per row), exact at prior 0 and 1."""
    if prior == 1.0:
        return attacked
    if prior == 0.0:
        return np.repeat(clean[:, None], attacked.shape[1], axis=1)
    return prior * attacked + (1.0 - prior) * clean[:, None]


def _name(attack: GameAttack) -> str:
    return "no attack" if attack is None else str(attack)


def _attack_list(attacks: Iterable[AttackLike | MimicryAttack | AttackerAutomaton]) -> list[GameAttack]:
    if isinstance(attacks, (str, bytes)) or not hasattr(attacks, "__iter__"):
        raise TypeError("attacks must be a list of attacks (None for no attack)")
    out = [as_game_attack(a, "attacks") for a in attacks]
    if not out:
        raise ValueError("attacks must not be empty")
    return out


def solve_game(
    system: LinearSystem,
    lam: float,
    ratio: RatioLike,
    n_steps: int,
    alphas: float | Iterable[float],
    fallbacks: int | Iterable[int],
    attacks: Iterable[AttackLike | MimicryAttack | AttackerAutomaton],
    tests: str | Iterable[str] = ("count", "interval"),
    rules: str | Iterable[str] = ("any", "harmful"),
    *,
    alternative: str = "two-sided",
    beta_bar: float | None = None,
    authenticated: bool = False,
    support: bool = True,
    attack_prior: float = 1.0,
    lr_alternative: object = None,
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
        The attacker's choices: ``None`` (no attack), any attack object,
        :class:`fakeack.MimicryAttack` or :class:`fakeack.AttackerAutomaton` (see
        :func:`game_payoff`).
    tests : sequence of {"count", "interval", "lr"}, optional
        The window tests (default the count and interval tests); ``"lr"`` is the
        likelihood-ratio test against ``lr_alternative`` (:class:`SensorPolicy`).
    rules : sequence of {"any", "harmful"}, optional
        The fall-back rules (default both; the likelihood-ratio test takes only "any").
    alternative : str, optional
        The count test's alternative (default two-sided).
    beta_bar : float, optional
        The harmful rule's threshold (default: the large-period β̄ of :func:`fakeack.choose_schedule`).
    authenticated : bool, optional
        Whether the sensor authenticates flag-ACKs, rejecting forged ones (default False): each
        attack is then scored by its blocking part (``fakeack.attacks.discard_forgeries``), so a
        forger gains nothing from forging.
    support : bool, optional
        Whether every test policy also runs the support check (default True; see
        :class:`SensorPolicy`). Against it a forger that ignores the attack-free gaps is seen in
        almost every window; the careful forger (``FlagInjection(..., min_gap=z0 + 1)``) and
        mimicry are not.
    attack_prior : float, optional
        The probability π in [0, 1] that the attacker is present at all (default 1): each entry
        is then :math:`\pi J(\text{policy}, \text{attack}) + (1 - \pi) J(\text{policy},
        \text{no attack})`, and likewise the energy and d, so that the sensor pays for its false
        alarms on the clean channel. With π = 0 the value is J_on (never test).
    lr_alternative : RandomBlocking, FlagInjection or array_like, optional
        The attack the likelihood-ratio test is tuned to (with ``"lr"`` among ``tests``;
        default ``RandomBlocking(0.2)``).

    Returns
    -------
    GameSolution
    """
    from scipy.optimize import linprog

    alternative = check_alternative(alternative)
    if not isinstance(support, bool):
        raise TypeError(f"support must be True or False, got {support!r}")
    policies = _policies(tests, alphas, fallbacks, rules, alternative, support, lr_alternative)
    attack_list = _attack_list(attacks)
    setting = _Setting.make(system, lam, ratio, n_steps, beta_bar)
    prior = as_probability("attack_prior", attack_prior, closed=True)
    played = [played_attack(setting, a, authenticated) for a in attack_list]
    rows, clean = [], []
    for p in policies:
        d = setting.detections(p, [*played, None])
        cells = [_payoff(setting, p, a, float(x)) for a, x in zip([*played, None], d, strict=True)]
        rows.append(cells[:-1])
        clean.append(cells[-1])
    # The attacker is present with probability prior; absent, every column is the clean one (an
    # infinite J of an attack that is never played does not count).
    A, H, D = (
        _mix(
            prior,
            np.array([[getattr(x, f) for x in row] for row in rows]),
            np.array([getattr(c, f) for c in clean]),
        )
        for f in ("j", "high_power", "detection")
    )
    if not np.all(np.isfinite(A)):
        j, a = np.argwhere(~np.isfinite(A))[0]
        raise ValueError(f"attacks: {_name(attack_list[a])} makes J infinite under {policies[j]}")
    m, k = A.shape
    # Sensor: min v  s.t.  A' x - v <= 0, sum x = 1, x >= 0.
    sen = linprog(
        np.r_[np.zeros(m), 1.0],
        A_ub=np.c_[A.T, -np.ones(k)],
        b_ub=np.zeros(k),
        A_eq=np.r_[np.ones(m), 0.0][None],
        b_eq=[1.0],
        bounds=[(0, None)] * m + [(None, None)],
        method="highs",
    )
    # Attacker: max u  s.t.  -A y + u <= 0, sum y = 1, y >= 0.
    att = linprog(
        np.r_[np.zeros(k), -1.0],
        A_ub=np.c_[-A, np.ones(m)],
        b_ub=np.zeros(m),
        A_eq=np.r_[np.ones(k), 0.0][None],
        b_eq=[1.0],
        bounds=[(0, None)] * k + [(None, None)],
        method="highs",
    )
    if not (sen.success and att.success) or sen.x is None or att.x is None:
        raise RuntimeError(f"linprog failed: {sen.message} / {att.message}")
    x = np.clip(sen.x[:m], 0.0, None)
    y = np.clip(att.x[:k], 0.0, None)
    worst = A.max(axis=1)
    i = int(np.argmin(worst))
    jbest = int(np.argmax(A[i]))
    return GameSolution(
        payoff=A,
        high_power=H,
        detection=D,
        policies=policies,
        attacks=attack_list,
        value=float(sen.x[m]),
        sensor_strategy=x / x.sum(),
        attacker_strategy=y / y.sum(),
        best_attack=A.argmax(axis=1),
        best_policy=A.argmin(axis=0),
        stackelberg=Stackelberg(policies[i], attack_list[jbest], float(worst[i])),
        j_offline=setting.j_off,
        j_online=setting.attack_costs(None)[0],
        n_steps=setting.n,
        beta_bar=setting.beta_bar,
        attack_prior=prior,
    )
