"""The careful attack set on the stealthy frontier: the forger that respects the support check
(min_gap = z0 + 1) and mimicry, which delivers exactly the attack-free flag process."""

import pytest

import fakeack as fa
from conftest import PAPER


@pytest.fixture(scope="module")
def paper():
    return fa.LinearSystem(**PAPER)


def test_mimicry_is_seen_at_the_false_alarm_rate_and_costs_more_than_offline(paper):
    for test in ("count", "interval"):
        f = fa.stealthy_frontier(paper, 0.5, 2, 1000, 0.01, test, "mimicry", 0.02)
        assert isinstance(f.attack, fa.MimicryAttack)
        assert f.detection == fa.detection_probability(0.5, 2, None, 1000, 0.01, test, support=False)
        assert f.j == fa.j_attack(paper, 0.5, 2, attack=fa.MimicryAttack())
    j_off = fa.solve_game(paper, 0.5, "1/7", 1000, 0.01, 2, [None], ["count"], ["any"]).j_offline
    assert f.j > j_off


def test_the_careful_forger_never_trips_the_support_check_and_its_best_beats_rate_matching(paper):
    f = fa.stealthy_frontier(paper, 0.5, 2, 1000, 0.01, "count", "careful", 0.02, grid=11)
    for a in f.frontier_attacks:
        assert a.min_gap == 3
        assert fa.detection_probability(0.5, 2, a, 1000, 0.01, test="support") == 0.0
    careful = fa.rate_matching_attack(0.5, 2, 0.2, min_gap=3)
    assert f.detection <= 0.02
    assert f.j >= fa.j_attack(paper, 0.5, 2, attack=careful) - 1e-12
    g = fa.stealthy_frontier(paper, 0.5, 2, 1000, 0.01, "interval", "careful", 0.02, grid=3)
    assert all(a.min_gap == 3 for a in g.frontier_attacks) and g.detection <= 0.02
    assert g.j > fa.j_online(paper, 0.5, 2)


def test_authenticated_mimicry_is_blocking_and_is_seen(paper):
    f = fa.stealthy_frontier(paper, 0.5, 2, 1000, 0.01, "count", "mimicry", 1.0, authenticated=True)
    assert f.detection > 0.99
