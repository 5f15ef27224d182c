"""fa.simulate on channel objects and on the automaton kernel, against the independent reference
of the exact engine (tests/engine/reference_engine.py): its exact finite-horizon curves and J."""

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import fakeack as fa
from conftest import names
from fakeack import _fakeack
from fakeack.attacks import as_automaton
from fakeack.attacks.kinds import core_attack
from fakeack.model.system import compiled

sys.path.insert(0, str(Path(__file__).parent.parent / "engine"))
import reference_engine as ref  # noqa: E402

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
#: Off: lets flag-ACKs through and turns on at one with probability 1/2; on: blocks them and
#: turns off on a quiet step with probability 0.2.
ON_OFF = fa.AttackerAutomaton(
    {
        0: {"flag": [(0.5, True, 0), (0.5, False, 1)], "quiet": [(1.0, False, 0)]},
        1: {"flag": [(1.0, False, 1)], "quiet": [(0.8, False, 1), (0.2, False, 0)]},
    }
)


def chain_of(channel, sched, attack=None):
    """The reference's explicit chain of a fa.simulate call's channel, schedule and attack."""
    ch = fa.model.as_channel(channel)
    if isinstance(sched, fa.OfflineSchedule):
        return ref.Chain(ch.P, ch.low, ch.high, ("offline", [int(x) for x in sched.pattern]))
    aut = as_automaton(attack, channel=ch, design=sched)
    attacker = ref.attacker_from(aut.flag, aut.quiet, aut.start)
    return ref.Chain(ch.P, ch.low, ch.high, ("online", sched.z0, sched.mu), attacker)


def exact_moments(chain, horizon, system=S):
    """E Tr P_k and E (Tr P_k)^2, k = 1..horizon, from the initial law: the reference's curve
    (the law of (tau, e) propagated step by step), with sparse products and second moments."""
    K0t, K1t = chain.K0.T.tocsr(), chain.K1.T.tocsr()
    tr = ref.traces(system.A, system.Q, system.pbar, horizon)
    law = np.zeros((horizon + 1, chain.n))
    law[0] = chain.x0
    m1, m2 = np.empty(horizon), np.empty(horizon)
    for k in range(horizon):
        new = np.zeros_like(law)
        new[0] = K1t @ law[: k + 1].sum(axis=0)
        new[1 : k + 2] = (K0t @ law[: k + 1].T).T
        law = new
        m = law[: k + 2].sum(axis=1)
        keep = m > 0  # unreachable holding times may have traces whose squares overflow
        m1[k], m2[k] = m[keep] @ tr[: k + 2][keep], m[keep] @ tr[: k + 2][keep] ** 2
    return m1, m2


def check(res, chain, k=4.0):
    """J over the horizon within k standard errors of the exact one, and every step's mean trace
    within 5 of its own standard error (from the exact second moment)."""
    m1, m2 = exact_moments(chain, res.horizon)
    exact = m1.mean()
    assert abs(res.j - exact) <= k * res.stderr, f"{res} vs {exact}"
    se = np.sqrt(np.maximum(m2 - m1**2, 0.0) / res.runs)
    bad = np.flatnonzero(np.abs(res.mean_trace - m1) > 5 * se + 1e-12 * m1)
    assert bad.size == 0, f"steps {bad[:5] + 1}: {res.mean_trace[bad[:5]]} vs {m1[bad[:5]]}"
    return exact


def test_exact_moments_are_the_reference_curve():
    chain = chain_of(GE, fa.OnlineDesign(2, 0.5), ON_OFF)
    m1, _ = exact_moments(chain, 40)
    np.testing.assert_allclose(m1, ref.curve(chain, S.A, S.Q, S.pbar, 40)[0], rtol=1e-12)


def test_gilbert_elliott_with_an_on_off_attacker():
    design = fa.OnlineDesign(2, 0.5)
    res = fa.simulate(S, GE, design, 300, 4000, seed=1, attack=ON_OFF, progress=False)
    chain = chain_of(GE, design, ON_OFF)
    check(res, chain)
    assert res.channel == GE and res.attack == str(ON_OFF) and res.mode == "covariance"
    # The flag rates against the stationary ones (the start-up transient is short here).
    high, sent, delivered, forged = ref.rates(chain)
    assert res.flags_sent == pytest.approx(sent, abs=0.01)
    assert res.flags_sent - res.flags_blocked == pytest.approx(delivered, abs=0.01)
    assert res.flags_forged == 0.0 == forged
    assert res.high_power_rate == pytest.approx(high, abs=0.01)
    # The stationary J of the reference, with the transient's share allowed for.
    j = ref.cost(chain, S.A, S.Q, S.pbar)
    assert abs(res.j - j) < 4 * res.stderr + 0.05 * j


def test_mimicry_on_gilbert_elliott():
    design = fa.OnlineDesign(2)
    res = fa.simulate(S, GE, design, 200, 20_000, seed=2, attack=fa.MimicryAttack(), progress=False)
    check(res, chain_of(GE, design, fa.MimicryAttack()))
    # Mimicry delivers flag-ACKs at the attack-free rate, and forges whenever the real detector
    # is quiet but the virtual one is not.
    free = fa.simulate(S, GE, design, 200, 20_000, seed=3, progress=False)
    assert res.high_power_rate == pytest.approx(free.high_power_rate, abs=0.01)
    assert res.flags_forged > 0 and res.flags_blocked > 0


def test_offline_pattern_on_gilbert_elliott():
    sched = fa.OfflineSchedule(pattern="0100")  # starts low: the first step may lose
    res = fa.simulate(S, GE, sched, 200, 4000, seed=4, progress=False)
    check(res, chain_of(GE, sched))
    assert res.high_power_rate == 0.25 and res.flags_sent == 0.0
    # A pattern on the paper's channel also runs (only the ratio has today's kernels).
    res = fa.simulate(S, 0.5, sched, 200, 4000, seed=5, progress=False)
    check(res, chain_of(0.5, sched))


def test_flag_injection_with_min_gap():
    att = fa.FlagInjection(0.3, fa.RandomBlocking(0.4), min_gap=3)
    res = fa.simulate(S, 0.5, fa.OnlineDesign(2), 200, 4000, seed=6, attack=att, progress=False)
    check(res, chain_of(0.5, fa.OnlineDesign(2), att))
    assert res.flags_forged > 0


def test_periodic_blocking_as_an_automaton_on_the_paper_channel():
    design, att = fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5)
    aut = as_automaton(att)
    horizon = 1000
    res = fa.simulate(S, 0.5, design, horizon, 4000, seed=7, attack=aut, progress=False)
    curve = fa.expected_trace_curve(S, 0.5, design, horizon, attack=att)
    check(res, chain_of(0.5, design, att))
    assert abs(res.j - curve.j_k[-1]) <= 4 * res.stderr
    j = fa.j_attack(S, 0.5, 2, attack=att)
    assert abs(res.j - j) <= 4 * res.stderr + abs(curve.j_k[-1] - j)
    # The built-in attack itself stays on today's kernels, bit for bit.
    today = fa.simulate(S, 0.5, design, 300, 2000, seed=8, attack=att, progress=False)
    raw = _fakeack.simulate(
        compiled(S),
        0.5,
        "online",
        1,
        2,
        2,
        1.0,
        core_attack(att),
        "covariance",
        "B",
        300,
        2000,
        8,
        lambda done: None,
        False,
    )
    assert np.array_equal(today.j_k, raw["j_k"]) and today.j == raw["j"]
    assert today.channel == fa.BernoulliChannel(0.5)


def test_the_lam_keyword_and_the_channel_argument():
    args = dict(horizon=50, runs=300, seed=9, progress=False)
    a = fa.simulate(S, 0.5, fa.OnlineDesign(2), **args)
    b = fa.simulate(S, lam=0.5, sched=fa.OnlineDesign(2), **args)
    c = fa.simulate(S, fa.BernoulliChannel(0.5), fa.OnlineDesign(2), **args)
    assert a.j == b.j == c.j and np.array_equal(a.j_k, c.j_k)
    assert a.channel == b.channel == fa.BernoulliChannel(0.5)
    with pytest.raises(TypeError, match=names("lam")):
        fa.simulate(S, 0.5, fa.OnlineDesign(2), lam=0.5, **args)
    with pytest.raises(TypeError, match=names("channel")):
        fa.simulate(S, sched=fa.OnlineDesign(2), **args)
    with pytest.raises(TypeError, match=names("sched")):
        fa.simulate(S, 0.5, **args)


def test_determinism_and_thread_count():
    args = (S, GE, fa.OnlineDesign(2, 0.5), 100, 1000)
    a = fa.simulate(*args, seed=10, attack=ON_OFF, progress=False, record_runs=True)
    b = fa.simulate(*args, seed=10, attack=ON_OFF, progress=False, record_runs=True)
    assert np.array_equal(a.j_k, b.j_k) and np.array_equal(a.delivered_per_run, b.delivered_per_run)
    assert a.delivered_per_run.mean() / 100 == pytest.approx(a.flags_sent - a.flags_blocked, rel=1e-12)
    c = fa.simulate(*args, seed=11, attack=ON_OFF, progress=False)
    assert c.j != a.j
    code = (
        "import fakeack as fa;"
        "s=fa.LinearSystem(1.2,0.7,0.8,0.8);"
        "r=fa.simulate(s,fa.GilbertElliott(0.1,0.3,0.9,0.2),fa.OfflineSchedule(pattern='01'),"
        "100,1000,seed=12,progress=False);"
        "print(repr(r.j), repr(float(r.j_k.sum())))"
    )
    outs = []
    for threads in ("1", "2"):
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        run = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
        outs.append(run.stdout)
    r = fa.simulate(S, GE, fa.OfflineSchedule(pattern="01"), 100, 1000, seed=12, progress=False)
    assert outs[0] == outs[1] == f"{r.j!r} {float(r.j_k.sum())!r}\n"


@pytest.mark.parametrize(
    "kw, exc, name",
    [
        (dict(mode="states"), ValueError, "mode"),
        (dict(channel="good"), TypeError, "channel"),
        (dict(channel=1.5), ValueError, "channel"),
        (dict(channel=None, lam=1.5), ValueError, "lam"),
        (dict(attack=fa.MimicryAttack(), sched=fa.OfflineSchedule(pattern="10")), ValueError, "attack"),
        (dict(horizon=0), ValueError, "horizon"),
        (dict(runs=0), ValueError, "runs"),
        (dict(seed=-1), ValueError, "seed"),
    ],
)
def test_bad_inputs_name_the_argument(kw, exc, name):
    args = dict(channel=GE, sched=fa.OnlineDesign(2), horizon=10, runs=10, attack=ON_OFF, progress=False)
    args.update(kw)
    with pytest.raises(exc, match=names(name)):
        fa.simulate(S, **args)


def _raw(**kw):
    args = dict(
        P=[[0.9, 0.1], [0.3, 0.7]],
        low=[0.9, 0.2],
        high=[1.0, 1.0],
        z0=2,
        mu=1.0,
        offline=None,
        flag=[[(1.0, True, 0)]],
        quiet=[[(1.0, False, 0)]],
        start=0,
        horizon=10,
        runs=10,
        seed=1,
        progress=lambda done: None,
    )
    args.update(kw)
    return _fakeack.simulate_automaton(compiled(S), **args)


@pytest.mark.parametrize(
    "kw, name",
    [
        (dict(P=[[0.5, 0.6], [0.3, 0.7]]), "P"),
        (dict(P=[[1.0, 0.0], [0.0, 1.0]]), "P"),
        (dict(low=[0.5]), "low"),
        (dict(high=[1.0, 1.5]), "high"),
        (dict(z0=0), "z0"),
        (dict(mu=2.0), "mu"),
        (dict(offline=[]), "offline"),
        (dict(flag=[[(0.5, True, 0)]]), "flag"),
        (dict(quiet=[[(1.0, False, 1)]]), "quiet"),
        (dict(start=1), "start"),
        (dict(horizon=0), "horizon"),
    ],
)
def test_the_binding_names_bad_arguments(kw, name):
    with pytest.raises(ValueError, match=names(name)):
        _raw(**kw)


def test_the_binding_returns_the_simulate_dict():
    out = _raw(record_runs=True)
    keys = {"mean_trace", "j_k", "j", "stderr", "high_power_rate", "flags_sent", "flags_blocked"}
    assert keys | {"flags_forged", "steps", "delivered_per_run"} == set(out)
    assert out["mean_trace"].shape == (10,) and out["delivered_per_run"].shape == (10,)


def test_progress_and_cancel_on_the_automaton_kernel(monkeypatch):
    """The automaton kernel reports progress through the same callback as today's kernels, and an
    error raised there cancels a run of hours within a second or two."""
    import fakeack.montecarlo.protocol as mc

    seen = []

    class Record(mc.Progress):
        def __call__(self, done):
            seen.append(done)

    monkeypatch.setattr(mc, "Progress", Record)
    fa.simulate(S, GE, fa.OnlineDesign(2), 1000, 20_000, seed=1, attack=ON_OFF)
    assert seen and seen[-1] == 20_000 and seen == sorted(seen)

    class Boom(mc.Progress):
        def __call__(self, done):
            raise RuntimeError("stop")

    monkeypatch.setattr(mc, "Progress", Boom)
    t0 = time.monotonic()
    with pytest.raises(RuntimeError, match="stop"):
        fa.simulate(S, GE, fa.OnlineDesign(2), 10_000, 10**8, seed=1, attack=ON_OFF)
    assert time.monotonic() - t0 < 2.0
