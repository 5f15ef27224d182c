"""Text and JSON of a :class:`fakeack.study.Analysis`, as ``reproduce`` and ``analyze`` print them."""

from __future__ import annotations

import math
import textwrap
from fractions import Fraction
from typing import Any

import numpy as np

from ..attacks.rates import online_high_power_rate
from ..model.schedules import OnlineDesign, offline_schedule
from ..model.system import LinearSystem
from ..studies.report import FLAG_SIGMAS, Analysis, Row

__all__ = [
    "analysis_json",
    "decision_lines",
    "footnotes",
    "format_number",
    "j_online_note",
    "online_text",
    "paragraph",
    "results_table",
    "system_text",
]


#: From this size on, numbers print in exponent form (a diverging J_H, e.g. under a bursty channel).
_EXPONENT_FROM = 1e12


def format_number(x: float | None, digits: int = 6) -> str:
    """``x`` with ``digits`` decimals (``digits`` significant ones in exponent form from 1e12 on);
    ``-`` for None and ``inf`` for infinity."""
    if x is None:
        return "-"
    if math.isinf(x):
        return "inf"
    if abs(x) >= _EXPONENT_FROM:
        return f"{x:.{digits}e}"
    return f"{x:.{digits}f}"


def system_text(s: LinearSystem) -> str:
    """``A=1.2, C=0.7, Q=0.8, R=0.8`` for a scalar system, else its sizes and spectral radius."""
    if s.n_x == 1 and s.n_y == 1:
        return ", ".join(f"{k}={float(m[0, 0]):g}" for k, m in zip("ACQR", (s.A, s.C, s.Q, s.R), strict=True))
    return f"n_x={s.n_x}, n_y={s.n_y}, rho(A)={s.spectral_radius:.6g}"


def online_text(online: OnlineDesign, designed: bool, lam: float, ratio: Fraction) -> str:
    """The online schedule, and whether it spends the budget exactly."""
    z0, mu = online
    text = f"online z0={z0}, mu={mu:.6g}"
    if designed:
        return text + " (design_online: spends the budget exactly)"
    rate = online_high_power_rate(lam, z0, mu)
    return text + f" (given; its high-power rate {rate:.6f} vs budget {float(ratio):.6f})"


def _table_cells(row: Row, with_mc: bool, with_paper: bool) -> list[str]:
    cells = [row.label, row.analytic_text or format_number(row.analytic), format_number(row.exact_h)]
    if with_mc:
        if row.mc is not None:
            flag = " !" if row.flagged else "  "
            cells.append(f"{format_number(row.mc)} +- {format_number(row.mc_stderr)}" + flag)
        else:
            cells.append(row.mc_text + "  ")
    if with_paper:
        cells.append(row.paper)
    return cells


def results_table(
    rows: list[Row],
    horizon: int,
    with_mc: bool,
    with_paper: bool,
    extra: tuple[str, dict[str, str]] | None = None,
) -> list[str]:
    """The results table: one line per row, columns aligned, ruled above and below.

    ``extra`` is one more column, ``(heading, text by row key)`` (``-`` where a key is missing).
    """
    head = ["quantity", "analytic", f"exact J_H (H={horizon})"]
    if with_mc:
        head.append("MC J_H +- stderr  ")
    if with_paper:
        head.append("paper")
    body = [_table_cells(row, with_mc, with_paper) for row in rows]
    if extra is not None:
        head.append(extra[0])
        for row, cells in zip(rows, body, strict=True):
            cells.append(extra[1].get(row.key, "-"))
    widths = [max(len(cells[i]) for cells in [head, *body]) for i in range(len(head))]

    def line(cells: list[str]) -> str:
        out = [cells[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(cells[1:], widths[1:], strict=True)]
        return "  ".join(out).rstrip()

    rule = "-" * len(line(head))
    return [line(head), rule, *[line(cells) for cells in body], rule]


def paragraph(text: str, width: int = 100) -> list[str]:
    """One note paragraph, wrapped with a hanging indent."""
    lead = text[: len(text) - len(text.lstrip(" "))]
    return textwrap.wrap(text, width, subsequent_indent=lead + "  ", break_on_hyphens=False) or [""]


def _monte_carlo_footnote(analysis: Analysis) -> str:
    mc = analysis.mc
    assert mc is not None
    flagged = [row.label for row in analysis.rows if row.flagged]
    verdict = (
        f"FLAGGED (|MC - exact J_H| > {FLAG_SIGMAS:g} stderr): " + ", ".join(flagged) + "."
        if flagged
        else f"All Monte Carlo rows agree with exact J_H within {FLAG_SIGMAS:g} stderr."
    )
    return (
        f"MC: {mc.runs} runs x {mc.horizon} steps, seed {mc.seed}, {mc.mode} mode, protocol "
        f"{mc.protocol}. The Monte Carlo estimates the same finite-horizon J_H (same H, same initial "
        "condition), so it is compared with exact J_H, not with the stationary value; "
        f"'!' marks a row with |MC - exact J_H| > {FLAG_SIGMAS:g} stderr. " + verdict
    )


def footnotes(analysis: Analysis) -> list[str]:
    """What each column of the table means, and the Monte Carlo verdict."""
    paras = [
        "analytic: the stationary cost J (k -> infinity). exact J_H: (1/H) sum_{k<=H} Tr E[P_k] from the "
        "paper's initial condition (high power at k=1, memory all ones, counter 0), computed without "
        "sampling (fakeack.expected_trace_curve)."
    ]
    if analysis.mc is not None:
        paras.append(_monte_carlo_footnote(analysis))
    paras.append("J_max: every flag-ACK blocked; tau is unbounded, so there is no finite Monte Carlo of it.")
    if analysis.bar is not None:
        t_max = analysis.bar.t_max
        paras.append(
            "beta-bar: large-period limit = root of J_inf(beta) = J_offline, where J_inf is the cost of "
            "blocking r of every t flag-ACKs with r, t -> infinity, r/t -> beta (the worst attacker with "
            f"budget beta); t<={t_max} = smallest r/t in lowest terms with t <= {t_max} and "
            "J_attack(r, t) >= J_offline."
        )
    return [line for para in paras for line in paragraph(para)]


def decision_lines(analysis: Analysis) -> list[str]:
    """Which schedule to use against each attack of the study."""
    if not analysis.decisions:
        return []
    out = [f"decision (keep the online schedule while J_attack < J_offline = {analysis.j_off:.6f}):"]
    for d in analysis.decisions:
        out += paragraph(
            f"  beta={d['attack']}: against this attack J = {d['j_attack']:.6f} -> "
            f"{d['choice_against_pattern']}; against the worst attack with this budget J_inf = "
            f"{format_number(d['j_attack_limit'])} -> {d['choice_against_worst_case']}"
        )
    return out


def _system_json(s: LinearSystem) -> dict[str, Any]:
    return {
        "A": s.A,
        "C": s.C,
        "Q": s.Q,
        "R": s.R,
        "n_x": s.n_x,
        "n_y": s.n_y,
        "rho_A": s.spectral_radius,
        "trace_pbar": float(np.trace(s.pbar)),
    }


def analysis_json(analysis: Analysis) -> dict[str, Any]:
    """The JSON fields shared by ``reproduce --json`` and ``analyze --json``."""
    mc, bar, online = analysis.mc, analysis.bar, analysis.online
    return {
        "system": _system_json(analysis.system),
        "lam": analysis.lam,
        "ratio": str(analysis.ratio),
        "offline_schedule": offline_schedule(analysis.ratio),
        "online": {
            "z0": online.z0,
            "mu": online.mu,
            "designed": analysis.designed,
            "high_power_rate": online_high_power_rate(analysis.lam, online.z0, online.mu),
        },
        "horizon": analysis.horizon,
        "montecarlo": None
        if mc is None
        else {
            "runs": mc.runs,
            "horizon": mc.horizon,
            "seed": mc.seed,
            "mode": mc.mode,
            "protocol": mc.protocol,
        },
        "montecarlo_note": None,  # kept in the JSON for scripts that read it; always null
        "j_offline": analysis.j_off,
        "j_online": analysis.j_on,
        "j_max": analysis.j_max,
        "rows": [row.as_dict() for row in analysis.rows],
        "flagged": [row.key for row in analysis.rows if row.flagged],
        "beta_bar": None
        if bar is None
        else {
            "t_max": bar.t_max,
            "finite": None if bar.finite is None else str(bar.finite),
            "finite_value": None if bar.finite is None else float(bar.finite),
            "limit": bar.limit,
        },
        "decisions": analysis.decisions,
        "elapsed_s": round(analysis.elapsed, 3),
    }


def j_online_note(analysis: Analysis) -> str:
    """The note on the paper's J_online = 1.6399 (Model notes 2 and 7)."""
    printed, model = "1.6399", f"{analysis.j_on:.4f}"
    one_digit = len(printed) == len(model) and sum(a != b for a, b in zip(printed, model, strict=True)) == 1
    typo = (
        f" The two differ in one digit only ({printed} vs {model}), as if that digit were misprinted."
        if one_digit
        else ""
    )
    mc = ""
    row = next((r for r in analysis.rows if r.key == "j_online"), None)
    if row is not None and row.mc is not None and row.z is not None:
        mc = (
            f" The Monte Carlo gives {row.mc:.4f} at H={analysis.horizon} "
            f"({row.z:+.1f} stderr from the exact J_H)."
        )
    return (
        f"note: the paper prints J_online = {printed}; the corrected model gives {analysis.j_on:.6f}"
        " (Model note 2: here mu=1, so J_on = lam/(1-a^(z0+1)) sum_(i<=z0) a^i tr_i, a = 1-lam)."
        + mc
        + " Model note 7: the printed Sec. V numbers are finite Monte Carlo values and one of them is"
        " misprinted." + typo + " Nothing here is tuned to the printed values."
    )
