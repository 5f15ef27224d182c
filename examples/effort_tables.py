"""The tables of the docs sections "Which attack to buy" and "The most robust online design".

    python examples/effort_tables.py [effort|costs|robust ...]

(all by default). Every number is computed here, exactly (no simulation).
"""

from __future__ import annotations

import sys
import time
from fractions import Fraction

import fakeack as fa
from fakeack.optimal import attack_effort, robust_design

SYSTEM = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
LAM = 0.5


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def effort() -> None:
    """J per kind against effort at unit costs, p/q = 1/7, and the best kind with and without fall-back."""
    t = time.perf_counter()
    res = attack_effort(SYSTEM, LAM, Fraction(1, 7), [0.0, 0.01, 0.02, 0.04, 1 / 12, 0.12, 1 / 6])
    took = time.perf_counter() - t
    print(f"{res.design}; J_on = {res.j_online:.6f}, J_off = {res.j_offline:.6f}; {took:.2f} s")
    print(_row(["effort", *res.kinds, "best", "best, fall-back sensor (its J)"]))
    print(_row(["---"] * (len(res.kinds) + 3)))
    for k, e in enumerate(res.effort):
        cells = [f"{e:.4g}", *(f"{res.j[i, k]:.6f}" for i in range(len(res.kinds)))]
        cells += [res.best[k], f"{res.best_fallback[k]} ({res.j_best_fallback[k]:.6f})"]
        print(_row(cells))


def costs() -> None:
    """When is blocking worth it: the best kind at effort 0.04 as jamming grows dearer."""
    print(_row(["jam_cost / block_cost", "J jam-high", "J block", "best", "best, fall-back sensor"]))
    print(_row(["---"] * 5))
    for c in (1.0, 1.5, 2.0, 3.0, 4.0):
        res = attack_effort(SYSTEM, LAM, Fraction(1, 7), [0.04], jam_cost=c, kinds=("jam-high", "block"))
        print(_row([f"{c:g}", f"{res.j[0, 0]:.6f}", f"{res.j[1, 0]:.6f}", res.best[0], res.best_fallback[0]]))


def robust() -> None:
    """The most robust design against the nominal one, per ratio and beta."""
    print(_row(["p/q", "beta", "nominal (z0, mu)", "its worst J", "robust (z0, mu)", "its worst J", "J_off"]))
    print(_row(["---"] * 7))
    for ratio in (Fraction(1, 10), Fraction(1, 7), Fraction(1, 5)):
        for beta in (0.0, 0.25, 0.5, 0.9):
            r = robust_design(SYSTEM, LAM, ratio, beta)
            print(
                _row(
                    [
                        str(ratio),
                        f"{beta:g}",
                        f"({r.nominal.z0}, {r.nominal.mu:.4g})",
                        f"{r.j_nominal_worst:.6f}",
                        f"({r.design.z0}, {r.design.mu:.4g})",
                        f"{r.j_worst:.6f}",
                        f"{r.j_offline:.6f}",
                    ]
                )
            )


TABLES = {"effort": effort, "costs": costs, "robust": robust}

if __name__ == "__main__":
    for name in sys.argv[1:] or list(TABLES):
        TABLES[name]()
        print()
