"""FlagInjection's min_gap: validated, kept out of the repr at its default, and refused with a
pointer to the exact engine by every route that cannot compute it."""

import pytest

import fakeack as fa
from conftest import names
from fakeack.attacks.kinds import core_attack


def test_default_and_repr():
    assert fa.FlagInjection(0.1).min_gap == 1
    assert repr(fa.FlagInjection(0.1)) == "FlagInjection(gamma=0.1, block=None)"
    att = fa.FlagInjection(0.1, fa.RandomBlocking(0.2), min_gap=3)
    assert repr(att) == "FlagInjection(gamma=0.1, block=RandomBlocking(beta=0.2), min_gap=3)"
    assert att.label == "inject:0.1+random:0.2 min_gap=3"
    assert "at least 3 steps" in str(att)
    assert fa.FlagInjection(0.1, None, 1) == fa.FlagInjection(0.1)
    assert fa.FlagInjection(0.1, min_gap=2) != fa.FlagInjection(0.1)


@pytest.mark.parametrize(
    "gap, exc", [(0, ValueError), (-1, ValueError), (1.5, TypeError), ("2", TypeError), (True, TypeError)]
)
def test_min_gap_validation_names_it(gap, exc):
    with pytest.raises(exc, match=names("min_gap")):
        fa.FlagInjection(0.1, min_gap=gap)


def test_today_routes_refuse_min_gap(paper):
    # fa.simulate takes min_gap > 1 on its automaton kernel (tests/montecarlo/test_automaton_mc.py);
    # j_attack and expected_trace_curve take it through the engine (tests/attacks/test_channel_attacks.py).
    att = fa.FlagInjection(0.1, min_gap=3)
    calls = [lambda: fa.flag_interval_law(0.5, 2, att)]
    for name, f in (("flag_rates", fa.flag_rates), ("high_power_rate", fa.high_power_rate)):
        try:
            f(0.5, 2, att)
        except ValueError as exc:  # a route that does not take min_gap names the engine
            assert "fakeack.Scenario" in str(exc), name
    for call in calls:
        with pytest.raises(ValueError, match="fakeack.Scenario"):
            call()
    assert core_attack(att, engine=True) is not None
    assert core_attack(fa.FlagInjection(0.1, min_gap=1)) is not None


def test_engine_only_attacks_are_refused_by_today_routes(paper):
    # j_attack takes them through the engine (tests/attacks/test_channel_attacks.py).
    for att in (fa.MimicryAttack(), fa.AttackerAutomaton([([(1.0, True, 0)], [(1.0, False, 0)])])):
        with pytest.raises(TypeError, match="fakeack.Scenario"):
            core_attack(att)
