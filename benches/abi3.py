"""What the stable ABI costs: the same calls timed with two builds of fakeack, in fresh processes.

``benches/compare.py --tasks abi3 --abi3-wheels ABI3.whl SPECIFIC.whl`` unpacks both wheels (same
Python code, different compiled extension), then runs this file as a child process with each on
``sys.path`` in turn, alternating the two for several rounds so that a change in the machine's load
falls on both. Each child times every call with ``timeit`` (auto-looped to ~0.2 s per sample, the
minimum of 5 samples), once by the wall clock and once by the process's CPU time, and prints JSON;
the reported time per call is the minimum over rounds. On a shared machine other jobs only ever
add time, and they add far less to CPU time (time spent descheduled does not count), so the CPU
time is the figure to compare. The children run with one rayon thread (``RAYON_NUM_THREADS=1``):
the stable ABI changes only the calls between Python and Rust, not the kernels, and a thread pool's
idle spinning would make CPU time depend on the other jobs again.

The calls: three small ones through the public API (``fa.j_online``, ``fa.j_attack``,
``fa.j_offline`` on the paper's example: argument checks in Python plus one call into Rust), the
same two straight into the compiled method (the binding layer alone), building a system, and two
large calls whose work is in Rust and whose result is a big array (the β sweep to t_max = 1000,
3.0e5 fractions, and the stationary law of a 1e6-state chain).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

SETUP = """
from fractions import Fraction
import fakeack as fa
s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
core = s._core
seven = Fraction(1, 7)
"""

# name -> (statement, what it measures)
CALLS = {
    "fa.j_online": ("fa.j_online(s, 0.5, 2, 1.0)", "small"),
    "fa.j_attack": ("fa.j_attack(s, 0.5, 2, r=1, t=5)", "small"),
    "fa.j_offline": ("fa.j_offline(s, 0.5, seven)", "small"),
    "compiled j_online": ("core.j_online(0.5, 2, 1.0)", "binding only"),
    "fa.LinearSystem": ("fa.LinearSystem(1.2, 0.7, 0.8, 0.8)", "small"),
    "fa.beta_sweep t_max=1e3": ("fa.beta_sweep(s, 0.5, seven, 1000)", "large"),
    "stationary |S|=1e6": ("fa.stationary_distribution(0.5, 2, 700, 169_767)", "large"),
}


def child() -> None:
    """Time every call with the fakeack found on sys.path; print {name: seconds} as JSON."""
    import timeit

    import fakeack

    out: dict[str, object] = {"__file__": fakeack._fakeack.__file__, "wall": {}, "cpu": {}}
    for name, (stmt, _) in CALLS.items():
        for clock, timer_fn in (("wall", time.perf_counter), ("cpu", time.process_time)):
            timer = timeit.Timer(stmt, setup=SETUP, timer=timer_fn)
            number, elapsed = timer.autorange()
            number = max(1, int(number * 0.2 / max(elapsed, 1e-9)))
            out[clock][name] = min(timer.repeat(repeat=5, number=number)) / number  # type: ignore[index]
    print(json.dumps(out))


def unpack(wheel: Path, into: Path) -> Path:
    """Unzip a wheel (a zip of site-packages entries) into ``into``; returns ``into``."""
    with zipfile.ZipFile(wheel) as z:
        z.extractall(into)
    return into


def measure(wheels: list[Path], rounds: int) -> tuple[list[str], dict[str, dict[str, list[float]]]]:
    """Seconds per call of each wheel: the minimum over ``rounds`` alternating child runs.

    Returns the extension file names and, for each clock ("cpu", "wall") and each call, one time
    per wheel.
    """
    with tempfile.TemporaryDirectory() as tmp:
        roots = [unpack(w, Path(tmp) / f"w{i}") for i, w in enumerate(wheels)]
        samples: list[list[dict]] = [[] for _ in wheels]
        for _ in range(rounds):
            for i, root in enumerate(roots):
                env_path = str(root)
                p = subprocess.run(
                    [sys.executable, __file__, "--child"],
                    env={
                        "PYTHONPATH": env_path,
                        "OPENBLAS_NUM_THREADS": "1",
                        "RAYON_NUM_THREADS": "1",
                        "PATH": "/usr/bin:/bin",
                    },
                    capture_output=True,
                    text=True,
                    check=True,
                )
                samples[i].append(json.loads(p.stdout))
        files = [Path(s[0]["__file__"]).name for s in samples]
        best = {
            clock: {name: [min(r[clock][name] for r in s) for s in samples] for name in CALLS}
            for clock in ("cpu", "wall")
        }
        return files, best


if __name__ == "__main__" and sys.argv[1:] == ["--child"]:
    child()
