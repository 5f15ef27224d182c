"""Text, JSON and figure output of a :class:`fakeack.study.Analysis`."""

from __future__ import annotations

import io
import math
import sys
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from ._cli_io import _frac, atomic_write
from .attack import attack_chain, stationary_distribution
from .attacks import PeriodicBlocking
from .schedules import (
    OnlineDesign,
    offline_schedule,
    online_high_power_rate,
)
from .study import FLAG_SIGMAS, Analysis, Row
from .system import LinearSystem
from .threshold import j_attack_limit


def _fmt(x: float | None, digits: int = 6) -> str:
    if x is None:
        return "-"
    if math.isinf(x):
        return "inf"
    return f"{x:.{digits}f}"


def _system_text(s: LinearSystem) -> str:
    if s.n_x == 1 and s.n_y == 1:
        return ", ".join(f"{k}={float(m[0, 0]):g}" for k, m in zip("ACQR", (s.A, s.C, s.Q, s.R), strict=True))
    return f"n_x={s.n_x}, n_y={s.n_y}, rho(A)={s.spectral_radius:.6g}"


def _online_text(online: OnlineDesign, designed: bool, lam: float, ratio: Fraction) -> str:
    z0, mu = online
    text = f"online z0={z0}, mu={mu:.6g}"
    if designed:
        return text + " (design_online: spends the budget exactly)"
    rate = online_high_power_rate(lam, z0, mu)
    return text + f" (given; its high-power rate {rate:.6f} vs budget {float(ratio):.6f})"


def _table(rows: list[Row], horizon: int, with_mc: bool, with_paper: bool) -> list[str]:
    head = ["quantity", "analytic", f"exact J_H (H={horizon})"]
    if with_mc:
        head.append("MC J_H +- stderr  ")
    if with_paper:
        head.append("paper")
    body = []
    for r in rows:
        cells = [r.label, r.analytic_text or _fmt(r.analytic), _fmt(r.exact_h)]
        if with_mc:
            if r.mc is not None:
                cells.append(f"{_fmt(r.mc)} +- {_fmt(r.mc_stderr)}" + (" !" if r.flagged else "  "))
            else:
                cells.append(r.mc_text + "  ")
        if with_paper:
            cells.append(r.paper)
        body.append(cells)
    widths = [max(len(c[i]) for c in [head, *body]) for i in range(len(head))]

    def line(cells: list[str]) -> str:
        out = [cells[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(cells[1:], widths[1:], strict=True)]
        return "  ".join(out).rstrip()

    rule = "-" * len(line(head))
    return [line(head), rule, *[line(c) for c in body], rule]


def _para(text: str, width: int = 100) -> list[str]:
    """One note paragraph, wrapped with a hanging indent."""
    import textwrap

    lead = text[: len(text) - len(text.lstrip(" "))]
    return textwrap.wrap(text, width, subsequent_indent=lead + "  ", break_on_hyphens=False) or [""]


def _footnotes(an: Analysis) -> list[str]:
    paras = [
        "analytic: the stationary cost J (k -> infinity). exact J_H: (1/H) sum_{k<=H} Tr E[P_k] from the "
        "paper's initial condition (high power at k=1, memory all ones, counter 0), computed without "
        "sampling (fakeack.expected_trace_curve)."
    ]
    if an.mc is not None:
        flagged = [r.label for r in an.rows if r.flagged]
        verdict = (
            f"FLAGGED (|MC - exact J_H| > {FLAG_SIGMAS:g} stderr): " + ", ".join(flagged) + "."
            if flagged
            else f"All Monte Carlo rows agree with exact J_H within {FLAG_SIGMAS:g} stderr."
        )
        paras.append(
            f"MC: {an.mc.runs} runs x {an.mc.horizon} steps, seed {an.mc.seed}, {an.mc.mode} mode, protocol "
            f"{an.mc.protocol}. The Monte Carlo estimates the same finite-horizon J_H (same H, same initial "
            "condition), so it is compared with exact J_H, not with the stationary value; "
            f"'!' marks a row with |MC - exact J_H| > {FLAG_SIGMAS:g} stderr. " + verdict
        )
    elif an.mc_note:
        paras.append(an.mc_note + ".")
    paras.append("J_max: every flag-ACK blocked; tau is unbounded, so there is no finite Monte Carlo of it.")
    if an.bar is not None:
        paras.append(
            "beta-bar: large-period limit = root of J_inf(beta) = J_offline, where J_inf is the cost of "
            "blocking r of every t flag-ACKs with r, t -> infinity, r/t -> beta (the worst attacker with "
            f"budget beta); t<={an.bar.t_max} = smallest r/t in lowest terms with t <= {an.bar.t_max} and "
            "J_attack(r, t) >= J_offline."
        )
    return [ln for p in paras for ln in _para(p)]


def _decision_lines(an: Analysis) -> list[str]:
    if not an.decisions:
        return []
    out = [f"decision (keep the online schedule while J_attack < J_offline = {an.j_off:.6f}):"]
    for d in an.decisions:
        out += _para(
            f"  beta={d['attack']}: against this attack J = {d['j_attack']:.6f} -> "
            f"{d['choice_against_pattern']}; against the worst attack with this budget J_inf = "
            f"{_fmt(d['j_attack_limit'])} -> {d['choice_against_worst_case']}"
        )
    return out


def _analysis_json(an: Analysis) -> dict[str, Any]:
    s = an.system
    return {
        "system": {
            "A": s.A,
            "C": s.C,
            "Q": s.Q,
            "R": s.R,
            "n_x": s.n_x,
            "n_y": s.n_y,
            "rho_A": s.spectral_radius,
            "trace_pbar": float(np.trace(s.pbar)),
        },
        "lam": an.lam,
        "ratio": _frac(an.ratio),
        "offline_schedule": offline_schedule(an.ratio),
        "online": {
            "z0": an.online.z0,
            "mu": an.online.mu,
            "designed": an.designed,
            "high_power_rate": online_high_power_rate(an.lam, an.online.z0, an.online.mu),
        },
        "horizon": an.horizon,
        "montecarlo": None
        if an.mc is None
        else {
            "runs": an.mc.runs,
            "horizon": an.mc.horizon,
            "seed": an.mc.seed,
            "mode": an.mc.mode,
            "protocol": an.mc.protocol,
        },
        "montecarlo_note": an.mc_note,
        "j_offline": an.j_off,
        "j_online": an.j_on,
        "j_max": an.j_max,
        "rows": [r.as_dict() for r in an.rows],
        "flagged": [r.key for r in an.rows if r.flagged],
        "beta_bar": None
        if an.bar is None
        else {
            "t_max": an.bar.t_max,
            "finite": None if an.bar.finite is None else _frac(an.bar.finite),
            "finite_value": None if an.bar.finite is None else float(an.bar.finite),
            "limit": an.bar.limit,
        },
        "decisions": an.decisions,
        "elapsed_s": round(an.elapsed, 3),
    }


# ------------------------------------------------------------------------------- figures


def _write_figures(
    an: Analysis, outdir: Path, *, paper_beta_bar: float | None, stationary: PeriodicBlocking | None
) -> list[Path]:
    """Draw and save fig3_jk, fig4_beta (if a sweep) and fig_stationary (if ``stationary``)."""
    from . import plots

    if not plots.have_matplotlib():
        print(
            "note: figures skipped: matplotlib is not installed (pip install 'fakeack[plot]')",
            file=sys.stderr,
        )
        return []
    import matplotlib

    written: list[Path] = []

    def save(fig: Any, stem: str) -> None:
        for ext in ("png", "svg"):
            buf = io.BytesIO()
            meta = {"Software": None} if ext == "png" else {"Date": None}
            with matplotlib.rc_context({"svg.hashsalt": "fakeack"}):
                fig.savefig(buf, format=ext, dpi=150, metadata=meta)
            written.append(atomic_write(outdir / f"{stem}.{ext}", buf.getvalue()))

    z0, mu = an.online
    mu_txt = "" if mu == 1.0 else f", $\\mu={mu:.4g}$"
    sys_txt = _system_text(an.system)
    curves = [
        plots.JkCurve(c.label, np.arange(1, an.horizon + 1), c.mc, c.exact, c.stationary) for c in an.curves
    ]
    save(
        plots.plot_jk(
            curves,
            title=f"{sys_txt}, $\\lambda={an.lam:g}$, energy ratio {_frac(an.ratio)}, $z_0={z0}${mu_txt}",
            mc_runs=None if an.mc is None else an.mc.runs,
        ),
        "fig3_jk",
    )
    if an.sweep is not None and an.bar is not None:
        grid = np.linspace(0.0, 1.0, 401)
        lim = np.array([j_attack_limit(an.system, an.lam, z0, b, mu) for b in grid])
        save(
            plots.plot_beta_sweep(
                an.sweep,
                an.bar,
                grid,
                lim,
                paper_beta_bar=paper_beta_bar,
                title=f"attacked cost against the budget ($z_0={z0}${mu_txt}, "
                f"$\\lambda={an.lam:g}$, ratio {_frac(an.ratio)})",
            ),
            "fig4_beta",
        )
    if stationary is not None:
        states, _ = attack_chain(an.lam, z0, stationary.r, stationary.t)
        pi = stationary_distribution(an.lam, z0, stationary.r, stationary.t)
        save(
            plots.plot_stationary(
                states,
                pi,
                r=stationary.r,
                title=f"stationary law of $(\\tau, \\sigma)$: $z_0={z0}$, attack "
                f"$r/t={stationary.label}$, $\\lambda={an.lam:g}$",
            ),
            "fig_stationary",
        )
    return written


# ------------------------------------------------------------------------------- commands




def _j_online_note(an: Analysis) -> str:
    """The note on the paper's J_online = 1.6399 (ERRATA items 2 and 7)."""
    printed, model = "1.6399", f"{an.j_on:.4f}"
    diff = [i for i, (a, b) in enumerate(zip(printed, model, strict=True)) if a != b]
    typo = (
        f" The two differ in one digit only ({printed} vs {model}), as if that digit were misprinted."
        if len(printed) == len(model) and len(diff) == 1
        else ""
    )
    mc = ""
    row = next((r for r in an.rows if r.key == "j_online"), None)
    if row is not None and row.mc is not None and row.z is not None:
        mc = (
            f" The Monte Carlo gives {row.mc:.4f} at H={an.horizon} ({row.z:+.1f} stderr from the exact J_H)."
        )
    return (
        f"note: the paper prints J_online = {printed}; the corrected model gives {an.j_on:.6f}"
        " (ERRATA 2: here mu = 1, so J_on = lam/(1-a^(z0+1)) sum_(i<=z0) a^i tr_i, a = 1-lam)."
        + mc
        + " ERRATA 7: the printed Sec. V numbers are finite Monte Carlo values and one of them is misprinted."
        + typo
        + " Nothing here is tuned to the printed values."
    )
