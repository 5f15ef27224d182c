"""The study of ``fakeack analyze`` under a channel that is not the paper's, and the i.i.d.
channel of the same mean beside it.

:func:`analyse_channel` is :func:`fakeack.studies.report.analyse` under the channel with the
best offline pattern of :func:`fakeack.offline_search` as the offline schedule. Its
:class:`~fakeack.studies.report.Analysis` has the same rows, so the same table, footnotes and
decisions print it; its ``lam`` field holds the channel's mean low-power arrival probability,
and :class:`ChannelStudy` carries the channel.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from ..attacks.kinds import PeriodicBlocking
from ..attacks.rates import high_power_rate
from ..config.analyze import Config, MonteCarloConfig
from ..model.channels import Channel, is_paper_channel
from ..model.offline import offline_search
from ..model.schedules import OfflineSchedule, OnlineDesign, design_online, j_online, offline_schedule
from ..model.system import LinearSystem
from ..studies.report import DEFAULT_HORIZON, Analysis, analyse
from ._channel import iid_twin
from ._report import format_number

__all__ = ["ChannelStudy", "Twin", "analyse_channel", "study_channel", "twin_values"]


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
    J_max's exact J_H is that of the online schedule with every flag-ACK blocked, from the paper's
    initial condition like the other rows.

    Returns
    -------
    (Analysis, str)
        The study (``lam`` = the channel's mean low-power arrival probability) and the offline
        pattern as 0/1 text.
    """
    search = offline_search(s, ch, ratio)
    pattern = _pattern_text(search.pattern)
    offline = (OfflineSchedule(pattern=pattern), search.j)
    analysis = analyse(s, ch, ratio, online, designed, attacks, t_max, mc, horizon, offline=offline)
    return analysis, pattern


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
