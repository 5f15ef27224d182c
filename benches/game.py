"""Speed of the game: solving 50 sensor policies x 200 attacks on the paper's system (every payoff
included), and the closed-loop Monte Carlo in covariance steps per second.

    python benches/game.py [--repeat 5]

Prints wall and CPU seconds (medians over the repeats) and the load average, which matters on a
shared machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from fractions import Fraction

import numpy as np

import fakeack as fa


def attacks(lam: float = 0.5, z0: int = 2) -> list:
    """200 attacks: none, periodic r/t (t <= 12), random, injection, rate matching, mixed."""
    out: list = [None]
    out += [fa.PeriodicBlocking(r, t) for t in range(2, 13) for r in range(1, t)]  # 66
    out += [fa.RandomBlocking(b) for b in np.linspace(0.025, 1.0, 40)]
    out += [fa.FlagInjection(g) for g in np.linspace(0.01, 0.2, 20)]
    out += [fa.rate_matching_attack(lam, z0, b) for b in np.linspace(0.02, 0.9, 45)]
    out += [fa.FlagInjection(0.02, fa.PeriodicBlocking(1, t)) for t in range(2, 30)]
    return out[:200]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    system, lam, ratio = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8), 0.5, Fraction(1, 7)
    atts = attacks()
    walls, cpus = [], []
    for _ in range(args.repeat):
        fa.intervals._walk.cache_clear()  # every payoff from scratch
        fa.detectors._TESTS.clear()
        w, c = time.perf_counter(), time.process_time()
        sol = fa.solve_game(system, lam, ratio, 1000, [0.001, 0.01, 0.05], [0, 1, 2, 4], atts)
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    print(
        f"solve_game {sol.payoff.shape[0]} policies x {sol.payoff.shape[1]} attacks: "
        f"wall {statistics.median(walls):.3f} s, cpu {statistics.median(cpus):.3f} s "
        f"(median of {args.repeat}; load average {os.getloadavg()[0]:.2f})"
    )
    policy = fa.SensorPolicy("interval", 0.01, 2)
    for attack in (None, fa.PeriodicBlocking(1, 5), fa.rate_matching_attack(lam, 2, 0.2)):
        runs, horizon = 4096, 100_000
        rates = []
        for _ in range(max(1, args.repeat // 2)):
            w = time.perf_counter()
            fa.simulate_game(
                system, lam, ratio, policy, attack, horizon, runs, seed=1, n_steps=1000, progress=False
            )
            rates.append(runs * horizon / (time.perf_counter() - w))
        print(
            f"simulate_game ({policy}; {'no attack' if attack is None else attack}): "
            f"{statistics.median(rates):.3g} covariance steps/s (load average {os.getloadavg()[0]:.2f})"
        )


if __name__ == "__main__":
    main()
