"""Parameter studies at scale: :func:`study_grid` over a grid of (system, lam, ratio[, beta]) on this
machine or any ``concurrent.futures`` executor (a Dask cluster included), resumable from its store."""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import datetime as _dt
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .cells import Block, ChannelAxes, run_block
from .channel import run_channel_block
from .dataset import _EXTRA, _attrs, _coords, _dataset, _variables
from .spec import Layout, RatioAxis, Spec, SystemsLike, spec
from .store import GridStore, StoreError, Variable

if TYPE_CHECKING:
    import xarray as xr
    from distributed import Client

__all__ = [
    "study_grid",
    "RunInfo",
    "run_study",
]


# -- executors ---------------------------------------------------------------------------------


def _is_dask_client(x: Any) -> bool:
    return type(x).__name__ == "Client" and hasattr(x, "get_executor") and hasattr(x, "scheduler_info")


def _executor(executor: Any) -> tuple[Any, bool, int]:
    """(executor, whether we own it, number of workers)."""
    if executor is None:
        n = os.cpu_count() or 1
        return cf.ThreadPoolExecutor(max_workers=2, thread_name_prefix="fakeack-grid"), True, n
    if _is_dask_client(executor):
        workers = max(1, len(executor.scheduler_info().get("workers", {})))
        return executor.get_executor(pure=False), False, workers
    if not callable(getattr(executor, "submit", None)):
        raise TypeError(
            "executor must be None, a concurrent.futures.Executor (e.g. a dask.distributed "
            f"Client's get_executor()) or a dask.distributed.Client, got {type(executor).__name__}"
        )
    context = getattr(executor, "_mp_context", None)
    if isinstance(executor, cf.ProcessPoolExecutor) and context is not None:
        if context.get_start_method() == "fork":
            raise ValueError(
                "executor: a ProcessPoolExecutor that forks can deadlock the compiled core's thread "
                "pool in its workers; create it with mp_context=multiprocessing.get_context('spawn') "
                "(or 'forkserver')"
            )
    return executor, False, getattr(executor, "_max_workers", None) or os.cpu_count() or 1


@contextlib.contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Hold Ctrl-C while a block is written, so a block is never half-recorded by an interrupt."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    try:
        old = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    except ValueError:  # not the main interpreter
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
        if caught:
            raise KeyboardInterrupt


def _bar(total: int, initial: int, progress: bool | None) -> Any:
    show = sys.stderr.isatty() if progress is None else bool(progress)
    if not show:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, initial=initial, unit="cell", desc="fakeack grid")


def _blocks(sp: Spec, layout: Layout, todo: list[int]) -> Iterator[Block]:
    for index in todo:
        region = layout.region(index)
        s, ri = region[0], region[-1]
        axes = None
        if sp.channel is not None:
            axes = ChannelAxes(sp.channel.mean[region[1]], sp.channel.memory[region[2]], sp.channel.kind)
        yield Block(
            index=index,
            system_name=sp.names[s.start],
            system=sp.systems[s.start],
            lam=() if axes is not None else sp.lam[region[1]],
            ratio=sp.ratio[ri],
            beta=sp.beta,
            family=sp.family,
            t_max=sp.t_max,
            montecarlo=sp.montecarlo,
            channel=axes,
        )


def _run(
    sp: Spec,
    layout: Layout,
    todo: list[int],
    pool: Any,
    sink: Callable[[int, dict[str, np.ndarray]], None],
    bar: Any,
) -> None:
    """Submit every block, and hand each result to ``sink`` as it comes (in the calling thread)."""
    pending: dict[Any, int] = {}
    try:
        task = run_block if sp.channel is None else run_channel_block
        for blk in _blocks(sp, layout, todo):
            pending[pool.submit(task, blk)] = blk.index
        while pending:
            done, _ = cf.wait(list(pending), return_when=cf.FIRST_COMPLETED)
            for fut in done:
                index = pending.pop(fut)
                result = fut.result()
                with _sigint_deferred():
                    sink(index, result["data"])
                if bar is not None:
                    bar.update(layout.cells(index))
    finally:
        for fut in pending:
            fut.cancel()


# -- the public function -----------------------------------------------------------------------


def study_grid(
    systems: SystemsLike,
    lam: npt.ArrayLike | None = None,
    ratio: RatioAxis | None = None,
    beta: RatioAxis | None = None,
    family: str = "periodic",
    t_max: int = 60,
    montecarlo: Mapping[str, object] | None = None,
    executor: cf.Executor | Client | None = None,
    store: str | os.PathLike[str] | None = None,
    resume: bool = False,
    block: int | None = None,
    progress: bool | None = None,
    channel: Mapping[str, object] | None = None,
) -> xr.Dataset:
    r"""Every quantity of the analysis over a grid of systems, lam, energy ratios and budgets.

    Each cell (system, lam, ratio) gets the online design of :func:`fakeack.design_online`, the
    costs :func:`fakeack.j_offline`, :func:`fakeack.j_online`, :func:`fakeack.j_max`, both
    thresholds of :func:`fakeack.beta_bar`, and at each budget β the attacked cost and the
    sensor's decision; optionally a Monte Carlo check. Every value equals the corresponding single
    call exactly. Cells are computed in blocks, batched in the compiled core (cells in parallel,
    traces shared per lam), on this machine or on any executor; the results do not depend on the
    executor, the number of workers or the block size.

    Parameters
    ----------
    systems : LinearSystem, list of LinearSystem or dict
        The systems; a dict names them (a list is named ``system0``, ``system1``, ...; one system
        ``system``).
    lam : array_like of float
        Arrival probabilities in (0, 1) of the paper's i.i.d. channel, one dimension; not with
        ``channel``.
    ratio : sequence of Fraction or str
        Energy ratios p/q in (0, 1) ("1/7", ``Fraction(1, 7)``); stored as "p/q" strings.
    beta : sequence of float, Fraction or str, optional
        Attacker budgets in [0, 1], read exactly (0.2 is 1/5).
    family : {"periodic", "random"}
        The attacked cost at each β: ``"periodic"``, the large-period worst case
        :math:`J_\infty(\beta)` of :func:`fakeack.j_attack_limit` (the decision is
        :func:`fakeack.choose_schedule`'s); ``"random"``, independent blocking with probability β
        (:class:`fakeack.RandomBlocking`), with ``beta_bar_random``.
    t_max : int
        Largest attack period of the finite threshold (default 60).
    montecarlo : dict, optional
        ``dict(runs=..., horizon=..., seed=1[, mode, protocol])``: a Monte Carlo
        (:func:`fakeack.simulate`) of the online schedule at every cell and budget, under the
        attack r/t = β in lowest terms (every flag blocked at β = 1) or independent blocking. Each
        cell's seed is a hash of ``seed`` and the cell's coordinates.
    executor : None, concurrent.futures.Executor or dask.distributed.Client
        None runs on this machine (all cores); an executor runs one task per block (a Dask
        client's ``get_executor()``, or the client itself).
    store : str or path, optional
        A zarr store to write block by block; it must not exist unless ``resume``.
    resume : bool
        With ``store``: keep the blocks already complete there and compute the rest. A store of
        another study, of another fakeack version, or not a fakeack store is refused.
    block : int, optional
        Cells per task (at most; one system and a tile of the other axes each); None picks a size.
    progress : bool or None
        A tqdm bar; None shows it when standard error is a terminal.
    channel : dict, optional
        ``dict(kind="gilbert-elliott", mean=[...], memory=[...])``: instead of ``lam``, the
        dimensions ``mean`` (the stationary low-power arrival probability, in (0, 1)) and
        ``memory`` :math:`= 1 - p - q` (below 1; 0 is the i.i.d. channel of λ = mean) of the on/off
        channel ``GilbertElliott(p, q, 1, 0)`` with :math:`p = (1 - m)(1 - \bar\lambda)`,
        :math:`q = (1 - m)\bar\lambda` (:func:`fakeack.memory_channel`). Each cell
        designs its online schedule under its channel (:func:`fakeack.design_online`), its offline
        schedule is the best pattern (:func:`fakeack.offline_search`), and every value equals the
        single call under ``fakeack.GilbertElliott(ds.p, ds.q, 1, 0)`` of that cell exactly.

    Returns
    -------
    xarray.Dataset
        Dimensions ``system, lam, ratio[, beta]`` (``system, mean, memory, ratio[, beta]`` with
        ``channel``, and coordinates ``p``, ``q`` over ``mean, memory``); variables
        ``j_offline, j_online, j_max, z0, mu, beta_bar_limit, beta_bar_finite,
        beta_bar_finite_rt, status`` (and ``beta_bar_random``),
        ``j_attack, decision`` with β, ``mc_j, mc_stderr, mc_j_analytic`` with a Monte Carlo.
        A cell that cannot be computed holds NaN (``z0`` 0, ``decision`` "n/a") and its reason in
        ``status``; where J_max is infinite the values are those of the single calls (``j_attack``
        inf, ``beta_bar_limit`` 0) and ``status`` says so. Attributes: ``fakeack_version``,
        ``fakeack_study`` (a hash of the study's definition), ``family``, ``t_max``, ``seed``,
        ``montecarlo``, ``systems`` (JSON) and ``run_time``, the only one that differs between
        runs of the same study.

    Raises
    ------
    ImportError
        Without the ``grid`` extra.
    ValueError
        Before any work starts, for a malformed grid: an empty axis, a value out of range, a
        duplicate coordinate, a ratio that no lam of the grid can meet (or a lam no ratio), an
        unknown family or Monte Carlo key, a ``channel`` with an unknown key or kind, a mean
        outside (0, 1), a memory that gives no channel of some mean, or ``lam`` together with
        ``channel``; for a store that cannot be resumed (``fakeack.grid.StoreError``).
    """
    ds, _ = run_study(
        systems,
        lam,
        ratio,
        beta,
        family,
        t_max,
        montecarlo,
        executor,
        store,
        resume,
        block,
        progress,
        channel,
    )
    return ds


@dataclass(frozen=True)
class RunInfo:
    """What one call of :func:`run_study` did."""

    blocks: int
    """Blocks of the study."""
    computed: int
    """Blocks computed by this call."""
    resumed: int
    """Blocks already complete in the store."""


def run_study(
    systems: SystemsLike,
    lam: npt.ArrayLike | None = None,
    ratio: RatioAxis | None = None,
    beta: RatioAxis | None = None,
    family: str = "periodic",
    t_max: int = 60,
    montecarlo: Mapping[str, object] | None = None,
    executor: cf.Executor | Client | None = None,
    store: str | os.PathLike[str] | None = None,
    resume: bool = False,
    block: int | None = None,
    progress: bool | None = None,
    channel: Mapping[str, object] | None = None,
) -> tuple[xr.Dataset, RunInfo]:
    """:func:`study_grid`, and how many blocks this call computed and found complete."""
    try:
        import xarray  # noqa: F401

        if store is not None:
            import zarr  # noqa: F401
    except ImportError as exc:
        raise ImportError(f"{_EXTRA}; missing: {exc.name}") from None
    sp = spec(systems, lam, ratio, beta, family, t_max, montecarlo, channel)
    pool, own, workers = _executor(executor)
    try:
        return _study(sp, pool, workers, store, resume, block, progress)
    finally:
        if own:
            pool.shutdown(wait=True, cancel_futures=True)


def _study(
    sp: Spec, pool: Any, workers: int, store: Any, resume: bool, block: Any, progress: Any
) -> tuple[Any, RunInfo]:
    from ... import __version__

    variables = _variables(sp)
    attrs = _attrs(sp)
    started = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    if store is None:
        layout = Layout.for_spec(sp, block, workers)
        values = {
            v.name: np.full((*sp.shape, *v.extent), v.fill, dtype=object if v.kind == "U" else v.dtype)
            for v in variables
        }

        def keep(index: int, data: dict[str, np.ndarray]) -> None:
            region = layout.region(index)
            for name, arr in values.items():
                arr[region] = data[name]

        bar = _bar(sp.n_cells, 0, progress)
        try:
            _run(sp, layout, list(range(layout.n_blocks)), pool, keep, bar)
        finally:
            if bar is not None:
                bar.close()
        info = RunInfo(layout.n_blocks, layout.n_blocks, 0)
        return _dataset(sp, values, {**attrs, "run_time": started}), info
    path = Path(store)
    gs, complete = _open_store(sp, path, resume, block, workers, variables, attrs, __version__)
    todo = [i for i in range(gs.layout.n_blocks) if i not in complete]
    done_cells = sum(gs.layout.cells(i) for i in complete)
    bar = _bar(sp.n_cells, done_cells, progress)
    try:
        _run(sp, gs.layout, todo, pool, gs.write_block, bar)
    finally:
        if bar is not None:
            bar.close()
    gs.finish({"run_time": started, "complete": True})
    info = RunInfo(gs.layout.n_blocks, len(todo), len(complete))
    return _dataset(sp, gs.read_all(), {**attrs, "run_time": started}), info


def _open_store(
    sp: Spec,
    path: Path,
    resume: bool,
    block: Any,
    workers: int,
    variables: list[Variable],
    attrs: dict[str, Any],
    version: str,
) -> tuple[GridStore, set[int]]:
    if path.is_file() or (path.is_dir() and any(path.iterdir())):
        if not resume:
            raise StoreError(
                f"store {str(path)!r} already exists; pass resume=True to finish it (fakeack grid "
                "--resume), or choose a new path"
            )
        requested = None if block is None else Layout.for_spec(sp, block, workers)
        gs = GridStore.open(path, requested, variables, attrs["fakeack_study"], version)
        if tuple(gs.layout.shape) != sp.shape:
            raise StoreError(f"store {str(path)!r} holds a grid of another shape {gs.layout.shape}")
        return gs, gs.verify()
    layout = Layout.for_spec(sp, block, workers)
    store_attrs = {
        **attrs,
        "fakeack_tile": list(layout.tile),
        "fakeack_shape": list(layout.shape),
        "complete": False,
    }
    return GridStore.create(path, layout, variables, _coords(sp), store_attrs), set()
