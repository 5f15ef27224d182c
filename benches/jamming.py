"""Speed of the optimal jamming: the finite horizon (closed form, block scan, exhaustive search)
and the long-run LP.

    python benches/jamming.py [--repeat 5]

Prints wall and CPU seconds (medians over the repeats) and the load average, which matters on a
shared machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import fakeack as fa
from fakeack.optimal import optimal_jamming

PAPER = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
STABLE = fa.LinearSystem(A=0.9, C=0.7, Q=0.8, R=0.8)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)

CASES: list[tuple[str, Callable[[], object]]] = [
    ("T=100, n=30, ideal channel (closed form)", lambda: optimal_jamming(PAPER, 1.0, 30, 100)),
    ("T=100, n=30, lam=0.5 (best consecutive block)", lambda: optimal_jamming(PAPER, 0.5, 30, 100)),
    ("T=100, n=30, Gilbert-Elliott (best consecutive block)", lambda: optimal_jamming(PAPER, GE, 30, 100)),
    ("T=20, n=10, lam=0.5 (exhaustive, 184756 schedules)", lambda: optimal_jamming(PAPER, 0.5, 10, 20)),
    ("long run, rate 0.1, tau_max=200 (LP)", lambda: optimal_jamming(STABLE, 0.5, rate=0.1, tau_max=200)),
    ("long run, rate 0.1, tau_max=1000 (LP)", lambda: optimal_jamming(STABLE, 0.5, rate=0.1, tau_max=1000)),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    for name, run in CASES:
        walls, cpus = [], []
        for _ in range(args.repeat):
            w, c = time.perf_counter(), time.process_time()
            run()
            walls.append(time.perf_counter() - w)
            cpus.append(time.process_time() - c)
        print(
            f"{name}: wall {statistics.median(walls):.4f} s, cpu {statistics.median(cpus):.4f} s "
            f"(median of {args.repeat}; load average {os.getloadavg()[0]:.2f})"
        )


if __name__ == "__main__":
    main()
