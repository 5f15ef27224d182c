"""authenticated=True: the sensor rejects forged flag-ACKs, so only an attack's blocking part acts
(fakeack.attacks.discard_forgeries), in j_attack, Scenario, detection_probability and
simulate_game; and what that leaves mimicry."""

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER
from conftest import PAPER_RATIO as RATIO
from fakeack.attacks.automata import as_automaton, discard_forgeries

GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


def test_a_forger_reduces_to_its_blocking_part(system):
    for ch in (0.5, GE):
        on = fa.j_online(system, ch, 2)
        assert fa.j_attack(system, ch, 2, attack=fa.FlagInjection(0.1), authenticated=True) == on
        block = fa.RandomBlocking(0.2)
        forger = fa.FlagInjection(0.1, block=block)
        assert fa.j_attack(system, ch, 2, attack=forger, authenticated=True) == fa.j_attack(
            system, ch, 2, attack=block
        )
        periodic = fa.PeriodicBlocking(1, 5)
        assert fa.j_attack(system, ch, 2, attack=periodic, authenticated=True) == fa.j_attack(
            system, ch, 2, attack=periodic
        )


def test_discarding_forgeries_keeps_the_strategy_and_drops_every_forged_delivery():
    auto = as_automaton(fa.MimicryAttack(), channel=fa.BernoulliChannel(0.5), design=fa.OnlineDesign(2))
    kept = discard_forgeries(fa.MimicryAttack(), channel=fa.BernoulliChannel(0.5), design=fa.OnlineDesign(2))
    assert kept.flag == auto.flag and kept.start == auto.start
    assert [[(p, n) for p, _, n in ev] for ev in kept.quiet] == [
        [(p, n) for p, _, n in ev] for ev in auto.quiet
    ]
    assert not any(d for ev in kept.quiet for _, d, _ in ev)
    assert discard_forgeries(None) is None and discard_forgeries("inject:0.1") is None


@pytest.mark.parametrize("channel", [0.5, GE])
def test_mimicry_against_authenticated_flags_is_blocking_and_is_seen(system, channel):
    """Its forgeries rejected, mimicry only blocks the genuine flag-ACKs its virtual detector
    would not send: no forged flag arrives, fewer flags than without attack arrive, J is at least
    J_on, and the count test sees it in almost every 1000-step window."""
    design = fa.OnlineDesign(2)
    sc = fa.Scenario(system, channel, design, fa.MimicryAttack(), authenticated=True)
    assert sc.cost() == fa.j_attack(system, channel, 2, attack=fa.MimicryAttack(), authenticated=True)
    rates = sc.flag_rates()
    free = fa.Scenario(system, channel, design).flag_rates()
    assert rates.forged == 0 and rates.delivered < free.delivered
    assert sc.cost() >= fa.j_online(system, channel, 2)
    p = fa.detection_probability(channel, 2, fa.MimicryAttack(), 1000, 0.01, authenticated=True)
    assert p > 0.99
    assert fa.detection_probability(channel, 2, fa.FlagInjection(0.05), 1000, 0.01, authenticated=True) == (
        fa.detection_probability(channel, 2, None, 1000, 0.01)
    )


def test_the_game_plays_only_the_blocking_part(system):
    pol = fa.SensorPolicy("count", 0.01, 2)
    a = fa.simulate_game(
        system, 0.5, "1/7", pol, fa.FlagInjection(0.05), 20_000, 8, seed=3, authenticated=True
    )
    b = fa.simulate_game(system, 0.5, "1/7", pol, None, 20_000, 8, seed=3)
    assert a.j == b.j and np.array_equal(a.delivered_per_run, b.delivered_per_run)


def test_the_frontier_and_the_matrix_game_score_only_the_blocking_part(system):
    """authenticated=True on stealthy_frontier, game_payoff and solve_game: the rate-matching
    family becomes random blocking of the same budgets, a pure forger becomes no attack."""
    args = (system, 0.5, 2, 1000, 0.01, "count")
    inject = fa.stealthy_frontier(*args, "random+inject", 0.5, grid=5, authenticated=True)
    random = fa.stealthy_frontier(*args, "random", 0.5, grid=5)
    # Each candidate (budget beta, forging gamma) scores as random blocking at beta.
    for d, j in zip(*inject.candidates, strict=True):
        i = int(np.argmin(np.abs(random.candidates[1] - j)))
        assert j == pytest.approx(random.candidates[1][i], rel=1e-12)
        assert d == pytest.approx(random.candidates[0][i], rel=1e-12)
    naive = fa.stealthy_frontier(*args, "random+inject", 0.5, grid=5)
    # Unauthenticated, forging changes J: the forged flags buy high-power packets (lower J), the
    # price the rate-matching forger pays to keep the count's mean.
    assert naive.candidates[1].min() < inject.candidates[1].min() - 1e-3
    policy = fa.SensorPolicy("count", 0.01, 2)
    block = fa.RandomBlocking(0.2)
    forger = fa.FlagInjection(0.03, block=block)
    auth = fa.game_payoff(system, 0.5, RATIO, policy, forger, 1000, authenticated=True)
    assert auth.j == fa.game_payoff(system, 0.5, RATIO, policy, block, 1000).j
    sol = fa.solve_game(
        system,
        0.5,
        RATIO,
        1000,
        0.01,
        2,
        [None, fa.FlagInjection(0.03), forger, block],
        ["count"],
        ["any"],
        authenticated=True,
    )
    np.testing.assert_array_equal(sol.payoff[:, 1], sol.payoff[:, 0])
    np.testing.assert_array_equal(sol.payoff[:, 2], sol.payoff[:, 3])
    with pytest.raises(TypeError, match="authenticated must be True or False"):
        fa.game_payoff(system, 0.5, RATIO, policy, forger, 1000, authenticated="yes")
