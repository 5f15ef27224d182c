"""fa.simulate_game under a Markov channel: the closed loop against the exact engine (the online
schedule designed for the channel, never tested; the offline fall-back pattern), the count test's
window alarm rate against detection_probability under the channel, the paper's channel unchanged,
and the interval test refused."""

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER

GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
RATIO = "1/7"


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


def test_never_testing_is_the_designed_online_schedule(system):
    design = fa.design_online(GE, RATIO)
    g = fa.simulate_game(system, GE, RATIO, fa.SensorPolicy("never"), None, 4000, 256, seed=1, burn_in=2000)
    exact = fa.Scenario(system, GE, design)
    assert abs(g.j - exact.cost()) < 4 * g.stderr + 0.002 * exact.cost()  # J_H of 4000 steps ~ J
    assert abs(g.high_power - exact.high_power_rate()) < 4 * g.high_power_stderr + 1e-3
    assert g.channel == GE


def test_always_offline_is_the_best_pattern_under_the_channel(system):
    search = fa.offline_search(system, GE, RATIO)
    g = fa.simulate_game(system, GE, RATIO, fa.SensorPolicy("offline"), None, 4200, 256, seed=2, burn_in=2100)
    assert abs(g.j - search.j) < 4 * g.stderr + 0.002 * search.j
    assert g.high_power == pytest.approx(1 / 7, abs=1e-12)  # whole periods of the pattern


@pytest.mark.parametrize("attack", [None, fa.PeriodicBlocking(1, 10)])
def test_the_count_tests_alarm_rate_is_its_detection_probability_under_the_channel(system, attack):
    """Windows of 2000 steps (about 140 flags); the sensor falls back for one window after an
    alarm, rare enough here that tested windows are close to the stationary regime."""
    n = 2000
    pol = fa.SensorPolicy("count", 0.05, 1)
    g = fa.simulate_game(system, GE, RATIO, pol, attack, 200 * n, 64, seed=3, n_steps=n, burn_in=4 * n)
    p = fa.detection_probability(
        GE, fa.design_online(GE, RATIO).z0, attack, n, 0.05, mu=fa.design_online(GE, RATIO).mu
    )
    assert abs(g.alarm_rate - p) < 4 * g.alarm_stderr + 0.005


def test_the_paper_channel_is_unchanged_and_lam_still_works(system):
    pol = fa.SensorPolicy("count", 0.01, 2)
    a = fa.simulate_game(system, 0.5, RATIO, pol, fa.RandomBlocking(0.2), 20_000, 8, seed=3)
    b = fa.simulate_game(
        system,
        lam=0.5,
        ratio=RATIO,
        policy=pol,
        attack=fa.RandomBlocking(0.2),
        horizon=20_000,
        runs=8,
        seed=3,
    )
    c = fa.simulate_game(
        system, fa.BernoulliChannel(0.5), RATIO, pol, fa.RandomBlocking(0.2), 20_000, 8, seed=3
    )
    assert a.j == b.j == c.j and np.array_equal(a.delivered_per_run, c.delivered_per_run)


def test_the_interval_test_and_bad_arguments_are_refused(system):
    with pytest.raises(ValueError, match="policy: the interval test's law assumes independent gaps"):
        fa.simulate_game(system, GE, RATIO, fa.SensorPolicy("interval", 0.01, 1), None, 1000, 4, seed=1)
    with pytest.raises(TypeError, match="give either channel or lam"):
        fa.simulate_game(system, GE, RATIO, fa.SensorPolicy("never"), None, 1000, 4, seed=1, lam=0.5)
    with pytest.raises(TypeError, match="missing required argument: 'horizon'"):
        fa.simulate_game(system, GE, RATIO, fa.SensorPolicy("never"))
