"""Speed of the sensor's optimal power policy: one LP (HiGHS) plus the exact cost of its policy,
on the paper's system at tau_max = 200 and with the automatic truncation.

    python benches/optimal.py [--repeat 7]

Prints wall and CPU seconds per call (medians over the repeats) and the load average, which
matters on a shared machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import fakeack as fa
from fakeack.optimal import optimal_power_policy

SYSTEM = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
CASES = [
    ("paper, 2 levels, tau_max=200", 0.5, [(1.0, 0.5), (3.0, 1.0)], 1 + 2 / 10, False, 200),
    ("paper, 3 levels, tau_max=200", 0.5, [(1.0, 0.5), (2.0, 0.8), (3.0, 1.0)], 1 + 2 / 10, False, 200),
    ("paper, 2 levels, automatic", 0.5, [(1.0, 0.5), (3.0, 1.0)], 1 + 2 / 10, False, None),
    ("Gilbert-Elliott csi, tau_max=200", GE, [(1.0, [0.9, 0.2]), (3.0, [1.0, 1.0])], 1.2, True, 200),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
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


if __name__ == "__main__":
    main()
