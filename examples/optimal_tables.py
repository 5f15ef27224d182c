"""The tables of the docs page "Optimal attacks and schedules".

    python examples/optimal_tables.py [paper|third|bursty|tail|attack|attack-other|stealth ...]

(all by default). Every number is computed here, exactly (no simulation).
"""

from __future__ import annotations

import sys
from fractions import Fraction

import fakeack as fa
from fakeack.optimal import optimal_power_policy, worst_attack

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


BETAS = [0.1, 0.25, 0.5, 0.75, 0.9]
PAPER_DESIGN = fa.OnlineDesign(2)


def attack() -> None:
    """The worst attack on the paper's example against the paper's families."""
    print("paper's example, z0 = 2, mu = 1: worst attack (eavesdropping, tau_max = 200) against")
    print("consecutive blocking's limit, the best periodic attack (t <= 60), the worst mask (t = 12), random")
    print(
        f"{'beta':>5} {'J worst':>12} {'j_lp':>12} {'J limit':>12} {'periodic':>12} {'mask 12':>12} "
        f"{'random':>12}"
    )
    for beta in BETAS:
        w = worst_attack(SYSTEM, LAM, PAPER_DESIGN, beta, tau_max=200)
        periodic = max(
            fa.j_attack(SYSTEM, LAM, 2, attack=fa.PeriodicBlocking(r, t))
            for t in range(1, 61)
            for r in range(t)
            if r <= beta * t
        )
        mask = fa.worst_mask(SYSTEM, LAM, 2, 12, round(beta * 12)).j
        random = fa.j_attack(SYSTEM, LAM, 2, attack=fa.RandomBlocking(beta))
        print(
            f"{beta:5.2f} {w.j:12.9f} {w.j_lp:12.9f} {fa.j_attack_limit(SYSTEM, LAM, 2, beta):12.9f} "
            f"{periodic:12.9f} {mask:12.9f} {random:12.9f}"
        )
        print(f"      policy: {w.policy}; flag-only automaton: {w.automaton is not None}")


def attack_other() -> None:
    """Where the state-aware attacker beats consecutive blocking's limit."""
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.4)
    cases = [
        ("lam = 0.5, z0 = 2, mu = 0.5", LAM, fa.OnlineDesign(2, 0.5)),
        ("GE(0.1, 0.3, 0.9, 0.4), z0 = 2", ge, PAPER_DESIGN),
        ("GE(0.1, 0.3, 0.9, 0.4), z0 = 3, mu = 0.6", ge, fa.OnlineDesign(3, 0.6)),
    ]
    print(f"{'case':<40} {'beta':>5} {'J worst':>10} {'J limit':>10} {'excess':>7}  policy")
    for name, channel, design in cases:
        for beta in (0.1, 0.5):
            w = worst_attack(SYSTEM, channel, design, beta)
            limit = fa.j_attack_limit(SYSTEM, channel, design.z0, beta, design.mu)
            print(f"{name:<40} {beta:5.2f} {w.j:10.6f} {limit:10.6f} {w.j / limit - 1:7.2%}  {w.policy}")
    print()
    print("forging without stealth, paper's example, beta = 0.25: the optimum does not use it")
    for phi in (0.0, 0.1, 0.5):
        w = worst_attack(SYSTEM, LAM, PAPER_DESIGN, 0.25, forge_budget=phi, tau_max=200)
        print(f"forge_budget {phi:4.2f}: J = {w.j:.9f}, forged fraction {w.forged_fraction:.3g}")


def stealth() -> None:
    """Stealthy worst attacks on the paper's example against mimicry and the offline schedule."""
    mimicry = fa.Scenario(SYSTEM, LAM, PAPER_DESIGN, fa.MimicryAttack()).cost()
    j_on = fa.Scenario(SYSTEM, LAM, PAPER_DESIGN).cost()
    j_off = fa.j_offline(SYSTEM, LAM, Fraction(1, 7))
    print(f"paper's example: J_on = {j_on:.6f}, J_off (ratio 1/7) = {j_off:.6f}, mimicry J = {mimicry:.6f}")
    print(
        f"{'stealth':<8} {'beta':>5} {'forge':>6} {'J worst':>10} {'j_lp':>10} {'blocked':>8} {'forged':>8} "
        f"{'vs mimicry':>10} {'vs J_off':>9}"
    )
    for st, beta, phi in [
        ("support", 0.5, 0.2),
        ("support", 1.0, 1.0),
        ("gap-law", 1.0, 1.0),
        ("gap-law", 0.5, 1.0),
    ]:
        w = worst_attack(SYSTEM, LAM, PAPER_DESIGN, beta, forge_budget=phi, stealth=st, tau_max=200)
        print(
            f"{st:<8} {beta:5.2f} {phi:6.2f} {w.j:10.6f} {w.j_lp:10.6f} {w.blocked_fraction:8.4f} "
            f"{w.forged_fraction:8.4f} {w.j / mimicry - 1:10.1%} {w.j / j_off - 1:9.1%}"
        )


TABLES = {
    "paper": paper,
    "third": third,
    "bursty": bursty,
    "tail": tail,
    "attack": attack,
    "attack-other": attack_other,
    "stealth": stealth,
}

if __name__ == "__main__":
    for name in sys.argv[1:] or list(TABLES):
        if name not in TABLES:
            raise SystemExit(f"unknown table {name!r}; choose from {', '.join(TABLES)}")
        TABLES[name]()
        print()
