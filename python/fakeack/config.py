"""TOML configuration of ``fakeack analyze``.

A config describes one system and what to compute for it. Every error names the section and key
and says what is wrong (``config: [system] A: must be square, found shape (2, 3)``), and unknown
keys are errors, so a typo never passes silently. ``fakeack analyze --example`` prints the shipped
example (:func:`example_text`), which is the paper's system of Sec. V::

    [system]            # A, C, Q, R: scalars or nested lists (rows); lam: arrival probability
    [energy]            # ratio = "p/q", or Psi, Delta, delta (numbers or "p/q" strings)
    [online]            # design = true, or z0 (and mu, default 1)
    [attack]            # betas = ["1/5", "2/3"]; optional [attack.sweep] t_max = 60
    [montecarlo]        # runs, horizon, seed, mode; omit the section to skip the Monte Carlo
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field
from fractions import Fraction
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ._validate import as_matrix
from .schedules import OnlineDesign, design_online, energy_ratio
from .system import LinearSystem

try:  # Python 3.11+
    import tomllib as _toml
except ModuleNotFoundError:  # pragma: no cover - Python 3.10 with the tomli backport
    try:
        import tomli as _toml  # type: ignore[no-redef]
    except ModuleNotFoundError:
        _toml = None  # type: ignore[assignment]

__all__ = [
    "AttackSpec",
    "Config",
    "ConfigError",
    "MonteCarloConfig",
    "example_text",
    "load_config",
    "loads",
    "parse_attack",
    "parse_config",
]


class ConfigError(ValueError):
    """A configuration problem; the message starts with ``config:`` and names the key."""


def _err(section: str, key: str | None, problem: str) -> ConfigError:
    where = f"[{section}]" + (f" {key}" if key else "")
    return ConfigError(f"config: {where}: {problem}")


def _kind(x: Any) -> str:
    """TOML-ish name of a value's type, for messages."""
    if isinstance(x, bool):
        return "boolean"
    if isinstance(x, int):
        return "integer"
    if isinstance(x, float):
        return "float"
    if isinstance(x, str):
        return "string"
    if isinstance(x, list):
        return "array"
    if isinstance(x, dict):
        return "table"
    return type(x).__name__


def _strip_name(msg: str, name: str) -> str:
    """``"A must be square"`` -> ``"must be square"`` (the key is already in the prefix)."""
    for sep in (": ", " "):
        if msg.startswith(name + sep):
            return msg[len(name) + len(sep) :]
    return msg


# ------------------------------------------------------------------------------------ values


@dataclass(frozen=True)
class AttackSpec:
    """The paper's attack: block the first ``r`` of every ``t`` flag-ACKs (Algorithm 1).

    A pair that is not in lowest terms (``"2/6"``) is kept as written: blocking 2 in a row out of
    6 is a different attack from 1 of 3.
    """

    r: int
    t: int

    @property
    def beta(self) -> Fraction:
        """The budget :math:`\\beta = r/t`."""
        return Fraction(self.r, self.t)

    @property
    def label(self) -> str:
        """``"r/t"`` as written."""
        return f"{self.r}/{self.t}"

    def __str__(self) -> str:
        return self.label


_RT = re.compile(r"^\s*(\d+)\s*/\s*(\d+)\s*$")


def parse_attack(value: Any, name: str = "attack") -> AttackSpec:
    """Read an attack ``"r/t"`` (block the first r of every t flag-ACKs).

    Parameters
    ----------
    value : str, int or float
        ``"r/t"`` with integers ``0 <= r < t`` (kept as written, not reduced), a decimal string
        such as ``"0.2"``, ``0`` (no attack), or a float in ``[0, 1)`` (read as the simplest
        fraction with denominator up to 1000 that equals it to 1e-12).
    name : str, optional
        Name used in error messages.

    Returns
    -------
    AttackSpec

    Raises
    ------
    ValueError
        If the value is not a fraction in ``[0, 1)``.
    TypeError
        If it is not a string or number.
    """
    if isinstance(value, bool) or not isinstance(value, (str, int, float, Fraction)):
        raise TypeError(f"{name} must be a fraction 'r/t' or a number, got {_kind(value)}")
    if isinstance(value, str):
        m = _RT.match(value)
        if m:
            r, t = int(m.group(1)), int(m.group(2))
        else:
            try:
                f = Fraction(value.strip())
            except (ValueError, ZeroDivisionError):
                raise ValueError(f"{name} must look like 'r/t' (e.g. '1/5'), got {value!r}") from None
            r, t = f.numerator, f.denominator
    elif isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value}")
        f = Fraction(value).limit_denominator(1000)
        if abs(float(f) - value) > 1e-12:
            raise ValueError(f"{name} {value!r} is not a simple fraction; write it as 'r/t'")
        r, t = f.numerator, f.denominator
    else:
        f = Fraction(value)
        r, t = f.numerator, f.denominator
    if t < 1:
        raise ValueError(f"{name}: the period t must be at least 1, got {value!r}")
    if not 0 <= r < t:
        raise ValueError(
            f"{name} must lie in [0, 1) (block r < t of every t flag-ACKs; r = t is J_max), got {value!r}"
        )
    return AttackSpec(r, t)


def _fraction(section: str, key: str, x: Any) -> Fraction:
    if isinstance(x, bool) or not isinstance(x, (int, float, str)):
        raise _err(section, key, f'must be a number or a fraction string like "1/7", got {_kind(x)}')
    if isinstance(x, float) and not math.isfinite(x):
        raise _err(section, key, f"must be finite, got {x}")
    if isinstance(x, str):
        try:
            return Fraction(x.strip())
        except (ValueError, ZeroDivisionError):
            raise _err(section, key, f'cannot read {x!r} as a number or fraction "p/q"') from None
    if isinstance(x, float):
        simple = Fraction(x).limit_denominator(10**9)
        return simple if float(simple) == x else Fraction(x)
    return Fraction(x)


def _real(section: str, key: str, x: Any) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise _err(section, key, f"must be a number, got {_kind(x)} {x!r}")
    v = float(x)
    if not math.isfinite(v):
        raise _err(section, key, f"must be finite, got {v}")
    return v


def _int(section: str, key: str, x: Any, minimum: int) -> int:
    if isinstance(x, bool) or not isinstance(x, int):
        raise _err(section, key, f"must be an integer, got {_kind(x)} {x!r}")
    if x < minimum:
        raise _err(section, key, f"must be at least {minimum}, got {x}")
    return x


def _matrix(section: str, key: str, x: Any) -> np.ndarray:
    def numeric(v: Any) -> bool:
        if isinstance(v, list):
            return all(numeric(u) for u in v)
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    if not numeric(x):
        raise _err(section, key, f"must be a number or a nested list of numbers (rows), got {_kind(x)} {x!r}")
    if isinstance(x, list) and x and not any(isinstance(u, list) for u in x):
        raise _err(
            section, key, f"must be a number or a list of rows, e.g. [[1.0, 0.0]], got the flat list {x!r}"
        )
    try:
        return as_matrix(key, x)
    except (TypeError, ValueError) as exc:
        raise _err(section, key, _strip_name(str(exc), key)) from None


# ------------------------------------------------------------------------------------ schema


_SCHEMA: dict[str, tuple[str, ...]] = {
    "system": ("A", "C", "Q", "R", "lam"),
    "energy": ("ratio", "Psi", "Delta", "delta"),
    "online": ("design", "z0", "mu"),
    "attack": ("betas", "sweep"),
    "montecarlo": ("runs", "horizon", "seed", "mode", "protocol"),
}
_SWEEP_KEYS = ("t_max",)


def _check_keys(section: str, table: Any, allowed: tuple[str, ...]) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise _err(section, None, f"must be a table ([{section}]), got {_kind(table)}")
    for key in table:
        if key not in allowed:
            hint = difflib.get_close_matches(key, allowed, n=1)
            tip = f"; did you mean {hint[0]!r}?" if hint else ""
            raise _err(section, key, f"unknown key (expected one of {', '.join(allowed)}){tip}")
    return table


def _require(section: str, table: dict[str, Any], key: str, why: str = "") -> Any:
    if key not in table:
        raise _err(section, key, "missing" + (f" ({why})" if why else ""))
    return table[key]


@dataclass(frozen=True)
class MonteCarloConfig:
    """The ``[montecarlo]`` section: arguments of :func:`fakeack.simulate`."""

    runs: int = 20_000
    horizon: int = 200
    seed: int = 1
    mode: str = "covariance"
    protocol: str = "B"


@dataclass(frozen=True)
class Config:
    """A parsed, validated ``fakeack analyze`` configuration.

    Attributes
    ----------
    system : LinearSystem
        The process and sensor (``[system]`` A, C, Q, R).
    lam : float
        Arrival probability at low power.
    ratio : fractions.Fraction
        Energy ratio p/q (``[energy]``).
    online : OnlineDesign
        ``(z0, mu)`` of the online schedule.
    designed : bool
        Whether ``online`` came from :func:`fakeack.design_online` (spends the budget exactly).
    attacks : tuple of AttackSpec
        ``[attack] betas``.
    sweep_t_max : int or None
        ``[attack.sweep] t_max``; None skips the sweep.
    montecarlo : MonteCarloConfig or None
        None when the section is absent.
    source : str
        Where the config came from (file name or ``"<string>"``).
    """

    system: LinearSystem
    lam: float
    ratio: Fraction
    online: OnlineDesign
    designed: bool
    attacks: tuple[AttackSpec, ...] = ()
    sweep_t_max: int | None = None
    montecarlo: MonteCarloConfig | None = None
    source: str = "<string>"
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


def parse_config(data: dict[str, Any], source: str = "<string>") -> Config:
    """Validate a TOML document (already parsed into a dict) as a ``fakeack analyze`` config.

    Parameters
    ----------
    data : dict
        The parsed TOML.
    source : str, optional
        Name for messages and :attr:`Config.source`.

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        The first problem found, naming its section and key.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"config: expected a TOML table at the top level, got {_kind(data)}")
    for sec in data:
        if sec not in _SCHEMA:
            hint = difflib.get_close_matches(sec, list(_SCHEMA), n=1)
            tip = f"; did you mean [{hint[0]}]?" if hint else ""
            raise ConfigError(
                f"config: [{sec}]: unknown section (expected {', '.join(f'[{s}]' for s in _SCHEMA)}){tip}"
            )

    # [system]
    if "system" not in data:
        raise ConfigError("config: [system]: missing section (A, C, Q, R and lam are required)")
    sys_t = _check_keys("system", data["system"], _SCHEMA["system"])
    mats = {k: _matrix("system", k, _require("system", sys_t, k)) for k in ("A", "C", "Q", "R")}
    n = mats["A"].shape[0]
    if mats["A"].shape != (n, n):
        raise _err("system", "A", f"must be square, found shape {mats['A'].shape}")
    if mats["C"].shape[1] != n:
        raise _err("system", "C", f"must have {n} columns (A is {n}x{n}), found shape {mats['C'].shape}")
    m = mats["C"].shape[0]
    if mats["Q"].shape != (n, n):
        raise _err("system", "Q", f"must be {n}x{n} like A, found shape {mats['Q'].shape}")
    if mats["R"].shape != (m, m):
        raise _err("system", "R", f"must be {m}x{m} (C has {m} rows), found shape {mats['R'].shape}")
    lam = _real("system", "lam", _require("system", sys_t, "lam", "arrival probability at low power"))
    if not 0 < lam < 1:
        raise _err("system", "lam", f"must lie in (0, 1), got {lam}")
    try:
        system = LinearSystem(mats["A"], mats["C"], mats["Q"], mats["R"])
    except (TypeError, ValueError) as exc:
        # Q not PSD, R not PD, (A, C) not detectable, ...: name the key if the message does.
        msg = str(exc)
        key = next((k for k in ("(A, C)", "A", "C", "Q", "R") if msg.startswith((k + " ", k + ":"))), None)
        if key is None:
            raise _err("system", None, msg) from None
        raise _err("system", key.strip("()"), _strip_name(msg, key)) from None

    # [energy]
    if "energy" not in data:
        raise ConfigError('config: [energy]: missing section (give ratio = "p/q", or Psi, Delta, delta)')
    en = _check_keys("energy", data["energy"], _SCHEMA["energy"])
    trio = [k for k in ("Psi", "Delta", "delta") if k in en]
    if "ratio" in en and trio:
        raise _err("energy", trio[0], "give either ratio or Psi, Delta, delta, not both")
    if "ratio" in en:
        ratio = _fraction("energy", "ratio", en["ratio"])
        if not 0 < ratio < 1:
            raise _err("energy", "ratio", f"must lie strictly between 0 and 1, got {ratio}")
    elif trio:
        vals = {
            k: _fraction("energy", k, _require("energy", en, k, "Psi, Delta and delta go together"))
            for k in ("Psi", "Delta", "delta")
        }
        try:
            ratio = energy_ratio(vals["Psi"], vals["Delta"], vals["delta"])
        except ValueError as exc:
            raise _err("energy", None, str(exc)) from None
    else:
        raise _err("energy", "ratio", 'missing (give ratio = "p/q", or Psi, Delta, delta)')

    # [online]
    on = _check_keys("online", data.get("online", {}), _SCHEMA["online"])
    design = on.get("design", "z0" not in on and "mu" not in on)
    if not isinstance(design, bool):
        raise _err("online", "design", f"must be true or false, got {_kind(design)} {design!r}")
    if design:
        for k in ("z0", "mu"):
            if k in on:
                raise _err("online", k, "cannot be given with design = true (the design fixes z0 and mu)")
        try:
            online = design_online(lam, ratio)
        except ValueError as exc:
            raise _err("energy", "ratio", str(exc)) from None
    else:
        z0 = _int("online", "z0", _require("online", on, "z0", "or set design = true"), 1)
        mu = _real("online", "mu", on.get("mu", 1.0))
        if not 0 <= mu <= 1:
            raise _err("online", "mu", f"must lie in [0, 1], got {mu}")
        online = OnlineDesign(z0, mu)

    # [attack]
    at = _check_keys("attack", data.get("attack", {}), _SCHEMA["attack"])
    attacks: list[AttackSpec] = []
    if "betas" in at:
        betas = at["betas"]
        if not isinstance(betas, list):
            raise _err("attack", "betas", f'must be an array such as ["1/5", "2/3"], got {_kind(betas)}')
        for i, b in enumerate(betas):
            try:
                spec = parse_attack(b, "beta")
            except (TypeError, ValueError) as exc:
                raise _err("attack", f"betas[{i}]", _strip_name(str(exc), "beta")) from None
            if spec in attacks:
                raise _err("attack", f"betas[{i}]", f"{spec.label} is listed twice")
            attacks.append(spec)
    t_max = None
    if "sweep" in at:
        sw = _check_keys("attack.sweep", at["sweep"], _SWEEP_KEYS)
        t_max = _int("attack.sweep", "t_max", _require("attack.sweep", sw, "t_max"), 2)
        if t_max > 100_000:
            raise _err("attack.sweep", "t_max", f"must be at most 100000 (about 3e9 fractions), got {t_max}")

    # [montecarlo]
    mc = None
    if "montecarlo" in data:
        mt = _check_keys("montecarlo", data["montecarlo"], _SCHEMA["montecarlo"])
        d = MonteCarloConfig()
        seed = _int("montecarlo", "seed", mt.get("seed", d.seed), 0)
        mode = mt.get("mode", d.mode)
        if mode not in ("covariance", "state"):
            raise _err("montecarlo", "mode", f'must be "covariance" or "state", got {mode!r}')
        protocol = mt.get("protocol", d.protocol)
        if protocol not in ("A", "B"):
            raise _err("montecarlo", "protocol", f'must be "A" or "B", got {protocol!r}')
        mc = MonteCarloConfig(
            runs=_int("montecarlo", "runs", mt.get("runs", d.runs), 2),
            horizon=_int("montecarlo", "horizon", mt.get("horizon", d.horizon), 1),
            seed=seed,
            mode=mode,
            protocol=protocol,
        )
    return Config(system, lam, ratio, online, design, tuple(attacks), t_max, mc, source, data)


def load_config(path: str | Path) -> Config:
    """Read and validate a TOML config file.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

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
    return parse_config(loads(text, str(p)), str(p))


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
