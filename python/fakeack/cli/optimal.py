"""``fakeack optimal``: the optimal policies of :mod:`fakeack.optimal` for the system of a config
and its ``[optimal]`` section (:mod:`fakeack.config.optimal`; the paper's example by default).

Three tables: the sensor's optimal power policy at each budget beside the online schedule that
spends it (:func:`fakeack.optimal_power_policy`, :func:`fakeack.design_online`); the worst attack
on the flag-ACKs at each blocking budget beside the large-period limit of the paper's consecutive
blocking (:func:`fakeack.worst_attack`, :func:`fakeack.j_attack_limit`); and the optimal jamming
of the data channel, finite-horizon and long-run (:func:`fakeack.optimal_jamming`). Every number
of the text is in the ``--json`` document (:func:`optimal_document`), which the text is printed
from.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from fractions import Fraction
from typing import Any, TypeVar

import numpy as np

from ..attacks.threshold import j_attack_limit
from ..config.analyze import Config, ConfigError, load_config, loads, parse_config
from ..config.optimal import OptimalConfig, example_text, parse_optimal
from ..config.values import config_error
from ..model.channels import Channel
from ..model.schedules import design_online, j_online
from ..optimal.attack import worst_attack
from ..optimal.jamming import optimal_jamming
from ..optimal.power import optimal_power_policy
from ._channel import channel_json
from ._inputs import option_channel
from ._io import to_json
from ._report import format_number, paragraph, system_text

__all__ = ["optimal_document", "optimal_text", "run"]

T = TypeVar("T")


def _read_config(args: argparse.Namespace) -> Config:
    """The config (the shipped example when none is given); ``--channel`` replaces its channel."""
    channel = option_channel(args)
    if not args.config:
        cfg = parse_config(
            loads(example_text(), "<example>"), "<example: the paper's system>", channel=channel
        )
    elif args.config == "-":
        cfg = parse_config(loads(sys.stdin.read(), "<stdin>"), "<stdin>", channel=channel)
    else:
        cfg = load_config(args.config, channel=channel)
    if channel is not None:
        cfg = replace(cfg, source=f"{cfg.source} with --channel {args.channel}")
    return cfg


class _ChannelRefused(Exception):
    """A function refuses the config's channel itself: its table is left out, with the reason."""


def _call(key: str, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
    """``fn(*args, **kwargs)``, a ValueError or TypeError refused by it naming the config ``key``
    (or, when the function refuses the channel itself, :class:`_ChannelRefused`)."""
    try:
        return fn(*args, **kwargs)
    except (TypeError, ValueError) as exc:
        if str(exc).startswith("channel:"):
            raise _ChannelRefused(str(exc)) from None
        raise config_error("optimal", key, f"{getattr(fn, '__name__', 'fakeack')}: {exc}") from None


def _arrivals(channel: float | Channel) -> tuple[np.ndarray, np.ndarray]:
    """The channel's low- and high-power arrival probabilities, one per state."""
    if isinstance(channel, Channel):
        return np.asarray(channel.low), np.asarray(channel.high)
    return np.array([float(channel)]), np.array([1.0])


def _online_levels(cfg: Config, opt: OptimalConfig) -> tuple[Fraction, Fraction] | None:
    """The energies (delta, Delta) of the online schedule's two levels, when the cheapest and the
    dearest level are the channel's low and high power (else None: no online schedule to compare)."""
    low, high = _arrivals(cfg.channel_arg)
    cheap = min(opt.levels, key=lambda lv: lv[0])
    dear = max(opt.levels, key=lambda lv: lv[0])
    if cheap[0] == dear[0]:
        return None
    same = [
        np.array_equal(np.broadcast_to(np.asarray(lv[1]), ref.shape), ref)
        for lv, ref in ((cheap, low), (dear, high))
    ]
    return (cheap[0], dear[0]) if all(same) else None


def _power_rows(cfg: Config, opt: OptimalConfig) -> list[dict[str, Any]]:
    """Per budget, :func:`fakeack.optimal_power_policy` and the online schedule spending it."""
    pair = _online_levels(cfg, opt)
    rows = []
    for i, budget in enumerate(opt.budgets):
        res = _call(
            f"budgets[{i}]",
            optimal_power_policy,
            cfg.system,
            cfg.channel_arg,
            opt.level_pairs,
            float(budget),
            csi=opt.csi,
            tau_max=opt.tau_max,
        )
        row: dict[str, Any] = {
            "budget": budget,
            "budget_value": float(budget),
            "j": res.j,
            "j_lp": res.j_lp,
            "tail_bound": res.tail_bound,
            "energy_per_step": res.energy_per_step,
            "tau_max": res.tau_max,
            "policy": str(res.policy),
            "share": None,
            "online": None,
            "j_online": None,
            "online_note": None,
        }
        if pair is None:
            row["online_note"] = "the cheapest and dearest levels are not the channel's low and high power"
        else:
            share = (budget - pair[0]) / (pair[1] - pair[0])
            row["share"] = share
            try:
                design = design_online(cfg.channel_arg, share)
            except ValueError as exc:
                row["online_note"] = str(exc)
            else:
                row["online"] = {"z0": design.z0, "mu": design.mu}
                row["j_online"] = j_online(cfg.system, cfg.channel_arg, design.z0, design.mu)
        rows.append(row)
    return rows


def _attack_rows(cfg: Config, opt: OptimalConfig) -> list[dict[str, Any]]:
    """Per blocking budget, :func:`fakeack.worst_attack` and :func:`fakeack.j_attack_limit`."""
    z0, mu = cfg.online
    rows = []
    for i, beta in enumerate(opt.betas):
        w = _call(
            f"betas[{i}]",
            worst_attack,
            cfg.system,
            cfg.channel_arg,
            cfg.online,
            beta,
            forge_budget=opt.forge_budget,
            stealth=opt.stealth,
            tau_max=opt.tau_max,
        )
        rows.append(
            {
                "beta": beta,
                "j": w.j,
                "j_lp": w.j_lp,
                "tail_bound": w.tail_bound,
                "blocked_fraction": w.blocked_fraction,
                "forged_fraction": w.forged_fraction,
                "tau_max": w.tau_max,
                "policy": str(w.policy),
                "j_limit": j_attack_limit(cfg.system, cfg.channel_arg, z0, beta, mu),
            }
        )
    return rows


def _jamming(cfg: Config, opt: OptimalConfig, refused: dict[str, str]) -> dict[str, Any]:
    """:func:`fakeack.optimal_jamming` at each jam budget of the horizon and each long-run rate
    (none, and the reason in ``refused``, where the long run refuses the channel)."""
    finite = []
    for i, n in enumerate(opt.n_jams):
        r = _call(f"n_jams[{i}]", optimal_jamming, cfg.system, cfg.channel_arg, n_jams=n, horizon=opt.horizon)
        finite.append({"n_jams": n, "j": r.j, "method": r.method, "jammed_steps": r.jammed_steps})
    long_run: list[dict[str, Any]] = []
    try:
        long_run = _long_run(cfg, opt)
    except _ChannelRefused as exc:
        refused["jamming"] = str(exc)
    return {"horizon": opt.horizon, "finite": finite, "long_run": long_run}


def _long_run(cfg: Config, opt: OptimalConfig) -> list[dict[str, Any]]:
    long_run = []
    for i, rate in enumerate(opt.jam_rates):
        r = _call(
            f"jam_rates[{i}]", optimal_jamming, cfg.system, cfg.channel_arg, rate=rate, tau_max=opt.tau_max
        )
        long_run.append(
            {
                "rate": rate,
                "j": r.j,
                "method": r.method,
                "j_lp": r.j_lp,
                "tail_bound": r.tail_bound,
                "jammed_fraction": r.jammed_fraction,
                "tau_max": r.tau_max,
            }
        )
    return long_run


def optimal_document(cfg: Config, opt: OptimalConfig) -> dict[str, Any]:
    """Everything ``fakeack optimal`` reports, as its ``--json`` document (before serialisation).

    Parameters
    ----------
    cfg : fakeack.config.Config
        The system, channel, energy ratio and online schedule.
    opt : fakeack.config.optimal.OptimalConfig
        The ``[optimal]`` section.

    Returns
    -------
    dict
        ``"power"``, ``"attack"`` and ``"jamming"`` (rows of the three tables, each with the
        fields of the library's result), the inputs, ``"refused"`` (per table whose function
        refuses the channel itself, e.g. a loss probability g with g rho(A)^2 >= 1 for the
        worst attack, its message; the table is then empty) and ``"seconds"`` per table.

    Raises
    ------
    fakeack.config.ConfigError
        Where a function refuses a value of the section (naming its key).
    """
    seconds: dict[str, float] = {}
    start = time.perf_counter()
    power = _power_rows(cfg, opt)
    seconds["power"] = time.perf_counter() - start
    refused: dict[str, str] = {}
    start = time.perf_counter()
    try:
        attack = _attack_rows(cfg, opt)
    except _ChannelRefused as exc:
        attack, refused["attack"] = [], str(exc)
    seconds["attack"] = time.perf_counter() - start
    start = time.perf_counter()
    jamming = _jamming(cfg, opt, refused)
    seconds["jamming"] = time.perf_counter() - start
    return {
        "command": "optimal",
        "config": cfg.source,
        "system": system_text(cfg.system),
        "lam": cfg.lam if cfg.paper_channel else None,
        "channel": channel_json(cfg.channel_arg),
        "ratio": cfg.ratio,
        "online": {"z0": cfg.online.z0, "mu": cfg.online.mu, "designed": cfg.designed},
        "j_online": j_online(cfg.system, cfg.channel_arg, cfg.online.z0, cfg.online.mu),
        "levels": [{"energy": e, "arrival": list(a)} for e, a in opt.levels],
        "csi": opt.csi,
        "tau_max": opt.tau_max,
        "forge_budget": opt.forge_budget,
        "stealth": opt.stealth,
        "power": power,
        "attack": attack,
        "jamming": jamming,
        "refused": refused,  # filled by the tables above
        "seconds": seconds,
    }


def _table(head: list[str], body: list[list[str]], left: int = 1) -> list[str]:
    """Aligned columns (the first ``left`` and the last left-aligned, the others right-aligned)."""
    widths = [max(len(cells[i]) for cells in [head, *body]) for i in range(len(head))]

    def line(cells: list[str]) -> str:
        out = [
            c.ljust(w) if i < left or i == len(cells) - 1 else c.rjust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        ]
        return "  " + "  ".join(out).rstrip()

    rule = "  " + "-" * (len(line(head)) - 2)
    return [line(head), rule, *[line(cells) for cells in body]]


def _percent(x: float, sign: bool = False) -> str:
    """``x`` in percent with two decimals; below their resolution 0 (rounding, not a sign)."""
    if x != x or abs(x) == float("inf"):
        return "-"
    x = 0.0 if abs(x) < 5e-5 else x
    return f"{x:+.2%}" if sign else f"{x:.2%}"


def _levels_text(doc: dict[str, Any]) -> str:
    return ", ".join(
        f"(energy {e['energy']}, arrival {'/'.join(f'{a:g}' for a in e['arrival'])})" for e in doc["levels"]
    )


def _power_text(doc: dict[str, Any]) -> list[str]:
    body = []
    for r in doc["power"]:
        online = "-" if r["online"] is None else f"{r['online']['z0']}, {r['online']['mu']:.6g}"
        gain = "-" if r["j_online"] is None else _percent((r["j_online"] - r["j"]) / r["j_online"])
        body.append(
            [
                str(r["budget"]),
                "-" if r["share"] is None else str(r["share"]),
                format_number(r["j"]),
                online,
                format_number(r["j_online"]),
                gain,
                r["policy"],
            ]
        )
    head = ["budget", "p/q", "J optimal", "online z0, mu", "J online", "gain", "optimal policy"]
    notes = sorted({r["online_note"] for r in doc["power"] if r["online_note"]})
    csi = ", channel state known" if doc["csi"] and len(doc["channel"]["low"]) > 1 else ""
    return [
        *paragraph(
            f"the sensor's optimal power policy (fakeack.optimal_power_policy; per-packet ACKs{csi}) "
            "against the online schedule spending the budget (fakeack.design_online):"
        ),
        f"  levels {_levels_text(doc)}",
        *_table(head, body, left=2),
        *[line for note in notes for line in paragraph(f"  online '-': {note}")],
    ]


def _attack_text(doc: dict[str, Any]) -> list[str]:
    body = [
        [
            f"{r['beta']:.6g}",
            format_number(r["j"]),
            format_number(r["j_lp"]),
            f"{r['tail_bound']:.1e}",
            format_number(r["j_limit"]),
            _percent((r["j"] - r["j_limit"]) / r["j_limit"], sign=True),
            f"{r['blocked_fraction']:.4f}",
            f"{r['forged_fraction']:.4f}",
            r["policy"],
        ]
        for r in doc["attack"]
    ]
    head = ["beta", "J worst", "j_lp", "tail", "J_inf(beta)", "excess", "blocked", "forged", "optimal attack"]
    online = doc["online"]
    stealth = doc["stealth"] or "none"
    return [
        *paragraph(
            f"the worst attack on the flag-ACKs (fakeack.worst_attack; online z0={online['z0']}, "
            f"mu={online['mu']:.6g}, J_on = {doc['j_online']:.6f}; forge budget {doc['forge_budget']:g}, "
            f"stealth {stealth}) against the large-period limit J_inf(beta) of consecutive blocking "
            "(fakeack.j_attack_limit):"
        ),
        *(
            paragraph(f"  not computed: {doc['refused']['attack']}")
            if "attack" in doc["refused"]
            else _table(head, body)
        ),
    ]


def _steps_text(steps: tuple[int, ...] | list[int]) -> str:
    steps = list(steps)
    if steps and steps == list(range(steps[0], steps[-1] + 1)) and len(steps) > 2:
        return f"{steps[0]}..{steps[-1]}"
    return ", ".join(map(str, steps)) or "-"


def _jamming_text(doc: dict[str, Any]) -> list[str]:
    jam = doc["jamming"]
    lines = [
        *paragraph(
            "optimal jamming of the data channel (fakeack.optimal_jamming; the sensor at low power), "
            f"finite horizon T={jam['horizon']} from tau_0 = 0:"
        ),
        *_table(
            ["n jams", "J", "method", "jammed steps"],
            [
                [str(r["n_jams"]), format_number(r["j"]), r["method"], _steps_text(r["jammed_steps"])]
                for r in jam["finite"]
            ],
        ),
    ]
    if "jamming" in doc["refused"]:
        lines += ["", *paragraph(f"long run: not computed: {doc['refused']['jamming']}")]
    elif not jam["long_run"] and len(doc["channel"]["low"]) > 1:
        lines += [
            "",
            "long run: not computed (it needs a one-state channel: the jammer sees tau, not the state)",
        ]
    if jam["long_run"]:
        lines += [
            "",
            "long run, the jammer seeing tau (J = inf: a policy within the rate makes the cost unbounded):",
            *_table(
                ["rate", "J", "method", "tail", "jammed fraction", "tau_max"],
                [
                    [
                        f"{r['rate']:g}",
                        format_number(r["j"]),
                        r["method"],
                        "-" if r["method"] == "unbounded" else f"{r['tail_bound']:.1e}",
                        f"{r['jammed_fraction']:.6g}",
                        str(r["tau_max"]),
                    ]
                    for r in jam["long_run"]
                ],
            ),
        ]
    return lines


def optimal_text(doc: dict[str, Any]) -> str:
    """The report of ``fakeack optimal``, from its JSON document.

    Parameters
    ----------
    doc : dict
        The document of :func:`optimal_document`.

    Returns
    -------
    str
        The three tables (power, attack, jamming), one line per row, and the time each took.
    """
    seconds = doc["seconds"]
    lines = [
        f"fakeack optimal: {doc['config']}",
        f"  system {doc['system']}; channel {doc['channel']['label']}; energy ratio {doc['ratio']}",
        "",
        *_power_text(doc),
        "",
        *_attack_text(doc),
        "",
        *_jamming_text(doc),
        "",
        f"({seconds['power']:.2f} s power, {seconds['attack']:.2f} s attack, "
        f"{seconds['jamming']:.2f} s jamming)",
    ]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack optimal`` with the parsed ``args``; returns the exit code."""
    if args.example:
        if args.config:
            raise ConfigError("config: give either CONFIG.toml or --example, not both")
        sys.stdout.write(example_text())
        return 0
    cfg = _read_config(args)
    opt = parse_optimal(cfg.raw, cfg.channel_arg, cfg.ratio)
    doc = optimal_document(cfg, opt)
    print(to_json(doc) if args.json else optimal_text(doc))
    return 0
