"""The ``fakeack`` command line."""

from __future__ import annotations

import argparse
import sys
from fractions import Fraction

from . import __version__
from .attack import j_attack
from .schedules import design_online, j_max, j_offline, j_online
from .system import LinearSystem


def _reproduce(args: argparse.Namespace) -> int:
    s = LinearSystem(1.2, 0.7, 0.8, 0.8)
    lam, ratio = 0.5, Fraction(1, 7)
    z0, mu = design_online(lam, ratio)
    rows = [
        ("J_offline", j_offline(s, lam, ratio), "2.0953"),
        ("J_online", j_online(s, lam, z0, mu), "1.6399"),
        ("J_attack beta=1/5", j_attack(s, lam, z0, 1, 5), "-"),
        ("J_attack beta=2/3", j_attack(s, lam, z0, 2, 3), "-"),
        ("J_max", j_max(s, lam), "-"),
    ]
    print("The paper's example: A=1.2, C=0.7, Q=R=0.8, lam=0.5, energy ratio 1/7, z0=2")
    print(f"{'quantity':<20} {'analytic':>12} {'paper':>10}")
    for name, value, printed in rows:
        print(f"{name:<20} {value:>12.6f} {printed:>10}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fakeack`` console script."""
    parser = argparse.ArgumentParser(prog="fakeack", description=__doc__)
    parser.add_argument("--version", action="version", version=f"fakeack {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("reproduce", help="reproduce the paper's numerical example")
    rep.set_defaults(func=_reproduce)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, TypeError) as exc:
        print(f"fakeack: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
