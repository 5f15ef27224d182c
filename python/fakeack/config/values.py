"""Reading one value of the TOML config, with errors that name the section and key.

Each reader takes the section, the key and the value as parsed by :mod:`tomllib`, and returns the
value in the form :mod:`fakeack.config` stores, or raises :class:`ConfigError` saying what is
wrong (``config: [system] A: must be square, found shape (2, 3)``).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .._internal.validate import as_fraction, as_matrix

__all__ = [
    "ConfigError",
    "config_error",
    "toml_kind",
    "strip_name",
    "read_fraction",
    "read_real",
    "read_int",
    "read_choice",
    "read_matrix",
    "Section",
    "check_keys",
    "require",
]


class ConfigError(ValueError):
    """A configuration problem; the message starts with ``config:`` and names the key."""


def config_error(section: str, key: str | None, problem: str) -> ConfigError:
    """``config: [section] key: problem``."""
    where = f"[{section}]" + (f" {key}" if key else "")
    return ConfigError(f"config: {where}: {problem}")


def toml_kind(x: Any) -> str:
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


def strip_name(msg: str, name: str) -> str:
    """``"A must be square"`` -> ``"must be square"`` (the key is already in the prefix)."""
    for sep in (": ", " "):
        if msg.startswith(name + sep):
            return msg[len(name) + len(sep) :]
    return msg


def read_fraction(section: str, key: str, x: Any) -> Fraction:
    """A number or fraction string, read exactly by :func:`fakeack._validate.as_fraction`."""
    try:
        return as_fraction(key, x)
    except TypeError:
        problem = f'must be a number or a fraction string like "1/7", got {toml_kind(x)}'
        raise config_error(section, key, problem) from None
    except ValueError as exc:
        if isinstance(x, str):
            raise config_error(section, key, f'cannot read {x!r} as a number or fraction "p/q"') from None
        raise config_error(section, key, strip_name(str(exc), key)) from None


def read_real(section: str, key: str, x: Any) -> float:
    """A finite number (TOML integer or float) as ``float``."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise config_error(section, key, f"must be a number, got {toml_kind(x)} {x!r}")
    v = float(x)
    if not math.isfinite(v):
        raise config_error(section, key, f"must be finite, got {v}")
    return v


def read_int(section: str, key: str, x: Any, minimum: int) -> int:
    """A TOML integer (not a float) of at least ``minimum``."""
    if isinstance(x, bool) or not isinstance(x, int):
        raise config_error(section, key, f"must be an integer, got {toml_kind(x)} {x!r}")
    if x < minimum:
        raise config_error(section, key, f"must be at least {minimum}, got {x}")
    return x


def read_choice(section: str, key: str, x: Any, allowed: tuple[str, ...]) -> str:
    """One of the strings ``allowed``."""
    if x not in allowed:
        options = " or ".join(f'"{a}"' for a in sorted(allowed))
        raise config_error(section, key, f"must be {options}, got {x!r}")
    return x


def read_matrix(section: str, key: str, x: Any) -> np.ndarray:
    """A number or a nested list of rows, as a finite 2-D float array."""

    def numeric(v: Any) -> bool:
        if isinstance(v, list):
            return all(numeric(u) for u in v)
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    if not numeric(x):
        raise config_error(
            section, key, f"must be a number or a nested list of numbers (rows), got {toml_kind(x)} {x!r}"
        )
    if isinstance(x, list) and x and not any(isinstance(u, list) for u in x):
        raise config_error(
            section, key, f"must be a number or a list of rows, e.g. [[1.0, 0.0]], got the flat list {x!r}"
        )
    try:
        return as_matrix(key, x)
    except (TypeError, ValueError) as exc:
        raise config_error(section, key, strip_name(str(exc), key)) from None


@dataclass(frozen=True)
class Section:
    """The keys a section accepts and, for a required section, what the error says is needed."""

    keys: tuple[str, ...]
    required: str | None = None


def check_keys(name: str, table: Any, section: Section) -> dict[str, Any]:
    """``table`` itself, once it is a table holding only the keys ``section`` accepts."""
    if not isinstance(table, dict):
        raise config_error(name, None, f"must be a table ([{name}]), got {toml_kind(table)}")
    for key in table:
        if key not in section.keys:
            hint = difflib.get_close_matches(key, section.keys, n=1)
            tip = f"; did you mean {hint[0]!r}?" if hint else ""
            raise config_error(name, key, f"unknown key (expected one of {', '.join(section.keys)}){tip}")
    return table


def require(section: str, table: dict[str, Any], key: str, why: str = "") -> Any:
    """``table[key]``, or an error saying it is missing (and ``why`` it is needed)."""
    if key not in table:
        raise config_error(section, key, "missing" + (f" ({why})" if why else ""))
    return table[key]
