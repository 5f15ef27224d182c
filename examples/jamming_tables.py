"""The tables of the docs page "Optimal jamming of the data channel".

    python examples/jamming_tables.py [finite|structure|longrun|unstable ...]

(all four by default). Every number is exact (no simulation).
"""

from __future__ import annotations

import sys

import numpy as np

import fakeack as fa
from fakeack.optimal import optimal_jamming

PAPER = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
STABLE = fa.LinearSystem(A=0.9, C=0.7, Q=0.8, R=0.8)
LAM = 0.5


def block_j(system: fa.LinearSystem, lam: float, T: int, steps: range) -> float:
    """J of one jam set on the paper's channel: P(tau_k = m) = lam (1-lam)^m past an unjammed
    step k - m, by propagating the law of tau (tau_0 = 0)."""
    tr = system.h_traces(T)
    law = np.zeros(T + 1)
    law[0] = 1.0
    total = 0.0
    for k in range(1, T + 1):
        p = 0.0 if k in steps else lam
        law = np.concatenate(([p * law.sum()], (1 - p) * law[:-1]))
        total += law @ tr
    return total / T


def finite() -> None:
    T = 20
    print(f"finite horizon T = {T}, paper's system, lam = {LAM} (tau_0 = 0)")
    print("| n | J optimal | method | optimal jammed steps | J block 1..n | J block ending at T |", end="")
    print(" J ideal channel |")
    print("|---|---|---|---|---|---|---|")
    for n in (1, 2, 3, 5, 8, 10, 15, 20):
        r = optimal_jamming(PAPER, LAM, n, T)
        ideal = optimal_jamming(PAPER, 1.0, n, T).j
        steps = f"{r.jammed_steps[0]}..{r.jammed_steps[-1]}" if n > 1 else str(r.jammed_steps)
        first = block_j(PAPER, LAM, T, range(1, n + 1))
        last = block_j(PAPER, LAM, T, range(T - n + 1, T + 1))
        print(f"| {n} | {r.j:.6g} | {r.method} | {steps} | {first:.6g} | {last:.6g} | {ideal:.6g} |")
    r = optimal_jamming(PAPER, LAM, 30, 100)
    print(f"\nT = 100, n = 30: J = {r.j:.6g} ({r.method}), steps {r.jammed_steps[0]}..{r.jammed_steps[-1]}")


def structure() -> None:
    print("is the exhaustive optimum a block of consecutive jams? (T = 12 and 16, every 1 <= n < T)")
    print("| channel / schedule | (T, n) whose optimum is not a block | example |")
    print("|---|---|---|")
    cases = [
        ("lam = 0.5", LAM, None),
        ("lam = 0.1", 0.1, None),
        ("lam = 0.9", 0.9, None),
        ("GilbertElliott(0.1, 0.3, 0.9, 0.2)", fa.GilbertElliott(0.1, 0.3, 0.9, 0.2), None),
        ("lam = 0.5, offline pattern 1000", LAM, fa.OfflineSchedule(pattern="1000")),
        ("lam = 0.5, offline 1/7", LAM, fa.OfflineSchedule("1/7")),
    ]
    for name, ch, sched in cases:
        bad = []
        for T in (12, 16):
            for n in range(1, T):
                st = optimal_jamming(PAPER, ch, n, T, schedule=sched).jammed_steps
                assert st is not None
                if st[-1] - st[0] != n - 1:
                    bad.append((T, n, st))
        example = f"T={bad[0][0]}, n={bad[0][1]}: {bad[0][2]}" if bad else "-"
        print(f"| {name} | {len(bad)} of 26 | {example} |")


def longrun() -> None:
    lim_j, tr_inf = fa.j_max(STABLE, LAM), 0.8 / (1 - 0.81)
    print(f"long run, A = 0.9 (C, Q, R of the paper), lam = {LAM}; ", end="")
    print(f"unjammed J = {lim_j:.6g}, tr_inf = {tr_inf:.6g}")
    print("| rate | tau_max | J | j_lp | tail_bound | jammed below tau_max | jam prob. at tau_max |", end="")
    print(" (1-r) J + r tr_inf |")
    print("|---|---|---|---|---|---|---|---|")
    for rate in (0.01, 0.1, 0.3):
        for m in (5, 10, 20, 200):
            r = optimal_jamming(STABLE, LAM, rate=rate, tau_max=m)
            assert r.jam_probability is not None and r.idle_probability is not None
            below = (
                "none"
                if not r.jam_probability[:m].any()
                else str(np.flatnonzero(r.jam_probability[:m]).tolist())
            )
            at = f"1 - {r.idle_probability[m]:.3g}"
            print(
                f"| {rate} | {m} | {r.j:.6g} | {r.j_lp:.6g} | {r.tail_bound:.3g} | {below} | {at} | "
                f"{(1 - rate) * lim_j + rate * tr_inf:.6g} |"
            )


def unstable() -> None:
    rho2 = PAPER.spectral_radius**2
    x_star = 1 - (1 - 1 / rho2) / LAM
    print(f"long run on the paper's system (rho(A)^2 = {rho2:.4g}), lam = {LAM}: holding the jam probability")
    print(f"x* = {x_star:.6g} beyond tau_max makes J infinite; the jammed fraction f* this costs:")
    print("| tau_max | f* | optimal_jamming(rate=0.01): method | J | j_lp | tail_bound |")
    print("|---|---|---|---|---|---|")
    a = 1 - LAM
    for m in (1, 2, 3, 4, 5, 6, 7, 8, 10, 20, 200):
        below, at_m = (1 - a**m) / LAM, a**m / ((1 - x_star) * LAM)
        f_star = x_star * at_m / (below + at_m)
        r = optimal_jamming(PAPER, LAM, rate=0.01, tau_max=m)
        print(f"| {m} | {f_star:.3g} | {r.method} | {r.j:.6g} | {r.j_lp:.6g} | {r.tail_bound:.3g} |")


TABLES = {"finite": finite, "structure": structure, "longrun": longrun, "unstable": unstable}

if __name__ == "__main__":
    for name in sys.argv[1:] or list(TABLES):
        TABLES[name]()
        print()
