"""``fakeack reproduce``: the paper's Sec. V, exact, by Monte Carlo and as printed, with figures."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..config.analyze import MonteCarloConfig
from ..model.schedules import design_online, offline_schedule
from ..model.system import LinearSystem
from ..studies.report import (
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
from ._figures import write_figures
from ._io import to_json
from ._other import family_figure, reproduce_lines
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


#: The paper's energies (Sec. V): Delta = 3, delta = 1 and Psi = 9/7 give the ratio 1/7.
PAPER_DELTA, PAPER_DELTA_LOW = 3.0, 1.0


def _other_attacks(analysis: Analysis) -> tuple[list[str], dict]:
    bar = analysis.bar
    return reproduce_lines(
        analysis.system,
        PAPER_LAM,
        PAPER_RATIO,
        PAPER_DELTA,
        PAPER_DELTA_LOW,
        None if bar is None else bar.limit,
        None if bar is None else bar.finite,
    )


def _text(analysis: Analysis, other: list[str], figures: list[Path], out: Path, started: float) -> str:
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
        "",
        *other,
    ]
    if figures:
        lines += paragraph(f"figures in {out}/: {', '.join(p.name for p in figures)}")
    lines.append(f"done in {time.perf_counter() - started:.1f} s")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack reproduce`` with the parsed ``args``; returns the exit code."""
    mc = None if args.runs == 0 else MonteCarloConfig(args.runs, args.horizon, args.seed)
    analysis = analyse(
        LinearSystem(*(PAPER_SYSTEM[k] for k in "ACQR")),
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
        figures += family_figure(analysis.system, PAPER_LAM, PAPER_RATIO, PAPER_DELTA, PAPER_DELTA_LOW, out)
    other, other_json = _other_attacks(analysis)
    if args.json:
        document = {
            "command": "reproduce",
            **analysis_json(analysis),
            "paper": {**PAPER_PRINTED, "source": "Sec. V, 100000-run Monte Carlo (Model note 7)"},
            "notes": [j_online_note(analysis)],
            "other_attacks": other_json,
            "figures": figures,
        }
        print(to_json(document))
        return 0
    print(_text(analysis, other, figures, out, args.start))
    return 0
