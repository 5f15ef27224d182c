"""The tables of the documentation's "Sequential detection" page, for the paper's example.

    python examples/sequential_tables.py [runlengths|closedloop|frontier|tuned|filter ...]

(all five by default). Every number is computed here; the simulated ones have fixed seeds.
"""

from __future__ import annotations

import sys
from fractions import Fraction

import fakeack as fa

SYSTEM = fa.LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8)
LAM, RATIO = 0.5, Fraction(1, 7)
DESIGN = fa.OnlineDesign(2)
ATTACKS = [
    None,
    fa.RandomBlocking(0.2),
    fa.RandomBlocking(0.5),
    fa.PeriodicBlocking(1, 5),
    fa.FlagInjection(0.05, min_gap=3),
    fa.rate_matching_attack(LAM, 2, 0.5, min_gap=3),
    fa.MimicryAttack(),
]


def _name(a: object) -> str:
    return "none" if a is None else getattr(a, "label", str(a))


def runlengths() -> None:
    """Mean run lengths of a CUSUM against RandomBlocking(0.5), threshold 4: renewal and steady state."""
    test = fa.CusumTest(fa.RandomBlocking(0.5), 4.0)
    print(f"{test}: mean steps to the alarm (renewal start | steady state), +- the stated accuracy")
    for a in ATTACKS:
        r = fa.cusum_run_length(LAM, DESIGN, test, a)
        try:
            s = fa.cusum_run_length(LAM, DESIGN, test, a, "stationary")
            steady = f"{s.mean:10.1f} +- {s.error:.1f}"
        except ValueError:
            steady = "         -"
        print(
            f"  {_name(a):45s} {r.mean:10.1f} +- {r.error:<6.1f} | {steady}   [{r.lower:.1f}, {r.upper:.1f}]"
        )


def closedloop() -> None:
    """The closed loop's steps per alarm (64 runs x 4e5 steps, seed 7) against the run length."""
    test = fa.CusumTest(fa.RandomBlocking(0.5), 2.5)
    print(f"{test}, 1 window of 100 steps offline after an alarm: steps per alarm, exact | closed loop")
    for a in (None, fa.RandomBlocking(0.5), fa.PeriodicBlocking(1, 3)):
        arl = fa.cusum_run_length(LAM, DESIGN, test, a)
        pol = fa.SensorPolicy("cusum", fallback=1, cusum=test)
        sim = fa.simulate_game(SYSTEM, LAM, RATIO, pol, a, 400_000, 64, seed=7, n_steps=100)
        se = sim.alarm_stderr / sim.alarm_rate**2
        print(f"  {_name(a):45s} {arl.mean:9.1f} | {1 / sim.alarm_rate:9.1f} +- {se:.1f}")


def frontier(
    alternative: object = None, families: tuple[str, ...] = ("random", "careful", "periodic", "mimicry")
) -> None:
    """The delay frontier at a mean time to a false alarm of 1e5 steps (count test: 1000-step windows
    at alpha = 0.01)."""
    fronts = [fa.delay_frontier(SYSTEM, LAM, RATIO, 1e5, fam, alternative=alternative) for fam in families]
    f0 = fronts[0]
    print(
        f"{f0.cusum}; J_online = {f0.j_online:.4f}, J_offline = {f0.j_offline:.4f}\n"
        "  attack                                          J      CUSUM delay     count: d, delay"
        "      interval: d, delay"
    )
    for f in fronts:
        rows = zip(
            f.attacks,
            f.j,
            f.cusum_delay,
            f.cusum_error,
            f.window_detection,
            f.window_delay,
            f.interval_detection,
            f.interval_delay,
            strict=True,
        )
        for a, j, dl, e, d, wd, di, wi in rows:
            print(f"  {_name(a):45s} {j:7.4f} {dl:10.0f} +- {e:<5.0f} {d:8.4f} {wd:9.0f} {di:8.4f} {wi:9.0f}")


def tuned() -> None:
    """The frontier when the CUSUM is tuned to the careful rate-matching forger at beta = 0.5."""
    frontier(fa.rate_matching_attack(LAM, 2, 0.5, min_gap=3), ("careful", "random"))


def filter_table(arl0: float = 1000.0, runs: int = 10_000) -> None:
    """The renewal and the filter CUSUM against RandomBlocking(0.5) on Gilbert-Elliott channels, at
    equal ARL0: the renewal's threshold and run lengths exact, the filter's simulated (runs each,
    seeds fixed), +- one standard error."""
    alt = fa.RandomBlocking(0.5)
    attacks = [
        None,
        fa.RandomBlocking(0.5),
        fa.RandomBlocking(0.2),
        fa.PeriodicBlocking(1, 5),
        fa.FlagInjection(0.05, min_gap=3),
        fa.MimicryAttack(),
    ]
    print(f"CUSUM against {alt}, ARL0 = {arl0:g}: mean steps to the alarm, renewal | filter")
    for ch in (fa.GilbertElliott(0.1, 0.3, 0.9, 0.2), fa.GilbertElliott(0.02, 0.06, 0.9, 0.2)):
        h_r = fa.cusum_threshold(ch, DESIGN, alt, arl0)
        h_f = fa.cusum_threshold(ch, DESIGN, alt, arl0, likelihood="filter", runs=runs, seed=1)
        renewal = fa.CusumTest(alt, h_r)
        filt = fa.CusumTest(alt, h_f, likelihood="filter")
        print(f"  {ch!r}: thresholds {h_r:.4f} (renewal) | {h_f:.4f} (filter)")
        for a in attacks:
            r = fa.cusum_run_length(ch, DESIGN, renewal, a)
            f = fa.cusum_run_length(ch, DESIGN, filt, a, runs=runs, seed=2)
            print(f"    {_name(a):45s} {r.mean:9.1f} +- {r.error:<6.1f} | {f.mean:9.1f} +- {f.error:.1f}")


TABLES = {
    "runlengths": runlengths,
    "closedloop": closedloop,
    "frontier": frontier,
    "tuned": tuned,
    "filter": filter_table,
}

if __name__ == "__main__":
    for name in sys.argv[1:] or list(TABLES):
        TABLES[name]()
        print()
