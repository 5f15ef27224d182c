"""fa.simulate(..., mode="state") on the automaton kernel (Markov channels, offline patterns,
mimicry, attacker automata, injection with min_gap > 1): J from the simulated estimation errors
against the exact J_H of fa.expected_trace_curve (the exact engine), protocols A and B, the same
protocol path as covariance mode, determinism across thread counts, and overflow to inf."""

import os
import subprocess
import sys

import numpy as np
import pytest

import fakeack as fa

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
#: A 2 x 2 system, unstable in one mode, observed through one output.
S2 = fa.LinearSystem(
    np.array([[1.1, 0.3], [0.0, 0.8]]),
    np.array([[1.0, 0.5]]),
    np.array([[0.5, 0.1], [0.1, 0.3]]),
    np.array([[0.6]]),
)
THREE = fa.MarkovChannel(
    [[0.8, 0.15, 0.05], [0.2, 0.6, 0.2], [0.1, 0.3, 0.6]], [0.9, 0.5, 0.1], [1.0, 0.95, 0.7]
)
#: A stable scalar system. On GE(0.2, 0.2, 1, 0) (no low-power packet in the bad state) the paper's
#: A = 1.2 makes the cost heavy-tailed under mimicry or the on/off attacker (J_H near 1.2e7 at 200
#: steps, carried by loss runs too rare for a few thousand runs), so that channel runs on this one.
STABLE = fa.LinearSystem(0.9, 0.7, 0.8, 0.8)
#: Each channel with the system it is checked on.
CHANNELS = {
    "ge-0.2-0.2-1-0": (fa.GilbertElliott(0.2, 0.2, 1.0, 0.0), STABLE),
    "ge-0.1-0.3-0.9-0.2": (fa.GilbertElliott(0.1, 0.3, 0.9, 0.2), S),
    "three-state": (THREE, S),
}
ON_OFF = fa.AttackerAutomaton(
    {
        0: {"flag": [(0.5, True, 0), (0.5, False, 1)], "quiet": [(1.0, False, 0)]},
        1: {"flag": [(1.0, False, 1)], "quiet": [(0.8, False, 1), (0.2, False, 0)]},
    }
)
ATTACKS = {
    "periodic": fa.PeriodicBlocking(1, 5),
    "random": fa.RandomBlocking(0.3),
    "injection": fa.FlagInjection(0.05, block=fa.RandomBlocking(0.2)),
    "mimicry": fa.MimicryAttack(),
    "automaton": ON_OFF,
}
H, RUNS = 200, 2000


def exact_j(system, channel, sched, attack=None):
    return float(fa.expected_trace_curve(system, channel, sched, H, attack=attack).j_k[-1])


@pytest.mark.parametrize("channel", CHANNELS.values(), ids=CHANNELS.keys())
@pytest.mark.parametrize("attack", ATTACKS.values(), ids=ATTACKS.keys())
def test_state_mode_matches_the_exact_cost(channel, attack):
    channel, system = channel
    design = fa.OnlineDesign(2)
    kw = dict(attack=attack, mode="state", progress=False, seed=5)
    b = fa.simulate(system, channel, design, H, RUNS, protocol="B", **kw)
    a = fa.simulate(system, channel, design, H, RUNS, protocol="A", **kw)
    exact = exact_j(system, channel, design, attack)
    assert np.isfinite(b.stderr) and abs(b.j - exact) < 4 * b.stderr, (b.j, b.stderr, exact)
    # A and B are the same in law; the automaton kernel simulates them with the same draws.
    assert a.j == b.j and np.array_equal(a.mean_trace, b.mean_trace)
    assert (b.mode, a.protocol) == ("state", "A")


@pytest.mark.parametrize(
    "sched, attack",
    [
        (fa.OnlineDesign(2, 0.4), ON_OFF),
        (fa.OnlineDesign(2), fa.FlagInjection(0.1, min_gap=3)),
        (fa.OfflineSchedule(pattern="0100"), None),
    ],
    ids=["mu-0.4-automaton", "injection-min-gap", "offline-pattern"],
)
@pytest.mark.parametrize("system", [S, S2], ids=["scalar", "2x2"])
def test_state_mode_on_other_schedules_and_a_vector_system(system, sched, attack):
    ch = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    res = fa.simulate(system, ch, sched, H, RUNS, seed=6, attack=attack, mode="state", progress=False)
    exact = exact_j(system, ch, sched, attack)
    assert np.isfinite(res.stderr) and abs(res.j - exact) < 4 * res.stderr, (res.j, res.stderr, exact)


def test_state_mode_follows_the_protocol_path_of_covariance_mode():
    kw = dict(
        attack=fa.FlagInjection(0.05, block=fa.RandomBlocking(0.3)), seed=9, progress=False, record_runs=True
    )
    st = fa.simulate(S, THREE, fa.OnlineDesign(2, 0.4), 150, 500, mode="state", **kw)
    cov = fa.simulate(S, THREE, fa.OnlineDesign(2, 0.4), 150, 500, mode="covariance", **kw)
    assert np.array_equal(st.delivered_per_run, cov.delivered_per_run)
    fields = ("flags_sent", "flags_blocked", "flags_forged", "high_power_rate")
    assert [getattr(st, f) for f in fields] == [getattr(cov, f) for f in fields]
    assert st.flags_forged > 0 and st.j != cov.j


def test_state_mode_is_deterministic_whatever_the_thread_count():
    code = (
        "import numpy as np, fakeack as fa;"
        "s=fa.LinearSystem(np.array([[1.1,0.3],[0,0.8]]),np.array([[1,0.5]]),"
        "np.array([[0.5,0.1],[0.1,0.3]]),np.array([[0.6]]));"
        "r=fa.simulate(s,fa.GilbertElliott(0.1,0.3,0.9,0.2),fa.OnlineDesign(2),100,700,seed=12,"
        "attack=fa.MimicryAttack(),mode='state',progress=False);"
        "print(repr(r.j), repr(float(r.j_k.sum())))"
    )
    outs = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        run = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
        outs.append(run.stdout)
    r = fa.simulate(
        S2, fa.GilbertElliott(0.1, 0.3, 0.9, 0.2), fa.OnlineDesign(2), 100, 700, seed=12,
        attack=fa.MimicryAttack(), mode="state", progress=False,
    )  # fmt: skip
    assert outs[0] == outs[1] == f"{r.j!r} {float(r.j_k.sum())!r}\n"


@pytest.mark.parametrize("system", [S, S2], ids=["scalar", "2x2"])
def test_state_mode_overflow_gives_inf_not_nan(system):
    # Unstable A, every flag-ACK blocked, a channel that almost never delivers: the errors
    # overflow after a few thousand steps.
    ch = fa.MarkovChannel([[0.5, 0.5], [0.5, 0.5]], [1e-6, 1e-6], [1.0, 1.0])
    res = fa.simulate(
        system, ch, fa.OnlineDesign(2), 8000, 8, attack=fa.MaskBlocking([1]), mode="state", progress=False
    )
    assert np.isinf(res.j) and np.isinf(res.stderr)
    assert not np.isnan(res.mean_trace).any() and np.isinf(res.mean_trace[-1])
