"""The study of ``fakeack analyze`` under a channel that is not the paper's, and the i.i.d.
channel of the same mean beside it.

:func:`fakeack.studies.report.analyse` takes the paper's ``lam``; :func:`analyse_channel` is the
same study for any channel, built from the functions that take one: :func:`fakeack.offline_search`
(the best offline pattern), :func:`fakeack.j_online`, :func:`fakeack.j_attack`,
:func:`fakeack.j_max`, :func:`fakeack.beta_sweep`, :func:`fakeack.beta_bar`,
:func:`fakeack.j_attack_limit`, the exact curves of :func:`fakeack.expected_trace_curve` and the
Monte Carlo of :func:`fakeack.simulate`. Its :class:`~fakeack.studies.report.Analysis` has the
same rows, so the same table, footnotes and decisions print it; its ``lam`` field holds the
channel's mean low-power arrival probability, and :class:`ChannelStudy` carries the channel.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from ..attacks.chain import j_attack
from ..attacks.kinds import PeriodicBlocking, RandomBlocking
from ..attacks.rates import high_power_rate
from ..attacks.threshold import BetaBar, beta_bar, beta_sweep, j_attack_limit
from ..config.analyze import Config, MonteCarloConfig
from ..model.channels import Channel, is_paper_channel
from ..model.offline import offline_search
from ..model.schedules import OfflineSchedule, OnlineDesign, design_online, j_max, j_online, offline_schedule
from ..model.system import LinearSystem
from ..montecarlo.curves import expected_trace_curve
from ..montecarlo.protocol import simulate
from ..studies.report import DEFAULT_HORIZON, Analysis, Curve, Row, analyse
from ._channel import iid_twin
from ._report import format_number

__all__ = ["ChannelStudy", "Twin", "analyse_channel", "study_channel", "twin_values"]

#: ``RandomBlocking(1)`` blocks every flag-ACK: the attack of J_max.
_ALL_BLOCKED = RandomBlocking(1.0)


@dataclass(frozen=True)
class Twin:
    """The i.i.d. channel of the same mean, with its own online schedule, and its study."""

    channel: Channel
    online: OnlineDesign
    analysis: Analysis
    offline_pattern: str
    rate: float  # the high-power rate of ``online`` under ``channel``

    @property
    def arg(self) -> float | Channel:
        """The channel as the analysis functions take it (a float ``lam`` for the paper's)."""
        return float(self.channel.low[0]) if is_paper_channel(self.channel) else self.channel


@dataclass(frozen=True)
class ChannelStudy:
    """:func:`analyse_channel` for a config's channel, and the i.i.d. twin beside it.

    ``analysis`` holds the values under ``channel`` (its ``lam`` is the mean low-power arrival
    probability); ``iid_design_rate`` and ``iid_design_j`` are the high-power rate and J_on of
    the twin's online design used under ``channel``: what a design for i.i.d. losses does there.
    """

    channel: Channel
    analysis: Analysis
    offline_pattern: str
    rate: float
    twin: Twin
    iid_design_rate: float
    iid_design_j: float


def _threshold_rows(bar: BetaBar) -> list[Row]:
    finite, t_max = bar.finite, bar.t_max
    return [
        Row("beta_bar_limit", "beta-bar (large-period limit)", analytic=bar.limit, mc_text="n/a"),
        Row(
            "beta_bar_finite",
            f"beta-bar (t<={t_max})",
            analytic=None if finite is None else float(finite),
            analytic_text=f"none with t<={t_max}" if finite is None else f"{finite} = {float(finite):.6f}",
            mc_text="n/a",
        ),
    ]


def _decisions(
    s: LinearSystem, ch: Channel, online: OnlineDesign, attacks: Sequence[PeriodicBlocking], j_off: float
) -> list[dict[str, Any]]:
    z0, mu = online
    out = []
    for a in attacks:
        j_pattern = j_attack(s, ch, z0, mu=mu, attack=a)
        j_worst = j_attack_limit(s, ch, z0, a.beta, mu)
        out.append(
            {
                "attack": a.label,
                "beta": float(a.beta),
                "j_attack": j_pattern,
                "j_attack_limit": j_worst,
                "choice_against_pattern": "online" if j_pattern < j_off else "offline",
                "choice_against_worst_case": "online" if j_worst < j_off else "offline",
            }
        )
    return out


def analyse_channel(
    s: LinearSystem,
    ch: Channel,
    ratio: Fraction,
    online: OnlineDesign,
    designed: bool,
    attacks: Sequence[PeriodicBlocking],
    t_max: int | None,
    mc: MonteCarloConfig | None,
    horizon: int = DEFAULT_HORIZON,
) -> tuple[Analysis, str]:
    """:func:`fakeack.studies.report.analyse` under any channel, and the offline pattern used.

    The offline schedule is the best pattern of density ``ratio`` under ``ch``
    (:func:`fakeack.offline_search`; the evenly spread one of Theorem 3.1 on an i.i.d. channel);
    J_max's exact J_H is that of the online schedule with every flag-ACK blocked
    (``RandomBlocking(1)``), from the paper's initial condition like the other rows.

    Returns
    -------
    (Analysis, str)
        The study (``lam`` = the channel's mean low-power arrival probability) and the offline
        pattern as 0/1 text.
    """
    start = time.perf_counter()
    H = mc.horizon if mc is not None else horizon
    z0, mu = online
    search = offline_search(s, ch, ratio)
    offline = OfflineSchedule(pattern=_pattern_text(search.pattern))
    cases: list[tuple[str, str, str, OfflineSchedule | OnlineDesign, PeriodicBlocking | None, float]] = [
        ("j_offline", "J_offline", "offline", offline, None, search.j),
        ("j_online", "J_online", "online, no attack", online, None, j_online(s, ch, z0, mu)),
    ]
    for a in attacks:
        label = f"online, attack $\\beta$ = {a.label}"
        cases.append(
            (
                f"j_attack_{a.label}",
                f"J_attack beta={a.label}",
                label,
                online,
                a,
                j_attack(s, ch, z0, mu=mu, attack=a),
            )
        )
    rows: list[Row] = []
    curves: list[Curve] = []
    for key, label, curve_label, sched, attack, stationary in cases:
        exact = expected_trace_curve(s, ch, sched, H, attack).j_k
        row = Row(
            key,
            label,
            analytic=stationary,
            exact_h=float(exact[-1]),
            mc_text="skipped" if mc is None else "-",
        )
        mc_curve = None
        if mc is not None:
            res = simulate(
                s,
                ch,
                sched,
                horizon=mc.horizon,
                runs=mc.runs,
                seed=mc.seed,
                attack=attack,
                mode=mc.mode,
                protocol=mc.protocol,
            )
            row.mc, row.mc_stderr, mc_curve = res.j, res.stderr, res.j_k
        rows.append(row)
        curves.append(Curve(curve_label, exact, mc_curve, stationary))
    j_all = j_max(s, ch)
    exact_all = float(expected_trace_curve(s, ch, online, H, _ALL_BLOCKED).j_k[-1])
    rows.append(Row("j_max", "J_max (all blocked)", analytic=j_all, exact_h=exact_all))
    sweep = bar = None
    if t_max is not None:
        z, m = (None, None) if designed else (z0, mu)
        sweep = beta_sweep(s, ch, ratio, t_max, z0=z, mu=m)
        bar = beta_bar(s, ch, ratio, t_max, z0=z, mu=m)
        rows += _threshold_rows(bar)
    analysis = Analysis(
        system=s,
        lam=ch.mean_low,
        ratio=ratio,
        online=online,
        designed=designed,
        attacks=tuple(attacks),
        horizon=H,
        mc=mc,
        rows=rows,
        curves=curves,
        j_off=search.j,
        j_on=cases[1][5],
        j_max=j_all,
        sweep=sweep,
        bar=bar,
        decisions=_decisions(s, ch, online, attacks, search.j),
        elapsed=time.perf_counter() - start,
    )
    return analysis, _pattern_text(search.pattern)


def _pattern_text(pattern: Any) -> str:
    return "".join(str(int(b)) for b in pattern)


def study_channel(cfg: Config) -> ChannelStudy:
    """The study of ``cfg`` (whose channel is not the paper's) and of its i.i.d. twin.

    The twin's online schedule is its own design (:func:`fakeack.design_online` under the twin)
    when ``cfg``'s is designed, else the same ``(z0, mu)``; the twin gets no Monte Carlo.
    """
    ch = cfg.channel
    assert ch is not None  # the paper's channel goes through fakeack.studies.report.analyse
    analysis, pattern = analyse_channel(
        cfg.system, ch, cfg.ratio, cfg.online, cfg.designed, cfg.attacks, cfg.sweep_t_max, cfg.montecarlo
    )
    twin_ch = iid_twin(ch)
    twin_arg: float | Channel = float(twin_ch.low[0]) if is_paper_channel(twin_ch) else twin_ch
    twin_online = design_online(twin_arg, cfg.ratio) if cfg.designed else cfg.online
    if isinstance(twin_arg, float):
        twin_analysis = analyse(
            cfg.system,
            twin_arg,
            cfg.ratio,
            twin_online,
            cfg.designed,
            cfg.attacks,
            cfg.sweep_t_max,
            None,
            analysis.horizon,
        )
        twin_pattern = _pattern_text(offline_schedule(cfg.ratio))
    else:
        twin_analysis, twin_pattern = analyse_channel(
            cfg.system,
            twin_ch,
            cfg.ratio,
            twin_online,
            cfg.designed,
            cfg.attacks,
            cfg.sweep_t_max,
            None,
            analysis.horizon,
        )
    z0, mu = twin_online
    twin = Twin(twin_ch, twin_online, twin_analysis, twin_pattern, high_power_rate(twin_arg, z0, mu=mu))
    return ChannelStudy(
        channel=ch,
        analysis=analysis,
        offline_pattern=pattern,
        rate=high_power_rate(ch, cfg.online.z0, mu=cfg.online.mu),
        twin=twin,
        iid_design_rate=high_power_rate(ch, z0, mu=mu),
        iid_design_j=j_online(cfg.system, ch, z0, mu),
    )


def twin_values(twin: Twin) -> dict[str, str]:
    """The twin's analytic value of each row, by row key, as the table prints it."""
    return {row.key: row.analytic_text or format_number(row.analytic) for row in twin.analysis.rows}
