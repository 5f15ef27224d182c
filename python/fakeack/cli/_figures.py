"""The figures ``reproduce`` and ``analyze --out`` write (PNG and SVG, atomically)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..attacks.chain import attack_chain, stationary_distribution
from ..attacks.kinds import PeriodicBlocking
from ..attacks.threshold import BetaBar, BetaSweep, j_attack_limit
from ..plots import save_figure
from ..studies.report import Analysis
from ._report import system_text

__all__ = ["write_figures"]


def _mu_text(analysis: Analysis) -> str:
    mu = analysis.online.mu
    return "" if mu == 1.0 else f", $\\mu={mu:.4g}$"


def _jk_figure(analysis: Analysis) -> Any:
    """Fig. 3: J_k of every schedule of the study, Monte Carlo and exact."""
    from .. import plots

    k = np.arange(1, analysis.horizon + 1)
    curves = [plots.JkCurve(c.label, k, c.mc, c.exact, c.stationary) for c in analysis.curves]
    title = (
        f"{system_text(analysis.system)}, $\\lambda={analysis.lam:g}$, energy ratio {analysis.ratio}, "
        f"$z_0={analysis.online.z0}${_mu_text(analysis)}"
    )
    return plots.plot_jk(curves, title=title, mc_runs=None if analysis.mc is None else analysis.mc.runs)


def _beta_figure(analysis: Analysis, sweep: BetaSweep, bar: BetaBar, paper_beta_bar: float | None) -> Any:
    """Fig. 4: the sweep, the large-period limit on a grid of budgets and both thresholds."""
    from .. import plots

    z0, mu = analysis.online
    grid = np.linspace(0.0, 1.0, 401)
    limit = np.array([j_attack_limit(analysis.system, analysis.lam, z0, b, mu) for b in grid])
    title = (
        f"attacked cost against the budget ($z_0={z0}${_mu_text(analysis)}, "
        f"$\\lambda={analysis.lam:g}$, ratio {analysis.ratio})"
    )
    return plots.plot_beta_sweep(sweep, bar, grid, limit, paper_beta_bar=paper_beta_bar, title=title)


def _stationary_figure(analysis: Analysis, attack: PeriodicBlocking) -> Any:
    """Heat map of the stationary law of (tau, sigma) under ``attack``."""
    from .. import plots

    z0 = analysis.online.z0
    states, _ = attack_chain(analysis.lam, z0, attack.r, attack.t)
    pi = stationary_distribution(analysis.lam, z0, attack.r, attack.t)
    title = (
        f"stationary law of $(\\tau, \\sigma)$: $z_0={z0}$, attack "
        f"$r/t={attack.label}$, $\\lambda={analysis.lam:g}$"
    )
    return plots.plot_stationary(states, pi, r=attack.r, title=title)


def write_figures(
    analysis: Analysis,
    outdir: Path,
    *,
    paper_beta_bar: float | None,
    stationary: PeriodicBlocking | None,
) -> list[Path]:
    """Draw and save fig3_jk, fig4_beta (if a sweep) and fig_stationary (if ``stationary``)."""
    from .. import plots

    if not plots.have_matplotlib():
        print(
            "note: figures skipped: matplotlib is not installed (pip install 'fakeack[plot]')",
            file=sys.stderr,
        )
        return []
    written = save_figure(_jk_figure(analysis), outdir, "fig3_jk")
    if analysis.sweep is not None and analysis.bar is not None:
        written += save_figure(
            _beta_figure(analysis, analysis.sweep, analysis.bar, paper_beta_bar), outdir, "fig4_beta"
        )
    if stationary is not None:
        written += save_figure(_stationary_figure(analysis, stationary), outdir, "fig_stationary")
    return written
