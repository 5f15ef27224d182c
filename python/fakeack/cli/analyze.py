"""``fakeack analyze``: the study of :mod:`fakeack.studies.report` for the system of a TOML config."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..attacks.kinds import PeriodicBlocking
from ..config.analyze import Config, ConfigError, example_text, load_config, loads, parse_config
from ..model.schedules import offline_schedule
from ..studies.report import Analysis, analyse
from ._figures import write_figures
from ._io import atomic_write, to_json
from ._other import attack_rows
from ._report import (
    analysis_json,
    decision_lines,
    footnotes,
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
    attack = _heat_map_attack(cfg)
    figures = write_figures(analysis, out, paper_beta_bar=None, stationary=attack)
    if attack is None and figures:
        why = "mu < 1" if cfg.online.mu != 1.0 else "no attack with r > 0, or the chain is too large"
        print(
            f"note: fig_stationary skipped ({why}; the heat map needs mu = 1 and one attack)",
            file=sys.stderr,
        )
    return figures


def _offline_text(cfg: Config) -> str:
    if cfg.ratio.denominator <= 40:
        return "".join(map(str, offline_schedule(cfg.ratio)))
    return f"period {cfg.ratio.denominator}"


def _text(cfg: Config, analysis: Analysis, other: list[str], out: str | None, figures: list[Path]) -> str:
    lines = [
        f"fakeack analyze: {cfg.source}",
        f"  system {system_text(cfg.system)}; Tr Pbar = {float(np.trace(cfg.system.pbar)):.6f}",
        f"  lam={cfg.lam:g}; energy ratio {cfg.ratio}; offline schedule " + _offline_text(cfg),
        f"  {online_text(cfg.online, cfg.designed, cfg.lam, cfg.ratio)}",
        "",
        *results_table(analysis.rows, analysis.horizon, with_mc=analysis.mc is not None, with_paper=False),
        *footnotes(analysis),
        "",
        *decision_lines(analysis),
        *([""] + other if other else []),
    ]
    if not cfg.designed and analysis.bar is not None:
        lines += paragraph(
            "note: J_offline is the offline cost at the budget's energy; the online schedule given in "
            "[online] may spend more or less than the budget."
        )
    if out:
        lines += paragraph(f"wrote {len(figures)} figure files and analysis.json in {Path(out)}/")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack analyze`` with the parsed ``args``; returns the exit code."""
    if args.example:
        if args.config:
            raise ConfigError("config: give either CONFIG.toml or --example, not both")
        sys.stdout.write(example_text())
        return 0
    cfg = _read_config(args)
    analysis = analyse(
        cfg.system, cfg.lam, cfg.ratio, cfg.online, cfg.designed, cfg.attacks, cfg.sweep_t_max, cfg.montecarlo
    )
    figures: list[Path] = []
    if args.out and not args.no_figures:
        figures = _figures(cfg, analysis, Path(args.out))
    other, other_json = attack_rows(cfg.system, cfg.lam, cfg.ratio, cfg.online, cfg.other_attacks)
    document = {"command": "analyze", "config": cfg.source, **analysis_json(analysis), "figures": figures}
    if other_json:
        document["other_attacks"] = other_json
    if args.out:
        atomic_write(Path(args.out) / "analysis.json", to_json(document) + "\n")
    if args.json:
        print(to_json(document))
        return 0
    print(_text(cfg, analysis, other, args.out, figures))
    return 0
