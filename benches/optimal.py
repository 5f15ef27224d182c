"""Speed of the sensor's optimal power policy and of the worst attack on the flag-ACKs: one LP
(HiGHS) plus the exact cost of its policy, on the paper's system at tau_max = 200 and with the
automatic truncation.

    python benches/optimal.py [--repeat 7] [--slow]

``--slow`` adds the gap-law program with a randomised memory (mu = 0.5, minutes per call), run once.

Prints wall and CPU seconds per call (medians over the repeats) and the load average, which
matters on a shared machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import fakeack as fa
from fakeack.optimal import optimal_power_policy, worst_attack

SYSTEM = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
CASES = [
    ("paper, 2 levels, tau_max=200", 0.5, [(1.0, 0.5), (3.0, 1.0)], 1 + 2 / 10, False, 200),
    ("paper, 3 levels, tau_max=200", 0.5, [(1.0, 0.5), (2.0, 0.8), (3.0, 1.0)], 1 + 2 / 10, False, 200),
    ("paper, 2 levels, automatic", 0.5, [(1.0, 0.5), (3.0, 1.0)], 1 + 2 / 10, False, None),
    ("Gilbert-Elliott csi, tau_max=200", GE, [(1.0, [0.9, 0.2]), (3.0, [1.0, 1.0])], 1.2, True, 200),
]

#: (name, channel, design, beta, keyword arguments of worst_attack)
ATTACKS = [
    ("worst attack, paper, beta=0.5, tau_max=200", 0.5, fa.OnlineDesign(2), 0.5, {"tau_max": 200}),
    ("worst attack, paper, beta=0.5, automatic", 0.5, fa.OnlineDesign(2), 0.5, {}),
    (
        "worst attack, paper mu=0.5, beta=0.5, tau_max=200",
        0.5,
        fa.OnlineDesign(2, 0.5),
        0.5,
        {"tau_max": 200},
    ),
    (
        "worst attack, paper, beta=0.25 + forging 0.1, tau_max=200",
        0.5,
        fa.OnlineDesign(2),
        0.25,
        {"tau_max": 200, "forge_budget": 0.1},
    ),
    (
        "worst attack, Gilbert-Elliott (0.1, 0.3, 0.9, 0.4), beta=0.5, tau_max=200",
        fa.GilbertElliott(0.1, 0.3, 0.9, 0.4),
        fa.OnlineDesign(2),
        0.5,
        {"tau_max": 200},
    ),
    (
        "worst attack, paper, stealth=gap-law, beta=1, forging 1, tau_max=200",
        0.5,
        fa.OnlineDesign(2),
        1.0,
        {"tau_max": 200, "forge_budget": 1.0, "stealth": "gap-law"},
    ),
    (
        "worst attack, paper, stealth=support, beta=0.5, forging 0.2, tau_max=200",
        0.5,
        fa.OnlineDesign(2),
        0.5,
        {"tau_max": 200, "forge_budget": 0.2, "stealth": "support"},
    ),
]

#: Cases of minutes per call, run once with ``--slow``.
SLOW_ATTACKS = [
    (
        "worst attack, paper mu=0.5, stealth=gap-law, beta=1, forging 1, tau_max=200",
        0.5,
        fa.OnlineDesign(2, 0.5),
        1.0,
        {"tau_max": 200, "forge_budget": 1.0, "stealth": "gap-law"},
    ),
]


def _timed(name: str, repeat: int, call: object) -> None:
    walls, cpus = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        res = call()  # type: ignore[operator]
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    print(
        f"{name}: wall {statistics.median(walls) * 1e3:.1f} ms, "
        f"cpu {statistics.median(cpus) * 1e3:.1f} ms "
        f"(J = {res.j:.6f}, tau_max {res.tau_max}; median of {repeat}; "
        f"load average {os.getloadavg()[0]:.2f})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--slow", action="store_true", help="also the cases of minutes per call, once")
    args = parser.parse_args()
    for name, channel, levels, budget, csi, tau_max in CASES:
        walls, cpus = [], []
        for _ in range(args.repeat):
            w, c = time.perf_counter(), time.process_time()
            res = optimal_power_policy(SYSTEM, channel, levels, budget, csi=csi, tau_max=tau_max)
            walls.append(time.perf_counter() - w)
            cpus.append(time.process_time() - c)
        print(
            f"{name}: wall {statistics.median(walls) * 1e3:.1f} ms, "
            f"cpu {statistics.median(cpus) * 1e3:.1f} ms "
            f"(J = {res.j:.6f}, tau_max {res.tau_max}; median of {args.repeat}; "
            f"load average {os.getloadavg()[0]:.2f})"
        )
    for name, channel, design, beta, kw in ATTACKS:
        _timed(name, args.repeat, lambda: worst_attack(SYSTEM, channel, design, beta, **kw))  # noqa: B023
    for name, channel, design, beta, kw in SLOW_ATTACKS if args.slow else []:
        _timed(name, 1, lambda: worst_attack(SYSTEM, channel, design, beta, **kw))  # noqa: B023


if __name__ == "__main__":
    main()
