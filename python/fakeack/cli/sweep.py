"""``fakeack sweep``: the attacked cost at every r/t with t <= t_max, and both thresholds."""

from __future__ import annotations

import argparse
import csv
import io
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from ..attacks.threshold import BetaBar, BetaSweep, beta_bar, beta_sweep, j_attack_limit
from ..studies.report import DEFAULT_T_MAX
from ._channel import channel_json, channel_text
from ._inputs import SystemInputs, resolve_system
from ._io import emit, to_json
from ._report import format_number, paragraph, system_text

__all__ = ["run"]

_COLUMNS = ["r", "t", "beta", "j_attack", "j_attack_limit", "better"]


@dataclass(frozen=True)
class _Point:
    """One attack r/t of the sweep."""

    r: int
    t: int
    beta: float
    j_attack: float
    j_attack_limit: float
    better: str  # the schedule to use against r/t: "online" or "offline"


@dataclass(frozen=True)
class _Result:
    """The sweep, its thresholds and the online schedule they were computed for."""

    inputs: SystemInputs
    t_max: int
    z0: int
    mu: float
    designed: bool
    sweep: BetaSweep
    bar: BetaBar
    points: list[_Point]


def _compute(inputs: SystemInputs, t_max: int) -> _Result:
    s, lam, ratio, cfg = inputs.system, inputs.channel_arg, inputs.ratio, inputs.config
    designed = cfg is None or cfg.designed
    # None: design_online's design under the channel.
    given_z0, given_mu = (None, None) if cfg is None or cfg.designed else cfg.online
    sweep = beta_sweep(s, lam, ratio, t_max, z0=given_z0, mu=given_mu)
    bar = beta_bar(s, lam, ratio, t_max, z0=given_z0, mu=given_mu)
    z0, mu = sweep.z0, sweep.mu
    points = []
    for r, t, beta, j in zip(sweep.r, sweep.t, sweep.beta, sweep.j_attack, strict=True):
        limit = j_attack_limit(s, lam, z0, Fraction(int(r), int(t)), mu)
        better = "online" if j < sweep.j_offline else "offline"
        points.append(_Point(int(r), int(t), float(beta), float(j), float(limit), better))
    return _Result(inputs, t_max, z0, mu, designed, sweep, bar, points)


def _csv(result: _Result) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(_COLUMNS)
    for p in result.points:
        writer.writerow([p.r, p.t, repr(p.beta), repr(p.j_attack), repr(p.j_attack_limit), p.better])
    return buf.getvalue()


def _summary(result: _Result) -> dict[str, Any]:
    sweep, bar, finite = result.sweep, result.bar, result.bar.finite
    inputs = result.inputs
    return {
        "system": system_text(inputs.system),
        "lam": inputs.lam if inputs.channel is None else None,
        "channel": channel_json(inputs.channel_arg),
        "ratio": str(inputs.ratio),
        "z0": result.z0,
        "mu": result.mu,
        "designed": result.designed,
        "t_max": result.t_max,
        "count": len(sweep),
        "j_offline": sweep.j_offline,
        "j_online": sweep.j_online,
        "j_max": bar.j_max,
        "beta_bar": {
            "finite": None if finite is None else str(finite),
            "finite_value": None if finite is None else float(finite),
            "limit": bar.limit,
        },
    }


def _json(result: _Result) -> str:
    points = [{name: getattr(p, name) for name in _COLUMNS} for p in result.points]
    return to_json({"command": "sweep", **_summary(result), "points": points})


def _table(result: _Result) -> str:
    sweep, bar, lam, ratio = result.sweep, result.bar, result.inputs.lam, result.inputs.ratio
    finite = "none" if bar.finite is None else f"{bar.finite} = {float(bar.finite):.6f}"
    channel = (
        f"lam={lam:g}" if result.inputs.channel is None else f"channel {channel_text(result.inputs.channel)}"
    )
    lines = [
        *paragraph(
            f"fakeack sweep: {system_text(result.inputs.system)}; {channel}; energy ratio {ratio}; "
            f"online z0={result.z0}, mu={result.mu:.6g}"
        ),
        f"J_offline = {sweep.j_offline:.6f}   J_online = {sweep.j_online:.6f}   "
        f"J_max = {format_number(bar.j_max)}",
        f"beta-bar: t<={result.t_max}: {finite}; large-period limit: {bar.limit:.6f}",
        *paragraph(
            f"{len(sweep)} attacks r/t in lowest terms with t <= {result.t_max}, by increasing beta "
            "(J_inf: the worst attack with the same budget; better: the schedule to use against r/t)"
        ),
        "",
        f"{'r':>5} {'t':>5} {'beta':>9} {'J_attack':>11} {'J_inf(beta)':>12}  better",
    ]
    for p in result.points:
        lines.append(
            f"{p.r:>5} {p.t:>5} {p.beta:>9.6f} {p.j_attack:>11.6f} {format_number(p.j_attack_limit):>12}  "
            f"{p.better}"
        )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack sweep`` with the parsed ``args``; returns the exit code."""
    inputs = resolve_system(args)
    t_max = args.t_max
    if t_max is None:
        cfg = inputs.config
        t_max = cfg.sweep_t_max if cfg is not None and cfg.sweep_t_max else DEFAULT_T_MAX
    result = _compute(inputs, t_max)
    if args.csv:
        emit(_csv(result), args.out)
    elif args.json:
        emit(_json(result), args.out)
    else:
        emit(_table(result), args.out)
    return 0
