"""The ``[game]`` section of a config: the sensor-attacker game of ``fakeack game``.

Every key is optional; the defaults are the paper example's game of the README::

    [game]
    n_steps = 1000                       # window length (steps)
    alphas = [0.01, 0.05]                # false-alarm levels
    fallbacks = [1, 2, 4]                # offline windows after a triggering alarm
    tests = ["count", "interval"]       # also "lr": the likelihood-ratio test against random:0.2
    rules = ["any", "harmful"]
    attacks = ["none", "1/5", "1/3", "random:0.2", "inject:0.05", "match:0.2"]
    max_detection = 0.02                 # the stealthy frontiers' detection bound
    t_max = 30                           # longest period of the periodic family in the frontiers
    runs = 64                            # closed-loop check of the equilibrium's pairs (0: none)
    horizon = 200000
    seed = 1
    grid = 41                            # budgets in the frontiers' random families
    support = true                       # the sensor runs the support check beside its test
    attack_prior = 1.0                   # the probability that the attacker is there at all

Attacks are written as everywhere else (``"r/t"``, ``"random:beta"``, ``"inject:gamma"``,
``"inject:gamma+random:beta"``), plus ``"none"``, ``"match:beta"`` (the rate-matching attack of
:func:`fakeack.rate_matching_attack` hiding independent blocking of budget beta), ``"careful:beta"``
(the same, forging no flag-ACK sooner than z0 + 1 steps after the last one, so that the support
check never sees it) and ``"mimicry"`` (:class:`fakeack.MimicryAttack`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..attacks.automata import MimicryAttack
from ..attacks.kinds import as_attack
from ..attacks.random import rate_matching_attack
from .values import ConfigError, Section, check_keys, config_error, read_int, read_real, toml_kind

__all__ = [
    "GAME_SECTION",
    "DEFAULT_ATTACKS",
    "GameConfig",
    "parse_game",
]


GAME_SECTION = Section(
    (
        "n_steps",
        "alphas",
        "fallbacks",
        "tests",
        "rules",
        "attacks",
        "max_detection",
        "t_max",
        "runs",
        "horizon",
        "seed",
        "grid",
        "support",
        "attack_prior",
    )
)

#: The attacker's choices of the default game: none, the paper's attack, a memoryless jammer, a
#: forger, rate matching (up to a budget of 0.8, where it costs more than the offline schedule),
#: its careful version that the support check never sees, and mimicry.
DEFAULT_ATTACKS = (
    "none",
    "1/10",
    "1/5",
    "1/4",
    "1/3",
    "2/5",
    "2/3",
    "random:0.1",
    "random:0.2",
    "random:0.3",
    "random:0.5",
    "inject:0.02",
    "inject:0.05",
    "match:0.1",
    "match:0.2",
    "match:0.3",
    "match:0.4",
    "match:0.5",
    "match:0.8",
    "careful:0.2",
    "careful:0.5",
    "careful:0.8",
    "mimicry",
)


@dataclass(frozen=True)
class GameConfig:
    """The parsed ``[game]`` section (see the module docstring)."""

    n_steps: int = 1000
    alphas: tuple[float, ...] = (0.01, 0.05)
    fallbacks: tuple[int, ...] = (1, 2, 4)
    tests: tuple[str, ...] = ("count", "interval")
    rules: tuple[str, ...] = ("any", "harmful")
    attacks: tuple[str, ...] = DEFAULT_ATTACKS
    max_detection: float = 0.02
    t_max: int = 30
    runs: int = 64
    horizon: int = 200_000
    seed: int = 1
    grid: int = 41
    support: bool = True
    attack_prior: float = 1.0

    def attack_objects(self, lam: float, z0: int, mu: float) -> list:
        """The attacks as objects (``None`` for no attack)."""
        return [_attack(text, lam, z0, mu, i) for i, text in enumerate(self.attacks)]


def _attack(text: str, lam: float, z0: int, mu: float, i: int) -> Any:
    where = f"attacks[{i}]"
    if text.strip() == "none":
        return None
    if text.strip() == "mimicry":
        return MimicryAttack()
    for prefix, gap in (("match:", 1), ("careful:", z0 + 1)):
        if text.strip().startswith(prefix):
            try:
                beta = float(text.strip()[len(prefix) :])
                return rate_matching_attack(lam, z0, beta, mu, min_gap=gap)
            except ValueError as exc:
                raise config_error("game", where, f"cannot read {text!r}: {exc}") from None
    try:
        return as_attack(text, "attack")
    except (TypeError, ValueError) as exc:
        raise config_error("game", where, str(exc)) from None


def _list(table: dict[str, Any], key: str, read: Any) -> tuple | None:
    if key not in table:
        return None
    values = table[key]
    if not isinstance(values, list) or not values:
        raise config_error("game", key, f"must be a non-empty array, got {toml_kind(values)}")
    return tuple(read(f"{key}[{i}]", v) for i, v in enumerate(values))


def _alpha(key: str, v: Any) -> float:
    a = read_real("game", key, v)
    if not 0 < a < 1:
        raise config_error("game", key, f"must lie in (0, 1), got {a}")
    return a


def _choice(allowed: tuple[str, ...]) -> Any:
    def read(key: str, v: Any) -> str:
        if v not in allowed:
            raise config_error("game", key, f"must be one of {allowed}, got {v!r}")
        return v

    return read


def _text(key: str, v: Any) -> str:
    if not isinstance(v, str):
        raise config_error("game", key, f'must be a string such as "1/5" or "match:0.2", got {toml_kind(v)}')
    return v


def parse_game(data: dict[str, Any]) -> GameConfig:
    """The ``[game]`` section of a parsed config (defaults when absent)."""
    if "game" not in data:
        return GameConfig()
    table = check_keys("game", data["game"], GAME_SECTION)
    given: dict[str, Any] = {}
    readers = {
        "alphas": _alpha,
        "fallbacks": lambda k, v: read_int("game", k, v, 0),
        "tests": _choice(("count", "interval", "lr")),
        "rules": _choice(("any", "harmful")),
        "attacks": _text,
    }
    for key, read in readers.items():
        got = _list(table, key, read)
        if got is not None:
            given[key] = got
    for key, minimum in (("n_steps", 1), ("t_max", 1), ("runs", 0), ("horizon", 1), ("seed", 0), ("grid", 2)):
        if key in table:
            given[key] = read_int("game", key, table[key], minimum)
    if given.get("runs") == 1:
        raise ConfigError("config: [game] runs: must be 0 (no closed-loop check) or at least 2, got 1")
    if "max_detection" in table:
        m = read_real("game", "max_detection", table["max_detection"])
        if not 0 <= m <= 1:
            raise config_error("game", "max_detection", f"must lie in [0, 1], got {m}")
        given["max_detection"] = m
    if "attack_prior" in table:
        prior = read_real("game", "attack_prior", table["attack_prior"])
        if not 0 <= prior <= 1:
            raise config_error("game", "attack_prior", f"must lie in [0, 1], got {prior}")
        given["attack_prior"] = prior
    if "support" in table:
        if not isinstance(table["support"], bool):
            raise config_error("game", "support", f"must be true or false, got {toml_kind(table['support'])}")
        given["support"] = table["support"]
    return GameConfig(**given)
