"""fa.expected_trace_curve on channel objects, offline patterns and every attack: the paper's channel
keeps today's structured propagation bit for bit, everything else is the engine's cost_curve,
checked against the i.i.d. reduction, the explicit chain of tests/engine/reference_engine.py and
closed forms."""

import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack.attacks import as_automaton
from fakeack.attacks.kinds import core_attack
from fakeack.model.system import compiled
from reference import pbar_scipy, traces

sys.path.insert(0, str(Path(__file__).parent.parent / "engine"))
import reference_engine as ref  # noqa: E402

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
GE2 = fa.GilbertElliott(0.2, 0.4, 0.7, 0.3, 1.0, 0.8)
ATTACKS = [
    None,
    fa.PeriodicBlocking(1, 3),
    fa.RandomBlocking(0.3),
    fa.FlagInjection(0.1, fa.RandomBlocking(0.2)),
]


@pytest.mark.parametrize("attack", ATTACKS, ids=str)
@pytest.mark.parametrize("mu", [1.0, 0.7])
def test_bernoulli_online_is_todays_core_call_bit_for_bit(attack, mu):
    design = fa.OnlineDesign(2, mu)
    old = compiled(S).curve_online(0.5, 2, mu, core_attack(attack), 60)  # the call made before channels
    for curve in (
        fa.expected_trace_curve(S, 0.5, design, 60, attack),
        fa.expected_trace_curve(S, lam=0.5, sched=design, horizon=60, attack=attack),
        fa.expected_trace_curve(S, fa.BernoulliChannel(0.5), design, 60, attack),
    ):
        assert isinstance(curve, fa.TraceCurve)
        np.testing.assert_array_equal(curve.trace, old)
        np.testing.assert_array_equal(curve.j_k, np.cumsum(old) / np.arange(1, 61))


def test_bernoulli_offline_ratio_is_todays_core_call_bit_for_bit():
    old = compiled(S).curve_offline(0.5, 2, 7, 50)
    for channel in (0.5, fa.BernoulliChannel(0.5)):
        np.testing.assert_array_equal(
            fa.expected_trace_curve(S, channel, fa.OfflineSchedule("2/7"), 50).trace, old
        )
    np.testing.assert_array_equal(
        fa.expected_trace_curve(S, lam=0.5, sched=fa.OfflineSchedule("2/7"), horizon=50).trace, old
    )


@pytest.mark.parametrize(
    "sched, attack",
    [(fa.OnlineDesign(2), a) for a in ATTACKS]
    + [(fa.OnlineDesign(3, 0.4), fa.PeriodicBlocking(1, 5))]
    + [(fa.OfflineSchedule("1/7"), None), (fa.OfflineSchedule(pattern="0110"), None)],
    ids=str,
)
def test_iid_gilbert_elliott_gives_the_bernoulli_curve(sched, attack):
    """p + q = 1 and high_good = high_bad = 1: the paper's channel with lam = pi_good lam_good +
    pi_bad lam_bad, so the two-state engine meets today's propagation (or, for a pattern, the
    one-state engine) to 1e-12 at every step."""
    ge, lam = fa.GilbertElliott(0.35, 0.65, 0.7, 0.1), 0.65 * 0.7 + 0.35 * 0.1
    got = fa.expected_trace_curve(S, ge, sched, 300, attack)
    want = fa.expected_trace_curve(S, lam, sched, 300, attack)
    assert_allclose(got.trace, want.trace, rtol=1e-12)
    assert_allclose(got.j_k, want.j_k, rtol=1e-12)


def chain(channel, sched, attack=None):
    ch = fa.model.as_channel(channel)
    if isinstance(sched, fa.OfflineSchedule):
        return ref.Chain(ch.P, ch.low, ch.high, ("offline", [int(x) for x in sched.pattern]))
    aut = as_automaton(attack, channel=ch, design=sched)
    return ref.Chain(
        ch.P,
        ch.low,
        ch.high,
        ("online", sched.z0, sched.mu),
        ref.attacker_from(aut.flag, aut.quiet, aut.start),
    )


@pytest.mark.parametrize(
    "channel, sched, attack",
    [
        (GE, fa.OnlineDesign(2), None),
        (GE2, fa.OnlineDesign(2, 0.6), fa.PeriodicBlocking(1, 3)),
        (GE2, fa.OnlineDesign(2), fa.MimicryAttack()),
        (0.5, fa.OnlineDesign(2), fa.MimicryAttack()),
        (GE, fa.OnlineDesign(2), fa.FlagInjection(0.2, min_gap=3)),
        (0.5, fa.OnlineDesign(2), fa.FlagInjection(0.2, fa.RandomBlocking(0.3), min_gap=3)),
        (0.5, fa.OnlineDesign(2), fa.MaskBlocking([1])),
        (GE2, fa.OfflineSchedule("1/7"), None),
        (0.5, fa.OfflineSchedule(pattern="0100"), None),
        (GE, fa.OfflineSchedule(pattern="0"), None),
    ],
    ids=str,
)
def test_engine_route_against_the_explicit_chain(channel, sched, attack):
    """Markov channels, patterns, mimicry, min_gap and every flag blocked: the reference's curve,
    propagated over (tau, e) from the paper's initial condition (c_1 stationary, high power at
    k = 1, memory all ones, the attacker at its start), shares no code with the engine."""
    trace, j_k = ref.curve(chain(channel, sched, attack), S.A, S.Q, S.pbar, 60)
    got = fa.expected_trace_curve(S, channel, sched, 60, attack)
    assert isinstance(got, fa.TraceCurve) and got.k.tolist() == list(range(1, 61))
    assert_allclose(got.trace, trace, rtol=1e-11)
    assert_allclose(got.j_k, j_k, rtol=1e-11)


def test_every_flag_blocked_on_the_paper_channel_is_the_closed_form():
    """High power at k = 1 (an arrival), low power ever after: tau_k = n with probability
    lam (1 - lam)^n for n < k - 1 and (1 - lam)^(k-1) for n = k - 1."""
    lam, horizon = 0.5, 40
    tr = traces(S.A, S.Q, pbar_scipy(S.A, S.C, S.Q, S.R), horizon)
    want = []
    for k in range(1, horizon + 1):
        law = [lam * (1 - lam) ** n for n in range(k - 1)] + [(1 - lam) ** (k - 1)]
        want.append(np.dot(law, tr[:k]))
    got = fa.expected_trace_curve(S, lam, fa.OnlineDesign(2), horizon, fa.MaskBlocking([1, 1]))
    assert_allclose(got.trace, want, rtol=1e-12)


@pytest.mark.parametrize("attack", [None, fa.PeriodicBlocking(1, 5), fa.MimicryAttack()], ids=str)
def test_the_long_horizon_end_approaches_the_stationary_cost_on_a_bursty_channel(attack):
    """Long good and bad runs (mean 1/p = 20 and 1/q = 5 steps): E Tr P_k converges geometrically
    to J and J_k - J decays like 1/k (twice the horizon, half the gap)."""
    ch = fa.GilbertElliott(0.05, 0.2, 0.95, 0.3)
    j = fa.Scenario(S, ch, fa.OnlineDesign(2), attack).cost()
    curve = fa.expected_trace_curve(S, ch, fa.OnlineDesign(2), 4000, attack)
    assert_allclose(curve.trace[-1], j, rtol=1e-10)
    gap_h, gap_2h = abs(curve.j_k[1999] - j), abs(curve.j_k[3999] - j)
    assert gap_2h < 0.001 * j and 0.49 < gap_2h / gap_h < 0.51


@pytest.mark.parametrize(
    "call, exc, arg",
    [
        (lambda: fa.expected_trace_curve(S, "x", fa.OnlineDesign(2)), TypeError, "channel"),
        (lambda: fa.expected_trace_curve(S, 1.5, fa.OnlineDesign(2)), ValueError, "channel"),
        (lambda: fa.expected_trace_curve(S, 1.0, fa.OnlineDesign(2)), ValueError, "channel"),
        (lambda: fa.expected_trace_curve(S, lam=0.0, sched=fa.OnlineDesign(2)), ValueError, "lam"),
        (lambda: fa.expected_trace_curve(S, 0.5, fa.OnlineDesign(2), lam=0.5), TypeError, "lam"),
        (lambda: fa.expected_trace_curve(S, sched=fa.OnlineDesign(2)), TypeError, "channel"),
        (lambda: fa.expected_trace_curve(S, GE), TypeError, "sched"),
        (lambda: fa.expected_trace_curve(S, GE, "1/7"), TypeError, "sched"),
        (lambda: fa.expected_trace_curve(S, GE, fa.OnlineDesign(2), 0), ValueError, "horizon"),
        (lambda: fa.expected_trace_curve(S, GE, fa.OnlineDesign(2), 10, [1, 0]), TypeError, "attack"),
        (lambda: fa.expected_trace_curve(S, GE, fa.OfflineSchedule("1/7"), 10, "1/5"), ValueError, "attack"),
        (
            lambda: fa.expected_trace_curve(S, 0.5, fa.OfflineSchedule(pattern="01"), 10, fa.MimicryAttack()),
            ValueError,
            "attack",
        ),
        (lambda: fa.expected_trace_curve("S", GE, fa.OnlineDesign(2)), TypeError, "system"),
    ],
)
def test_bad_input_names_the_argument(call, exc, arg):
    with pytest.raises(exc, match=names(arg)):
        call()
