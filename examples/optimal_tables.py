"""The tables of the docs page "Optimal attacks and schedules" (the sensor's part).

    python examples/optimal_tables.py [paper|third|bursty|tail ...]

(all four by default). Every number is computed here, exactly (no simulation).
"""

from __future__ import annotations

import sys
from fractions import Fraction

import fakeack as fa
from fakeack.optimal import optimal_power_policy

SYSTEM = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
LAM = 0.5
TWO = [(1.0, 0.5), (3.0, 1.0)]  # (energy per step, arrival probability): delta = 1, Delta = 3
THREE = [(1.0, 0.5), (2.0, 0.8), (3.0, 1.0)]
RATIOS = [
    Fraction(1, 20),
    Fraction(1, 10),
    Fraction(1, 8),
    Fraction(1, 7),
    Fraction(1, 6),
    Fraction(1, 5),
    Fraction(1, 4),
    Fraction(2, 7),
    Fraction(1, 3),
]


def budget(ratio: Fraction) -> float:
    """The energy per step of a fraction ``ratio`` of high-power steps."""
    return float(1 + 2 * ratio)


def paper() -> None:
    """Two levels on the paper's channel: the LP's optimum against the online schedule."""
    print("two levels (1, 0.5), (3, 1) on lam = 0.5: J_on (Theorem 4.5) | J of the LP's policy | LP value")
    print(f"{'p/q':>5} {'budget':>8} {'z0':>3} {'mu':>8} {'J_on':>14} {'J':>14} {'j_lp':>14}  policy")
    for r in RATIOS:
        d = fa.design_online(LAM, r)
        res = optimal_power_policy(SYSTEM, LAM, TWO, budget(r))
        print(
            f"{str(r):>5} {budget(r):8.5f} {d.z0:3d} {d.mu:8.6f} {fa.j_online(SYSTEM, LAM, *d):14.10f} "
            f"{res.j:14.10f} {res.j_lp:14.10f}  {res.policy}"
        )


def third() -> None:
    """A third level (2, 0.8) between the two: where it lowers J."""
    print("adding the level (2, 0.8): J with two levels | with three | gain")
    print(f"{'p/q':>5} {'mu':>8} {'J two':>12} {'J three':>12} {'gain':>10}  policy with three levels")
    for r in RATIOS:
        d = fa.design_online(LAM, r)
        two = optimal_power_policy(SYSTEM, LAM, TWO, budget(r))
        three = optimal_power_policy(SYSTEM, LAM, THREE, budget(r))
        print(
            f"{str(r):>5} {d.mu:8.6f} {two.j:12.8f} {three.j:12.8f} {two.j - three.j:10.2e}  {three.policy}"
        )


def bursty() -> None:
    """Gilbert-Elliott: the flag-ACK design against per-packet ACKs with channel-state information."""
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    levels = [(1.0, [0.9, 0.2]), (3.0, [1.0, 1.0])]
    print(f"{ge}, levels (1, [0.9, 0.2]), (3, [1, 1]): flag-ACK design | ACK + channel state optimum")
    print(
        f"{'p/q':>5} {'z0':>3} {'mu':>8} {'J flag-ACK':>11} {'J csi':>9} {'price':>7}"
        "  policy (state 0 good, 1 bad)"
    )
    for r in [Fraction(1, 40), Fraction(1, 20), Fraction(1, 10), Fraction(1, 7), Fraction(3, 20)]:
        d = fa.design_online(ge, r)
        j_flag = fa.j_online(SYSTEM, ge, *d)
        res = optimal_power_policy(SYSTEM, ge, levels, budget(r), csi=True)
        price = (j_flag - res.j) / res.j
        print(f"{str(r):>5} {d.z0:3d} {d.mu:8.6f} {j_flag:11.6f} {res.j:9.6f} {price:7.1%}  {res.policy}")


def tail() -> None:
    """The truncation: LP value, exact J and tail bound when tau has a tail (always the cheapest level)."""
    print(f"budget 1 (always the level (1, 0.5)); J_max = {fa.j_max(SYSTEM, LAM):.15f}")
    print(f"{'tau_max':>7} {'j_lp':>18} {'J':>18} {'J - j_lp':>10} {'tail_bound':>10}")
    for T in (10, 20, 40, 80, None):
        res = optimal_power_policy(SYSTEM, LAM, TWO, 1.0, tau_max=T)
        label = f"{res.tau_max}" + ("" if T is not None else " (auto)")
        print(f"{label:>7} {res.j_lp:18.15f} {res.j:18.15f} {res.j - res.j_lp:10.3e} {res.tail_bound:10.3e}")


TABLES = {"paper": paper, "third": third, "bursty": bursty, "tail": tail}

if __name__ == "__main__":
    for name in sys.argv[1:] or list(TABLES):
        if name not in TABLES:
            raise SystemExit(f"unknown table {name!r}; choose from {', '.join(TABLES)}")
        TABLES[name]()
        print()
