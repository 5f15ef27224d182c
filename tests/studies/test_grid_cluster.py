"""fakeack.study_grid on a Dask LocalCluster (2 worker processes), a worker killed mid-study, and
the command line killed part-way (SIGINT, then SIGKILL) and resumed. Kept small: a few seconds each.
"""

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from test_grid import BETAS, LAMS, RATIOS, TWO_STATE, assert_same_dataset

import fakeack as fa
from conftest import PAPER

distributed = pytest.importorskip("distributed")
zarr = pytest.importorskip("zarr")
xr = pytest.importorskip("xarray")

MC = dict(runs=64, horizon=30, seed=5)


@pytest.fixture(scope="module")
def client():
    with (
        # The scheduler's HTTP server on a free port: another test may hold 8787 at the same time.
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        distributed.Client(cluster) as c,
    ):
        yield c


@pytest.fixture(scope="module")
def systems():
    return {"paper": fa.LinearSystem(**PAPER), "two": fa.LinearSystem(**TWO_STATE)}


def test_local_cluster_gives_the_same_dataset(client, systems):
    ref = fa.study_grid(systems, LAMS, RATIOS, BETAS, t_max=40, montecarlo=MC)
    assert_same_dataset(
        ref, fa.study_grid(systems, LAMS, RATIOS, BETAS, t_max=40, montecarlo=MC, executor=client)
    )
    via_executor = client.get_executor()
    got = fa.study_grid(systems, LAMS, RATIOS, BETAS, t_max=40, montecarlo=MC, executor=via_executor, block=1)
    assert_same_dataset(ref, got)


def records(store: Path) -> np.ndarray:
    try:
        return np.asarray(zarr.open_group(str(store), mode="r")["fakeack_blocks"]["done"][...])
    except Exception:  # not created yet
        return np.zeros(0, dtype=np.uint64)


# Slow enough per cell (t_max = 2500 with mixed memories) to stop the study part-way.
SLOW = dict(lam=[0.42, 0.5, 0.58, 0.66], ratio=["2/13", "3/17", "1/6", "2/11", "3/19", "1/7"], t_max=2500)


def test_a_worker_killed_mid_study_does_not_change_the_result(client, tmp_path, systems):
    s = {"two": systems["two"]}
    ref = fa.study_grid(s, **SLOW, beta=[0.2])
    store = tmp_path / "kill.zarr"
    pids = list(client.run(os.getpid).values())
    killed = {}

    def kill_when_started():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            done = records(store)
            if done.size and 0 < np.count_nonzero(done) < done.size:
                os.kill(pids[0], signal.SIGKILL)
                killed["at"] = np.count_nonzero(done), done.size
                return
            time.sleep(0.01)

    killer = threading.Thread(target=kill_when_started)
    killer.start()
    got = fa.study_grid(s, **SLOW, beta=[0.2], executor=client, store=store, block=1)
    killer.join()
    assert killed, "the study ended before a worker could be killed"
    assert pids[0] not in client.run(os.getpid).values()
    assert_same_dataset(ref, got)


def cli(out: Path, config: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "fakeack", "grid", str(config), "--out", str(out), "--no-figures", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def stop_part_way(proc: subprocess.Popen, store: Path, sig: int) -> int:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        done = records(store)
        if done.size and np.count_nonzero(done) >= 2:
            proc.send_signal(sig)
            break
        time.sleep(0.01)
    proc.wait(timeout=120)
    return proc.returncode


def chunk_files(store: Path) -> dict[str, tuple[int, int]]:
    files = (p for p in store.rglob("*") if p.is_file() and "c" in p.relative_to(store).parts[1:-1])
    return {str(p): (p.stat().st_ino, p.stat().st_mtime_ns) for p in files}


def test_cli_interrupted_and_killed_then_resumed(tmp_path):
    config = tmp_path / "slow.toml"
    lam = ", ".join(map(str, SLOW["lam"]))
    ratio = ", ".join(f'"{r}"' for r in SLOW["ratio"])
    config.write_text(
        f'[grid]\nlam = [{lam}]\nratio = [{ratio}]\nbeta = ["1/5"]\nt_max = {SLOW["t_max"]}\nblock = 1\n\n'
        "[systems.two]\nA = [[1.1, 0.3], [-0.2, 0.8]]\nC = [[1.0, 0.5]]\nQ = [[0.5, 0.1], [0.1, 0.3]]\nR = 0.4\n"
    )
    out = tmp_path / "out"
    store = out / "study.zarr"
    n_blocks = len(SLOW["lam"]) * len(SLOW["ratio"])
    # Ctrl-C: exit 130, a consistent store and a hint to resume.
    with cli(out, config) as proc:  # `with` closes the pipes
        assert stop_part_way(proc, store, signal.SIGINT) == 130
        assert "--resume" in proc.stderr.read()
    first = np.count_nonzero(records(store))
    assert 0 < first < n_blocks
    # SIGKILL part-way through the resumed run.
    with cli(out, config, "--resume") as proc:
        stop_part_way(proc, store, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    done = records(store)
    complete = np.count_nonzero(done)
    assert first <= complete < n_blocks
    before = chunk_files(store)
    # The resumed run computes exactly the missing blocks and leaves the others' files alone.
    with cli(out, config, "--resume") as proc:
        stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    assert f"{n_blocks - complete} computed now, {complete} already complete" in stdout
    after = chunk_files(store)
    data = [p for p in before if "fakeack_blocks" not in p and Path(p).parts[-4] != "study.zarr"]
    kept = [p for p in data if after.get(p) == before[p]]
    assert len(kept) >= complete * 11  # every variable's chunk of every complete block is untouched
    ref = fa.study_grid({"two": fa.LinearSystem(**TWO_STATE)}, **SLOW, beta=["1/5"])
    nc = xr.open_dataset(out / "study.nc", engine="h5netcdf").load()
    for name in ref.data_vars:
        a, b = ref[name].values, nc[name].values
        assert (
            a.tobytes() == b.astype(a.dtype).tobytes()
            if a.dtype.kind == "f"
            else list(a.ravel()) == list(b.ravel())
        )
