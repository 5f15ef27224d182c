"""TOML configuration of ``fakeack grid`` (a parameter study, see :func:`fakeack.study_grid`).

Sections: ``[grid]`` (the axes lam, ratio and optionally beta, each a list or
``{start, stop, num}``; family, t_max, block; or instead of lam a ``[grid.channel]`` table with
``kind = "gilbert-elliott"`` and the axes ``mean`` and ``memory``), the systems
(``[systems.NAME]`` tables, or one ``[system]``) and optionally ``[montecarlo]`` (runs,
horizon, seed, mode, protocol). Unknown sections and keys are errors, and every error names its
section and key (``config: [grid] ratio: ...``). ``fakeack grid --example`` prints :func:`example_text`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from importlib import resources
from pathlib import Path
from typing import Any

from ..model.system import LinearSystem
from ..studies.grid.spec import spec
from .analyze import _linear_system, loads
from .values import (
    ConfigError,
    Section,
    check_keys,
    config_error,
    read_fraction,
    read_int,
    read_matrix,
    toml_kind,
)

__all__ = [
    "GridConfig",
    "parse_grid_config",
    "load_grid_config",
    "example_text",
]


_SECTIONS = ("grid", "systems", "system", "montecarlo")
_GRID = Section(
    ("lam", "ratio", "beta", "family", "t_max", "block", "channel"),
    "ratio and either lam or channel are required",
)
_CHANNEL = Section(("kind", "mean", "memory"), "kind, mean and memory are required")
_SYSTEM = Section(("A", "C", "Q", "R"), "A, C, Q and R are required")
_MONTECARLO = Section(("runs", "horizon", "seed", "mode", "protocol"))
_RANGE = Section(("start", "stop", "num"))
_MAX_AXIS = 10_000_000


@dataclass(frozen=True)
class GridConfig:
    """A parsed, validated ``fakeack grid`` configuration: the arguments of :func:`fakeack.study_grid`."""

    systems: dict[str, LinearSystem]
    lam: list[float] | None
    ratio: list[Fraction]
    beta: list[Fraction] | None = None
    family: str = "periodic"
    t_max: int = 60
    block: int | None = None
    montecarlo: dict[str, Any] | None = None
    channel: dict[str, Any] | None = None
    source: str = "<string>"
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    def arguments(self) -> dict[str, Any]:
        """Keyword arguments of :func:`fakeack.study_grid`."""
        return {
            "systems": self.systems,
            "lam": self.lam,
            "ratio": self.ratio,
            "beta": self.beta,
            "family": self.family,
            "t_max": self.t_max,
            "montecarlo": self.montecarlo,
            "block": self.block,
            "channel": self.channel,
        }


def _axis(key: str, value: Any, section: str = "grid") -> list[Fraction]:
    """A list of numbers/fraction strings, or ``{start, stop, num}`` evenly spaced, exactly."""
    if isinstance(value, dict):
        table = check_keys(f"{section}.{key}", value, _RANGE)
        for k in _RANGE.keys:
            if k not in table:
                raise config_error(section, key, f"a range needs start, stop and num (missing {k})")
        start = read_fraction(section, f"{key}.start", table["start"])
        stop = read_fraction(section, f"{key}.stop", table["stop"])
        num = read_int(section, f"{key}.num", table["num"], 1)
        if num > _MAX_AXIS:
            raise config_error(section, f"{key}.num", f"must be at most {_MAX_AXIS}, got {num}")
        if num == 1:
            return [start]
        step = (stop - start) / (num - 1)
        return [start + i * step for i in range(num)]
    if not isinstance(value, list):
        raise config_error(
            section, key, f"must be a list or a table {{start, stop, num}}, got {toml_kind(value)}"
        )
    if not value:
        raise config_error(section, key, "empty axis (give at least one value)")
    return [read_fraction(section, f"{key}[{i}]", x) for i, x in enumerate(value)]


def _channel(grid: dict[str, Any]) -> dict[str, Any] | None:
    """``[grid.channel]``: the mean and memory dimensions of a study over bursty channels."""
    if "channel" not in grid:
        return None
    if "lam" in grid:
        raise config_error(
            "grid", "channel", "give either lam (the i.i.d. channel) or [grid.channel], not both"
        )
    if not isinstance(grid["channel"], dict):
        raise config_error("grid", "channel", f"must be a table, got {toml_kind(grid['channel'])}")
    table = check_keys("grid.channel", grid["channel"], _CHANNEL)
    for key in _CHANNEL.keys:
        if key not in table:
            raise config_error("grid.channel", key, "missing")
    if table["kind"] != "gilbert-elliott":
        raise config_error("grid.channel", "kind", f"must be 'gilbert-elliott', got {table['kind']!r}")
    return {
        "kind": table["kind"],
        "mean": [float(x) for x in _axis("mean", table["mean"], "grid.channel")],
        "memory": [float(x) for x in _axis("memory", table["memory"], "grid.channel")],
    }


def _systems(data: dict[str, Any]) -> dict[str, LinearSystem]:
    if "system" in data and "systems" in data:
        raise config_error("system", None, "give either one [system] or [systems.NAME] tables, not both")
    if "system" in data:
        tables = {"system": data["system"]}
        where = {"system": "system"}
    elif "systems" in data:
        if not isinstance(data["systems"], dict) or not data["systems"]:
            raise config_error("systems", None, "give one [systems.NAME] table per system")
        tables = data["systems"]
        where = {name: f"systems.{name}" for name in tables}
    else:
        raise config_error("systems", None, "missing: give [systems.NAME] tables (or one [system])")
    out = {}
    for name, table in tables.items():
        section = where[name]
        table = check_keys(section, table, _SYSTEM)
        m = {}
        for k in _SYSTEM.keys:
            if k not in table:
                raise config_error(section, k, "missing")
            m[k] = read_matrix(section, k, table[k])
        try:
            out[name] = _linear_system(m)
        except ConfigError as exc:
            raise ConfigError(str(exc).replace("[system]", f"[{section}]", 1)) from None
    return out


def _montecarlo(data: dict[str, Any]) -> dict[str, Any] | None:
    if "montecarlo" not in data:
        return None
    table = check_keys("montecarlo", data["montecarlo"], _MONTECARLO)
    out: dict[str, Any] = {"seed": 1}
    for key, minimum in (("runs", 2), ("horizon", 1), ("seed", 0)):
        if key in table:
            out[key] = read_int("montecarlo", key, table[key], minimum)
        elif key != "seed":
            raise config_error("montecarlo", key, "missing")
    for key in ("mode", "protocol"):
        if key in table:
            out[key] = table[key]
    return out


def parse_grid_config(data: dict[str, Any], source: str = "<string>") -> GridConfig:
    """Validate a parsed TOML document as a ``fakeack grid`` config, grid included.

    Parameters
    ----------
    data : dict
        The parsed TOML.
    source : str, optional
        Name for messages.

    Returns
    -------
    GridConfig

    Raises
    ------
    ConfigError
        The first problem found, naming its section and key.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"config: expected a TOML table at the top level, got {toml_kind(data)}")
    for name in data:
        if name not in _SECTIONS:
            expected = ", ".join(f"[{s}]" for s in ("grid", "systems.NAME", "montecarlo"))
            raise ConfigError(f"config: [{name}]: unknown section (expected {expected})")
    if "grid" not in data:
        raise ConfigError("config: [grid]: missing section (ratio and either lam or channel are required)")
    grid = check_keys("grid", data["grid"], _GRID)
    for key in ("lam", "ratio"):
        if key not in grid and not (key == "lam" and "channel" in grid):
            raise config_error("grid", key, "missing")
    systems = _systems(data)
    channel = _channel(grid)
    cfg = GridConfig(
        systems=systems,
        lam=None if channel is not None else [float(x) for x in _axis("lam", grid["lam"])],
        ratio=_axis("ratio", grid["ratio"]),
        beta=_axis("beta", grid["beta"]) if "beta" in grid else None,
        family=grid.get("family", "periodic"),
        t_max=read_int("grid", "t_max", grid.get("t_max", 60), 2),
        block=read_int("grid", "block", grid["block"], 1) if "block" in grid else None,
        montecarlo=_montecarlo(data),
        channel=channel,
        source=source,
        raw=data,
    )
    a = cfg.arguments()
    try:
        spec(
            a["systems"],
            a["lam"],
            a["ratio"],
            a["beta"],
            a["family"],
            a["t_max"],
            a["montecarlo"],
            a["channel"],
        )
    except (TypeError, ValueError) as exc:
        msg = str(exc)
        section = "montecarlo" if msg.startswith("montecarlo") else "grid"
        if msg.startswith("channel "):
            section, msg = "grid.channel", msg[len("channel ") :]
        raise ConfigError(f"config: [{section}] {msg}") from None
    return cfg


def load_grid_config(path: str | Path) -> GridConfig:
    """Read and validate a ``fakeack grid`` config file.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    GridConfig
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"config: cannot read {str(p)!r}: {exc.strerror or exc}") from None
    return parse_grid_config(loads(text, str(p)), str(p))


def example_text() -> str:
    """The shipped example config, as printed by ``fakeack grid --example``.

    Returns
    -------
    str
    """
    return resources.files("fakeack.data").joinpath("grid_example.toml").read_text(encoding="utf-8")
