"""A complete study of one system: every cost, both thresholds, the Monte Carlo checks and the exact curves.

Used by ``fakeack reproduce`` and ``fakeack analyze``; importable from scripts (:func:`analyse`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np

from ..attacks.chain import j_attack
from ..attacks.kinds import Attack, PeriodicBlocking, RandomBlocking
from ..attacks.threshold import BetaBar, BetaSweep, beta_bar, beta_sweep, j_attack_limit
from ..config.analyze import MonteCarloConfig
from ..model.channels import Channel
from ..model.schedules import OfflineSchedule, OnlineDesign, OnlineSchedule, j_max, j_offline, j_online
from ..model.system import LinearSystem
from ..montecarlo.curves import expected_trace_curve
from ..montecarlo.protocol import SimulationResult, simulate

# Defaults of `fakeack reproduce`: the paper's 100000 runs; with the compiled Monte Carlo the whole
# command (4 x 2e7 simulated steps, 6 figure files) measured about 3 s wall time on 2 cores.
DEFAULT_RUNS = 100_000
DEFAULT_HORIZON = 200
DEFAULT_SEED = 1
DEFAULT_T_MAX = 60
DEFAULT_OUT = "fakeack-out"

# The paper's system (Sec. V) and the values it prints.
PAPER_SYSTEM = {"A": 1.2, "C": 0.7, "Q": 0.8, "R": 0.8}
PAPER_LAM = 0.5
PAPER_RATIO = Fraction(1, 7)
PAPER_ATTACKS = (PeriodicBlocking(1, 5), PeriodicBlocking(2, 3))
PAPER_PRINTED = {
    "j_offline": "2.0953",
    "j_online": "1.6399",
    "beta_bar_limit": "~0.28",
    "beta_bar_finite": "~0.28",
}
PAPER_BETA_BAR = 0.28
# The heat map of the stationary law: a longer attack than the paper's 2/3 shows more structure.
STATIONARY_EXAMPLE = PeriodicBlocking(4, 9)

FLAG_SIGMAS = 4.0


@dataclass
class Row:
    """One line of a results table."""

    key: str
    label: str
    analytic: float | None = None
    analytic_text: str | None = None
    exact_h: float | None = None
    mc: float | None = None
    mc_stderr: float | None = None
    mc_text: str = "-"
    paper: str = "-"

    @property
    def z(self) -> float | None:
        """(MC - exact J_H) / stderr."""
        if self.mc is None or self.exact_h is None or self.mc_stderr is None:
            return None
        diff = self.mc - self.exact_h
        if self.mc_stderr > 0:
            return diff / self.mc_stderr
        return 0.0 if abs(diff) <= 1e-12 * max(1.0, abs(self.exact_h)) else math.inf

    @property
    def flagged(self) -> bool:
        """Whether ``|MC - exact J_H| > 4 stderr``."""
        z = self.z
        return z is not None and abs(z) > FLAG_SIGMAS

    def as_dict(self) -> dict[str, Any]:
        """JSON form."""
        d: dict[str, Any] = {
            "key": self.key,
            "label": self.label,
            "analytic": self.analytic,
            "exact_h": self.exact_h,
            "mc": self.mc,
            "mc_stderr": self.mc_stderr,
            "mc_z": self.z,
            "flagged": self.flagged,
            "paper": None if self.paper == "-" else self.paper,
        }
        if self.analytic_text is not None:
            d["analytic_text"] = self.analytic_text
        return d


@dataclass
class Curve:
    """J_k curves of one schedule."""

    label: str
    exact: np.ndarray
    mc: np.ndarray | None
    stationary: float


@dataclass
class Analysis:
    """Everything ``reproduce`` and ``analyze`` print, save and plot."""

    system: LinearSystem
    lam: float
    ratio: Fraction
    online: OnlineDesign
    designed: bool
    attacks: tuple[PeriodicBlocking, ...]
    horizon: int
    mc: MonteCarloConfig | None
    rows: list[Row]
    curves: list[Curve]
    j_off: float
    j_on: float
    j_max: float
    sweep: BetaSweep | None = None
    bar: BetaBar | None = None
    decisions: list[dict[str, Any]] = field(default_factory=list)
    elapsed: float = 0.0

    def __repr__(self) -> str:
        z0, mu = self.online
        return (
            f"Analysis(lam={self.lam:g}, ratio={self.ratio}, z0={z0}, mu={mu:g}, J_offline={self.j_off:.6g}, "
            f"J_online={self.j_on:.6g}, {len(self.rows)} rows, {len(self.decisions)} decisions)"
        )

    def _repr_html_(self) -> str:
        from .._internal import html as _html

        return _html.analysis(self)


def _exact_j_max_curve(s: LinearSystem, lam: float, horizon: int) -> np.ndarray:
    r"""Exact J_k with every flag-ACK blocked.

    From the initial arrival, :math:`\mathbb E\,\mathrm{Tr}P_k = \lambda\sum_{i\le k-2} w_i + w_{k-1}`
    with :math:`w_i = a^i\,\mathrm{tr}_i`.
    """
    w = s.weighted_traces(1.0 - lam, horizon)  # w_i = a^i tr_i
    c = np.cumsum(w)
    k = np.arange(1, horizon + 1)
    trace = w[k - 1] + lam * np.concatenate(([0.0], c[: horizon - 1]))
    return np.cumsum(trace) / k


def run_monte_carlo(
    s: LinearSystem,
    lam: float | Channel,
    sched: OfflineSchedule | OnlineDesign,
    mc: MonteCarloConfig,
    attack: Attack | None,
) -> SimulationResult:
    """:func:`fakeack.simulate` with the settings of ``mc`` (``lam``: a float or any channel)."""
    return simulate(
        s,
        lam,
        sched,
        horizon=mc.horizon,
        runs=mc.runs,
        seed=mc.seed,
        attack=attack,
        mode=mc.mode,
        protocol=mc.protocol,
    )


@dataclass(frozen=True)
class _Case:
    """One schedule of the study: a table row and a J_k curve."""

    key: str
    label: str
    curve_label: str
    schedule: OfflineSchedule | OnlineSchedule
    attack: PeriodicBlocking | None
    stationary: float


def _cases(
    s: LinearSystem,
    lam: float | Channel,
    ratio: Fraction,
    online: OnlineDesign,
    attacks: Sequence[PeriodicBlocking],
    offline: tuple[OfflineSchedule, float] | None,
) -> list[_Case]:
    """Offline (Theorem 3.1's, or ``offline``: a schedule and its J), online without attack, then
    online under each attack."""
    z0, mu = online
    on = OnlineSchedule(z0, mu)
    off, j_off = (OfflineSchedule(ratio), j_offline(s, lam, ratio)) if offline is None else offline
    cases = [
        _Case("j_offline", "J_offline", "offline", off, None, j_off),
        _Case("j_online", "J_online", "online, no attack", on, None, j_online(s, lam, z0, mu)),
    ]
    for a in attacks:
        cases.append(
            _Case(
                f"j_attack_{a.label}",
                f"J_attack beta={a.label}",
                f"online, attack $\\beta$ = {a.label}",
                on,
                a,
                j_attack(s, lam, z0, a.r, a.t, mu),
            )
        )
    return cases


def _evaluate(
    case: _Case,
    s: LinearSystem,
    lam: float | Channel,
    horizon: int,
    mc: MonteCarloConfig | None,
    paper: dict[str, str],
) -> tuple[Row, Curve]:
    """The case's stationary, exact finite-horizon and (if ``mc``) Monte Carlo cost."""
    exact = expected_trace_curve(s, lam, case.schedule, horizon, case.attack).j_k
    row = Row(
        case.key,
        case.label,
        analytic=case.stationary,
        exact_h=float(exact[-1]),
        mc_text="skipped" if mc is None else "-",
        paper=paper.get(case.key, "-"),
    )
    mc_curve = None
    if mc is not None:
        result = run_monte_carlo(s, lam, case.schedule, mc, case.attack)
        row.mc, row.mc_stderr, mc_curve = result.j, result.stderr, result.j_k
    return row, Curve(case.curve_label, exact, mc_curve, case.stationary)


def sweep_and_thresholds(
    system: LinearSystem, lam: float | Channel, ratio: Fraction, online: OnlineDesign | None, t_max: int
) -> tuple[BetaSweep, BetaBar]:
    """The beta sweep and both thresholds, for the online schedule given or (None) designed."""
    z0, mu = (None, None) if online is None else online
    return (
        beta_sweep(system, lam, ratio, t_max, z0=z0, mu=mu),
        beta_bar(system, lam, ratio, t_max, z0=z0, mu=mu),
    )


def _threshold_rows(bar: BetaBar, paper: dict[str, str]) -> list[Row]:
    """Both beta-bar rows (no Monte Carlo of a threshold)."""
    finite, t_max = bar.finite, bar.t_max
    return [
        Row(
            "beta_bar_limit",
            "beta-bar (large-period limit)",
            analytic=bar.limit,
            mc_text="n/a",
            paper=paper.get("beta_bar_limit", "-"),
        ),
        Row(
            "beta_bar_finite",
            f"beta-bar (t<={t_max})",
            analytic=None if finite is None else float(finite),
            analytic_text=f"none with t<={t_max}" if finite is None else f"{finite} = {float(finite):.6f}",
            mc_text="n/a",
            paper=paper.get("beta_bar_finite", "-"),
        ),
    ]


def _decisions(
    s: LinearSystem,
    lam: float | Channel,
    online: OnlineDesign,
    attacks: Sequence[PeriodicBlocking],
    j_off: float,
) -> list[dict[str, Any]]:
    """For each attack: the schedule to use against it, and against the worst attack of its budget."""
    z0, mu = online
    decisions = []
    for a in attacks:
        j_pattern = j_attack(s, lam, z0, a.r, a.t, mu)
        j_worst = j_attack_limit(s, lam, z0, a.beta, mu)
        decisions.append(
            {
                "attack": a.label,
                "beta": float(a.beta),
                "j_attack": j_pattern,
                "j_attack_limit": j_worst,
                "choice_against_pattern": "online" if j_pattern < j_off else "offline",
                "choice_against_worst_case": "online" if j_worst < j_off else "offline",
            }
        )
    return decisions


def analyse(
    s: LinearSystem,
    lam: float | Channel,
    ratio: Fraction,
    online: OnlineDesign,
    designed: bool,
    attacks: Sequence[PeriodicBlocking],
    t_max: int | None,
    mc: MonteCarloConfig | None,
    horizon: int = DEFAULT_HORIZON,
    paper: dict[str, str] | None = None,
    offline: tuple[OfflineSchedule, float] | None = None,
) -> Analysis:
    """Stationary, exact finite-horizon and Monte Carlo costs of the offline, online and attacked
    schedules, J_max, and (if ``t_max``) the sweep and both thresholds.

    Parameters
    ----------
    s : LinearSystem
        The process and sensor.
    lam : float or Channel
        Arrival probability at low power (the paper's channel), or any channel; the study's
        ``lam`` is then the channel's mean low-power arrival probability.
    ratio : fractions.Fraction
        Energy ratio p/q.
    online : OnlineDesign
        ``(z0, mu)`` of the online schedule.
    designed : bool
        Whether ``online`` is :func:`fakeack.design_online` ``(lam, ratio)``.
    attacks : sequence of PeriodicBlocking
        The attacks to evaluate.
    t_max : int or None
        Largest attack period of the sweep; None skips sweep and thresholds.
    mc : MonteCarloConfig or None
        Monte Carlo settings; None skips it. Its horizon overrides ``horizon``.
    horizon : int, optional
        Horizon of the exact finite-horizon curves when there is no Monte Carlo.
    paper : dict, optional
        Printed values by row key, for the ``paper`` column.
    offline : (OfflineSchedule, float), optional
        The offline schedule and its J (default: Theorem 3.1's pattern, :func:`fakeack.j_offline`).

    Returns
    -------
    Analysis
    """
    start = time.perf_counter()
    paper = paper or {}
    H = mc.horizon if mc is not None else horizon
    cases = _cases(s, lam, ratio, online, attacks, offline)
    j_off, j_on, j_all_blocked = cases[0].stationary, cases[1].stationary, j_max(s, lam)
    rows: list[Row] = []
    curves: list[Curve] = []
    for case in cases:
        row, curve = _evaluate(case, s, lam, H, mc, paper)
        rows.append(row)
        curves.append(curve)
    if isinstance(lam, Channel):
        # Every flag-ACK blocked from the paper's initial condition, like the other rows.
        exact_j_max = float(expected_trace_curve(s, lam, online, H, RandomBlocking(1.0)).j_k[-1])
    else:
        exact_j_max = float(_exact_j_max_curve(s, lam, H)[-1])
    paper_j_max = paper.get("j_max", "-")
    rows.append(
        Row("j_max", "J_max (all blocked)", analytic=j_all_blocked, exact_h=exact_j_max, paper=paper_j_max)
    )

    sweep = bar = None
    if t_max is not None:
        sweep, bar = sweep_and_thresholds(s, lam, ratio, None if designed else online, t_max)
        rows += _threshold_rows(bar, paper)
    return Analysis(
        system=s,
        lam=lam.mean_low if isinstance(lam, Channel) else lam,
        ratio=ratio,
        online=online,
        designed=designed,
        attacks=tuple(attacks),
        horizon=H,
        mc=mc,
        rows=rows,
        curves=curves,
        j_off=j_off,
        j_on=j_on,
        j_max=j_all_blocked,
        sweep=sweep,
        bar=bar,
        decisions=_decisions(s, lam, online, attacks, j_off),
        elapsed=time.perf_counter() - start,
    )
