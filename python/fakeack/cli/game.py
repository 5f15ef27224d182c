"""``fakeack game``: the sensor-attacker game of a config's ``[game]`` section (the paper's example
by default): the value, both optimal strategies, the Stackelberg outcome, the stealthy frontiers,
and a closed-loop check of the pairs that matter."""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..config.analyze import ConfigError, example_text, load_config, loads, parse_config
from ..config.game import GameConfig, parse_game
from ..game.frontier import FAMILIES, stealthy_frontier
from ..game.simulate import simulate_game
from ..game.solve import solve_game
from ..model.channels import BernoulliChannel
from ..plots import have_matplotlib, plot_frontiers, plot_game, save_figure
from ._channel import channel_json, channel_label
from ._inputs import option_channel
from ._io import atomic_write, to_json

__all__ = ["run"]


#: Why the game refuses a channel that is not the paper's.
_IID_ONLY = (
    "takes the paper's i.i.d. channel only for now (fakeack.solve_game, simulate_game and "
    "stealthy_frontier take lam, not a channel)"
)


def _config(args: argparse.Namespace) -> tuple[Any, GameConfig]:
    """The config (the shipped example, the paper's system, when none is given) and its game.

    ``--channel`` replaces the config's channel; the game needs the paper's (i.i.d.) channel.
    """
    channel = option_channel(args)
    if channel is not None and not isinstance(channel, BernoulliChannel):
        raise ValueError(f"--channel {args.channel}: fakeack game {_IID_ONLY}; give bernoulli:LAM")
    if not args.config:
        source = "<example: the paper's system>"
        cfg = parse_config(loads(example_text(), "<example>"), source, channel=channel)
    elif args.config == "-":
        cfg = parse_config(loads(sys.stdin.read(), "<stdin>"), "<stdin>", channel=channel)
    else:
        cfg = load_config(args.config, channel=channel)
    if channel is not None:
        cfg = replace(cfg, source=f"{cfg.source} with --channel {args.channel}")
    if not cfg.paper_channel:
        raise ConfigError(
            f"config: [channel]: fakeack game {_IID_ONLY}; got {channel_label(cfg.channel_arg)}"
        )
    return cfg, parse_game(cfg.raw)


def _name(attack: Any) -> str:
    return "no attack" if attack is None else str(attack)


def _checks(cfg: Any, game: GameConfig, sol: Any) -> list[dict]:
    """Closed-loop Monte Carlo of the pairs the outcome rests on, beside the payoff formula."""
    if game.runs == 0:
        return []
    pairs = []
    st = sol.stackelberg
    pairs.append((st.policy, st.attack))
    for i in sorted(range(len(sol.policies)), key=lambda i: -sol.sensor_strategy[i]):
        if sol.sensor_strategy[i] > 1e-9:
            for j in sorted(range(len(sol.attacks)), key=lambda j: -sol.attacker_strategy[j]):
                if sol.attacker_strategy[j] > 1e-9 and len(pairs) < 4:
                    pairs.append((sol.policies[i], sol.attacks[j]))
    out, seen = [], set()
    for pol, att in pairs:
        key = (pol, att)
        if key in seen:
            continue
        seen.add(key)
        i = sol.policies.index(pol)
        j = sol.attacks.index(att)
        sim = simulate_game(
            cfg.system,
            cfg.lam,
            cfg.ratio,
            pol,
            att,
            game.horizon,
            game.runs,
            game.seed,
            n_steps=game.n_steps,
            burn_in=10 * game.n_steps,
        )
        out.append(
            {
                "policy": str(pol),
                "attack": _name(att),
                "formula": float(sol.payoff[i, j]),
                "monte_carlo": sim.j,
                "stderr": sim.stderr,
            }
        )
    return out


def _frontiers(cfg: Any, game: GameConfig) -> list:
    alpha = min(game.alphas)
    return [
        stealthy_frontier(
            cfg.system,
            cfg.lam,
            cfg.online.z0,
            game.n_steps,
            alpha,
            test,
            family,
            game.max_detection,
            t_max=game.t_max,
            mu=cfg.online.mu,
            grid=game.grid,
            support=game.support,
        )
        for test in game.tests
        for family in FAMILIES
    ]


def _text(cfg: Any, game: GameConfig, sol: Any, frontiers: list, checks: list, figures: list) -> str:
    lines = [
        f"fakeack game: {cfg.source}",
        f"  lam={cfg.lam:g}; energy ratio {cfg.ratio}; online z0={cfg.online.z0}, mu={cfg.online.mu:g}; "
        f"windows of {game.n_steps} steps; beta-bar (harmful rule) = {sol.beta_bar:.6f}",
        f"  {len(sol.policies)} sensor policies x {len(sol.attacks)} attacks"
        + (
            "" if sol.attack_prior == 1.0 else f"; the attacker present with probability {sol.attack_prior:g}"
        ),
        "",
        sol.summary(top=6),
        "",
        "the attacker's best response to each policy (J; probability d that a window triggers the "
        "fall-back):",
    ]
    for i, pol in enumerate(sol.policies):
        j = sol.best_attack[i]
        lines.append(
            f"  {str(pol):62s} {_name(sol.attacks[j])[:58]:58s} J = {sol.payoff[i, j]:.4f}, "
            f"d = {sol.detection[i, j]:.3f}"
        )
    lines += [
        "",
        f"stealthy frontiers (detection per window <= {game.max_detection:g}, alpha = {min(game.alphas):g}):",
    ]
    for f in frontiers:
        what = (
            "none admissible"
            if f.attack is None
            else (f"J = {f.j:.6f} at detection {f.detection:.4f}: {_name(f.attack)}")
        )
        lines.append(f"  {f.test:8s} test, {f.family:13s} family: {what}")
    if checks:
        lines += ["", "closed-loop Monte Carlo (fakeack.simulate_game) against the payoff formula:"]
        for c in checks:
            z = (c["monte_carlo"] - c["formula"]) / c["stderr"] if c["stderr"] > 0 else 0.0
            lines.append(
                f"  {c['policy']} / {c['attack']}: formula {c['formula']:.6f}, "
                f"simulated {c['monte_carlo']:.6f} +- {c['stderr']:.6f} ({z:+.1f} s.e.)"
            )
    if figures:
        lines += ["", f"wrote {len(figures)} figure files in {Path(figures[0]).parent}/"]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack game`` with the parsed ``args``; returns the exit code."""
    start = time.perf_counter()
    cfg, game = _config(args)
    attacks = game.attack_objects(cfg.lam, cfg.online.z0, cfg.online.mu)
    # The approximations the results rest on are reported with them (text and JSON), once each.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        sol = solve_game(
            cfg.system,
            cfg.lam,
            cfg.ratio,
            game.n_steps,
            game.alphas,
            game.fallbacks,
            attacks,
            tests=game.tests,
            rules=game.rules,
            support=game.support,
            attack_prior=game.attack_prior,
        )
        solved = time.perf_counter() - start
        frontiers = _frontiers(cfg, game)
        checks = _checks(cfg, game, sol)
    notes = list(dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, UserWarning)))
    figures: list[Path] = []
    if args.out and not args.no_figures:
        if have_matplotlib():
            out = Path(args.out)
            figures += save_figure(plot_frontiers(frontiers, j_offline=sol.j_offline), out, "fig_frontiers")
            figures += save_figure(plot_game(sol), out, "fig_game_payoff")
        else:
            print("note: figures skipped (pip install 'fakeack[plot]' for matplotlib)", file=sys.stderr)
    document = {
        "command": "game",
        "config": cfg.source,
        "lam": cfg.lam,
        "channel": channel_json(cfg.lam),
        "value": sol.value,
        "j_online": sol.j_online,
        "j_offline": sol.j_offline,
        "beta_bar": sol.beta_bar,
        "attack_prior": sol.attack_prior,
        "n_steps": game.n_steps,
        "policies": [str(p) for p in sol.policies],
        "attacks": [_name(a) for a in sol.attacks],
        "payoff": sol.payoff,
        "high_power": sol.high_power,
        "detection": sol.detection,
        "sensor_strategy": sol.sensor_strategy,
        "attacker_strategy": sol.attacker_strategy,
        "stackelberg": {
            "policy": str(sol.stackelberg.policy),
            "attack": _name(sol.stackelberg.attack),
            "payoff": sol.stackelberg.payoff,
        },
        "frontiers": [
            {
                "test": f.test,
                "family": f.family,
                "attack": _name(f.attack),
                "j": f.j,
                "detection": f.detection,
                "frontier_detection": f.frontier[0],
                "frontier_j": f.frontier[1],
            }
            for f in frontiers
        ],
        "closed_loop": checks,
        "notes": notes,
        "seconds_to_solve": solved,
        "figures": figures,
    }
    if args.out:
        atomic_write(Path(args.out) / "game.json", to_json(document) + "\n")
    if args.json:
        print(to_json(document))
        return 0
    print(_text(cfg, game, sol, frontiers, checks, figures))
    for note in notes:
        print(f"note: {note}")
    return 0
