"""The argument parser of the ``fakeack`` command: one function per sub-command."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from .. import __version__
from .._internal.validate import MODES, PROTOCOLS
from ..config.channel import CHANNEL_OPTION
from ..studies.report import DEFAULT_HORIZON, DEFAULT_OUT, DEFAULT_RUNS, DEFAULT_SEED, DEFAULT_T_MAX
from . import analyze, game, grid, optimal, reproduce, simulate, sweep

__all__ = ["build_parser"]


def _int_at_least(minimum: int) -> Callable[[str], int]:
    """An argparse type: an integer (``_`` separators allowed) of at least ``minimum``."""

    def parse(text: str) -> int:
        try:
            v = int(text.replace("_", ""))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {v}")
        return v

    return parse


def _runs(text: str) -> int:
    """An argparse type: 0 (no Monte Carlo) or at least 2 runs."""
    v = _int_at_least(0)(text)
    if v == 1:
        raise argparse.ArgumentTypeError("must be 0 (skip the Monte Carlo) or at least 2, got 1")
    return v


class _Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """Show defaults, except the uninformative ones of flags and unset options."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False) or isinstance(action.default, bool):
            return action.help
        return super()._get_help_string(action)


def _add_system_flags(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        "system (default: the paper's A=1.2, C=0.7, Q=R=0.8, lam=0.5, ratio 1/7)"
    )
    for k in "ACQR":
        group.add_argument(f"--{k}", type=float, default=None, metavar="X", help=f"scalar {k}")
    group.add_argument(
        "--lam", type=float, default=None, metavar="P", help="arrival probability at low power"
    )
    group.add_argument(
        "--ratio", default=None, metavar="P/Q", help="energy ratio (Psi-delta)/(Delta-delta), e.g. 1/7"
    )
    _add_channel_flag(group, "instead of --lam, or of the config's channel")
    group.add_argument(
        "--config",
        metavar="FILE",
        help="take the system, lam and ratio (and the online schedule) "
        "from a TOML config instead (matrices: see 'fakeack analyze --example')",
    )


def _add_channel_flag(group: argparse._ActionsContainer, instead: str) -> None:
    group.add_argument(
        "--channel",
        default=None,
        metavar="KIND:VALUES",
        help=f"the packet channel ({instead}): {CHANNEL_OPTION}, "
        "e.g. ge:0.1,0.1,1,0 (a Gilbert-Elliott channel: P(good->bad), P(bad->good), low-power arrival "
        "probability when good, when bad; then optionally the high-power ones, default 1); a designed "
        "online schedule is designed for it",
    )


def _add_format_flags(parser: argparse.ArgumentParser) -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--json", action="store_true", help="JSON instead of the table")
    group.add_argument("--csv", action="store_true", help="CSV instead of the table")
    parser.add_argument("--out", metavar="FILE", help="write to FILE (atomically) instead of stdout")


def _add_reproduce(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "reproduce",
        formatter_class=_Formatter,
        help="reproduce the paper's Sec. V (table and figures)",
        description="The paper's example (A=1.2, C=0.7, Q=R=0.8, lam=0.5, energy ratio 1/7, online z0=2): "
        "J_offline, J_online, J_attack at beta=1/5 and 2/3, J_max and beta-bar, each analytic (stationary), "
        "exact at the finite horizon, by Monte Carlo, and as printed in the paper; figures fig3_jk, "
        "fig4_beta and fig_stationary (PNG and SVG) in --out. Defaults: 100000 runs x 200 steps for each "
        "of the 4 simulated schedules (8e7 steps); the whole command, figures included, takes a few "
        "seconds on 2 cores.",
    )
    parser.add_argument("--out", default=DEFAULT_OUT, metavar="DIR", help="directory for the figures")
    parser.add_argument(
        "--runs",
        type=_runs,
        default=DEFAULT_RUNS,
        metavar="N",
        help="Monte Carlo runs per schedule (0 skips the Monte Carlo)",
    )
    parser.add_argument(
        "--seed",
        type=_int_at_least(0),
        default=DEFAULT_SEED,
        metavar="S",
        help="Monte Carlo seed (the same for every schedule)",
    )
    parser.add_argument(
        "--horizon",
        type=_int_at_least(1),
        default=DEFAULT_HORIZON,
        metavar="H",
        help="steps per run (and of the exact finite-horizon J_H)",
    )
    parser.add_argument(
        "--t-max",
        type=_int_at_least(2),
        default=DEFAULT_T_MAX,
        metavar="T",
        help="largest attack period t of the beta sweep and the finite beta-bar",
    )
    parser.add_argument("--no-figures", action="store_true", help="do not draw figures")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    parser.set_defaults(func=reproduce.run)


def _add_analyze(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "analyze",
        formatter_class=_Formatter,
        help="analyze a system described by a TOML config",
        description="Costs, Monte Carlo, beta sweep and thresholds for the system in CONFIG.toml, under "
        "its channel ([system] lam, or a [channel] section; a channel with memory is reported beside "
        "the i.i.d. channel of the same mean). 'fakeack analyze --example' prints a commented config "
        "(the paper's system) to start from.",
    )
    parser.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="the config file ('-' reads standard input)"
    )
    parser.add_argument("--example", action="store_true", help="print the example config and exit")
    parser.add_argument("--out", metavar="DIR", help="write figures and analysis.json into DIR")
    parser.add_argument("--no-figures", action="store_true", help="with --out, write analysis.json only")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    parser.set_defaults(func=analyze.run)


def _add_sweep(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "sweep",
        formatter_class=_Formatter,
        help="J_attack at every beta = r/t with t <= t_max",
        description="The attacked cost at every r/t in lowest terms with t <= T (online schedule from "
        "design_online unless the config fixes it), the large-period limit J_inf(beta) and beta-bar.",
    )
    _add_system_flags(parser)
    parser.add_argument(
        "--t-max",
        type=_int_at_least(2),
        default=None,
        metavar="T",
        help=f"largest attack period (default: the config's [attack.sweep] t_max, else {DEFAULT_T_MAX})",
    )
    _add_format_flags(parser)
    parser.set_defaults(func=sweep.run)


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "simulate",
        formatter_class=_Formatter,
        help="Monte Carlo of one schedule, against its exact J_H",
        description="Monte Carlo of the protocol (sensor, channel, event detector, attacker) from the "
        "paper's initial condition, compared with the exact finite-horizon J_H of the same horizon.",
    )
    _add_system_flags(parser)
    parser.add_argument("--schedule", choices=("online", "offline"), default="online", help="power schedule")
    parser.add_argument(
        "--z0",
        type=_int_at_least(1),
        default=None,
        metavar="Z",
        help="memory length (default: design_online(lam, ratio))",
    )
    parser.add_argument(
        "--mu",
        type=float,
        default=None,
        metavar="MU",
        help="probability of the z0-bit memory (default 1 with --z0)",
    )
    parser.add_argument(
        "--attack",
        metavar="ATTACK",
        help="R/T blocks the first R of every T flag-ACKs; random:BETA blocks each with probability "
        "BETA; inject:GAMMA forges one with probability GAMMA on each step without a genuine one "
        "(inject:GAMMA+random:BETA or inject:GAMMA+R/T also blocks)",
    )
    parser.add_argument("--runs", type=_int_at_least(2), default=10_000, metavar="N", help="independent runs")
    parser.add_argument(
        "--horizon", type=_int_at_least(1), default=DEFAULT_HORIZON, metavar="H", help="steps per run"
    )
    parser.add_argument(
        "--seed", type=_int_at_least(0), default=DEFAULT_SEED, metavar="S", help="random seed"
    )
    parser.add_argument(
        "--mode",
        choices=MODES,
        default="covariance",
        help="average Tr P_k, or simulate the noise and average the squared error",
    )
    parser.add_argument("--protocol", choices=sorted(PROTOCOLS), default="B", help="flag-ACK protocol type")
    _add_format_flags(parser)
    parser.set_defaults(func=simulate.run)


def _add_grid(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "grid",
        formatter_class=_Formatter,
        help="a parameter study over (lam, energy ratio, beta) from a TOML config",
        description="Every cost, both thresholds and the decision over a grid of systems, lam, energy "
        "ratios and budgets (fakeack.study_grid), written to DIR/study.zarr block by block, DIR/study.nc "
        "and heat maps per system. Needs pip install 'fakeack[grid]'. 'fakeack grid --example' prints a "
        "config to start from.",
    )
    parser.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="the config file with a [grid] section"
    )
    parser.add_argument("--example", action="store_true", help="print the example config and exit")
    parser.add_argument("--out", metavar="DIR", help="directory for study.zarr, study.nc and the figures")
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=_int_at_least(1),
        metavar="N",
        help="run on a dask LocalCluster of N worker processes",
    )
    where.add_argument(
        "--scheduler", metavar="ADDRESS", help="run on a running dask scheduler (tcp://host:8786)"
    )
    parser.add_argument(
        "--resume", action="store_true", help="finish DIR/study.zarr, keeping the blocks already complete"
    )
    parser.add_argument("--no-figures", action="store_true", help="write the store and study.nc only")
    parser.set_defaults(func=grid.run)


def _add_game(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "game",
        formatter_class=_Formatter,
        help="the sensor-attacker game: value, strategies, Stackelberg, stealthy frontiers",
        description="The repeated game between the sensor (a detection test and a fall-back to the "
        "offline schedule) and an attacker choosing from a list, for the system of CONFIG.toml and its "
        "[game] section (default: the paper's example and the README's game). Prints the value, both "
        "optimal mixed strategies and the Stackelberg outcome; with --out writes fig_frontiers and "
        "fig_game_payoff (PNG and SVG) and game.json.",
    )
    parser.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="the config file ('-' reads standard input)"
    )
    parser.add_argument("--out", metavar="DIR", help="write figures and game.json into DIR")
    parser.add_argument("--no-figures", action="store_true", help="with --out, write game.json only")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the text")
    _add_channel_flag(parser, "instead of the config's; the game takes i.i.d. channels only for now")
    parser.set_defaults(func=game.run)


def _add_optimal(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "optimal",
        formatter_class=_Formatter,
        help="the optimal power policy, the worst attack and the optimal jamming",
        description="For the system of CONFIG.toml and its [optimal] section (default: the paper's "
        "example): the sensor's optimal power policy at each energy budget beside the online schedule "
        "that spends it (fakeack.optimal_power_policy), the worst attack on the flag-ACKs at each "
        "blocking budget beside the large-period limit of consecutive blocking (fakeack.worst_attack), "
        "and the optimal jamming of the data channel, finite-horizon and long-run "
        "(fakeack.optimal_jamming). 'fakeack optimal --example' prints a commented config.",
    )
    parser.add_argument(
        "config", nargs="?", metavar="CONFIG.toml", help="the config file ('-' reads standard input)"
    )
    parser.add_argument("--example", action="store_true", help="print the example config and exit")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the tables")
    _add_channel_flag(parser, "instead of the config's")
    parser.set_defaults(func=optimal.run)


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
    for add in (_add_reproduce, _add_analyze, _add_sweep, _add_simulate, _add_grid, _add_game, _add_optimal):
        add(sub)
    return parser
