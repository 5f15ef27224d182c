"""fa.simulate on two-state Markov channels with high power always arriving, which run on the
bit-sliced kernel: against the exact engine's finite-horizon J and stationary high-power rate,
under every attack kind that kernel takes and both protocols, and its routing."""

import numpy as np
import pytest

import fakeack as fa
from fakeack import _fakeack
from fakeack.attacks.kinds import core_attack
from fakeack.model.system import compiled

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
CHANNELS = [fa.GilbertElliott(0.2, 0.2, 1, 0), fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)]
ATTACKS = [
    None,
    fa.PeriodicBlocking(1, 5),
    fa.MaskBlocking([1, 0, 1, 1, 0]),
    fa.RandomBlocking(0.3),
    fa.FlagInjection(0.05),
    fa.FlagInjection(0.1, block=fa.PeriodicBlocking(1, 4)),
    fa.FlagInjection(0.1, block=fa.RandomBlocking(0.2)),
]
HORIZON, RUNS = 400, 6000


def _direct(ch, sched, attack, protocol="B", horizon=HORIZON, runs=RUNS, seed=1):
    """The bit-sliced kernel called directly on the channel's (p, q, low_good, low_bad)."""
    markov = (float(ch.P[0, 1]), float(ch.P[1, 0]), float(ch.low[0]), float(ch.low[1]))
    return _fakeack.simulate(
        compiled(S), 0.5, "online", 1, 2, sched.z0, sched.mu, core_attack(attack), "covariance",
        protocol, horizon, runs, seed, lambda _: None, False, markov,
    )  # fmt: skip


@pytest.mark.parametrize("protocol", ["A", "B"])
@pytest.mark.parametrize("attack", ATTACKS, ids=str)
@pytest.mark.parametrize("ch", CHANNELS, ids=repr)
def test_agrees_with_the_exact_engine(ch, attack, protocol):
    design = fa.OnlineDesign(2)
    res = fa.simulate(S, ch, design, HORIZON, RUNS, seed=5, attack=attack, protocol=protocol, progress=False)
    curve = fa.expected_trace_curve(S, ch, design, HORIZON, attack=attack)
    assert abs(res.j - curve.j_k[-1]) <= 4 * res.stderr, (res.j, curve.j_k[-1], res.stderr)
    rate = fa.Scenario(S, ch, design, attack).high_power_rate()
    # Stationary rate against the horizon's: 5 binomial standard errors plus the transient.
    tol = 5 * np.sqrt(rate * (1 - rate) / (RUNS * HORIZON)) + 2 / HORIZON
    assert abs(res.high_power_rate - rate) <= tol
    assert res.channel == ch


def test_offline_ratio_agrees_with_the_exact_engine():
    ch, sched = CHANNELS[1], fa.OfflineSchedule("1/3")
    res = fa.simulate(S, ch, sched, HORIZON, RUNS, seed=2, progress=False)
    curve = fa.expected_trace_curve(S, ch, sched, HORIZON)
    assert abs(res.j - curve.j_k[-1]) <= 4 * res.stderr
    assert res.high_power_rate == pytest.approx(1 / 3, abs=1 / HORIZON)


def test_routes_to_the_bit_sliced_kernel():
    ch, design, att = CHANNELS[0], fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5)
    res = fa.simulate(S, ch, design, 300, 1000, seed=3, attack=att, progress=False)
    direct = _direct(ch, design, att, horizon=300, runs=1000, seed=3)
    assert direct is not None
    np.testing.assert_array_equal(res.j_k, direct["j_k"])
    # Any two-state channel with high power always arriving, given as a MarkovChannel.
    mc = fa.MarkovChannel([[0.8, 0.2], [0.2, 0.8]], [1.0, 0.0], [1.0, 1.0])
    again = fa.simulate(S, mc, design, 300, 1000, seed=3, attack=att, progress=False)
    np.testing.assert_array_equal(again.j_k, res.j_k)


def test_falls_back_outside_the_kernel_limits():
    # A memory of 41 bits under attack is deeper than the bit-sliced kernel's thermometer.
    ch, design, att = CHANNELS[1], fa.OnlineDesign(40), fa.PeriodicBlocking(1, 5)
    assert _direct(ch, design, att, horizon=100, runs=300) is None
    res = fa.simulate(S, ch, design, 100, 300, seed=1, attack=att, progress=False)
    assert np.isfinite(res.j) and res.channel == ch


def test_state_mode_on_a_markov_channel_runs_on_the_automaton_kernel():
    """The bit-sliced kernel is covariance-only; state mode under the channel goes to the
    automaton kernel, and its mean squared error is the exact J_H."""
    design = fa.OnlineDesign(2)
    res = fa.simulate(S, CHANNELS[0], design, 200, 4000, seed=1, mode="state", progress=False)
    exact = fa.expected_trace_curve(S, CHANNELS[0], design, 200).j_k[-1]
    assert abs(res.j - exact) <= 4 * res.stderr and res.mode == "state"


def test_high_power_losses_stay_on_the_automaton_kernel():
    lossy = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2, high_bad=0.5)
    res = fa.simulate(S, lossy, fa.OnlineDesign(2), 200, 2000, seed=1, progress=False)
    curve = fa.expected_trace_curve(S, lossy, fa.OnlineDesign(2), 200)
    assert abs(res.j - curve.j_k[-1]) <= 4 * res.stderr
