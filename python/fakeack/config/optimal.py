"""The ``[optimal]`` section of a config: the optimal policies of ``fakeack optimal``.

Every key is optional; the defaults are the paper's example (two levels, energy 1 arriving with
the channel's low-power probability and energy 3 arriving with its high-power one)::

    [optimal]
    levels = [[1, 0.5], [3, 1]]     # (energy per step, arrival probability); default: the
                                     # channel's low and high power at energies 1 and 3
    budgets = ["6/5", "9/7", "7/5", "5/3"]     # average energy per step; default: the shares
                                     # 1/10, 1/7, 1/5, 1/3 of the dearest level and the config's ratio
    csi = true                       # the sensor also knows the channel state
    tau_max = 200                    # truncation of tau (default: each function's own)
    betas = [0.1, 0.2, 0.25, 0.5, "2/3", 0.9]  # blocking budgets of the worst attack
    forge_budget = 0.0               # share of quiet steps with a forged flag-ACK
    stealth = "none"                 # or "support", "gap-law"
    jam_rates = [0.01, 0.1, 0.3]     # long-run jammed fractions (one-state channels only)
    horizon = 20                     # finite-horizon jamming: n_jams of horizon steps
    n_jams = [1, 2, 3, 5, 8, 10]

A budget is an energy per step; with the default levels the budget of the share p/q of
high-power steps is 1 + 2 p/q, the paper's (Psi - delta)/(Delta - delta) = p/q.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from importlib import resources
from typing import Any

import numpy as np

from ..model.channels import Channel
from ..optimal.jamming import MAX_TAU as JAMMING_MAX_TAU
from ..optimal.policies import as_levels
from ..optimal.power import MAX_TAU as POWER_MAX_TAU
from .values import (
    Section,
    check_keys,
    config_error,
    read_choice,
    read_fraction,
    read_int,
    read_real,
    strip_name,
    toml_kind,
)

__all__ = [
    "DEFAULT_BETAS",
    "DEFAULT_SHARES",
    "OPTIMAL_SECTION",
    "OptimalConfig",
    "STEALTH_CHOICES",
    "example_text",
    "parse_optimal",
]

OPTIMAL_SECTION = Section(
    (
        "levels",
        "budgets",
        "csi",
        "tau_max",
        "betas",
        "forge_budget",
        "stealth",
        "jam_rates",
        "horizon",
        "n_jams",
    )
)

#: Shares p/q of high-power steps whose budgets the power table shows by default (beside the
#: config's own ratio).
DEFAULT_SHARES = (Fraction(1, 10), Fraction(1, 7), Fraction(1, 5), Fraction(1, 3))
#: Blocking budgets of the worst attack by default (the paper's 1/5 and 2/3 among them).
DEFAULT_BETAS = (0.1, 0.2, 0.25, 0.5, 2 / 3, 0.9)
#: Long-run jammed fractions by default.
DEFAULT_JAM_RATES = (0.01, 0.1, 0.3)
#: The ``stealth`` values and what :func:`fakeack.worst_attack` takes for each.
STEALTH_CHOICES: dict[str, str | None] = {"none": None, "support": "support", "gap-law": "gap-law"}
#: The default levels' energies (low, high): the paper's delta and Delta up to scale.
_LOW_ENERGY, _HIGH_ENERGY = Fraction(1), Fraction(3)
#: Largest tau_max every optimal function takes.
_MAX_TAU = min(POWER_MAX_TAU, JAMMING_MAX_TAU)

#: One power level as read: energy (exact) and arrival probabilities (one, or one per state).
Level = tuple[Fraction, tuple[float, ...]]


@dataclass(frozen=True)
class OptimalConfig:
    """The parsed ``[optimal]`` section, defaults filled in (see the module docstring).

    Attributes
    ----------
    levels : tuple of (Fraction, tuple of float)
        The power levels: energy per step and arrival probability (one, or one per channel state).
    budgets : tuple of Fraction
        Average energies per step of :func:`fakeack.optimal_power_policy`, increasing.
    csi : bool
        Whether the sensor also knows the channel state.
    tau_max : int or None
        The truncation of tau passed to every function; None: each function's default.
    betas : tuple of float
        Blocking budgets of :func:`fakeack.worst_attack`.
    forge_budget : float
        Largest share of quiet steps with a forged flag-ACK.
    stealth : str or None
        :func:`fakeack.worst_attack`'s ``stealth`` (None, ``"support"`` or ``"gap-law"``).
    jam_rates : tuple of float
        Long-run jammed fractions of :func:`fakeack.optimal_jamming` (empty on a channel with
        memory unless given, which is refused).
    horizon : int
        The finite horizon T of the jamming table.
    n_jams : tuple of int
        The jam budgets n <= T of the jamming table.
    """

    levels: tuple[Level, ...]
    budgets: tuple[Fraction, ...]
    csi: bool = True
    tau_max: int | None = None
    betas: tuple[float, ...] = DEFAULT_BETAS
    forge_budget: float = 0.0
    stealth: str | None = None
    jam_rates: tuple[float, ...] = DEFAULT_JAM_RATES
    horizon: int = 20
    n_jams: tuple[int, ...] = (1, 2, 3, 5, 8, 10)

    @property
    def level_pairs(self) -> list[tuple[float, float | list[float]]]:
        """The levels as :func:`fakeack.optimal_power_policy` takes them."""
        return [(float(e), a[0] if len(a) == 1 else list(a)) for e, a in self.levels]


def _array(key: str, values: Any, example: str) -> list[Any]:
    if not isinstance(values, list) or not values:
        raise config_error(
            "optimal", key, f"must be a non-empty array such as {example}, got {toml_kind(values)}"
        )
    return values


def _probability(key: str, x: Any) -> float:
    v = read_real("optimal", key, x)
    if not 0 <= v <= 1:
        raise config_error("optimal", key, f"must lie in [0, 1], got {v}")
    return v


def _levels(values: Any, n_states: int) -> tuple[Level, ...]:
    out: list[Level] = []
    for i, item in enumerate(_array("levels", values, "[[1, 0.5], [3, 1]]")):
        key = f"levels[{i}]"
        if not isinstance(item, list) or len(item) != 2:
            raise config_error("optimal", key, f"must be a pair [energy, arrival], got {item!r}")
        energy = read_fraction("optimal", f"{key} energy", item[0])
        raw = item[1] if isinstance(item[1], list) else [item[1]]
        arrival = tuple(_probability(f"{key} arrival", a) for a in raw)
        if len(arrival) not in (1, n_states):
            raise config_error(
                "optimal",
                f"{key} arrival",
                f"must be one probability or one per channel state ({n_states}), got {len(arrival)}",
            )
        out.append((energy, arrival))
    try:
        as_levels([(float(e), list(a)) for e, a in out])
    except (TypeError, ValueError) as exc:
        raise config_error("optimal", "levels", strip_name(str(exc), "levels")) from None
    return tuple(out)


def _default_levels(channel: float | Channel) -> tuple[Level, ...]:
    if isinstance(channel, Channel):
        low, high = tuple(float(x) for x in channel.low), tuple(float(x) for x in channel.high)
        if channel.n_states == 1 or np.ptp(channel.low) == 0.0:
            low = low[:1]
        if channel.n_states == 1 or np.ptp(channel.high) == 0.0:
            high = high[:1]
        return ((_LOW_ENERGY, low), (_HIGH_ENERGY, high))
    return ((_LOW_ENERGY, (float(channel),)), (_HIGH_ENERGY, (1.0,)))


def _budgets(table: dict[str, Any], levels: tuple[Level, ...], ratio: Fraction) -> tuple[Fraction, ...]:
    low = min(e for e, _ in levels)
    high = max(e for e, _ in levels)
    if "budgets" not in table:
        return tuple(sorted({low + (high - low) * s for s in (*DEFAULT_SHARES, ratio)}))
    out: list[Fraction] = []
    for i, x in enumerate(_array("budgets", table["budgets"], '["9/7", 1.5]')):
        b = read_fraction("optimal", f"budgets[{i}]", x)
        if b < low:
            raise config_error(
                "optimal", f"budgets[{i}]", f"must be at least the cheapest level's energy {low}, got {b}"
            )
        out.append(b)
    return tuple(out)


def _jam_rates(table: dict[str, Any], channel: float | Channel) -> tuple[float, ...]:
    memory = isinstance(channel, Channel) and channel.n_states > 1
    if "jam_rates" not in table:
        return () if memory else DEFAULT_JAM_RATES
    rates = _array("jam_rates", table["jam_rates"], "[0.01, 0.1]")
    if memory:
        raise config_error(
            "optimal",
            "jam_rates",
            "the long-run jamming needs a one-state channel (the jammer sees tau, not the state)",
        )
    return tuple(_probability(f"jam_rates[{i}]", r) for i, r in enumerate(rates))


def parse_optimal(data: dict[str, Any], channel: float | Channel, ratio: Fraction) -> OptimalConfig:
    """The ``[optimal]`` section of a parsed config, defaults filled in for its channel.

    Parameters
    ----------
    data : dict
        The parsed TOML (:attr:`fakeack.config.Config.raw`).
    channel : float or Channel
        The config's channel (:attr:`fakeack.config.Config.channel_arg`): the default levels
        arrive with its low- and high-power probabilities.
    ratio : Fraction
        The config's energy ratio p/q; its budget is among the default budgets.

    Returns
    -------
    OptimalConfig

    Raises
    ------
    ConfigError
        Naming the key (``config: [optimal] betas[2]: must lie in [0, 1], got 1.5``).
    """
    table = check_keys("optimal", data.get("optimal", {}), OPTIMAL_SECTION)
    n_states = channel.n_states if isinstance(channel, Channel) else 1
    levels = _levels(table["levels"], n_states) if "levels" in table else _default_levels(channel)
    given: dict[str, Any] = {"levels": levels, "budgets": _budgets(table, levels, ratio)}
    if "csi" in table:
        if not isinstance(table["csi"], bool):
            raise config_error("optimal", "csi", f"must be true or false, got {toml_kind(table['csi'])}")
        given["csi"] = table["csi"]
    if "tau_max" in table:
        given["tau_max"] = read_int("optimal", "tau_max", table["tau_max"], 1)
        if given["tau_max"] > _MAX_TAU:
            raise config_error("optimal", "tau_max", f"must be at most {_MAX_TAU}, got {given['tau_max']}")
    if "betas" in table:
        betas = _array("betas", table["betas"], '[0.2, "2/3"]')
        given["betas"] = tuple(float(_beta(f"betas[{i}]", b)) for i, b in enumerate(betas))
    if "forge_budget" in table:
        given["forge_budget"] = _probability("forge_budget", table["forge_budget"])
    if "stealth" in table:
        given["stealth"] = STEALTH_CHOICES[
            read_choice("optimal", "stealth", table["stealth"], tuple(STEALTH_CHOICES))
        ]
    given["jam_rates"] = _jam_rates(table, channel)
    if "horizon" in table:
        given["horizon"] = read_int("optimal", "horizon", table["horizon"], 1)
    if "n_jams" in table:
        jams = _array("n_jams", table["n_jams"], "[1, 5]")
        given["n_jams"] = tuple(read_int("optimal", f"n_jams[{i}]", n, 0) for i, n in enumerate(jams))
    horizon = given.get("horizon", OptimalConfig.horizon)
    if "n_jams" not in table:  # the default budgets that fit a shorter horizon
        given["n_jams"] = tuple(n for n in OptimalConfig.n_jams if n <= horizon)
    for i, n in enumerate(given["n_jams"]):
        if n > horizon:
            raise config_error("optimal", f"n_jams[{i}]", f"must be at most horizon = {horizon}, got {n}")
    return OptimalConfig(**given)


def _beta(key: str, x: Any) -> Fraction:
    b = read_fraction("optimal", key, x)
    if not 0 <= b <= 1:
        raise config_error("optimal", key, f"must lie in [0, 1], got {b}")
    return b


def example_text() -> str:
    """The example config of ``fakeack optimal --example`` (the paper's system, every
    ``[optimal]`` key at its default).

    Returns
    -------
    str
        The TOML text of ``fakeack/data/optimal_example.toml``.
    """
    return resources.files("fakeack.data").joinpath("optimal_example.toml").read_text(encoding="utf-8")
