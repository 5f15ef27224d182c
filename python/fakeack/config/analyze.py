"""TOML configuration of ``fakeack analyze``.

A config describes one system and what to compute for it. Every error names the section and key
and says what is wrong (``config: [system] A: must be square, found shape (2, 3)``), and unknown
keys are errors, so a typo never passes silently. ``fakeack analyze --example`` prints the shipped
example (:func:`example_text`), which is the paper's system of Sec. V::

    [system]            # A, C, Q, R: scalars or nested lists (rows); lam: arrival probability
    [channel]           # instead of [system] lam: kind = "bernoulli", "gilbert-elliott" or
                        # "markov" and its keys (fakeack.config.channel)
    [energy]            # ratio = "p/q", or Psi, Delta, delta (numbers or "p/q" strings)
    [online]            # design = true, or z0 (and mu, default 1)
    [attack]            # betas = ["1/5", "2/3"]; random = [0.2]; inject = [0.05];
                        # optional [attack.sweep] t_max = 60
    [montecarlo]        # runs, horizon, seed, mode; omit the section to skip the Monte Carlo
    [game]              # the sensor-attacker game of ``fakeack game`` (fakeack._game_config)
    [optimal]           # the optimal policies of ``fakeack optimal`` (fakeack.config.optimal)
"""

from __future__ import annotations

import difflib
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from functools import partial
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .._internal.validate import MODES, PROTOCOLS, as_ratio
from ..attacks.kinds import FlagInjection, PeriodicBlocking, RandomBlocking, as_attack
from ..model.channels import Channel
from ..model.schedules import OnlineDesign, design_online, energy_ratio
from ..model.system import LinearSystem
from .channel import CHANNEL_SECTION, system_channel, with_channel
from .game import GAME_SECTION
from .optimal import OPTIMAL_SECTION
from .values import (
    ConfigError,
    Section,
    check_keys,
    config_error,
    read_choice,
    read_fraction,
    read_int,
    read_matrix,
    read_real,
    require,
    strip_name,
    toml_kind,
)

if sys.version_info >= (3, 11):
    import tomllib as _toml
else:  # pragma: no cover - Python 3.10 with the tomli backport
    try:
        import tomli as _toml
    except ModuleNotFoundError:
        _toml = None  # type: ignore[assignment]  # no TOML reader: the config functions say so

__all__ = [
    "Config",
    "ConfigError",
    "MonteCarloConfig",
    "example_text",
    "load_config",
    "loads",
    "parse_config",
]


_SECTIONS: dict[str, Section] = {
    "system": Section(
        ("A", "C", "Q", "R", "lam"), "A, C, Q, R and lam (or a [channel] section) are required"
    ),
    "channel": CHANNEL_SECTION,  # read by fakeack.config.channel
    "energy": Section(("ratio", "Psi", "Delta", "delta"), 'give ratio = "p/q", or Psi, Delta, delta'),
    "online": Section(("design", "z0", "mu")),
    "attack": Section(("betas", "random", "inject", "sweep")),
    "montecarlo": Section(("runs", "horizon", "seed", "mode", "protocol")),
    "game": GAME_SECTION,  # read by fakeack game (fakeack._game_config)
    "optimal": OPTIMAL_SECTION,  # read by fakeack optimal (fakeack.config.optimal)
}
_SWEEP_SECTION = Section(("t_max",))


def _check_sections(data: Any) -> None:
    if not isinstance(data, dict):
        raise ConfigError(f"config: expected a TOML table at the top level, got {toml_kind(data)}")
    for name in data:
        if name not in _SECTIONS:
            hint = difflib.get_close_matches(name, list(_SECTIONS), n=1)
            tip = f"; did you mean [{hint[0]}]?" if hint else ""
            expected = ", ".join(f"[{s}]" for s in _SECTIONS)
            raise ConfigError(f"config: [{name}]: unknown section (expected {expected}){tip}")


def _section(data: dict[str, Any], name: str) -> dict[str, Any]:
    """The checked table of section ``name`` (empty when an optional section is absent)."""
    section = _SECTIONS[name]
    if name not in data:
        if section.required:
            raise ConfigError(f"config: [{name}]: missing section ({section.required})")
        return {}
    return check_keys(name, data[name], section)


# [system]

_MATRIX_KEYS = ("A", "C", "Q", "R")


def _system_matrices(table: dict[str, Any]) -> dict[str, np.ndarray]:
    """A, C, Q and R, each read and checked against the others' shapes."""
    matrices = {k: read_matrix("system", k, require("system", table, k)) for k in _MATRIX_KEYS}
    n = matrices["A"].shape[0]
    if matrices["A"].shape != (n, n):
        raise config_error("system", "A", f"must be square, found shape {matrices['A'].shape}")
    if matrices["C"].shape[1] != n:
        raise config_error(
            "system", "C", f"must have {n} columns (A is {n}x{n}), found shape {matrices['C'].shape}"
        )
    m = matrices["C"].shape[0]
    if matrices["Q"].shape != (n, n):
        raise config_error("system", "Q", f"must be {n}x{n} like A, found shape {matrices['Q'].shape}")
    if matrices["R"].shape != (m, m):
        raise config_error(
            "system", "R", f"must be {m}x{m} (C has {m} rows), found shape {matrices['R'].shape}"
        )
    return matrices


def _linear_system(matrices: dict[str, np.ndarray]) -> LinearSystem:
    try:
        return LinearSystem(*(matrices[k] for k in _MATRIX_KEYS))
    except (TypeError, ValueError) as exc:
        # Q not PSD, R not PD, (A, C) not detectable, ...: name the key if the message does.
        msg = str(exc)
        key = next((k for k in ("(A, C)", *_MATRIX_KEYS) if msg.startswith((k + " ", k + ":"))), None)
        if key is None:
            raise config_error("system", None, msg) from None
        raise config_error("system", key.strip("()"), strip_name(msg, key)) from None


# [energy]

_ENERGIES = ("Psi", "Delta", "delta")


def _energy_ratio(table: dict[str, Any]) -> Fraction:
    """The budget p/q, given as ``ratio`` or as the three energies."""
    given = [k for k in _ENERGIES if k in table]
    if "ratio" in table and given:
        raise config_error("energy", given[0], "give either ratio or Psi, Delta, delta, not both")
    if "ratio" in table:
        ratio = read_fraction("energy", "ratio", table["ratio"])
        try:
            return as_ratio("ratio", ratio)
        except ValueError as exc:
            raise config_error("energy", "ratio", strip_name(str(exc), "ratio")) from None
    if not given:
        raise config_error("energy", "ratio", 'missing (give ratio = "p/q", or Psi, Delta, delta)')
    energies = {
        k: read_fraction("energy", k, require("energy", table, k, "Psi, Delta and delta go together"))
        for k in _ENERGIES
    }
    try:
        return energy_ratio(energies["Psi"], energies["Delta"], energies["delta"])
    except ValueError as exc:
        raise config_error("energy", None, str(exc)) from None


# [online]


def _online(table: dict[str, Any], lam: float | Channel, ratio: Fraction) -> tuple[OnlineDesign, bool]:
    """``(z0, mu)`` and whether it is ``design_online``'s under the channel ``lam`` (``mu``
    defaults to 1 with ``z0``)."""
    design = table.get("design", "z0" not in table and "mu" not in table)
    if not isinstance(design, bool):
        raise config_error("online", "design", f"must be true or false, got {toml_kind(design)} {design!r}")
    if design:
        for k in ("z0", "mu"):
            if k in table:
                raise config_error(
                    "online", k, "cannot be given with design = true (the design fixes z0 and mu)"
                )
        try:
            return design_online(lam, ratio), True
        except ValueError as exc:
            raise config_error("energy", "ratio", str(exc)) from None
    z0 = read_int("online", "z0", require("online", table, "z0", "or set design = true"), 1)
    mu = read_real("online", "mu", table.get("mu", 1.0))
    if not 0 <= mu <= 1:
        raise config_error("online", "mu", f"must lie in [0, 1], got {mu}")
    return OnlineDesign(z0, mu), False


# [attack]

_MAX_SWEEP_T = 100_000


def _attacks(table: dict[str, Any]) -> tuple[PeriodicBlocking, ...]:
    """``betas``, each read by :func:`fakeack.attacks.as_attack` ("2/6" kept as written)."""
    if "betas" not in table:
        return ()
    betas = table["betas"]
    if not isinstance(betas, list):
        raise config_error(
            "attack", "betas", f'must be an array such as ["1/5", "2/3"], got {toml_kind(betas)}'
        )
    attacks: list[PeriodicBlocking] = []
    for i, value in enumerate(betas):
        key = f"betas[{i}]"
        try:
            attack = as_attack(value, "beta")
        except TypeError:
            raise config_error(
                "attack", key, f"must be a fraction 'r/t' or a number, got {toml_kind(value)}"
            ) from None
        except ValueError as exc:
            raise config_error("attack", key, strip_name(str(exc), "beta")) from None
        assert isinstance(attack, PeriodicBlocking)  # as_attack's reading of a string or number
        if attack in attacks:
            raise config_error("attack", key, f"{attack.label} is listed twice")
        attacks.append(attack)
    return tuple(attacks)


def _probabilities(table: dict[str, Any], key: str, make: Any) -> tuple[Any, ...]:
    """``[attack] random`` / ``inject``: arrays of probabilities, each an attack object."""
    if key not in table:
        return ()
    values = table[key]
    if not isinstance(values, list):
        raise config_error("attack", key, f"must be an array such as [0.2, 0.5], got {toml_kind(values)}")
    out: list[Any] = []
    for i, value in enumerate(values):
        where = f"{key}[{i}]"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise config_error("attack", where, f"must be a number in [0, 1], got {toml_kind(value)}")
        try:
            attack = make(value)
        except ValueError as exc:
            raise config_error("attack", where, strip_name(str(exc), str(exc).split()[0])) from None
        if attack in out:
            raise config_error("attack", where, f"{value} is listed twice")
        out.append(attack)
    return tuple(out)


def _sweep_t_max(table: dict[str, Any]) -> int | None:
    """``[attack.sweep] t_max``, or None (no sweep)."""
    if "sweep" not in table:
        return None
    sweep = check_keys("attack.sweep", table["sweep"], _SWEEP_SECTION)
    t_max = read_int("attack.sweep", "t_max", require("attack.sweep", sweep, "t_max"), 2)
    if t_max > _MAX_SWEEP_T:
        problem = f"must be at most {_MAX_SWEEP_T} (about 3e9 fractions), got {t_max}"
        raise config_error("attack.sweep", "t_max", problem)
    return t_max


# [montecarlo]


@dataclass(frozen=True)
class MonteCarloConfig:
    """The ``[montecarlo]`` section: arguments of :func:`fakeack.simulate`."""

    runs: int = 20_000
    horizon: int = 200
    seed: int = 1
    mode: str = "covariance"
    protocol: str = "B"


#: How each ``[montecarlo]`` key is read.
_MONTECARLO_READERS: dict[str, Callable[[str, str, Any], Any]] = {
    "runs": partial(read_int, minimum=2),
    "horizon": partial(read_int, minimum=1),
    "seed": partial(read_int, minimum=0),
    "mode": partial(read_choice, allowed=MODES),
    "protocol": partial(read_choice, allowed=PROTOCOLS),
}


def _montecarlo(data: dict[str, Any], channel: Channel | None) -> MonteCarloConfig | None:
    """The Monte Carlo settings, or None when the section is absent (no Monte Carlo)."""
    if "montecarlo" not in data:
        return None
    table = _section(data, "montecarlo")
    given = {
        key: read("montecarlo", key, table[key]) for key, read in _MONTECARLO_READERS.items() if key in table
    }
    if channel is not None and given.get("mode") == "state":
        # fakeack.simulate simulates the noise and the estimator on the paper's channel only.
        raise config_error(
            "montecarlo",
            "mode",
            'must be "covariance" with this [channel]: state mode needs the paper\'s channel '
            "(one state, every high-power packet arrives)",
        )
    return MonteCarloConfig(**given)


@dataclass(frozen=True)
class Config:
    """A parsed, validated ``fakeack analyze`` configuration.

    Attributes
    ----------
    system : LinearSystem
        The process and sensor (``[system]`` A, C, Q, R).
    lam : float
        Arrival probability at low power: ``[system] lam``, or the ``lam`` of a ``[channel]`` of
        kind ``"bernoulli"``. For any other channel its long-run mean (the ``lam`` of the i.i.d.
        channel of the same mean); the analysis then uses :attr:`channel`.
    ratio : fractions.Fraction
        Energy ratio p/q (``[energy]``).
    online : OnlineDesign
        ``(z0, mu)`` of the online schedule.
    designed : bool
        Whether ``online`` came from :func:`fakeack.design_online` (spends the budget exactly).
    attacks : tuple of PeriodicBlocking
        ``[attack] betas``, each as written (``"2/6"`` blocks 2 in a row of 6).
    other_attacks : tuple of RandomBlocking and FlagInjection
        ``[attack] random`` (blocking probabilities) then ``inject`` (forging probabilities).
    sweep_t_max : int or None
        ``[attack.sweep] t_max``; None skips the sweep.
    montecarlo : MonteCarloConfig or None
        None when the section is absent.
    channel : Channel or None
        The ``[channel]`` when it is not the paper's (Gilbert-Elliott, Markov); None for the
        paper's channel with :attr:`lam`. :attr:`channel_arg` is what the analysis takes.
    source : str
        Where the config came from (file name or ``"<string>"``).
    """

    system: LinearSystem
    lam: float
    ratio: Fraction
    online: OnlineDesign
    designed: bool
    attacks: tuple[PeriodicBlocking, ...] = ()
    other_attacks: tuple[RandomBlocking | FlagInjection, ...] = ()
    sweep_t_max: int | None = None
    montecarlo: MonteCarloConfig | None = None
    channel: Channel | None = None
    source: str = "<string>"
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def channel_arg(self) -> float | Channel:
        """The channel as the analysis functions take it: :attr:`lam` (a float, the paper's
        channel) unless :attr:`channel` is set."""
        return self.lam if self.channel is None else self.channel

    @property
    def paper_channel(self) -> bool:
        """Whether the channel is the paper's (i.i.d. losses, high power always arrives)."""
        return self.channel is None


def parse_config(data: dict[str, Any], source: str = "<string>", *, channel: Channel | None = None) -> Config:
    """Validate a TOML document (already parsed into a dict) as a ``fakeack analyze`` config.

    Parameters
    ----------
    data : dict
        The parsed TOML.
    source : str, optional
        Name for messages and :attr:`Config.source`.
    channel : Channel, keyword-only, optional
        Use this channel instead of the config's ``[system] lam`` or ``[channel]``
        (:func:`fakeack.config.channel.with_channel`; the command line's ``--channel``).

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        The first problem found, naming its section and key.
    """
    if channel is not None:
        data = with_channel(data, channel)
    _check_sections(data)
    system_table = _section(data, "system")
    matrices = _system_matrices(system_table)
    lam, channel = system_channel(data, system_table)
    system = _linear_system(matrices)
    ratio = _energy_ratio(_section(data, "energy"))
    online, designed = _online(_section(data, "online"), lam if channel is None else channel, ratio)
    attack_table = _section(data, "attack")
    return Config(
        system=system,
        lam=lam,
        ratio=ratio,
        online=online,
        designed=designed,
        attacks=_attacks(attack_table),
        other_attacks=_probabilities(attack_table, "random", RandomBlocking)
        + _probabilities(attack_table, "inject", FlagInjection),
        sweep_t_max=_sweep_t_max(attack_table),
        montecarlo=_montecarlo(data, channel),
        channel=channel,
        source=source,
        raw=data,
    )


def load_config(path: str | Path, *, channel: Channel | None = None) -> Config:
    """Read and validate a TOML config file.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    channel : Channel, keyword-only, optional
        Use this channel instead of the config's (see :func:`parse_config`).

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        If the file cannot be read, is not valid TOML, or fails validation.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"config: cannot read {str(p)!r}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"config: {str(p)!r} is not UTF-8 text ({exc.reason})") from None
    return parse_config(loads(text, str(p)), str(p), channel=channel)


def loads(text: str, source: str = "<string>") -> dict[str, Any]:
    """Parse TOML text with :mod:`tomllib` (or the ``tomli`` backport on Python 3.10).

    Parameters
    ----------
    text : str
        TOML document.
    source : str, optional
        Name for messages.

    Returns
    -------
    dict
        The parsed document (not validated; see :func:`parse_config`).

    Raises
    ------
    ConfigError
        If the text is not valid TOML or no TOML parser is available.
    """
    if _toml is None:  # pragma: no cover
        raise ConfigError(
            "config: reading TOML needs Python 3.11+ or the 'tomli' package (pip install tomli)"
        )
    try:
        return _toml.loads(text)
    except _toml.TOMLDecodeError as exc:
        raise ConfigError(f"config: {source}: invalid TOML: {exc}") from None


def example_text() -> str:
    """The shipped example config (the paper's Sec. V system), as printed by ``analyze --example``.

    Returns
    -------
    str
        The TOML text of ``fakeack/data/example.toml``.
    """
    return resources.files("fakeack.data").joinpath("example.toml").read_text(encoding="utf-8")
