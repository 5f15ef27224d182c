"""``fakeack simulate``: a Monte Carlo of one schedule against its exact finite-horizon J_H."""

from __future__ import annotations

import argparse
import csv
import io
from dataclasses import dataclass
from typing import Any

from ..attacks.chain import j_attack
from ..attacks.kinds import Attack, FlagInjection, MaskBlocking, PeriodicBlocking, RandomBlocking, as_attack
from ..model.offline import offline_search
from ..model.schedules import (
    OfflineSchedule,
    OnlineDesign,
    OnlineSchedule,
    design_online,
    j_offline,
    j_online,
)
from ..montecarlo.curves import TraceCurve, expected_trace_curve
from ..montecarlo.protocol import SimulationResult, simulate
from ..studies.report import FLAG_SIGMAS, Row
from ._channel import channel_json, channel_label, channel_text
from ._inputs import SystemInputs, resolve_system
from ._io import emit, to_json
from ._report import format_number, paragraph, system_text

__all__ = ["run"]


@dataclass(frozen=True)
class _Plan:
    """What to simulate, and its stationary cost."""

    schedule: OfflineSchedule | OnlineSchedule
    attack: Attack | None
    stationary: float


@dataclass(frozen=True)
class _Outcome:
    """The Monte Carlo result beside the exact curve of the same horizon."""

    inputs: SystemInputs
    plan: _Plan
    result: SimulationResult
    exact: TraceCurve
    row: Row


def _online_design(args: argparse.Namespace, inputs: SystemInputs) -> OnlineDesign:
    """--z0/--mu, else the config's [online], else design_online."""
    if args.z0 is not None:
        return OnlineDesign(args.z0, 1.0 if args.mu is None else args.mu)
    if args.mu is not None:
        raise ValueError("--mu needs --z0 (without them both come from design_online)")
    cfg = inputs.config
    if cfg is not None and not cfg.designed:
        return cfg.online
    return design_online(inputs.channel_arg, inputs.ratio)


def _offline(inputs: SystemInputs) -> tuple[OfflineSchedule, float]:
    """The offline schedule of the budget and its J: Theorem 3.1's on the paper's channel, else
    the best pattern of :func:`fakeack.offline_search` under the channel."""
    if inputs.channel is None:
        return OfflineSchedule(inputs.ratio), j_offline(inputs.system, inputs.lam, inputs.ratio)
    search = offline_search(inputs.system, inputs.channel, inputs.ratio)
    return OfflineSchedule(pattern="".join(str(int(b)) for b in search.pattern)), search.j


def _plan(args: argparse.Namespace, inputs: SystemInputs, attack: Attack | None) -> _Plan:
    s, lam = inputs.system, inputs.channel_arg
    if args.schedule == "offline":
        if args.z0 is not None or args.mu is not None:
            raise ValueError("--z0 and --mu apply to the online schedule only")
        if attack is not None:
            raise ValueError("--attack: an offline schedule ignores ACKs, so an attack has no effect")
        offline, j = _offline(inputs)
        return _Plan(offline, None, j)
    z0, mu = _online_design(args, inputs)
    schedule = OnlineSchedule(z0, mu)
    if attack is None:
        return _Plan(schedule, None, j_online(s, lam, z0, mu))
    return _Plan(schedule, attack, j_attack(s, lam, z0, mu=mu, attack=attack))


def _csv(outcome: _Outcome, horizon: int) -> str:
    res, exact = outcome.result, outcome.exact
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["k", "mc_trace", "mc_j_k", "exact_trace", "exact_j_k"])
    for i in range(horizon):
        writer.writerow(
            [
                i + 1,
                repr(float(res.mean_trace[i])),
                repr(float(res.j_k[i])),
                repr(float(exact.trace[i])),
                repr(float(exact.j_k[i])),
            ]
        )
    return buf.getvalue()


def _document(outcome: _Outcome) -> dict[str, Any]:
    res, row, attack = outcome.result, outcome.row, outcome.plan.attack
    return {
        "command": "simulate",
        "system": system_text(outcome.inputs.system),
        "lam": outcome.inputs.lam if outcome.inputs.channel is None else None,
        "channel": channel_json(outcome.inputs.channel_arg),
        "ratio": str(outcome.inputs.ratio),
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
        "stationary_j": outcome.plan.stationary,
        "high_power_rate": res.high_power_rate,
        "flags_sent": res.flags_sent,
        "flags_blocked": res.flags_blocked,
        "flags_forged": res.flags_forged,
        "j_k": res.j_k,
        "mean_trace": res.mean_trace,
        "exact_j_k": outcome.exact.j_k,
        "exact_trace": outcome.exact.trace,
    }


def _attack_text(attack: Attack | None) -> str:
    """The attack as the report's heading names it: its label and what it does."""
    if attack is None:
        return "no attack"
    if isinstance(attack, PeriodicBlocking):
        return f"attack {attack.label} (blocks the first {attack.r} of every {attack.t} flag-ACKs)"
    assert isinstance(attack, (MaskBlocking, RandomBlocking, FlagInjection))
    return f"attack {attack.label} ({attack})"


def _text(outcome: _Outcome) -> str:
    res, row, attack = outcome.result, outcome.row, outcome.plan.attack
    what = _attack_text(attack)
    check = f"; more than {FLAG_SIGMAS:g}: check!)" if row.flagged else ")"
    inputs = outcome.inputs
    channel = f"lam={inputs.lam:g}" if inputs.channel is None else f"channel {channel_text(inputs.channel)}"
    lines = [
        f"fakeack simulate: {res.schedule}, {what}",
        *paragraph(f"  system {system_text(inputs.system)}; {channel}; energy ratio {inputs.ratio}"),
        f"  {res.runs} runs x {res.horizon} steps, seed {res.seed}, {res.mode} mode, protocol {res.protocol}",
        "",
        f"  J_H Monte Carlo   {res.j:.6f} +- {res.stderr:.6f}",
        f"  J_H exact         {row.exact_h:.6f}   (MC - exact = {format_number(row.z, 2)} stderr" + check,
        f"  J stationary      {format_number(outcome.plan.stationary)}   "
        "(k -> infinity; J_H differs by the transient)",
        f"  high-power rate {res.high_power_rate:.6f}; flag-ACKs sent {res.flags_sent:.6f}/step, "
        f"blocked {res.flags_blocked:.6f}/step"
        + (
            ""
            if not isinstance(attack, FlagInjection)
            else f", forged {res.flags_forged:.6f}/step (taken for genuine)"
        ),
    ]
    if res.mode == "state":
        lines.append("  (state mode: the squared estimation error averaged over runs; its mean is Tr E[P_k])")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack simulate`` with the parsed ``args``; returns the exit code."""
    inputs = resolve_system(args)
    if args.runs < 2:
        raise ValueError(f"--runs must be at least 2 (the standard error needs two runs), got {args.runs}")
    if inputs.channel is not None and args.mode == "state":
        raise ValueError(
            "--mode state needs the paper's channel (one state, every high-power packet arrives); "
            f"under {channel_label(inputs.channel)} use --mode covariance"
        )
    attack = as_attack(args.attack, "--attack")
    plan = _plan(args, inputs, attack)
    result = simulate(
        inputs.system,
        inputs.channel_arg,
        plan.schedule,
        horizon=args.horizon,
        runs=args.runs,
        seed=args.seed,
        attack=plan.attack,
        mode=args.mode,
        protocol=args.protocol,
    )
    exact = expected_trace_curve(inputs.system, inputs.channel_arg, plan.schedule, args.horizon, plan.attack)
    row = Row("j", "J_H", mc=result.j, mc_stderr=result.stderr, exact_h=float(exact.j_k[-1]))
    outcome = _Outcome(inputs, plan, result, exact, row)
    if args.csv:
        emit(_csv(outcome, args.horizon), args.out)
    elif args.json:
        emit(to_json(_document(outcome)), args.out)
    else:
        emit(_text(outcome), args.out)
    return 0
