"""The packet channel of a config (``[channel]``) and of the command line (``--channel``).

One reader for both spellings, so a value is checked the same way wherever it is given. In a
config::

    [channel]
    kind = "gilbert-elliott"   # or "bernoulli" (with lam), or "markov" (with P, low, high)
    p = 0.1                    # P(good -> bad) per step
    q = 0.1                    # P(bad -> good) per step
    lam_good = 1.0             # low-power arrival probability in the good state
    lam_bad = 0.0              # ... and in the bad state
    high_good = 1.0            # optional (default 1): high-power arrival probabilities
    high_bad = 1.0

``kind = "markov"`` takes ``P`` (rows of transition probabilities, ``P[i][j]`` = P(next state j |
state i)), ``low`` and optionally ``high`` (default 1 in every state): the channel
:class:`fakeack.MarkovChannel` ``(P, low, high)``. Probabilities are numbers or fraction strings
(``"1/3"``). On the command line, ``--channel ge:p,q,lam_good,lam_bad[,high_good,high_bad]`` or
``--channel bernoulli:lam``.

Every channel read here is irreducible (every state reachable from every other): a channel with a
transient state or with several closed classes is refused, naming the key (``p``, ``q`` or
``P``). The library itself accepts transient states (:class:`fakeack.MarkovChannel`); a config
refuses them because their ``low`` and ``high`` would have no effect, which is a mistake more
often than an intention. A channel with one state whose high-power packets always arrive is the
paper's and is returned as :class:`fakeack.BernoulliChannel`, whose ``lam`` must lie in (0, 1)
like ``[system] lam``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from fractions import Fraction
from typing import Any

import numpy as np

from ..model.channels import (
    ROW_SUM_TOL,
    BernoulliChannel,
    Channel,
    GilbertElliott,
    MarkovChannel,
    closed_classes,
)
from .values import Section, check_keys, config_error, read_choice, read_real, require, toml_kind

__all__ = [
    "CHANNEL_KINDS",
    "CHANNEL_SECTION",
    "CHANNEL_OPTION",
    "read_channel",
    "parse_channel_option",
    "channel_table",
    "system_channel",
    "with_channel",
]

#: The values of ``[channel] kind``.
CHANNEL_KINDS = ("bernoulli", "gilbert-elliott", "markov")

#: Per kind: the required keys, then the optional ones.
_KIND_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "bernoulli": (("lam",), ()),
    "gilbert-elliott": (("p", "q", "lam_good", "lam_bad"), ("high_good", "high_bad")),
    "markov": (("P", "low"), ("high",)),
}

#: Every key a ``[channel]`` section may hold (which ones depends on ``kind``).
CHANNEL_SECTION = Section(
    ("kind", "lam", "p", "q", "lam_good", "lam_bad", "high_good", "high_bad", "P", "low", "high")
)

#: How ``--channel`` is written (for help texts and messages).
CHANNEL_OPTION = "ge:p,q,lam_good,lam_bad[,high_good,high_bad] or bernoulli:lam"

#: ``problem(key, text)``: the exception to raise for a bad value of ``key`` (None: the whole channel).
Problem = Callable[[str | None, str], ValueError]

_GE_NAMES = ("p", "q", "lam_good", "lam_bad", "high_good", "high_bad")


def _probability(problem: Problem, key: str, x: Any) -> float:
    """A probability in [0, 1]: a TOML number or a fraction string such as ``"1/3"``."""
    v = _number(problem, key, x)
    if not 0.0 <= v <= 1.0:
        raise problem(key, f"must lie in [0, 1], got {v}")
    return v


def _number(problem: Problem, key: str, x: Any) -> float:
    """A finite number: a TOML number or a fraction string."""
    if isinstance(x, str):
        try:
            v = float(Fraction(x.strip()))
        except (ValueError, ZeroDivisionError):
            raise problem(key, f'cannot read {x!r} as a number or fraction "p/q"') from None
    elif isinstance(x, bool) or not isinstance(x, (int, float)):
        raise problem(key, f'must be a probability (a number in [0, 1] or "p/q"), got {toml_kind(x)} {x!r}')
    else:
        v = float(x)
    if not math.isfinite(v):
        raise problem(key, f"must be finite, got {v}")
    return v


def _bernoulli(problem: Problem, key: str, lam: float) -> BernoulliChannel:
    """The paper's channel; like ``[system] lam``, ``lam`` lies strictly between 0 and 1."""
    if not 0.0 < lam < 1.0:
        raise problem(key, f"must lie in (0, 1), got {lam}")
    return BernoulliChannel(lam)


def _gilbert_elliott(problem: Problem, values: dict[str, float]) -> GilbertElliott:
    """``GilbertElliott(p, q, lam_good, lam_bad, high_good, high_bad)``, irreducible."""
    if values["p"] == 0.0:
        raise problem(
            "p",
            "must be positive: with p = 0 the channel never enters the bad state (a reducible "
            "channel); for i.i.d. losses use a Bernoulli channel (lam)",
        )
    if values["q"] == 0.0:
        raise problem(
            "q",
            "must be positive: with q = 0 the channel never leaves the bad state (a reducible "
            "channel); for i.i.d. losses use a Bernoulli channel (lam)",
        )
    return GilbertElliott(*(values[k] for k in _GE_NAMES))


def _states(indices: Sequence[int] | np.ndarray) -> str:
    return ", ".join(str(int(i)) for i in indices)


def _irreducible(problem: Problem, P: np.ndarray) -> None:
    """Refuse a transition matrix with a transient state or several closed classes."""
    classes = closed_classes(P)
    if len(classes) > 1:
        groups = "; ".join("{" + _states(c) + "}" for c in classes)
        raise problem(
            "P",
            f"the channel is reducible: its states split into {len(classes)} closed classes ({groups}) "
            "that never reach each other, so the long-run law depends on the start; every state must "
            "be reachable from every other",
        )
    (cls,) = classes
    if len(cls) < P.shape[0]:
        transient = sorted(set(range(P.shape[0])) - {int(i) for i in cls})
        raise problem(
            "P",
            f"the channel is reducible: state(s) {_states(transient)} cannot be reached again from "
            f"state(s) {_states(cls)} (transient, so their low and high have no effect); every state "
            "must be reachable from every other",
        )


def _vector(problem: Problem, key: str, x: Any, k: int) -> list[float]:
    """``low`` or ``high``: one probability per state."""
    if not isinstance(x, list):
        raise problem(key, f"must be an array with one probability per state, got {toml_kind(x)}")
    if len(x) != k:
        raise problem(key, f"must have one entry per channel state ({k}, the rows of P), got {len(x)}")
    return [_probability(problem, f"{key}[{i}]", v) for i, v in enumerate(x)]


def _matrix(problem: Problem, x: Any) -> np.ndarray:
    """``P``: square, entries in [0, 1], rows summing to 1 (within 1e-12)."""
    example = "e.g. [[0.9, 0.1], [0.3, 0.7]]"
    if not isinstance(x, list) or not x or not all(isinstance(row, list) for row in x):
        raise problem("P", f"must be a non-empty array of rows, {example}, got {toml_kind(x)} {x!r}")
    k = len(x)
    for i, row in enumerate(x):
        if len(row) != k:
            raise problem("P", f"must be square ({k} rows, so {k} entries in each): row {i} has {len(row)}")
    P = np.array(
        [[_probability(problem, f"P[{i}][{j}]", v) for j, v in enumerate(row)] for i, row in enumerate(x)]
    )
    sums = P.sum(axis=1)
    for i, s in enumerate(sums):
        if abs(s - 1.0) > ROW_SUM_TOL:
            raise problem(
                f"P[{i}]", f"must sum to 1 (each row is a law of the next state), sums to {float(s)!r}"
            )
    return P


def _markov(problem: Problem, table: dict[str, Any]) -> Channel:
    """``MarkovChannel(P, low, high)``, irreducible; one state with high = 1 is the paper's channel."""
    P = _matrix(problem, table["P"])
    k = P.shape[0]
    low = _vector(problem, "low", table["low"], k)
    high = _vector(problem, "high", table["high"], k) if "high" in table else [1.0] * k
    _irreducible(problem, P)
    if k == 1 and high[0] == 1.0:
        return _bernoulli(problem, "low[0]", low[0])
    try:
        return MarkovChannel(P, low, high)
    except (TypeError, ValueError) as exc:  # not expected after the checks above
        raise problem(None, str(exc)) from None


def read_channel(table: Any, section: str = "channel") -> Channel:
    """The channel of a ``[channel]`` section.

    Parameters
    ----------
    table : dict
        The section as parsed by :mod:`tomllib`.
    section : str, optional
        The section's name in messages.

    Returns
    -------
    Channel
        :class:`fakeack.BernoulliChannel` for ``kind = "bernoulli"`` (and for a one-state
        ``"markov"`` channel whose high-power packets always arrive), else
        :class:`fakeack.GilbertElliott` or :class:`fakeack.MarkovChannel`.

    Raises
    ------
    ConfigError
        Naming the key: unknown or missing keys, a key of another kind, probabilities outside
        [0, 1], a matrix that is not square or not row-stochastic, a reducible channel.
    """
    table = check_keys(section, table, CHANNEL_SECTION)
    kinds = " or ".join(f'"{k}"' for k in CHANNEL_KINDS)
    kind = read_choice(section, "kind", require(section, table, "kind", f"give {kinds}"), CHANNEL_KINDS)
    required, optional = _KIND_KEYS[kind]
    accepted = ("kind", *required, *optional)
    for key in table:
        if key not in accepted:
            raise config_error(
                section, key, f'not a key of kind = "{kind}" (its keys: {", ".join(accepted)})'
            )
    for key in required:
        require(section, table, key, f'kind = "{kind}" needs {", ".join(required)}')

    def problem(key: str | None, text: str) -> ValueError:
        return config_error(section, key, text)

    if kind == "bernoulli":
        return _bernoulli(problem, "lam", _number(problem, "lam", table["lam"]))
    if kind == "gilbert-elliott":
        values = {k: _probability(problem, k, table.get(k, 1.0)) for k in _GE_NAMES}
        return _gilbert_elliott(problem, values)
    return _markov(problem, table)


def parse_channel_option(text: str, flag: str = "--channel") -> Channel:
    """The channel of ``--channel ge:p,q,lam_good,lam_bad[,high_good,high_bad]`` or ``bernoulli:lam``.

    Parameters
    ----------
    text : str
        The option's value. ``gilbert-elliott:`` is accepted for ``ge:``; values may be fractions
        (``ge:1/10,1/10,1,0``).
    flag : str, optional
        The option's name in messages.

    Returns
    -------
    Channel

    Raises
    ------
    ValueError
        Naming the option and the value (``--channel lam_bad: must lie in [0, 1], got 1.5``).
    """

    def problem(key: str | None, detail: str) -> ValueError:
        return ValueError(f"{flag} {key}: {detail}" if key else f"{flag}: {detail}")

    kind, sep, rest = text.partition(":")
    kind = kind.strip().lower()
    values = [v.strip() for v in rest.split(",")] if rest.strip() else []
    if not sep or kind not in ("ge", "gilbert-elliott", "bernoulli"):
        raise problem(None, f"expected {CHANNEL_OPTION}, got {text!r}")
    if kind == "bernoulli":
        if len(values) != 1:
            raise problem(None, f"bernoulli takes one value, lam (e.g. bernoulli:0.5), got {text!r}")
        return _bernoulli(problem, "lam", _number(problem, "lam", values[0]))
    if len(values) not in (4, 6):
        raise problem(
            None,
            f"ge takes 4 values p,q,lam_good,lam_bad (and optionally high_good,high_bad), e.g. "
            f"ge:0.1,0.1,1,0; got {len(values)} in {text!r}",
        )
    read = {k: _probability(problem, k, v) for k, v in zip(_GE_NAMES[: len(values)], values, strict=True)}
    read.setdefault("high_good", 1.0)
    read.setdefault("high_bad", 1.0)
    return _gilbert_elliott(problem, read)


def channel_table(channel: Channel) -> dict[str, Any]:
    """The ``[channel]`` table that :func:`read_channel` reads back as ``channel``.

    Parameters
    ----------
    channel : Channel

    Returns
    -------
    dict
        ``kind`` and the kind's keys.
    """
    if isinstance(channel, BernoulliChannel):
        return {"kind": "bernoulli", "lam": channel.lam}
    if isinstance(channel, GilbertElliott):
        return {"kind": "gilbert-elliott", **{k: getattr(channel, k) for k in _GE_NAMES}}
    return {
        "kind": "markov",
        "P": channel.P.tolist(),
        "low": channel.low.tolist(),
        "high": channel.high.tolist(),
    }


def _system_lam(table: dict[str, Any]) -> float:
    why = "arrival probability at low power, or give a [channel] section"
    lam = read_real("system", "lam", require("system", table, "lam", why))
    if not 0 < lam < 1:
        raise config_error("system", "lam", f"must lie in (0, 1), got {lam}")
    return lam


def system_channel(data: dict[str, Any], system: dict[str, Any]) -> tuple[float, Channel | None]:
    """The channel of an ``analyze`` config: ``[system] lam`` (the i.i.d. short form) or the
    ``[channel]`` section, not both.

    Parameters
    ----------
    data : dict
        The parsed config.
    system : dict
        Its ``[system]`` table (keys checked).

    Returns
    -------
    (float, Channel or None)
        ``(lam, None)`` on the paper's channel (also when ``[channel]`` is of kind
        ``"bernoulli"``), else ``(the mean low-power arrival probability, the channel)``.

    Raises
    ------
    ConfigError
        Both or neither given (naming ``[system] lam``), or a bad ``[channel]``.
    """
    if "channel" not in data:
        return _system_lam(system), None
    if "lam" in system:
        raise config_error(
            "system",
            "lam",
            "give either [system] lam (the i.i.d. short form) or a [channel] section, not both",
        )
    channel = read_channel(data["channel"])
    if isinstance(channel, BernoulliChannel):
        return channel.lam, None
    return channel.mean_low, channel


def with_channel(data: dict[str, Any], channel: Channel) -> dict[str, Any]:
    """The parsed config ``data`` with its channel replaced by ``channel`` (``--channel``).

    ``[system] lam`` and ``[channel]`` are dropped and ``channel`` written as a ``[channel]``
    table (:func:`channel_table`), so :func:`fakeack.config.parse_config` checks it like any
    other and designs the online schedule for it when ``[online] design`` is on.

    Parameters
    ----------
    data : dict
        A parsed (not yet validated) config.
    channel : Channel
        The channel to use instead.

    Returns
    -------
    dict
        A new document; ``data`` is not modified.
    """
    if not isinstance(data, dict):
        return data  # parse_config says what is wrong
    out = {k: v for k, v in data.items() if k != "channel"}
    if isinstance(out.get("system"), dict):
        out["system"] = {k: v for k, v in out["system"].items() if k != "lam"}
    out["channel"] = channel_table(channel)
    return out
