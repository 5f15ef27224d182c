"""``fakeack grid``: a parameter study from a TOML config (:func:`fakeack.study_grid`).

Writes ``DIR/study.zarr`` block by block (Ctrl-C or a killed run leaves it consistent, and
``--resume`` finishes it), then ``DIR/study.nc`` (netCDF) and the heat maps of
:mod:`fakeack.plots.grid` (for a study over channels, the memory figures of
:func:`fakeack.plots.write_memory_figures`). ``--workers N`` runs on a ``dask.distributed.LocalCluster`` of N
worker processes, ``--scheduler ADDRESS`` on a running Dask scheduler.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..config.analyze import ConfigError
from ..config.grid import GridConfig, example_text, load_grid_config
from ..studies.grid.run import run_study
from ._io import atomic_write

__all__ = ["run"]


@contextlib.contextmanager
def _executor(args: argparse.Namespace) -> Iterator[Any]:
    """None (this machine), a LocalCluster's client, or a client of a running scheduler."""
    if not args.workers and not args.scheduler:
        yield None
        return
    from dask.distributed import Client, LocalCluster

    if args.scheduler:
        with Client(args.scheduler) as client:
            yield client
        return
    # Each worker process gets its share of the cores for the compiled core's threads: left to
    # its default, every process would start one thread per core and oversubscribe them.
    threads = max(1, (os.cpu_count() or 1) // args.workers)
    with (
        LocalCluster(
            n_workers=args.workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            env={"RAYON_NUM_THREADS": str(threads)},
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def _status_summary(ds: Any) -> str:
    kinds = Counter(str(s).split(":", 1)[0] for s in ds["status"].values.ravel())
    return ", ".join(f"{n} {k}" for k, n in kinds.most_common())


def _write_netcdf(ds: Any, path: Path) -> Path:
    """``ds`` as netCDF-4 (h5netcdf), atomically."""
    data = ds.to_netcdf(None, engine="h5netcdf")
    return atomic_write(path, bytes(data))


def _read(args: argparse.Namespace) -> GridConfig:
    if args.example:
        if args.config:
            raise ConfigError("config: give either CONFIG.toml or --example, not both")
        return None  # type: ignore[return-value]
    if not args.config:
        raise ConfigError("config: give a CONFIG.toml file (fakeack grid --example prints one)")
    return load_grid_config(args.config)


def run(args: argparse.Namespace) -> int:
    """Run ``fakeack grid`` with the parsed ``args``; returns the exit code."""
    cfg = _read(args)
    if cfg is None:
        sys.stdout.write(example_text())
        return 0
    if not args.out:
        raise ConfigError("--out DIR is required (the study is written to DIR/study.zarr)")
    out = Path(args.out)
    store = out / "study.zarr"
    if store.exists() and not args.resume:
        raise ValueError(f"{store} exists: run with --resume to finish it, or choose another --out")
    start = time.perf_counter()
    try:
        with _executor(args) as executor:
            ds, info = run_study(**cfg.arguments(), executor=executor, store=store, resume=args.resume)
    except ImportError as exc:
        print(f"fakeack: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(
            f"fakeack: interrupted; {store} keeps every finished block: run the same command with "
            "--resume to finish it",
            file=sys.stderr,
        )
        return 130
    elapsed = time.perf_counter() - start
    written = [_write_netcdf(ds, out / "study.nc")]
    figures: list[Path] = []
    if not args.no_figures:
        from ..plots.grid import write_heat_maps
        from ..plots.memory import write_memory_figures
        from ..plots.paper import have_matplotlib

        if have_matplotlib():
            figures = write_memory_figures(ds, out) if "memory" in ds.dims else write_heat_maps(ds, out)
        else:
            print("note: heat maps skipped (pip install 'fakeack[plot]' for matplotlib)", file=sys.stderr)
    dims = " x ".join(f"{ds.sizes[d]} {d}" for d in ds.sizes)
    print(f"fakeack grid: {cfg.source}: {dims} in {elapsed:.1f} s")
    print(f"  blocks: {info.blocks} in all, {info.computed} computed now, {info.resumed} already complete")
    print(f"  cells: {_status_summary(ds)}")
    print(f"  wrote {store}, {written[0]} and {len(figures)} figure files in {out}/")
    return 0
