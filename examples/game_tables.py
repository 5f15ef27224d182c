"""The tables of the README's "Detection and the game", for the paper's example.

    python examples/game_tables.py [detection|frontier|windows|responses|curves|lr ...]

(all by default). Every number is computed here; the simulated ones have fixed seeds.
"""

from __future__ import annotations

import sys
from fractions import Fraction

import fakeack as fa
from fakeack.game.frontier import FAMILIES

SYSTEM = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
LAM, RATIO, Z0 = 0.5, Fraction(1, 7), 2


def detection() -> None:
    """Detection probability per window: formula against simulated stationary windows."""
    n, alpha, runs = 1000, 0.01, 40_000
    print(f"detection per window of {n} steps at alpha = {alpha}: formula | simulated ({runs} windows)")
    attacks = [
        None,
        fa.PeriodicBlocking(1, 5),
        fa.PeriodicBlocking(3, 20),
        fa.RandomBlocking(0.2),
        fa.FlagInjection(0.02),
        fa.rate_matching_attack(LAM, Z0, 0.2),
        fa.rate_matching_attack(LAM, Z0, 0.5),
    ]
    for a in attacks:
        row = []
        for test in ("count", "interval"):
            p = fa.detection_probability(LAM, Z0, a, n, alpha, test)
            r = fa.detection_rates(
                LAM,
                Z0,
                a or fa.PeriodicBlocking(0, 1),
                n,
                runs,
                alpha=alpha,
                seed=7,
                test=test,
                alternative="two-sided",
                burn_in=n,
                support=False,  # the formula is the test's alone
            )
            if a is None:
                sim, se = r.false_alarm, r.false_alarm_stderr
            else:
                sim, se = r.detection, r.detection_stderr
            row.append(f"{p:.4f} | {sim:.4f} ± {se:.4f}")
        print(f"| {'no attack' if a is None else a} | " + " | ".join(row) + " |", flush=True)


def frontier() -> None:
    """The best attack of each family at a detection probability of at most 0.02 (alpha = 0.01),
    with the support check beside each test (the default)."""
    for n in (1000, 10_000):
        for test in ("count", "interval"):
            cells = []
            for family in FAMILIES:
                f = fa.stealthy_frontier(SYSTEM, LAM, Z0, n, 0.01, test, family, 0.02, t_max=60)
                cells.append(f"{f.j:.4f} at {f.detection:.4f}: {f.attack}")
            print(f"| {n} | {test} | " + " | ".join(cells) + " |", flush=True)


def windows() -> None:
    """The payoff formula against the closed loop, short to long windows."""
    pairs = [
        (fa.SensorPolicy("count", 0.01, 2), fa.PeriodicBlocking(1, 5)),
        # Without the support check, which would see the forger in nearly every window.
        (fa.SensorPolicy("interval", 0.05, 2, support=False), fa.rate_matching_attack(LAM, Z0, 0.3)),
    ]
    for pol, att in pairs:
        # The interval test needs 100 expected flag-ACKs per window (700 steps here).
        for n in (100, 300, 1000, 3000, 10_000) if pol.test == "count" else (1000, 3000, 10_000):
            p = fa.game_payoff(SYSTEM, LAM, RATIO, pol, att, n)
            g = fa.simulate_game(
                SYSTEM, LAM, RATIO, pol, att, 210 * n, 1024, seed=3, n_steps=n, burn_in=20 * n
            )
            print(
                f"| {pol} | {att} | {n} | {p.j:.4f} | {g.j:.4f} ± {g.stderr:.4f} | "
                f"{g.j - p.j:+.4f} | {p.detection:.3f} | {g.fallback_rate:.3f} |",
                flush=True,
            )


def responses() -> None:
    """Payoffs that show why the two fall-back rules differ."""
    cases = [
        (fa.SensorPolicy("count", 0.01, 4), fa.FlagInjection(0.05)),
        (fa.SensorPolicy("count", 0.01, 4, "harmful"), fa.FlagInjection(0.05)),
        (fa.SensorPolicy("never"), fa.FlagInjection(0.05)),
        (fa.SensorPolicy("count", 0.01, 4), fa.rate_matching_attack(LAM, Z0, 0.8)),
        (fa.SensorPolicy("count", 0.01, 4, "harmful"), fa.rate_matching_attack(LAM, Z0, 0.8)),
        (fa.SensorPolicy("interval", 0.01, 4), fa.rate_matching_attack(LAM, Z0, 0.8)),
        (fa.SensorPolicy("interval", 0.01, 4, "harmful"), fa.rate_matching_attack(LAM, Z0, 0.8)),
        (fa.SensorPolicy("interval", 0.01, 4), fa.PeriodicBlocking(2, 3)),
        # The careful attacker: rate matching that never forges within z0 steps of the last
        # flag-ACK (the support check never sees it), and mimicry.
        (fa.SensorPolicy("count", 0.01, 4), fa.rate_matching_attack(LAM, Z0, 0.8, min_gap=Z0 + 1)),
        (fa.SensorPolicy("count", 0.01, 4, "harmful"), fa.rate_matching_attack(LAM, Z0, 0.8, min_gap=Z0 + 1)),
        (fa.SensorPolicy("interval", 0.01, 4), fa.rate_matching_attack(LAM, Z0, 0.8, min_gap=Z0 + 1)),
        (fa.SensorPolicy("count", 0.01, 4), fa.MimicryAttack()),
        (fa.SensorPolicy("interval", 0.01, 4), fa.MimicryAttack()),
    ]
    for pol, att in cases:
        p = fa.game_payoff(SYSTEM, LAM, RATIO, pol, att, 1000)
        print(f"| {pol} | {att} | {p.j_attack:.4f} | {p.detection:.3f} | {p.j:.4f} |")


def curves() -> None:
    """Detection probability per window against the window length (the docs page's figure)."""
    c = fa.detection_curves(LAM, Z0, CURVE_ATTACKS, CURVE_WINDOWS)
    for i, test in enumerate(c.tests):
        for j, a in enumerate(c.attacks):
            cells = " | ".join("-" if x != x else f"{x:.4f}" for x in c.probability[i, j])
            print(f"| {test} | {'no attack' if a is None else a} | {cells} |")


def lr() -> None:
    """The likelihood-ratio test beside the count, interval and support tests, at equal alpha
    (the docs page's section "The likelihood-ratio test")."""
    from fakeack.detection import likelihood_ratio_law, likelihood_ratio_test

    n, alpha = 1000, 0.01
    careful = fa.FlagInjection(0.02, min_gap=Z0 + 1)
    tuned = {"lr vs blocking": fa.RandomBlocking(0.2), "lr vs careful forger": careful}
    attacks = [
        None,
        fa.RandomBlocking(0.2),
        fa.RandomBlocking(0.5),
        fa.PeriodicBlocking(1, 5),
        careful,
        fa.rate_matching_attack(LAM, Z0, 0.2),
        fa.rate_matching_attack(LAM, Z0, 0.2, min_gap=Z0 + 1),
        fa.rate_matching_attack(LAM, Z0, 0.975, min_gap=Z0 + 1),
        fa.MimicryAttack(),
    ]
    names = ["count", "interval", "support", *tuned]
    print(f"detection per window of {n} steps at alpha = {alpha}; lr: estimate (grid error)")
    print("| attack | " + " | ".join(names) + " |")
    for a in attacks:
        row = [f"{fa.detection_probability(LAM, Z0, a, n, alpha, t):.4f}" for t in names[:3]]
        for alt in tuned.values():
            test = likelihood_ratio_test(LAM, Z0, n, alpha, alternative=alt)
            p = test.detection_probability(a)
            coarse = likelihood_ratio_law(LAM, Z0, n, a, alternative=alt, resolution=4.0).tail(test.critical)
            row.append(f"{p:.4f} ({abs(p - coarse):.1g})")
        print(f"| {'no attack' if a is None else a} | " + " | ".join(row) + " |", flush=True)


#: The attacks and windows of the detection curves.
CURVE_ATTACKS = [
    None,
    fa.PeriodicBlocking(1, 5),
    fa.rate_matching_attack(LAM, Z0, 0.2),
    fa.rate_matching_attack(LAM, Z0, 0.2, min_gap=Z0 + 1),
    fa.rate_matching_attack(LAM, Z0, 0.975, min_gap=Z0 + 1),
    fa.MimicryAttack(),
]
CURVE_WINDOWS = [200, 500, 1000, 2000, 5000, 10_000]


if __name__ == "__main__":
    tables = {
        "detection": detection,
        "frontier": frontier,
        "windows": windows,
        "responses": responses,
        "curves": curves,
        "lr": lr,
    }
    for name in sys.argv[1:] or list(tables):
        tables[name]()
