"""``fakeack analyze``: the study of :mod:`fakeack.studies.report` for the system of a TOML config.

On the paper's channel (``[system] lam``) the study is :func:`fakeack.studies.report.analyse`. Under
another ``[channel]`` it is :func:`fakeack.cli._channel_study.study_channel`: the same table for the
channel, with a column for the i.i.d. channel of the same mean (its own design, offline schedule,
costs and thresholds), and the same in ``--json`` under ``"iid"``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..attacks.kinds import PeriodicBlocking
from ..config.analyze import Config, ConfigError, example_text, load_config, loads, parse_config
from ..model.schedules import offline_schedule
from ..studies.report import Analysis, analyse
from ._channel import channel_json, channel_label, channel_text
from ._channel_study import ChannelStudy, study_channel, twin_values
from ._figures import write_figures
from ._io import atomic_write, to_json
from ._other import attack_rows
from ._report import (
    analysis_json,
    decision_lines,
    footnotes,
    format_number,
    online_text,
    paragraph,
    results_table,
    system_text,
)

__all__ = ["run"]

#: Largest (tau, sigma) extent of the heat map of the stationary law.
_MAX_HEAT_MAP = 400


def _read_config(args: argparse.Namespace) -> Config:
    if not args.config:
        raise ConfigError("config: give a CONFIG.toml file (fakeack analyze --example prints one)")
    if args.config == "-":
        return parse_config(loads(sys.stdin.read(), "<stdin>"), "<stdin>")
    return load_config(args.config)


def _heat_map_attack(cfg: Config) -> PeriodicBlocking | None:
    """The attack whose stationary law is drawn: the largest budget (then period), if the chain is small."""
    candidates = [a for a in cfg.attacks if a.r > 0]
    if cfg.online.mu != 1.0 or not candidates:
        return None
    attack = max(candidates, key=lambda a: (a.beta, a.t))
    if cfg.online.z0 * (attack.r + 1) > _MAX_HEAT_MAP or attack.t > _MAX_HEAT_MAP:
        return None
    return attack


def _figures(cfg: Config, analysis: Analysis, out: Path) -> list[Path]:
    attack = _heat_map_attack(cfg) if cfg.paper_channel else None
    figures = write_figures(analysis, out, paper_beta_bar=None, stationary=attack, channel=cfg.channel)
    if attack is None and figures:
        if not cfg.paper_channel:
            why = "the heat map of (tau, sigma) is drawn on the paper's channel only"
        else:
            why = "mu < 1" if cfg.online.mu != 1.0 else "no attack with r > 0, or the chain is too large"
            why += "; the heat map needs mu = 1 and one attack"
        print(f"note: fig_stationary skipped ({why})", file=sys.stderr)
    return figures


def _offline_text(cfg: Config) -> str:
    if cfg.ratio.denominator <= 40:
        return "".join(map(str, offline_schedule(cfg.ratio)))
    return f"period {cfg.ratio.denominator}"


def _text(cfg: Config, analysis: Analysis, other: list[str], out: str | None, figures: list[Path]) -> str:
    lines = [
        f"fakeack analyze: {cfg.source}",
        f"  system {system_text(cfg.system)}; Tr Pbar = {float(np.trace(cfg.system.pbar)):.6f}",
        f"  channel i.i.d., lam={cfg.lam:g}; energy ratio {cfg.ratio}; offline schedule "
        + _offline_text(cfg),
        f"  {online_text(cfg.online, cfg.designed, cfg.lam, cfg.ratio)}",
        "",
        *results_table(analysis.rows, analysis.horizon, with_mc=analysis.mc is not None, with_paper=False),
        *footnotes(analysis),
        "",
        *decision_lines(analysis),
        *([""] + other if other else []),
    ]
    return "\n".join(lines + _closing(cfg, analysis, out, figures))


def _closing(cfg: Config, analysis: Analysis, out: str | None, figures: list[Path]) -> list[str]:
    """The notes after the decisions: a given online schedule, the files written."""
    lines: list[str] = []
    if not cfg.designed and analysis.bar is not None:
        lines += paragraph(
            "note: J_offline is the offline cost at the budget's energy; the online schedule given in "
            "[online] may spend more or less than the budget."
        )
    if out:
        lines += paragraph(f"wrote {len(figures)} figure files and analysis.json in {Path(out)}/")
    return lines


def _pattern_text(pattern: str) -> str:
    return pattern if len(pattern) <= 40 else f"period {len(pattern)}"


def _online_channel_text(cfg: Config, study: ChannelStudy) -> str:
    """The online schedule under the channel, and whether it spends the budget exactly."""
    z0, mu = cfg.online
    text = f"online z0={z0}, mu={mu:.6g}"
    if cfg.designed:
        return text + " (design_online under the channel: spends the budget exactly)"
    return (
        text
        + f" (given; its high-power rate under the channel {study.rate:.6f} vs budget {float(cfg.ratio):.6f})"
    )


def _twin_text(cfg: Config, study: ChannelStudy) -> str:
    """What the i.i.d. column is; for a designed schedule, what the i.i.d. design does here."""
    twin = study.twin
    z0, mu = twin.online
    pattern = _pattern_text(twin.offline_pattern)
    if not cfg.designed:
        same = f"the same z0={z0}, mu={mu:.6g}"
        return f"the i.i.d. channel of the same mean, with {same} and offline schedule {pattern}."
    return (
        f"the i.i.d. channel of the same mean, with its own design z0={z0}, mu={mu:.6g} and offline "
        f"schedule {pattern}. That design, made for i.i.d. losses, has the high-power rate "
        f"{study.iid_design_rate:.6f} under this channel (budget {float(cfg.ratio):.6f}) and J_on = "
        f"{format_number(study.iid_design_j)}."
    )


def _channel_text(
    cfg: Config, study: ChannelStudy, other: list[str], out: str | None, figures: list[Path]
) -> str:
    """The report under a channel that is not the paper's, the i.i.d. twin beside it."""
    analysis, twin = study.analysis, study.twin
    column = channel_label(twin.channel)
    lines = [
        f"fakeack analyze: {cfg.source}",
        f"  system {system_text(cfg.system)}; Tr Pbar = {float(np.trace(cfg.system.pbar)):.6f}",
        *paragraph(f"  channel {channel_text(study.channel)}"),
        f"  energy ratio {cfg.ratio}; offline schedule {_pattern_text(study.offline_pattern)} "
        "(the best pattern of this density under the channel)",
        f"  {_online_channel_text(cfg, study)}",
        *paragraph(f"  column '{column}': {_twin_text(cfg, study)}"),
        "",
        *results_table(
            analysis.rows,
            analysis.horizon,
            with_mc=analysis.mc is not None,
            with_paper=False,
            extra=(column, twin_values(twin)),
        ),
        *footnotes(analysis),
        *paragraph(
            f"{column}: the stationary value under the i.i.d. channel of the same mean (no Monte Carlo): "
            "what the analysis gives if the losses are taken to be independent."
        ),
    ]
    if analysis.j_max == math.inf:
        lines += paragraph(
            "J_max = inf: with every flag-ACK blocked the expected error grows without bound under this "
            "channel, so an attacker who blocks long enough runs makes the online cost unbounded (the "
            "large-period beta-bar is 0; docs page 'Bursty channels')."
        )
    lines += ["", *decision_lines(analysis), *([""] + other if other else [])]
    return "\n".join(lines + _closing(cfg, analysis, out, figures))


def _twin_json(study: ChannelStudy) -> dict[str, Any]:
    """The i.i.d. channel of the same mean, as ``analyze --json`` gives it under ``"iid"``."""
    twin, analysis = study.twin, study.twin.analysis
    doc = analysis_json(analysis)
    return {
        "channel": channel_json(twin.channel),
        "lam": float(twin.channel.low[0]),
        "offline_schedule": [int(c) for c in twin.offline_pattern],
        "online": {
            "z0": twin.online.z0,
            "mu": twin.online.mu,
            "designed": analysis.designed,
            "high_power_rate": twin.rate,
        },
        "j_offline": analysis.j_off,
        "j_online": analysis.j_on,
        "j_max": analysis.j_max,
        "rows": [{"key": r.key, "label": r.label, "analytic": r.analytic} for r in analysis.rows],
        "beta_bar": doc["beta_bar"],
        "decisions": analysis.decisions,
        "design_under_channel": {
            "high_power_rate": study.iid_design_rate,
            "j_online": study.iid_design_j,
        },
    }


def _document(cfg: Config, analysis: Analysis, study: ChannelStudy | None) -> dict[str, Any]:
    """The ``--json`` document: the study, the channel, and (bursty) the i.i.d. twin."""
    document: dict[str, Any] = {"command": "analyze", "config": cfg.source}
    for key, value in analysis_json(analysis).items():
        document[key] = value
        if key == "lam":
            document["channel"] = channel_json(cfg.channel_arg)
    if study is not None:
        document["lam"] = None  # not the paper's channel: see "channel" (and "iid")
        document["offline_schedule"] = [int(c) for c in study.offline_pattern]
        document["online"]["high_power_rate"] = study.rate
        document["iid"] = _twin_json(study)
    return document


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack analyze`` with the parsed ``args``; returns the exit code."""
    if args.example:
        if args.config:
            raise ConfigError("config: give either CONFIG.toml or --example, not both")
        sys.stdout.write(example_text())
        return 0
    cfg = _read_config(args)
    study: ChannelStudy | None = None
    if cfg.paper_channel:
        analysis = analyse(
            cfg.system,
            cfg.lam,
            cfg.ratio,
            cfg.online,
            cfg.designed,
            cfg.attacks,
            cfg.sweep_t_max,
            cfg.montecarlo,
        )
    else:
        study = study_channel(cfg)
        analysis = study.analysis
    figures: list[Path] = []
    if args.out and not args.no_figures:
        figures = _figures(cfg, analysis, Path(args.out))
    iid = None if study is None else (study.twin.arg, study.twin.online)
    other, other_json = attack_rows(
        cfg.system, cfg.channel_arg, cfg.ratio, cfg.online, cfg.other_attacks, iid
    )
    document = {**_document(cfg, analysis, study), "figures": figures}
    if other_json:
        document["other_attacks"] = other_json
    if args.out:
        atomic_write(Path(args.out) / "analysis.json", to_json(document) + "\n")
    if args.json:
        print(to_json(document))
        return 0
    if study is None:
        print(_text(cfg, analysis, other, args.out, figures))
    else:
        print(_channel_text(cfg, study, other, args.out, figures))
    return 0
