#!/usr/bin/env python
"""fakeack.study_grid against a plain Python loop over the single functions, locally and on Dask.

The study: the paper's system (A = 1.2, C = 0.7, Q = R = 0.8) over a lam x ratio grid (lam from
0.3 to 0.8, ratio from 1/20 to 1/5, both evenly spaced, exact), budgets beta = 1/5 and 1/2,
t_max = 60, no Monte Carlo. Every cell gets J_offline, the online design, J_online, J_max, both
thresholds, J_inf(beta) and the decision at each beta.

Rows (cells per second; the median of ``--repeats`` runs):

* ``loop``: for each cell ``fa.j_offline``, ``fa.design_online``, ``fa.j_online``, ``fa.j_max``,
  ``fa.beta_bar`` (given the design), and per beta ``fa.j_attack_limit`` and ``fa.choose_schedule``
  (given the design) -- the loop a user would write, already passing the design on instead of
  recomputing it. Timed on a random sample of ``--loop-cells`` cells of the 100 x 100 grid (the
  per-cell cost does not depend on the grid's size); checked to equal the grid's cells.
* ``local``: ``fa.study_grid(..., executor=None)`` over 100 x 100 cells (this machine, all cores).
* ``cluster``: the same on a ``dask.distributed.LocalCluster(n_workers=2, processes=True)`` (the
  compiled core limited to one thread per worker with ``RAYON_NUM_THREADS=1``) that is
  started (and warmed up with one tiny study) before timing.
* ``local 1e5`` / ``cluster 1e5``: 100 x 1000 cells, where the target asks the cluster to stay within
  20% of the local time.

Usage::

    python benches/grid.py                 # everything, about a minute on 2 cores
    python benches/grid.py --quick         # 30 x 30 and 100 x 100 cells only
    python benches/grid.py --json out.json

Timings depend on the machine and its load; the header prints the core count and load average.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from fractions import Fraction

import numpy as np

import fakeack as fa

BETAS = [Fraction(1, 5), Fraction(1, 2)]


def axes(n_lam: int, n_ratio: int) -> tuple[list[float], list[Fraction]]:
    lam = [float(Fraction(3, 10) + i * Fraction(1, 2) / (n_lam - 1)) for i in range(n_lam)]
    lo, hi = Fraction(1, 20), Fraction(1, 5)
    ratio = [lo + k * (hi - lo) / (n_ratio - 1) for k in range(n_ratio)]
    return lam, ratio


def loop_cell(s: fa.LinearSystem, lam: float, ratio: Fraction) -> tuple:
    j_off = fa.j_offline(s, lam, ratio)
    try:
        z0, mu = fa.design_online(lam, ratio)
    except ValueError:
        return (j_off,)
    j_on = fa.j_online(s, lam, z0, mu)
    fa.j_max(s, lam)
    bar = fa.beta_bar(s, lam, ratio, 60, z0=z0, mu=mu)
    att = [fa.j_attack_limit(s, lam, z0, b, mu) for b in BETAS]
    dec = [fa.choose_schedule(s, lam, ratio, b, z0=z0, mu=mu).schedule for b in BETAS]
    return (j_off, j_on, bar.limit, bar.finite, att, dec)


def time_loop(s: fa.LinearSystem, n_cells: int, repeats: int) -> tuple[float, list]:
    lam, ratio = axes(100, 100)
    rng = np.random.default_rng(1)
    idx = rng.choice(len(lam) * len(ratio), n_cells, replace=False)
    cells = [(lam[k // len(ratio)], ratio[k % len(ratio)]) for k in idx]
    times, out = [], []
    for _ in range(repeats):
        t = time.perf_counter()
        out = [loop_cell(s, lam_, r) for lam_, r in cells]
        times.append(time.perf_counter() - t)
    return n_cells / statistics.median(times), list(zip(cells, out, strict=True))


def clear_designs() -> None:
    """Forget what a previous run cached (how each lam reads as a fraction), so every run starts cold."""
    from fakeack.studies.grid.design import _lam_parts

    _lam_parts.cache_clear()


def time_grid(
    s: fa.LinearSystem, n_lam: int, n_ratio: int, repeats: int, executor=None
) -> tuple[float, object]:
    lam, ratio = axes(n_lam, n_ratio)
    times, ds = [], None
    for _ in range(repeats):
        clear_designs()
        if executor is not None:
            executor.run(clear_designs)
        t = time.perf_counter()
        ds = fa.study_grid(s, lam, ratio, BETAS, t_max=60, executor=executor, progress=False)
        times.append(time.perf_counter() - t)
    return n_lam * n_ratio / statistics.median(times), ds


def check(ds, sample: list) -> None:
    """The loop's values equal the grid's cells."""
    for (lam, ratio), got in sample:
        c = ds.sel(system="system", lam=lam, ratio=str(ratio))
        assert float(c["j_offline"]) == got[0]
        if len(got) > 1:
            assert float(c["j_online"]) == got[1] and float(c["beta_bar_limit"]) == got[2]
            assert list(c["j_attack"].values) == got[4] and list(c["decision"].values) == got[5]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--loop-cells", type=int, default=300)
    parser.add_argument("--json", metavar="FILE")
    args = parser.parse_args()
    print(f"cores: {os.cpu_count()}, load average: {os.getloadavg()[0]:.2f}")
    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    fa.study_grid(s, *axes(3, 3), BETAS, progress=False)  # imports and first-call costs
    records = []

    def row(name: str, cells: int, rate: float, base: float | None) -> None:
        speed = "" if base is None else f"  {rate / base:6.1f}x the loop"
        print(f"{name:<22} {cells:>7} cells  {rate:>10.0f} cells/s{speed}")
        records.append({"row": name, "cells": cells, "cells_per_second": rate})

    loop_rate, sample = time_loop(s, args.loop_cells, args.repeats)
    row("loop (sampled)", args.loop_cells, loop_rate, None)
    local_rate, ds = time_grid(s, 100, 100, args.repeats)
    check(ds, sample)
    row("local", 10_000, local_rate, loop_rate)
    from dask.distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            env={"RAYON_NUM_THREADS": "1"},  # one core each, as `fakeack grid --workers 2` does
        ) as cluster,
        Client(cluster) as client,
    ):
        fa.study_grid(s, *axes(3, 3), BETAS, executor=client, progress=False)  # warm the workers
        rate, ds_c = time_grid(s, 100, 100, args.repeats, client)
        assert ds_c["j_attack"].equals(ds["j_attack"])
        row("cluster (2 workers)", 10_000, rate, loop_rate)
        if not args.quick:
            big_local, ds_l = time_grid(s, 100, 1000, args.repeats)
            row("local 1e5", 100_000, big_local, loop_rate)
            big_cluster, ds_b = time_grid(s, 100, 1000, args.repeats, client)
            assert ds_b["beta_bar_limit"].equals(ds_l["beta_bar_limit"])
            row("cluster 1e5", 100_000, big_cluster, loop_rate)
            print(f"cluster time / local time at 1e5 cells: {big_local / big_cluster:.2f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(records, fh, indent=2)


if __name__ == "__main__":
    main()
