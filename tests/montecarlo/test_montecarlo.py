"""Monte Carlo of the protocol against the analytic formulas and the exact curves."""

import os
import signal
import subprocess
import sys
import threading
import time
from fractions import Fraction

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
import reference as ref
from conftest import PAPER_LAM, PAPER_RATIO, names, random_system

H, RUNS = 5000, 2000  # bias of J_H vs the stationary J is ~1e-4 here, far below 4 standard errors


def close(res, expected, k=4.0):
    assert abs(res.j - expected) <= k * res.stderr, f"{res} vs {expected}"


@pytest.mark.parametrize("protocol", ["B", "A"])
def test_paper_example_all_schedules(paper, protocol):
    lam, z0 = PAPER_LAM, 2
    close(
        fa.simulate(paper, lam, fa.OfflineSchedule(PAPER_RATIO), H, RUNS, seed=1, protocol=protocol),
        fa.j_offline(paper, lam, PAPER_RATIO),
    )
    on = fa.simulate(paper, lam, fa.OnlineSchedule(z0), H, RUNS, seed=2, protocol=protocol)
    close(on, fa.j_online(paper, lam, z0))
    assert on.high_power_rate == pytest.approx(1 / 7, abs=4e-3)
    # One seed per attack: with a shared seed the three checks would share one random stream and
    # could pass or fail together by one fluke.
    for seed, (r, t) in enumerate([(1, 5), (2, 3), (1, 3)], start=3):
        res = fa.simulate(
            paper, lam, fa.OnlineSchedule(z0), H, RUNS, seed=seed, attack=(r, t), protocol=protocol
        )
        close(res, fa.j_attack(paper, lam, z0, r, t))
        assert res.flags_blocked / res.flags_sent == pytest.approx(r / t, rel=0.02)


def test_every_flag_blocked_is_j_max(paper):
    """J_max by Monte Carlo to 0.1% (4 standard errors < 0.4% of J, so a 1% error shows; the
    former check, 4 SE = 1.4% of J at lam = 0.5, could not see one). lam = 0.8: at lam = 0.5 the
    per-run cost has infinite variance ((1 - lam) rho^4 = 1.04 > 1), so no standard error is
    trustworthy there; here (1 - lam) rho^8 = 0.86 < 1 and the standard error itself is stable.
    The expected value is the series sum of lam a^i Tr h^i(P̄) (reference traces), and the
    finite-horizon mean is the exact curve of the all-blocked walk, 1/H sum_k E Tr P_k.

    Kills: a 1% error in the all-blocked simulation or in j_max (e.g. J_max's Stein equation
    with lam P̄ + Q for lam P̄ + a Q)."""
    lam, horizon = 0.8, 400
    res = fa.simulate(paper, lam, fa.OnlineSchedule(2), horizon, 400_000, seed=8, attack=fa.MaskBlocking([1]))
    a = 1 - lam
    tr = ref.traces(1.2, 0.8, paper.pbar, 200)
    j_max = sum(lam * a**i * tr[i] for i in range(201))
    assert_allclose(fa.j_max(paper, lam), j_max, rtol=1e-12)
    # E Tr P_k for the walk started at tau = 0 (high power at k = 1): law of tau_k is
    # lam a^i for i < k - 1 and a^(k-1) at i = k - 1.
    e = [
        sum(lam * a**i * tr[i] for i in range(k - 1)) + a ** (k - 1) * tr[k - 1] if k <= 200 else j_max
        for k in range(1, horizon + 1)
    ]
    exact_h = float(np.mean(e))
    assert res.stderr < 1e-3 * exact_h
    close(res, exact_h)
    assert abs(res.j - j_max) < 0.004 * j_max
    assert res.high_power_rate == pytest.approx(1 / horizon)  # only the initial step


def test_protocols_give_identical_statistics(paper):
    a = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 300, 3000, seed=9, attack=(2, 5), protocol="A")
    b = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 300, 3000, seed=9, attack=(2, 5), protocol="B")
    assert_allclose(a.mean_trace, b.mean_trace, rtol=0, atol=0)
    assert a.flags_blocked == b.flags_blocked


def test_mu_below_one_and_masks(paper):
    design = fa.OnlineSchedule.design(0.5, Fraction(1, 10))
    assert design.mu < 1
    close(fa.simulate(paper, 0.5, design, H, RUNS, seed=4), fa.j_online(paper, 0.5, design.z0, design.mu))
    res = fa.simulate(paper, 0.5, design, H, RUNS, seed=5, attack=(2, 3))
    close(res, fa.j_attack(paper, 0.5, design.z0, 2, 3, mu=design.mu))
    mask = [1, 0, 1, 1, 0, 0, 0]
    res = fa.simulate(paper, 0.5, design, H, RUNS, seed=6, attack=fa.MaskBlocking(mask))
    close(res, fa.j_attack_pattern(paper, 0.5, design.z0, mask, design.mu))


def test_random_small_systems():
    rng = np.random.default_rng(12)
    for i in range(4):
        s = fa.LinearSystem(*random_system(rng, int(rng.integers(2, 4))))
        lam = float(rng.uniform(0.4, 0.8))
        close(
            fa.simulate(s, lam, fa.OfflineSchedule(Fraction(1, 4)), H, RUNS, seed=i),
            fa.j_offline(s, lam, Fraction(1, 4)),
        )
        close(
            fa.simulate(s, lam, fa.OnlineSchedule(2), H, RUNS, seed=i, attack=(3, 4)),
            fa.j_attack(s, lam, 2, 3, 4),
        )


@pytest.mark.parametrize("n", [1, 2, 3])
def test_state_mode_matches_covariance_mode(n):
    rng = np.random.default_rng(30 + n)
    s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8) if n == 1 else fa.LinearSystem(*random_system(rng, n))
    kw = dict(horizon=2000, runs=3000, attack=(1, 3))
    cov = fa.simulate(s, 0.5, fa.OnlineSchedule(2), seed=1, **kw)
    st = fa.simulate(s, 0.5, fa.OnlineSchedule(2), seed=2, mode="state", **kw)
    assert abs(cov.j - st.j) <= 4 * np.hypot(cov.stderr, st.stderr), (cov, st)
    # Both estimate the exact finite-horizon value.
    exact = fa.expected_trace_curve(s, 0.5, fa.OnlineSchedule(2), 2000, attack=(1, 3)).j_k[-1]
    close(st, exact)


def test_exact_curve_converges_to_stationary(paper):
    for sched, attack, j in [
        (fa.OfflineSchedule(PAPER_RATIO), None, fa.j_offline(paper, 0.5, PAPER_RATIO)),
        (fa.OnlineSchedule(2), None, fa.j_online(paper, 0.5, 2)),
        (fa.OnlineSchedule(2), (2, 3), fa.j_attack(paper, 0.5, 2, 2, 3)),
        (fa.OnlineSchedule(2, 0.4), (1, 4), fa.j_attack(paper, 0.5, 2, 1, 4, mu=0.4)),
    ]:
        c = fa.expected_trace_curve(paper, 0.5, sched, 20000, attack=attack)
        assert c.trace[0] == pytest.approx(paper.pbar[0, 0])  # high power at k = 1
        # E Tr P_k converges geometrically (the offline one is periodic: compare a period mean).
        tail = c.trace[-7 * 100 :].mean()
        assert tail == pytest.approx(j, rel=1e-9)
        assert abs(c.j_k[-1] - j) < 2e-4 * j  # the 1/k transient of the running mean


def test_monte_carlo_curve_pointwise(paper):
    """J_k of the Monte Carlo against the exact curve at every k, with per-k errors estimated from
    independent replicates."""
    horizon, reps = 60, 16
    exact = fa.expected_trace_curve(paper, 0.5, fa.OnlineSchedule(2), horizon, attack=(2, 3)).j_k
    curves = np.array(
        [
            fa.simulate(paper, 0.5, fa.OnlineSchedule(2), horizon, 4000, seed=100 + i, attack=(2, 3)).j_k
            for i in range(reps)
        ]
    )
    mean, se = curves.mean(axis=0), curves.std(axis=0, ddof=1) / np.sqrt(reps)
    assert np.all(np.abs(mean - exact) <= 5 * se + 1e-12)
    assert curves[0][0] == pytest.approx(paper.pbar[0, 0])


@pytest.mark.parametrize(
    "mode, sched, attack, runs",
    [
        ("covariance", fa.OnlineSchedule(2), (1, 5), 2000),  # bit-sliced kernel
        ("covariance", fa.OnlineSchedule(2, 0.4), (2, 7), 2000),  # lane kernels
        ("state", fa.OnlineSchedule(2), (1, 3), 500),
    ],
)
def test_standard_error_is_calibrated(paper, mode, sched, attack, runs):
    """Over 30 seeds, the spread of J divided by the mean reported standard error lies in
    [0.7, 1.4] (the sample spread of 30 values is itself uncertain by 13%, so this is about
    3 of its standard errors either way). The attacks keep tau bounded, so every moment of the
    per-run cost is finite.

    Kills: a standard error over steps instead of runs, without the square root of the run
    count, with the run count squared, or runs that share random streams (a spread too large)."""
    js, ses = [], []
    for seed in range(30):
        res = fa.simulate(paper, 0.5, sched, 300, runs, seed=1000 + seed, attack=attack, mode=mode)
        js.append(res.j)
        ses.append(res.stderr)
    ratio = np.std(js, ddof=1) / np.mean(ses)
    assert 0.7 <= ratio <= 1.4, ratio


def test_seed_determinism_and_thread_independence(paper):
    a = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 200, 20000, seed=42, attack=(1, 5))
    b = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 200, 20000, seed=42, attack=(1, 5))
    assert_allclose(a.j_k, b.j_k, rtol=0, atol=0)
    code = (
        "import fakeack as fa;"
        "s=fa.LinearSystem(1.2,0.7,0.8,0.8);"
        "r=fa.simulate(s,0.5,fa.OnlineSchedule(2),200,20000,seed=42,attack=(1,5));"
        "print(repr(r.j), repr(float(r.j_k.sum())))"
    )
    outs = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        outs.append(
            subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            ).stdout
        )
    assert outs[0] == outs[1] == f"{a.j!r} {float(a.j_k.sum())!r}\n"
    c = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 200, 20000, seed=43, attack=(1, 5))
    assert c.j != a.j


def test_gil_released_during_simulation(paper):
    """Another Python thread keeps running while a simulation runs. The work grows until one
    call lasts at least 0.3 s, so the check cannot pass by being too quick to measure (the former
    `or elapsed < 0.05` passed on a fast machine whatever the GIL did).

    Kills: running the kernel without releasing the GIL (no py.detach in the bindings)."""
    runs = 200_000
    while True:
        ticks = []
        stop = threading.Event()

        def count(ticks=ticks, stop=stop):
            while not stop.is_set():
                ticks.append(1)
                time.sleep(0.001)

        th = threading.Thread(target=count)
        th.start()
        t0 = time.monotonic()
        fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 5000, runs, seed=1, mode="covariance")
        elapsed = time.monotonic() - t0
        stop.set()
        th.join()
        if elapsed >= 0.3:
            break
        runs *= 4
    # At one tick per 1 ms sleep (plus scheduling), a GIL-free call of >= 0.3 s gives >= 60.
    assert len(ticks) > 0.2 * elapsed / 0.001, (len(ticks), elapsed)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_ctrl_c_stops_within_a_second(paper, monkeypatch):
    """A SIGINT sent while the simulation runs raises KeyboardInterrupt within a second.

    The signal comes from a thread that the first progress report starts, so it always lands
    while the kernel runs (a fixed timer could fire before the call starts on a loaded machine).
    """
    import fakeack.montecarlo.protocol as mc

    fired = {}

    def interrupt():
        fired["t"] = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    class SignalOnFirstReport(mc.Progress):
        def __call__(self, done):
            if "thread" not in fired:
                fired["thread"] = threading.Thread(target=interrupt)
                fired["thread"].start()

    monkeypatch.setattr(mc, "Progress", SignalOnFirstReport)
    # Python's own Ctrl-C behaviour, whatever handler an earlier test or library left installed.
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            # ~10^12 steps: hours if not interrupted.
            fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 10_000, 10**8, seed=1, progress=False)
    finally:
        signal.signal(signal.SIGINT, old)
    assert time.monotonic() - fired["t"] < 1.0
    fired["thread"].join()
    # The process is responsive and can simulate again.
    fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 10, 10, seed=1)


def test_progress_callback_error_cancels(paper, monkeypatch):
    import fakeack.montecarlo.protocol as mc

    class Boom(mc.Progress):
        def __call__(self, done):
            raise RuntimeError("stop")

    monkeypatch.setattr(mc, "Progress", Boom)
    t0 = time.monotonic()
    with pytest.raises(RuntimeError, match="stop"):
        fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 10_000, 10**8, seed=1)
    assert time.monotonic() - t0 < 2.0


@pytest.mark.parametrize(
    "kw, exc, name",
    [
        (dict(horizon=0), ValueError, "horizon"),
        (dict(runs=0), ValueError, "runs"),
        (dict(horizon=10**12), ValueError, "horizon"),
        (dict(seed=-1), ValueError, "seed"),
        (dict(mode="exact"), ValueError, "mode"),
        (dict(protocol="C"), ValueError, "protocol"),
        (dict(attack=(3, 2)), ValueError, "r"),
        (dict(attack=[1, 0]), TypeError, "attack"),
    ],
)
def test_bad_input(paper, kw, exc, name):
    args = dict(horizon=10, runs=10)
    args.update(kw)
    with pytest.raises(exc, match=names(name)):
        fa.simulate(paper, 0.5, fa.OnlineSchedule(2), **args)


def test_offline_rejects_attack(paper):
    with pytest.raises(ValueError, match="attack"):
        fa.simulate(paper, 0.5, fa.OfflineSchedule(PAPER_RATIO), 10, 10, attack=(1, 2))
    with pytest.raises(TypeError, match="sched"):
        fa.simulate(paper, 0.5, "online", 10, 10)


def test_trace_curve_is_array_like(paper):
    c = fa.expected_trace_curve(paper, 0.5, fa.OnlineSchedule(2), 10)
    assert len(c) == 10 and np.asarray(c).shape == (10,) and c[0] == c.trace[0]


def test_recording_too_many_runs_refused(paper):
    with pytest.raises(ValueError, match="runs"):
        fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 10, 2**29, record_runs=True)


def test_attack_pattern_is_a_deprecated_spelling():
    with pytest.warns(DeprecationWarning, match="MaskBlocking"):
        att = fa.AttackPattern([1, 0, 0])
    assert att == fa.MaskBlocking([1, 0, 0])
    with pytest.warns(DeprecationWarning, match="PeriodicBlocking"):
        assert fa.AttackPattern.first(1, 5) == fa.PeriodicBlocking(1, 5)
