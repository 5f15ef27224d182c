"""The "other attacks" block of ``fakeack reproduce`` and ``fakeack analyze``: independent
blocking and forged flag-ACKs beside the paper's periodic attack."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import Any

from ..attacks.chain import j_attack
from ..attacks.families import attack_families, other_attacks_table
from ..attacks.random import beta_bar_random
from ..attacks.rates import high_power_rate
from ..model.channels import Channel
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem
from ..plots import plot_attack_families, save_figure
from ._report import format_number

__all__ = ["attack_rows", "family_figure", "reproduce_lines"]


def reproduce_lines(
    system: LinearSystem,
    lam: float,
    ratio: Fraction,
    delta_hi: float,
    delta_lo: float,
    beta_bar_limit: float | None,
    beta_bar_finite: Fraction | None,
) -> tuple[list[str], dict[str, Any]]:
    """The table of the paper's example under the other attacks (text lines and JSON)."""
    rows, bar_random = other_attacks_table(system, lam, ratio, delta_hi, delta_lo)
    psi = delta_lo + (delta_hi - delta_lo) * float(ratio)
    lines = [
        f"other attacks (beyond the paper; energy per step with Delta={delta_hi:g}, delta={delta_lo:g}, "
        f"budget Psi={psi:.6f}):",
        f"  {'attack':<44} {'J':>10} {'energy/step':>12}",
        *(f"  {r.label:<44} {format_number(r.j):>10} {r.energy:>12.6f}" for r in rows),
        f"  beta-bar against random blocking: {bar_random:.6f} (periodic: large period "
        f"{format_number(beta_bar_limit)}, t<=60 {beta_bar_finite if beta_bar_finite else '-'})",
    ]
    document = {
        "rows": [{"attack": r.label, "j": r.j, "energy_per_step": r.energy} for r in rows],
        "beta_bar_random": bar_random,
        "psi": psi,
    }
    return lines, document


def attack_rows(
    system: LinearSystem,
    lam: float | Channel,
    ratio: Fraction,
    online: OnlineDesign,
    attacks: tuple[Any, ...],
    iid: tuple[float | Channel, OnlineDesign] | None = None,
) -> tuple[list[str], dict[str, Any]]:
    """Rows for the config's ``[attack] random`` and ``inject`` (J and high-power rate).

    ``lam`` is the channel (a float: the paper's). ``iid``, the i.i.d. channel of the same mean
    and its online schedule, adds a column with J under it.
    """
    if not attacks:
        return [], {}
    z0, mu = online
    rate0 = high_power_rate(lam, z0, None, mu)
    iid_head = "" if iid is None else f" {'J (i.i.d.)':>11}"
    lines = [
        f"other attacks (exact; high-power rate = share of steps at high power, {rate0:.6f} without attack):",
        f"  {'attack':<52} {'J':>10} {'high-power rate':>16}{iid_head}",
    ]
    rows = []
    for att in attacks:
        j = j_attack(system, lam, z0, mu=mu, attack=att)
        rate = high_power_rate(lam, z0, att, mu)
        row: dict[str, Any] = {"attack": att.label, "j": j, "high_power_rate": rate}
        line = f"  {str(att):<52} {format_number(j):>10} {rate:>16.6f}"
        if iid is not None:
            row["j_iid"] = j_attack(system, iid[0], iid[1].z0, mu=iid[1].mu, attack=att)
            line += f" {format_number(row['j_iid']):>11}"
        lines.append(line)
        rows.append(row)
    bar = beta_bar_random(system, lam, ratio, z0, mu)
    doc: dict[str, Any] = {"rows": rows, "beta_bar_random": bar}
    text = f"  beta-bar against random blocking: {bar:.6f}"
    if iid is not None:
        doc["beta_bar_random_iid"] = beta_bar_random(system, iid[0], ratio, iid[1].z0, iid[1].mu)
        text += f" (i.i.d.: {doc['beta_bar_random_iid']:.6f})"
    lines.append(text)
    return lines, doc


def family_figure(
    system: LinearSystem, lam: float, ratio: Fraction, delta_hi: float, delta_lo: float, out: Path
) -> list[Path]:
    """fig_attack_families (PNG + SVG): J and energy per step against beta for each family."""
    from .. import plots

    if not plots.have_matplotlib():
        return []
    # The figure lives on its own Agg canvas, outside pyplot: nothing to close after saving.
    fig = plot_attack_families(attack_families(system, lam, ratio, delta_hi, delta_lo))
    return save_figure(fig, out, "fig_attack_families")
