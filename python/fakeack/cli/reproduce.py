"""``fakeack reproduce``: the paper's Sec. V, exact, by Monte Carlo and as printed, with figures."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..config import MonteCarloConfig
from ..schedules import design_online, offline_schedule
from ..study import (
    PAPER_ATTACKS,
    PAPER_BETA_BAR,
    PAPER_LAM,
    PAPER_PRINTED,
    PAPER_RATIO,
    PAPER_SYSTEM,
    STATIONARY_EXAMPLE,
    Analysis,
    analyse,
)
from ..system import LinearSystem
from ._figures import write_figures
from ._io import to_json
from ._report import (
    analysis_json,
    decision_lines,
    footnotes,
    j_online_note,
    online_text,
    paragraph,
    results_table,
    system_text,
)

__all__ = ["run"]

_PAPER_NOTE = (
    "paper: the values printed in Sec. V (a 100000-run Monte Carlo of unstated horizon; '-' = not "
    "printed). Its beta-bar ~0.28 is read off a figure and rests on a definition it does not give "
    "(Model note 7)."
)


def _text(analysis: Analysis, figures: list[Path], out: Path, started: float) -> str:
    lines = [
        "fakeack reproduce: the paper's example (Sec. V)",
        f"  system {system_text(analysis.system)}; lam={PAPER_LAM}; energy ratio {PAPER_RATIO}",
        f"  offline schedule {''.join(map(str, offline_schedule(PAPER_RATIO)))} (period "
        f"{PAPER_RATIO.denominator}); {online_text(analysis.online, True, PAPER_LAM, PAPER_RATIO)}",
        "",
        *results_table(analysis.rows, analysis.horizon, with_mc=True, with_paper=True),
        *footnotes(analysis),
        *paragraph(_PAPER_NOTE),
        *paragraph(j_online_note(analysis)),
        "",
        *decision_lines(analysis),
    ]
    if figures:
        lines += paragraph(f"figures in {out}/: {', '.join(p.name for p in figures)}")
    lines.append(f"done in {time.perf_counter() - started:.1f} s")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack reproduce`` with the parsed ``args``; returns the exit code."""
    mc = None if args.runs == 0 else MonteCarloConfig(args.runs, args.horizon, args.seed)
    analysis = analyse(
        LinearSystem(**PAPER_SYSTEM),
        PAPER_LAM,
        PAPER_RATIO,
        design_online(PAPER_LAM, PAPER_RATIO),
        True,
        PAPER_ATTACKS,
        args.t_max,
        mc,
        horizon=args.horizon,
        paper=PAPER_PRINTED,
    )
    out = Path(args.out)
    figures: list[Path] = []
    if not args.no_figures:
        figures = write_figures(analysis, out, paper_beta_bar=PAPER_BETA_BAR, stationary=STATIONARY_EXAMPLE)
    if args.json:
        document = {
            "command": "reproduce",
            **analysis_json(analysis),
            "paper": {**PAPER_PRINTED, "source": "Sec. V, 100000-run Monte Carlo (Model note 7)"},
            "notes": [j_online_note(analysis)],
            "figures": figures,
        }
        print(to_json(document))
        return 0
    print(_text(analysis, figures, out, args.start))
    return 0
