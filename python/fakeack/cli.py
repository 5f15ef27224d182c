"""The ``fakeack`` command line.

Sub-commands: ``reproduce`` (the paper's Sec. V with exact and Monte Carlo values and figures),
``analyze`` (a TOML config, see :mod:`fakeack.config`), ``sweep`` (the attacked cost over every
r/t) and ``simulate`` (one Monte Carlo run set against its exact finite-horizon value).

Exit codes: 0 success, 1 a runtime failure (a file that cannot be written, a missing compiled
feature), 2 bad arguments or config (``fakeack: error: ...``), 130 interrupted (Ctrl-C). Every
output file is written atomically (temporary file in the same directory, then ``os.replace``), so
an interrupted run never leaves a half-written file.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__, _fakeack
from .attack import attack_chain, j_attack, stationary_distribution
from .config import (
    AttackSpec,
    Config,
    ConfigError,
    MonteCarloConfig,
    example_text,
    load_config,
    loads,
    parse_attack,
    parse_config,
)
from .montecarlo import OfflineSchedule, OnlineSchedule, SimulationResult, expected_trace_curve, simulate
from .schedules import (
    OnlineDesign,
    design_online,
    j_max,
    j_offline,
    j_online,
    offline_schedule,
    online_high_power_rate,
)
from .system import LinearSystem
from .threshold import BetaBar, BetaSweep, beta_bar, beta_sweep, j_attack_limit

__all__ = ["atomic_write", "main"]

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
PAPER_ATTACKS = (AttackSpec(1, 5), AttackSpec(2, 3))
PAPER_PRINTED = {
    "j_offline": "2.0953",
    "j_online": "1.6399",
    "beta_bar_limit": "~0.28",
    "beta_bar_finite": "~0.28",
}
PAPER_BETA_BAR = 0.28
# The heat map of the stationary law: a longer attack than the paper's 2/3 shows more structure.
STATIONARY_EXAMPLE = AttackSpec(4, 9)

FLAG_SIGMAS = 4.0


class CliError(Exception):
    """A failure reported as ``fakeack: error: ...`` with its own exit code."""

    def __init__(self, message: str, code: int = 1):
        super().__init__(message)
        self.code = code


# ------------------------------------------------------------------------------- file output


def _default_mode(path: Path) -> int:
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def atomic_write(path: str | os.PathLike[str], data: bytes | str) -> Path:
    """Write a file atomically: a temporary file in the same directory, then ``os.replace``.

    Readers see either the old file or the complete new one; if writing fails or is interrupted
    (including ``KeyboardInterrupt``) the temporary file is removed and the target is untouched.

    Parameters
    ----------
    path : str or os.PathLike
        Destination. Missing parent directories are created.
    data : bytes or str
        Contents; text is encoded as UTF-8.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    p = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    parent = p.parent
    parent.mkdir(parents=True, exist_ok=True)
    mode = _default_mode(p)
    fd, tmp = tempfile.mkstemp(dir=parent, prefix=f".{p.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return p


def _emit(text: str, out: str | None) -> None:
    """Print ``text`` or write it atomically to ``out``."""
    if out is None:
        sys.stdout.write(text if text.endswith("\n") else text + "\n")
        sys.stdout.flush()
    else:
        atomic_write(out, text if text.endswith("\n") else text + "\n")
        print(f"wrote {out}", file=sys.stderr)


def _jsonable(x: Any) -> Any:
    """Replace non-finite floats (not valid JSON) by None; numpy and Fractions by plain types."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, Fraction):
        return _frac(x)
    if isinstance(x, Path):
        return str(x)
    return x


def _dumps(obj: Any) -> str:
    return json.dumps(_jsonable(obj), indent=2, allow_nan=False)


def _frac(x: Fraction) -> str:
    return str(x.numerator) if x.denominator == 1 else f"{x.numerator}/{x.denominator}"


# ------------------------------------------------------------------------------- computation


def _mc_available() -> bool:
    return hasattr(_fakeack, "simulate")


_MC_MISSING = (
    "Monte Carlo skipped: this build of the compiled core has no simulate "
    "(fakeack._fakeack.simulate); rebuild the package to enable it"
)


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
    attacks: tuple[AttackSpec, ...]
    horizon: int
    mc: MonteCarloConfig | None
    mc_note: str | None
    rows: list[Row]
    curves: list[Curve]
    j_off: float
    j_on: float
    j_max: float
    sweep: BetaSweep | None = None
    bar: BetaBar | None = None
    decisions: list[dict[str, Any]] = field(default_factory=list)
    elapsed: float = 0.0


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


def _custom_threshold(
    s: LinearSystem, lam: float, ratio: Fraction, z0: int, mu: float, t_max: int
) -> tuple[BetaSweep, BetaBar]:
    """beta_sweep / beta_bar for an online schedule that is not the energy-matched design."""
    pairs = sorted(
        ((r, t) for t in range(2, t_max + 1) for r in range(1, t) if math.gcd(r, t) == 1),
        key=lambda p: Fraction(*p),
    )
    rr = np.array([p[0] for p in pairs], dtype=np.uint32)
    tt = np.array([p[1] for p in pairs], dtype=np.uint32)
    jj = np.array([j_attack(s, lam, z0, r, t, mu) for r, t in pairs])
    joff, jon, jmx = j_offline(s, lam, ratio), j_online(s, lam, z0, mu), j_max(s, lam)
    sw = BetaSweep(rr, tt, rr / tt, jj, joff, jon, z0, mu, lam, ratio)
    hit = np.nonzero(jj >= joff)[0]
    finite = Fraction(int(rr[hit[0]]), int(tt[hit[0]])) if len(hit) else None
    # Root of J_inf(beta) = J_off by bisection (J_inf is a weighted mean of J_on and J_max,
    # increasing in beta).
    lo, hi = 0.0, 1.0
    if jon >= joff:
        limit = 0.0
    elif not jmx > joff:
        limit = 1.0
    else:
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if j_attack_limit(s, lam, z0, mid, mu) < joff:
                lo = mid
            else:
                hi = mid
        limit = 0.5 * (lo + hi)
    return sw, BetaBar(finite, limit, t_max, joff, jon, jmx, z0, mu)


def _run_mc(
    s: LinearSystem, lam: float, sched: Any, mc: MonteCarloConfig, attack: AttackSpec | None
) -> SimulationResult:
    return simulate(
        s,
        lam,
        sched,
        horizon=mc.horizon,
        runs=mc.runs,
        seed=mc.seed,
        attack=None if attack is None else (attack.r, attack.t),
        mode=mc.mode,
        protocol=mc.protocol,
    )


def analyse(
    s: LinearSystem,
    lam: float,
    ratio: Fraction,
    online: OnlineDesign,
    designed: bool,
    attacks: Sequence[AttackSpec],
    t_max: int | None,
    mc: MonteCarloConfig | None,
    horizon: int = DEFAULT_HORIZON,
    paper: dict[str, str] | None = None,
) -> Analysis:
    """Stationary, exact finite-horizon and Monte Carlo costs of the offline, online and attacked
    schedules, J_max, and (if ``t_max``) the sweep and both thresholds.

    Parameters
    ----------
    s : LinearSystem
        The process and sensor.
    lam : float
        Arrival probability at low power.
    ratio : fractions.Fraction
        Energy ratio p/q.
    online : OnlineDesign
        ``(z0, mu)`` of the online schedule.
    designed : bool
        Whether ``online`` is :func:`fakeack.design_online` ``(lam, ratio)``.
    attacks : sequence of AttackSpec
        The attacks to evaluate.
    t_max : int or None
        Largest attack period of the sweep; None skips sweep and thresholds.
    mc : MonteCarloConfig or None
        Monte Carlo settings; None skips it. Its horizon overrides ``horizon``.
    horizon : int, optional
        Horizon of the exact finite-horizon curves when there is no Monte Carlo.
    paper : dict, optional
        Printed values by row key, for the ``paper`` column.

    Returns
    -------
    Analysis
    """
    start = time.perf_counter()
    paper = paper or {}
    z0, mu = online
    mc_note = None
    if mc is not None and not _mc_available():
        mc, mc_note = None, _MC_MISSING
    H = mc.horizon if mc is not None else horizon
    off, on = OfflineSchedule(ratio), OnlineSchedule(z0, mu)
    j_off, j_on, jmx = j_offline(s, lam, ratio), j_online(s, lam, z0, mu), j_max(s, lam)

    specs: list[tuple[str, str, Any, AttackSpec | None, float]] = [
        ("j_offline", "J_offline", off, None, j_off),
        ("j_online", "J_online", on, None, j_on),
    ]
    for a in attacks:
        specs.append(
            (f"j_attack_{a.label}", f"J_attack beta={a.label}", on, a, j_attack(s, lam, z0, a.r, a.t, mu))
        )

    rows: list[Row] = []
    curves: list[Curve] = []
    for key, label, sched, a, stat in specs:
        atk = None if a is None else (a.r, a.t)
        exact = expected_trace_curve(s, lam, sched, H, atk).j_k
        row = Row(key, label, analytic=stat, exact_h=float(exact[-1]), paper=paper.get(key, "-"))
        res = None
        if mc is not None:
            res = _run_mc(s, lam, sched, mc, a)
            row.mc, row.mc_stderr = res.j, res.stderr
        rows.append(row)
        name = "offline" if a is None and sched is off else "online, no attack"
        if a is not None:
            name = f"online, attack $\\beta$ = {a.label}"
        curves.append(Curve(name, exact, None if res is None else res.j_k, stat))
    rows.append(
        Row(
            "j_max",
            "J_max (all blocked)",
            analytic=jmx,
            exact_h=float(_exact_j_max_curve(s, lam, H)[-1]),
            mc_text="-",
            paper=paper.get("j_max", "-"),
        )
    )

    sweep = bar = None
    if t_max is not None:
        if designed:
            sweep, bar = beta_sweep(s, lam, ratio, t_max), beta_bar(s, lam, ratio, t_max)
        else:
            sweep, bar = _custom_threshold(s, lam, ratio, z0, mu, t_max)
        rows.append(
            Row(
                "beta_bar_limit",
                "beta-bar (large-period limit)",
                analytic=bar.limit,
                mc_text="n/a",
                paper=paper.get("beta_bar_limit", "-"),
            )
        )
        fin = bar.finite
        rows.append(
            Row(
                "beta_bar_finite",
                f"beta-bar (t<={t_max})",
                analytic=None if fin is None else float(fin),
                analytic_text=f"none with t<={t_max}" if fin is None else f"{_frac(fin)} = {float(fin):.6f}",
                mc_text="n/a",
                paper=paper.get("beta_bar_finite", "-"),
            )
        )

    decisions = []
    for a in attacks:
        ja = j_attack(s, lam, z0, a.r, a.t, mu)
        jl = j_attack_limit(s, lam, z0, a.beta, mu)
        decisions.append(
            {
                "attack": a.label,
                "beta": float(a.beta),
                "j_attack": ja,
                "j_attack_limit": jl,
                "choice_against_pattern": "online" if ja < j_off else "offline",
                "choice_against_worst_case": "online" if jl < j_off else "offline",
            }
        )
    for r in rows:
        if r.mc is None and r.key.startswith("j_") and r.key != "j_max" and mc is None:
            r.mc_text = "skipped"
    return Analysis(
        s,
        lam,
        ratio,
        online,
        designed,
        tuple(attacks),
        H,
        mc,
        mc_note,
        rows,
        curves,
        j_off,
        j_on,
        jmx,
        sweep,
        bar,
        decisions,
        time.perf_counter() - start,
    )


# ------------------------------------------------------------------------------- formatting


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
    an: Analysis, outdir: Path, *, paper_beta_bar: float | None, stationary: AttackSpec | None
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


def _cmd_reproduce(args: argparse.Namespace) -> int:
    s = LinearSystem(**PAPER_SYSTEM)
    online = design_online(PAPER_LAM, PAPER_RATIO)
    mc = None if args.runs == 0 else MonteCarloConfig(args.runs, args.horizon, args.seed)
    an = analyse(
        s,
        PAPER_LAM,
        PAPER_RATIO,
        online,
        True,
        PAPER_ATTACKS,
        args.t_max,
        mc,
        horizon=args.horizon,
        paper=PAPER_PRINTED,
    )
    j_on_note = _j_online_note(an)
    figures: list[Path] = []
    if not args.no_figures:
        figures = _write_figures(
            an, Path(args.out), paper_beta_bar=PAPER_BETA_BAR, stationary=STATIONARY_EXAMPLE
        )
    if args.json:
        d = {
            "command": "reproduce",
            **_analysis_json(an),
            "paper": {**PAPER_PRINTED, "source": "Sec. V, 100000-run Monte Carlo (ERRATA 7)"},
            "notes": [j_on_note],
            "figures": figures,
        }
        print(_dumps(d))
        return 0
    z0, mu = an.online
    lines = [
        "fakeack reproduce: the paper's example (Sec. V)",
        f"  system {_system_text(s)}; lam={PAPER_LAM}; energy ratio {_frac(PAPER_RATIO)}",
        f"  offline schedule {''.join(map(str, offline_schedule(PAPER_RATIO)))} (period "
        f"{PAPER_RATIO.denominator}); {_online_text(an.online, True, PAPER_LAM, PAPER_RATIO)}",
        "",
        *_table(an.rows, an.horizon, with_mc=True, with_paper=True),
        *_footnotes(an),
        *_para(
            "paper: the values printed in Sec. V (a 100000-run Monte Carlo of unstated horizon; '-' = not "
            "printed). Its beta-bar ~0.28 is read off a figure and rests on a definition it does not give "
            "(ERRATA 7)."
        ),
        *_para(j_on_note),
        "",
        *_decision_lines(an),
    ]
    if figures:
        lines += _para(f"figures in {Path(args.out)}/: {', '.join(p.name for p in figures)}")
    lines.append(f"done in {time.perf_counter() - args._start:.1f} s")
    print("\n".join(lines))
    return 0


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


def _cmd_analyze(args: argparse.Namespace) -> int:
    if args.example:
        if args.config:
            raise ConfigError("config: give either CONFIG.toml or --example, not both")
        sys.stdout.write(example_text())
        return 0
    if not args.config:
        raise ConfigError("config: give a CONFIG.toml file (fakeack analyze --example prints one)")
    if args.config == "-":
        cfg = parse_config(loads(sys.stdin.read(), "<stdin>"), "<stdin>")
    else:
        cfg = load_config(args.config)
    an = analyse(
        cfg.system, cfg.lam, cfg.ratio, cfg.online, cfg.designed, cfg.attacks, cfg.sweep_t_max, cfg.montecarlo
    )
    figures: list[Path] = []
    if args.out and not args.no_figures:
        stat = None
        cands = [a for a in cfg.attacks if a.r > 0]
        if cfg.online.mu == 1.0 and cands:
            stat = max(cands, key=lambda a: (a.beta, a.t))
            if cfg.online.z0 * (stat.r + 1) > 400 or stat.t > 400:
                stat = None
        figures = _write_figures(an, Path(args.out), paper_beta_bar=None, stationary=stat)
        if stat is None and figures:
            why = "mu < 1" if cfg.online.mu != 1.0 else "no attack with r > 0, or the chain is too large"
            print(
                f"note: fig_stationary skipped ({why}; the heat map needs mu = 1 and one attack)",
                file=sys.stderr,
            )
    d = {"command": "analyze", "config": cfg.source, **_analysis_json(an), "figures": figures}
    if args.out:
        atomic_write(Path(args.out) / "analysis.json", _dumps(d) + "\n")
    if args.json:
        print(_dumps(d))
        return 0
    lines = [
        f"fakeack analyze: {cfg.source}",
        f"  system {_system_text(cfg.system)}; Tr Pbar = {float(np.trace(cfg.system.pbar)):.6f}",
        f"  lam={cfg.lam:g}; energy ratio {_frac(cfg.ratio)}; offline schedule "
        + (
            "".join(map(str, offline_schedule(cfg.ratio)))
            if cfg.ratio.denominator <= 40
            else f"period {cfg.ratio.denominator}"
        ),
        f"  {_online_text(cfg.online, cfg.designed, cfg.lam, cfg.ratio)}",
        "",
        *_table(an.rows, an.horizon, with_mc=an.mc is not None, with_paper=False),
        *_footnotes(an),
        "",
        *_decision_lines(an),
    ]
    if not cfg.designed and an.bar is not None:
        lines += _para(
            "note: J_offline is the offline cost at the budget's energy; the online schedule given in "
            "[online] may spend more or less than the budget."
        )
    if args.out:
        lines += _para(f"wrote {len(figures)} figure files and analysis.json in {Path(args.out)}/")
    print("\n".join(lines))
    return 0


# -- sweep and simulate share the system options


_SYSTEM_FLAGS = ("A", "C", "Q", "R", "lam", "ratio")


def _resolve_system(args: argparse.Namespace) -> tuple[LinearSystem, float, Fraction, Config | None]:
    given = [f"--{k.replace('_', '-')}" for k in _SYSTEM_FLAGS if getattr(args, k) is not None]
    if args.config:
        if given:
            raise ValueError(f"give either --config or {', '.join(given)}, not both")
        cfg = load_config(args.config)
        return cfg.system, cfg.lam, cfg.ratio, cfg
    v = {k: (PAPER_SYSTEM[k] if getattr(args, k) is None else getattr(args, k)) for k in "ACQR"}
    lam = PAPER_LAM if args.lam is None else args.lam
    ratio = PAPER_RATIO if args.ratio is None else _ratio(args.ratio)
    # Validate lam here so the message names the flag.
    if not 0 < lam < 1:
        raise ValueError(f"--lam must lie in (0, 1), got {lam}")
    return LinearSystem(**v), lam, ratio, None


def _ratio(text: str) -> Fraction:
    try:
        r = Fraction(text.strip())
    except (ValueError, ZeroDivisionError):
        raise ValueError(f"--ratio: cannot read {text!r} as a fraction p/q (e.g. 1/7)") from None
    if not 0 < r < 1:
        raise ValueError(f"--ratio must lie strictly between 0 and 1, got {_frac(r)}")
    return r


def _cmd_sweep(args: argparse.Namespace) -> int:
    s, lam, ratio, cfg = _resolve_system(args)
    t_max = args.t_max
    if t_max is None:
        t_max = cfg.sweep_t_max if cfg is not None and cfg.sweep_t_max else DEFAULT_T_MAX
    if cfg is not None and not cfg.designed:
        z0, mu = cfg.online
        sw, bar = _custom_threshold(s, lam, ratio, z0, mu, t_max)
        designed = False
    else:
        sw, bar = beta_sweep(s, lam, ratio, t_max), beta_bar(s, lam, ratio, t_max)
        z0, mu, designed = sw.z0, sw.mu, True
    lim = np.array(
        [j_attack_limit(s, lam, z0, Fraction(int(r), int(t)), mu) for r, t in zip(sw.r, sw.t, strict=True)]
    )
    better = np.where(sw.j_attack < sw.j_offline, "online", "offline")
    if args.csv:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["r", "t", "beta", "j_attack", "j_attack_limit", "better"])
        for i in range(len(sw)):
            w.writerow(
                [
                    int(sw.r[i]),
                    int(sw.t[i]),
                    repr(float(sw.beta[i])),
                    repr(float(sw.j_attack[i])),
                    repr(float(lim[i])),
                    better[i],
                ]
            )
        _emit(buf.getvalue(), args.out)
        return 0
    meta = {
        "system": _system_text(s),
        "lam": lam,
        "ratio": _frac(ratio),
        "z0": z0,
        "mu": mu,
        "designed": designed,
        "t_max": t_max,
        "count": len(sw),
        "j_offline": sw.j_offline,
        "j_online": sw.j_online,
        "j_max": bar.j_max,
        "beta_bar": {
            "finite": None if bar.finite is None else _frac(bar.finite),
            "finite_value": None if bar.finite is None else float(bar.finite),
            "limit": bar.limit,
        },
    }
    if args.json:
        pts = [
            {
                "r": int(sw.r[i]),
                "t": int(sw.t[i]),
                "beta": float(sw.beta[i]),
                "j_attack": float(sw.j_attack[i]),
                "j_attack_limit": float(lim[i]),
                "better": str(better[i]),
            }
            for i in range(len(sw))
        ]
        _emit(_dumps({"command": "sweep", **meta, "points": pts}), args.out)
        return 0
    fin = "none" if bar.finite is None else f"{_frac(bar.finite)} = {float(bar.finite):.6f}"
    lines = [
        f"fakeack sweep: {meta['system']}; lam={lam:g}; energy ratio {_frac(ratio)}; "
        f"online z0={z0}, mu={mu:.6g}",
        f"J_offline = {sw.j_offline:.6f}   J_online = {sw.j_online:.6f}   J_max = {_fmt(bar.j_max)}",
        f"beta-bar: t<={t_max}: {fin}; large-period limit: {bar.limit:.6f}",
        *_para(
            f"{len(sw)} attacks r/t in lowest terms with t <= {t_max}, by increasing beta (J_inf: the "
            "worst attack with the same budget; better: the schedule to use against r/t)"
        ),
        "",
        f"{'r':>5} {'t':>5} {'beta':>9} {'J_attack':>11} {'J_inf(beta)':>12}  better",
    ]
    for i in range(len(sw)):
        lines.append(
            f"{int(sw.r[i]):>5} {int(sw.t[i]):>5} {float(sw.beta[i]):>9.6f} "
            f"{float(sw.j_attack[i]):>11.6f} {_fmt(float(lim[i])):>12}  {better[i]}"
        )
    _emit("\n".join(lines), args.out)
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    s, lam, ratio, cfg = _resolve_system(args)
    if args.runs < 2:
        raise ValueError(f"--runs must be at least 2 (the standard error needs two runs), got {args.runs}")
    attack = None if args.attack is None else parse_attack(args.attack, "--attack")
    if args.schedule == "offline":
        if args.z0 is not None or args.mu is not None:
            raise ValueError("--z0 and --mu apply to the online schedule only")
        if attack is not None:
            raise ValueError("--attack: an offline schedule ignores ACKs, so an attack has no effect")
        sched: Any = OfflineSchedule(ratio)
        stationary = j_offline(s, lam, ratio)
    else:
        if args.z0 is None:
            if args.mu is not None:
                raise ValueError("--mu needs --z0 (without them both come from design_online)")
            if cfg is not None and not cfg.designed:
                z0, mu = cfg.online
            else:
                z0, mu = design_online(lam, ratio)
        else:
            z0, mu = args.z0, 1.0 if args.mu is None else args.mu
        sched = OnlineSchedule(z0, mu)
        stationary = (
            j_online(s, lam, z0, mu) if attack is None else j_attack(s, lam, z0, attack.r, attack.t, mu)
        )
    if not _mc_available():
        raise CliError(_MC_MISSING.replace("Monte Carlo skipped: ", "cannot simulate: "), 1)
    mc = MonteCarloConfig(args.runs, args.horizon, args.seed, args.mode, args.protocol)
    res = _run_mc(s, lam, sched, mc, attack)
    exact = expected_trace_curve(
        s, lam, sched, args.horizon, None if attack is None else (attack.r, attack.t)
    )
    row = Row("j", "J_H", mc=res.j, mc_stderr=res.stderr, exact_h=float(exact.j_k[-1]))
    if args.csv:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["k", "mc_trace", "mc_j_k", "exact_trace", "exact_j_k"])
        for i in range(args.horizon):
            w.writerow(
                [
                    i + 1,
                    repr(float(res.mean_trace[i])),
                    repr(float(res.j_k[i])),
                    repr(float(exact.trace[i])),
                    repr(float(exact.j_k[i])),
                ]
            )
        _emit(buf.getvalue(), args.out)
        return 0
    d = {
        "command": "simulate",
        "system": _system_text(s),
        "lam": lam,
        "ratio": _frac(ratio),
        "schedule": res.schedule,
        "attack": None if attack is None else attack.label,
        "runs": res.runs,
        "horizon": res.horizon,
        "seed": res.seed,
        "mode": res.mode,
        "protocol": res.protocol,
        "j": res.j,
        "stderr": res.stderr,
        "exact_j_h": row.exact_h,
        "z": row.z,
        "flagged": row.flagged,
        "stationary_j": stationary,
        "high_power_rate": res.high_power_rate,
        "flags_sent": res.flags_sent,
        "flags_blocked": res.flags_blocked,
        "j_k": res.j_k,
        "mean_trace": res.mean_trace,
        "exact_j_k": exact.j_k,
        "exact_trace": exact.trace,
    }
    if args.json:
        _emit(_dumps(d), args.out)
        return 0
    att = (
        "no attack"
        if attack is None
        else f"attack {attack.label} (blocks the first {attack.r} of every {attack.t} flag-ACKs)"
    )
    z = row.z
    lines = [
        f"fakeack simulate: {res.schedule}, {att}",
        f"  system {_system_text(s)}; lam={lam:g}; energy ratio {_frac(ratio)}",
        f"  {res.runs} runs x {res.horizon} steps, seed {res.seed}, {res.mode} mode, protocol {res.protocol}",
        "",
        f"  J_H Monte Carlo   {res.j:.6f} +- {res.stderr:.6f}",
        f"  J_H exact         {row.exact_h:.6f}   (MC - exact = {_fmt(z, 2)} stderr"
        + (f"; more than {FLAG_SIGMAS:g}: check!)" if row.flagged else ")"),
        f"  J stationary      {_fmt(stationary)}   (k -> infinity; J_H differs by the transient)",
        f"  high-power rate {res.high_power_rate:.6f}; flag-ACKs sent {res.flags_sent:.6f}/step, "
        f"blocked {res.flags_blocked:.6f}/step",
    ]
    if res.mode == "state":
        lines.append("  (state mode: the squared estimation error averaged over runs; its mean is Tr E[P_k])")
    _emit("\n".join(lines), args.out)
    return 0


# ------------------------------------------------------------------------------- parser


def _int_at_least(minimum: int, extra: str = "") -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            v = int(text.replace("_", ""))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}{extra}, got {v}")
        return v

    return parse


def _runs(text: str) -> int:
    v = _int_at_least(0)(text)
    if v == 1:
        raise argparse.ArgumentTypeError("must be 0 (skip the Monte Carlo) or at least 2, got 1")
    return v


def _add_system_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("system (default: the paper's A=1.2, C=0.7, Q=R=0.8, lam=0.5, ratio 1/7)")
    for k in "ACQR":
        g.add_argument(f"--{k}", type=float, default=None, metavar="X", help=f"scalar {k}")
    g.add_argument("--lam", type=float, default=None, metavar="P", help="arrival probability at low power")
    g.add_argument(
        "--ratio", default=None, metavar="P/Q", help="energy ratio (Psi-delta)/(Delta-delta), e.g. 1/7"
    )
    g.add_argument(
        "--config",
        metavar="FILE",
        help="take the system, lam and ratio (and the online schedule) "
        "from a TOML config instead (matrices: see 'fakeack analyze --example')",
    )


def _add_format_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--json", action="store_true", help="JSON instead of the table")
    g.add_argument("--csv", action="store_true", help="CSV instead of the table")
    p.add_argument("--out", metavar="FILE", help="write to FILE (atomically) instead of stdout")


class _Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """Show defaults, except the uninformative ones of flags and unset options."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False) or isinstance(action.default, bool):
            return action.help
        return super()._get_help_string(action)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``fakeack`` command.

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = argparse.ArgumentParser(
        prog="fakeack",
        description="Fake-ACK attacks on ACK-based sensor power schedules: exact analysis, Monte Carlo "
        "and the attacker threshold (Li, Quevedo, Dey, Shi, with the corrections of the README's "
        "model notes).",
        epilog="exit codes: 0 ok, 1 runtime failure, 2 bad arguments or config, 130 interrupted",
    )
    parser.add_argument("--version", action="version", version=f"fakeack {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    fmt = _Formatter

    rep = sub.add_parser(
        "reproduce",
        formatter_class=fmt,
        help="reproduce the paper's Sec. V (table and figures)",
        description="The paper's example (A=1.2, C=0.7, Q=R=0.8, lam=0.5, energy ratio 1/7, online z0=2): "
        "J_offline, J_online, J_attack at beta=1/5 and 2/3, J_max and beta-bar, each analytic (stationary), "
        "exact at the finite horizon, by Monte Carlo, and as printed in the paper; figures fig3_jk, "
        "fig4_beta and fig_stationary (PNG and SVG) in --out. Defaults: 100000 runs x 200 steps for each "
        "of the 4 simulated schedules (8e7 steps); the whole command, figures included, takes a few "
        "seconds on 2 cores.",
    )
    rep.add_argument("--out", default=DEFAULT_OUT, metavar="DIR", help="directory for the figures")
    rep.add_argument(
        "--runs",
        type=_runs,
        default=DEFAULT_RUNS,
        metavar="N",
        help="Monte Carlo runs per schedule (0 skips the Monte Carlo)",
    )
    rep.add_argument(
        "--seed",
        type=_int_at_least(0),
        default=DEFAULT_SEED,
        metavar="S",
        help="Monte Carlo seed (the same for every schedule)",
    )
    rep.add_argument(
        "--horizon",
        type=_int_at_least(1),
        default=DEFAULT_HORIZON,
        metavar="H",
        help="steps per run (and of the exact finite-horizon J_H)",
    )
    rep.add_argument(
        "--t-max",
        type=_int_at_least(2),
        default=DEFAULT_T_MAX,
        metavar="T",
        help="largest attack period t of the beta sweep and the finite beta-bar",
    )
    rep.add_argument("--no-figures", action="store_true", help="do not draw figures")
    rep.add_argument("--json", action="store_true", help="print JSON instead of the table")
    rep.set_defaults(func=_cmd_reproduce)

    ana = sub.add_parser(
        "analyze",
        formatter_class=fmt,
        help="analyze a system described by a TOML config",
        description="Costs, Monte Carlo, beta sweep and thresholds for the system in CONFIG.toml. "
        "'fakeack analyze --example' prints a commented config (the paper's system) to start from.",
    )
    ana.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="the config file ('-' reads standard input)"
    )
    ana.add_argument("--example", action="store_true", help="print the example config and exit")
    ana.add_argument("--out", metavar="DIR", help="write figures and analysis.json into DIR")
    ana.add_argument("--no-figures", action="store_true", help="with --out, write analysis.json only")
    ana.add_argument("--json", action="store_true", help="print JSON instead of the table")
    ana.set_defaults(func=_cmd_analyze)

    swp = sub.add_parser(
        "sweep",
        formatter_class=fmt,
        help="J_attack at every beta = r/t with t <= t_max",
        description="The attacked cost at every r/t in lowest terms with t <= T (online schedule from "
        "design_online unless the config fixes it), the large-period limit J_inf(beta) and beta-bar.",
    )
    _add_system_flags(swp)
    swp.add_argument(
        "--t-max",
        type=_int_at_least(2),
        default=None,
        metavar="T",
        help=f"largest attack period (default: the config's [attack.sweep] t_max, else {DEFAULT_T_MAX})",
    )
    _add_format_flags(swp)
    swp.set_defaults(func=_cmd_sweep)

    sim = sub.add_parser(
        "simulate",
        formatter_class=fmt,
        help="Monte Carlo of one schedule, against its exact J_H",
        description="Monte Carlo of the protocol (sensor, channel, event detector, attacker) from the "
        "paper's "
        "initial condition, compared with the exact finite-horizon J_H of the same horizon.",
    )
    _add_system_flags(sim)
    sim.add_argument("--schedule", choices=("online", "offline"), default="online", help="power schedule")
    sim.add_argument(
        "--z0",
        type=_int_at_least(1),
        default=None,
        metavar="Z",
        help="memory length (default: design_online(lam, ratio))",
    )
    sim.add_argument(
        "--mu",
        type=float,
        default=None,
        metavar="MU",
        help="probability of the z0-bit memory (default 1 with --z0)",
    )
    sim.add_argument("--attack", metavar="R/T", help="block the first R of every T flag-ACKs")
    sim.add_argument("--runs", type=_int_at_least(2), default=10_000, metavar="N", help="independent runs")
    sim.add_argument(
        "--horizon", type=_int_at_least(1), default=DEFAULT_HORIZON, metavar="H", help="steps per run"
    )
    sim.add_argument("--seed", type=_int_at_least(0), default=DEFAULT_SEED, metavar="S", help="random seed")
    sim.add_argument(
        "--mode",
        choices=("covariance", "state"),
        default="covariance",
        help="average Tr P_k, or simulate the noise and average the squared error",
    )
    sim.add_argument("--protocol", choices=("A", "B"), default="B", help="flag-ACK protocol type")
    _add_format_flags(sim)
    sim.set_defaults(func=_cmd_simulate)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``fakeack`` console script and of ``python -m fakeack``.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code (0 ok, 1 runtime failure, 2 bad arguments or config, 130 interrupted).
        ``--help`` and ``--version`` return 0 instead of raising :class:`SystemExit`.
    """
    start = time.perf_counter()
    parser = build_parser()
    try:
        args = parser.parse_args(None if argv is None else list(argv))
    except SystemExit as exc:  # --help, --version, usage errors (argparse printed the message)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    args._start = start
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("fakeack: interrupted", file=sys.stderr)
        return 130
    except CliError as exc:
        print(f"fakeack: error: {exc}", file=sys.stderr)
        return exc.code
    except (ValueError, TypeError) as exc:
        print(f"fakeack: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `fakeack sweep | head`
        with contextlib.suppress(OSError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        return 0
    except OSError as exc:
        where = f"{exc.filename!s}: " if exc.filename else ""
        print(f"fakeack: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
