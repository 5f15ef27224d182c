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
import os
import sys
import time
from collections.abc import Callable, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from ._cli_io import CliError, _dumps, _emit, _frac, atomic_write
from ._cli_report import (
    _analysis_json,
    _decision_lines,
    _fmt,
    _footnotes,
    _j_online_note,
    _online_text,
    _para,
    _system_text,
    _table,
    _write_figures,
)
from .attack import j_attack
from .attacks import as_attack
from .config import (
    Config,
    ConfigError,
    MonteCarloConfig,
    example_text,
    load_config,
    loads,
    parse_config,
)
from .montecarlo import OfflineSchedule, OnlineSchedule, expected_trace_curve
from .schedules import (
    design_online,
    j_offline,
    j_online,
    offline_schedule,
)
from .study import (
    DEFAULT_HORIZON,
    DEFAULT_OUT,
    DEFAULT_RUNS,
    DEFAULT_SEED,
    DEFAULT_T_MAX,
    FLAG_SIGMAS,
    PAPER_ATTACKS,
    PAPER_BETA_BAR,
    PAPER_LAM,
    PAPER_PRINTED,
    PAPER_RATIO,
    PAPER_SYSTEM,
    STATIONARY_EXAMPLE,
    Row,
    _custom_threshold,
    _run_mc,
    analyse,
)
from .system import LinearSystem
from .threshold import beta_bar, beta_sweep, j_attack_limit

__all__ = ["atomic_write", "main"]


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
    attack = as_attack(args.attack, "--attack")
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
