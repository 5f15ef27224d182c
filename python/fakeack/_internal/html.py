"""HTML summaries for Jupyter (``_repr_html_``) of the result objects: small tables, no arrays dumped."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from fractions import Fraction
from html import escape
from typing import Any

__all__ = [
    "number",
    "table",
    "key_values",
    "analysis",
]


_STYLE = "border-collapse:collapse;font-variant-numeric:tabular-nums;margin:0.4em 0"
_CELL = "padding:0.15em 0.6em;text-align:{align};border-bottom:1px solid #ddd"


def number(x: Any, digits: int = 6) -> str:
    """``x`` for a table: fractions as p/q, floats with ``digits`` decimals, None as a dash."""
    if x is None:
        return "–"
    if isinstance(x, Fraction):
        return f"{x.numerator}/{x.denominator} ≈ {float(x):.{digits}f}"
    if isinstance(x, float):
        return "inf" if math.isinf(x) else f"{x:.{digits}f}"
    return str(x)


def _row(cells: Sequence[str], tag: str = "td") -> str:
    out = []
    for i, c in enumerate(cells):
        align = "left" if i == 0 else "right"
        out.append(f'<{tag} style="{_CELL.format(align=align)}">{escape(c)}</{tag}>')
    return "<tr>" + "".join(out) + "</tr>"


def table(title: str, head: Sequence[str] | None, rows: Iterable[Sequence[str]], note: str = "") -> str:
    """A titled HTML table; the first column is left-aligned, the others right-aligned (numbers)."""
    caption = f'<caption style="text-align:left;font-weight:bold">{escape(title)}</caption>'
    parts = [f'<table style="{_STYLE}">{caption}']
    if head:
        parts.append("<thead>" + _row(head, "th") + "</thead>")
    parts.append("<tbody>" + "".join(_row(r) for r in rows) + "</tbody></table>")
    if note:
        parts.append(f'<div style="font-size:smaller;max-width:50em">{escape(note)}</div>')
    return "".join(parts)


def key_values(title: str, items: Iterable[tuple[str, Any]], note: str = "") -> str:
    """A two-column table of named values."""
    return table(title, None, [(k, number(v)) for k, v in items], note)


def analysis(a: Any) -> str:
    """The study's results table and decisions (a :class:`fakeack.study.Analysis`)."""
    with_mc = a.mc is not None
    with_paper = any(row.paper != "-" for row in a.rows)
    head = ["quantity", "analytic", f"exact J_H (H={a.horizon})"]
    head += ["Monte Carlo J_H ± stderr"] if with_mc else []
    head += ["paper"] if with_paper else []
    rows = []
    for row in a.rows:
        cells = [row.label, row.analytic_text or number(row.analytic), number(row.exact_h)]
        if with_mc:
            mc = row.mc_text if row.mc is None else f"{row.mc:.6f} ± {row.mc_stderr:.6f}"
            cells.append(mc + (" !" if row.flagged else ""))
        if with_paper:
            cells.append(row.paper)
        rows.append(cells)
    z0, mu = a.online
    title = f"Study: lam={a.lam:g}, energy ratio {a.ratio}, online z0={z0}, mu={mu:g}"
    note = "'!' marks a Monte Carlo row more than 4 standard errors from the exact J_H." if with_mc else ""
    out = table(title, head, rows, note)
    if a.decisions:
        out += table(
            f"Decision (keep the online schedule while J_attack < J_offline = {a.j_off:.6f})",
            ["attack β", "J against this pattern", "choice", "J against the worst attack", "choice"],
            [
                (
                    d["attack"],
                    number(d["j_attack"]),
                    d["choice_against_pattern"],
                    number(d["j_attack_limit"]),
                    d["choice_against_worst_case"],
                )
                for d in a.decisions
            ],
        )
    return out
