"""The figures ``reproduce`` and ``analyze --out`` write (PNG and SVG, atomically)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..attacks.chain import attack_chain, stationary_distribution
from ..attacks.kinds import PeriodicBlocking
from ..attacks.threshold import BetaBar, BetaSweep, j_attack_limit
from ..model.channels import Channel
from ..plots import save_figure
from ..studies.report import Analysis
from ._channel import channel_short
from ._report import system_text

__all__ = ["write_figures"]


def _mu_text(analysis: Analysis) -> str:
    mu = analysis.online.mu
    return "" if mu == 1.0 else f", $\\mu={mu:.4g}$"


def _channel_title(analysis: Analysis, channel: Channel | None) -> str:
    """``$\\lambda=0.5$`` for the paper's channel, else the channel's short label."""
    return f"$\\lambda={analysis.lam:g}$" if channel is None else channel_short(channel)


def _jk_figure(analysis: Analysis, channel: Channel | None = None) -> Any:
    """Fig. 3: J_k of every schedule of the study, Monte Carlo and exact."""
    from .. import plots

    k = np.arange(1, analysis.horizon + 1)
    curves = [plots.JkCurve(c.label, k, c.mc, c.exact, c.stationary) for c in analysis.curves]
    title = (
        f"{system_text(analysis.system)}, {_channel_title(analysis, channel)}, "
        f"energy ratio {analysis.ratio}, $z_0={analysis.online.z0}${_mu_text(analysis)}"
    )
    return plots.plot_jk(curves, title=title, mc_runs=None if analysis.mc is None else analysis.mc.runs)


def _beta_figure(
    analysis: Analysis,
    sweep: BetaSweep,
    bar: BetaBar,
    paper_beta_bar: float | None,
    channel: Channel | None = None,
) -> Any:
    """Fig. 4: the sweep, the large-period limit on a grid of budgets and both thresholds."""
    from .. import plots

    z0, mu = analysis.online
    grid = np.linspace(0.0, 1.0, 401)
    link: float | Channel = analysis.lam if channel is None else channel
    limit = np.array([j_attack_limit(analysis.system, link, z0, b, mu) for b in grid])
    title = (
        f"attacked cost against the budget ($z_0={z0}${_mu_text(analysis)}, "
        f"{_channel_title(analysis, channel)}, ratio {analysis.ratio})"
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
    channel: Channel | None = None,
) -> list[Path]:
    """Draw and save fig3_jk, fig4_beta (if a sweep) and fig_stationary (if ``stationary``).

    ``channel`` is the channel of a study that is not the paper's (:mod:`fakeack.cli._channel_study`):
    the titles name it and the large-period limit is computed under it. fig_stationary is the
    i.i.d. chain's, so it needs ``channel`` None.
    """
    from .. import plots

    if not plots.have_matplotlib():
        print(
            "note: figures skipped: matplotlib is not installed (pip install 'fakeack[plot]')",
            file=sys.stderr,
        )
        return []
    written = save_figure(_jk_figure(analysis, channel), outdir, "fig3_jk")
    if analysis.sweep is not None and analysis.bar is not None:
        written += save_figure(
            _beta_figure(analysis, analysis.sweep, analysis.bar, paper_beta_bar, channel), outdir, "fig4_beta"
        )
    if stationary is not None and channel is None:
        written += save_figure(_stationary_figure(analysis, stationary), outdir, "fig_stationary")
    return written
