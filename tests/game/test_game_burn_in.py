"""simulate_game's default burn-in: the attack's mixing time in whole windows, after which the
closed loop's windows have the stationary detection probability the payoff formula uses."""

import math

import pytest

import fakeack as fa
from conftest import PAPER


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


def test_a_long_period_attack_needs_its_mixing_time(system):
    """PeriodicBlocking(8, 59) keeps its phase for about 1.7e4 steps. With no fall-back every window
    is tested: after the default burn-in the alarm rate is the stationary window's exact alarm
    probability (the count law of the flag process); measured from the paper's initial condition
    it is not."""
    attack = fa.PeriodicBlocking(8, 59)
    policy = fa.SensorPolicy("count", 0.01, 0)
    process = fa.flag_process(0.5, fa.OnlineDesign(2), attack)
    mixing = process.mixing_steps()
    bounds = fa.detection.count_alarm_bounds(0.5, 2, 1000, 0.01, "two-sided")
    d = process.window_alarm_probability(1000, 1, bounds)
    g = fa.simulate_game(system, 0.5, "1/7", policy, attack, 4000, 2000, seed=2)
    assert g.burn_in == 1000 * math.ceil(mixing / 1000) and g.burn_in > 10_000
    assert abs(g.alarm_rate - d) < 4 * g.alarm_stderr, (g.alarm_rate, g.alarm_stderr, d)
    cold = fa.simulate_game(system, 0.5, "1/7", policy, attack, 4000, 2000, seed=2, burn_in=0)
    assert cold.burn_in == 0 and abs(cold.alarm_rate - d) > 4 * cold.alarm_stderr


def test_the_default_burn_in_on_a_markov_channel_and_without_attack(system):
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    g = fa.simulate_game(system, ge, "1/7", fa.SensorPolicy("count", 0.01, 1), None, 2000, 4, seed=1)
    design = fa.design_online(ge, "1/7")
    mixing = fa.flag_process(ge, design).mixing_steps()
    assert g.burn_in == 1000 * math.ceil(mixing / 1000)
    with pytest.raises(ValueError, match="burn_in"):
        fa.simulate_game(system, 0.5, "1/7", fa.SensorPolicy("never"), None, 10, 2, seed=1, burn_in=-1)
