"""Attacker automata in the closed loop (fa.simulate_game, fa.detection_rates): mimicry delivers the
attack-free flag law, so the count test alarms at its false-alarm rate, the support check never,
and the game's cost is the renewal average of the mimicry cost and the offline one; an automaton
plays as the built-in attack it writes; the careful forger (min_gap > 1) and authenticated
flag-ACKs; the compiled kernel's argument checked."""

import math
from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER
from fakeack import _fakeack
from fakeack.attacks import as_automaton, discard_forgeries

LAM, RATIO = 0.5, Fraction(1, 7)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


@pytest.mark.parametrize("support", [True, False])
def test_mimicry_windows_alarm_at_the_false_alarm_rate(support):
    """The sensor sees the attack-free flag law: the count test's alarm rate is its false-alarm
    rate (the normal approximation of detection_probability, within 4 standard errors of 20000
    windows), and no gap is shorter than without attack, so the support check changes nothing."""
    free = fa.detection_probability(LAM, 2, None, 1000, 0.01)
    r = fa.detection_rates(
        LAM, 2, fa.MimicryAttack(), 1000, runs=20_000, alternative="two-sided", support=support
    )
    assert abs(r.detection - free) < 4 * r.detection_stderr, (r.detection, r.detection_stderr, free)
    assert r.support is support
    other = fa.detection_rates(
        LAM, 2, fa.MimicryAttack(), 1000, runs=20_000, alternative="two-sided", support=not support
    )
    assert other.detection == r.detection  # the same windows bit for bit
    # It blocks most genuine flag-ACKs: those a virtual flag does not meet.
    rates = fa.flag_rates(LAM, 2, fa.MimicryAttack())
    assert r.beta == pytest.approx(rates.blocked / rates.sent, rel=1e-12) and 0.5 < r.beta < 1


def test_mimicry_never_trips_the_support_check():
    r = fa.detection_rates(LAM, 2, fa.MimicryAttack(), 1000, runs=5000, test="support")
    assert r.detection == 0.0 and r.false_alarm == 0.0


def test_the_careful_forger_is_seen_at_the_count_tests_rate_and_never_by_the_support_check():
    """Rate matching with min_gap = z0 + 1 (an automaton of its own now plays in the loop): the
    count test's alarm rate is detection_probability's, the support check's 0."""
    careful = fa.rate_matching_attack(LAM, 2, 0.2, min_gap=3)
    expected = fa.detection_probability(LAM, 2, careful, 1000, 0.01)
    r = fa.detection_rates(LAM, 2, careful, 1000, runs=20_000, alternative="two-sided")
    assert abs(r.detection - expected) < 4 * r.detection_stderr, (r.detection, r.detection_stderr, expected)
    assert r.beta == 0.2
    assert fa.detection_rates(LAM, 2, careful, 1000, runs=5000, test="support").detection == 0.0


def renewal(j_att, j_off, d, k):
    """The repeated game's long-run cost: online windows until an alarm (probability d each), then
    k offline windows, J = (J_att + d k J_off) / (1 + d k)."""
    return (j_att + d * k * j_off) / (1 + d * k)


def test_mimicry_in_the_closed_loop_is_the_renewal_average(system):
    """Windows of 10^4 steps, so that the transients at switches are below the standard error; the
    fall-back rate is the false-alarm rate d of the count test (the support check, on, never
    fires), and J the renewal average of the mimicry cost (exact engine) and the offline one."""
    n, k = 10_000, 2
    policy = fa.SensorPolicy("count", 0.05, k)
    d = fa.detection_probability(LAM, 2, None, n, 0.05, alternative=policy.alternative)
    j_att = fa.j_attack(system, LAM, 2, attack=fa.MimicryAttack())
    j_off = fa.j_offline(system, LAM, RATIO)
    sim = fa.simulate_game(
        system, LAM, RATIO, policy, fa.MimicryAttack(), 100 * n, 256, seed=31, n_steps=n, burn_in=10 * n
    )
    expected = renewal(j_att, j_off, d, k)
    assert abs(sim.j - expected) < 4 * sim.stderr, (sim.j, sim.stderr, expected)
    assert abs(sim.fallback_rate - d) < 4 * sim.fallback_stderr, (sim.fallback_rate, sim.fallback_stderr, d)
    assert sim.alarm_rate == sim.fallback_rate  # every alarm falls back (the "any" rule)
    # The renewal average is not the attack-free one: mimicry costs more than its alarms show.
    assert expected - renewal(fa.j_online(system, LAM, 2), j_off, d, k) > 20 * sim.stderr


@pytest.mark.parametrize(
    "attack", [fa.PeriodicBlocking(1, 5), fa.FlagInjection(0.04, fa.RandomBlocking(0.2))], ids=str
)
def test_an_automaton_plays_as_its_built_in_attack(system, attack):
    """The built-in attack (bit-sliced kernel) and its automaton (lane kernel): different streams,
    the same means of J and of the fall-back rate."""
    policy = fa.SensorPolicy("count", 0.05, 2, support=False)
    runs = dict(horizon=20_000, runs=512, burn_in=2000)
    a = fa.simulate_game(system, LAM, RATIO, policy, attack, seed=5, **runs)
    b = fa.simulate_game(system, LAM, RATIO, policy, as_automaton(attack), seed=6, **runs)
    assert abs(a.j - b.j) < 4 * math.hypot(a.stderr, b.stderr), (a.j, b.j)
    assert abs(a.fallback_rate - b.fallback_rate) < 4 * math.hypot(a.fallback_stderr, b.fallback_stderr)
    assert abs(a.high_power - b.high_power) < 4 * math.hypot(a.high_power_stderr, b.high_power_stderr)


def test_injection_with_a_minimum_gap_runs_as_its_automaton(system):
    careful = fa.rate_matching_attack(LAM, 2, 0.2, min_gap=3)
    policy = fa.SensorPolicy("count", 0.05, 2)
    a = fa.simulate_game(system, LAM, RATIO, policy, careful, 5000, 16, seed=2)
    b = fa.simulate_game(system, LAM, RATIO, policy, as_automaton(careful), 5000, 16, seed=2)
    assert a.j == b.j and np.array_equal(a.delivered_per_run, b.delivered_per_run)


def test_authenticated_mimicry_is_its_blocking(system):
    """A sensor that rejects forgeries meets the mimicry attacker's deliveries on quiet steps
    discarded: never testing, J is the exact engine's cost of that automaton."""
    kept = discard_forgeries(fa.MimicryAttack(), channel=LAM, design=fa.OnlineDesign(2))
    exact = fa.j_attack(system, LAM, 2, attack=kept)
    never = fa.SensorPolicy("never")
    sim = fa.simulate_game(
        system, LAM, RATIO, never, fa.MimicryAttack(), 20_000, 256, seed=3, burn_in=5000, authenticated=True
    )
    assert abs(sim.j - exact) < 4 * sim.stderr, (sim.j, sim.stderr, exact)
    again = fa.simulate_game(system, LAM, RATIO, never, kept, 20_000, 256, seed=3, burn_in=5000)
    assert again.j == sim.j


def test_mimicry_under_a_markov_channel_runs_the_channel_and_the_design(system):
    """Under a Gilbert-Elliott channel the mimicry attacker without a channel or design of its own
    runs the played ones (the channel, the design made for it): the exact engine's cost."""
    design = fa.design_online(GE, RATIO)
    exact = fa.Scenario(system, GE, design, fa.MimicryAttack()).cost()
    g = fa.simulate_game(
        system, GE, RATIO, fa.SensorPolicy("never"), fa.MimicryAttack(), 4000, 256, seed=1, burn_in=2000
    )
    assert abs(g.j - exact) < 4 * g.stderr + 0.002 * exact


def _kernel(**kw):
    args = [fa.LinearSystem(**PAPER)._core, LAM, 1, 7, 2, 1.0]
    tail = ["online", -1, 0, [], [], 0.0, None, 0, 100, 200, 10, 4, 1, lambda done: None]
    return _fakeack.simulate_game(*args, kw.pop("attack", None), *tail, **kw)


def test_the_kernels_automaton_argument():
    table = ([[(1.0, False, 0)]], [[(1.0, False, 0)]], 0)  # blocks everything
    out = _kernel(automaton=table)  # after the burn-in, no flag-ACK and low power throughout
    assert (out["delivered"] == 0).all() and (out["high_power"] == 0.0).all()
    with pytest.raises(ValueError, match="^automaton: give either attack or automaton"):
        _kernel(attack=_fakeack.Attack.periodic(1, 5), automaton=table)
    with pytest.raises(ValueError, match="^automaton:.*sum to 1"):
        _kernel(automaton=([[(0.5, False, 0)]], [[(1.0, False, 0)]], 0))
    with pytest.raises(ValueError, match="^automaton:.*start"):
        _kernel(automaton=([[(1.0, False, 0)]], [[(1.0, False, 0)]], 3))
