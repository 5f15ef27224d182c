"""Attacker automata: validation that names transitions or start, reprs, and every built-in attack
written as an automaton (their equal costs are checked in tests/engine)."""

import pytest

import fakeack as fa
from conftest import names
from fakeack.attacks import as_automaton

ONOFF = {
    0: {"flag": [(0.5, True, 0), (0.5, False, 1)], "quiet": [(1.0, False, 0)]},
    1: {"flag": [(1.0, False, 1)], "quiet": [(0.9, False, 1), (0.1, False, 0)]},
}


def test_forms_and_properties():
    a = fa.AttackerAutomaton(ONOFF)
    b = fa.AttackerAutomaton([(ONOFF[0]["flag"], ONOFF[0]["quiet"]), ONOFF[1]], start=0)
    assert a == b and hash(a) == hash(b)
    assert a.n_states == 2 and a.start == 0
    assert a.flag == (((0.5, True, 0), (0.5, False, 1)), ((1.0, False, 1),))
    assert a.quiet[1] == ((0.9, False, 1), (0.1, False, 0))
    assert fa.AttackerAutomaton(a.transitions) == a
    assert repr(a) == f"AttackerAutomaton({a.transitions!r}, start=0)"
    assert eval(repr(a), {"AttackerAutomaton": fa.AttackerAutomaton}) == a
    big = as_automaton(fa.PeriodicBlocking(1, 6))
    assert repr(big) == "AttackerAutomaton(<6 states>, start=0)"
    # 0/1 and numpy values are read as bool and int.
    c = fa.AttackerAutomaton([([(1, 1, 0)], [(1.0, 0, 0)])])
    assert c.flag == (((1.0, True, 0),),) and c.quiet == (((1.0, False, 0),),)


@pytest.mark.parametrize(
    "transitions, start, exc, arg",
    [
        ([], 0, ValueError, "transitions"),
        ("abc", 0, TypeError, "transitions"),
        (None, 0, TypeError, "transitions"),
        ({1: ONOFF[0]}, 0, ValueError, "transitions"),
        ({"a": ONOFF[0]}, 0, TypeError, "transitions"),
        ([{"flag": [(1.0, True, 0)]}], 0, ValueError, "transitions"),
        ([{"flag": [(1.0, True, 0)], "quiet": [(1.0, False, 0)], "x": []}], 0, ValueError, "transitions"),
        ([([(1.0, True, 0)],)], 0, TypeError, "transitions"),
        ([([], [(1.0, False, 0)])], 0, TypeError, "transitions"),
        ([([(1.0, True)], [(1.0, False, 0)])], 0, TypeError, "transitions"),
        ([([(1.5, True, 0)], [(1.0, False, 0)])], 0, ValueError, "transitions"),
        ([([(-0.5, True, 0), (1.5, True, 0)], [(1.0, False, 0)])], 0, ValueError, "transitions"),
        ([([(0.5, True, 0)], [(1.0, False, 0)])], 0, ValueError, "transitions"),  # sums to 0.5
        ([([(0.5, True, 0), (0.5 + 1e-11, True, 0)], [(1.0, False, 0)])], 0, ValueError, "transitions"),
        ([([("1", True, 0)], [(1.0, False, 0)])], 0, TypeError, "transitions"),
        ([([(1.0, "yes", 0)], [(1.0, False, 0)])], 0, TypeError, "transitions"),
        ([([(1.0, 2, 0)], [(1.0, False, 0)])], 0, TypeError, "transitions"),
        ([([(1.0, True, 1)], [(1.0, False, 0)])], 0, ValueError, "transitions"),  # no state 1
        ([([(1.0, True, 0.0)], [(1.0, False, 0)])], 0, TypeError, "transitions"),
        ([([(1.0, True, 0)], [(1.0, False, 0)])] * 2, 0, ValueError, "transitions"),  # 1 unreachable
        ([([(1.0, True, 0)], [(1.0, False, 0)])], 1, ValueError, "start"),
        ([([(1.0, True, 0)], [(1.0, False, 0)])], -1, ValueError, "start"),
        ([([(1.0, True, 0)], [(1.0, False, 0)])], True, TypeError, "start"),
        ([([(1.0, True, 0)], [(1.0, False, 0)])], "0", TypeError, "start"),
    ],
)
def test_validation_names_the_argument(transitions, start, exc, arg):
    with pytest.raises(exc, match=names(arg)):
        fa.AttackerAutomaton(transitions, start)


def test_sum_within_tolerance_and_zero_probability_edges():
    fa.AttackerAutomaton([([(0.5, True, 0), (0.5 + 5e-13, False, 0)], [(1.0, False, 0)])])
    # A state reached only through a zero-probability edge is unreachable.
    with pytest.raises(ValueError, match="not reachable"):
        fa.AttackerAutomaton(
            [([(1.0, True, 0), (0.0, True, 1)], [(1.0, False, 0)]), ([(1.0, True, 1)], [(1.0, False, 1)])]
        )


def test_built_in_attacks_as_automata():
    assert as_automaton(None).flag == (((1.0, True, 0),),)
    assert as_automaton(None).quiet == (((1.0, False, 0),),)
    per = as_automaton(fa.PeriodicBlocking(2, 5))
    assert [e[0][1] for e in per.flag] == [False, False, True, True, True]
    assert [e[0][2] for e in per.flag] == [1, 2, 3, 4, 0]
    assert all(q == ((1.0, False, s),) for s, q in enumerate(per.quiet))
    assert as_automaton("1/5") == as_automaton(fa.PeriodicBlocking(1, 5))
    assert as_automaton(fa.MaskBlocking([0, 1])).flag == (((1.0, True, 1),), ((1.0, False, 0),))
    assert as_automaton(fa.RandomBlocking(0.3)).flag == (((0.3, False, 0), (0.7, True, 0)),)
    assert as_automaton(fa.RandomBlocking(1.0)).flag == (((1.0, False, 0),),)
    inj = as_automaton(fa.FlagInjection(0.1))
    assert inj.flag == (((1.0, True, 0),),) and inj.quiet == (((0.1, True, 0), (0.9, False, 0)),)
    # min_gap = 3: gap counters 0, 1, 2; forging only from the last.
    gap = as_automaton(fa.FlagInjection(0.2, min_gap=3))
    assert gap.n_states == 3
    assert gap.quiet == (((1.0, False, 1),), ((1.0, False, 2),), ((0.2, True, 0), (0.8, False, 2)))
    assert gap.flag == (((1.0, True, 0),),) * 3
    both = as_automaton(fa.FlagInjection(0.2, fa.PeriodicBlocking(1, 2), min_gap=2))
    assert both.n_states == 4  # state b * 2 + g
    assert both.flag[0] == ((1.0, False, 3),) and both.flag[2] == ((1.0, True, 0),)
    aut = fa.AttackerAutomaton(ONOFF)
    assert as_automaton(aut) is aut


def test_mimicry():
    m = fa.MimicryAttack()
    assert repr(m) == "MimicryAttack()" and m.channel is None and m.design is None
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    m2 = fa.MimicryAttack(ge, (2, 0.5))
    assert m2.design == fa.OnlineDesign(2, 0.5) and m2.channel == ge
    assert repr(m2) == f"MimicryAttack(channel={ge!r}, design=OnlineDesign(z0=2, mu=0.5))"
    assert fa.MimicryAttack(0.5).channel == fa.BernoulliChannel(0.5)
    aut = as_automaton(m2)
    assert aut.flag == aut.quiet
    # A start state plus (c, z, h) for c in 2 channel states, z in 0..z0 and the flag state.
    assert aut.n_states == 1 + 2 * (2 + 2)
    assert as_automaton(m, channel=ge, design=fa.OnlineDesign(2, 0.5)) == aut
    assert as_automaton(fa.MimicryAttack(design=(2, 1.0)), channel=0.5).n_states == 4
    with pytest.raises(ValueError, match=names("channel")):
        as_automaton(m, design=fa.OnlineDesign(2))
    with pytest.raises(ValueError, match=names("design")):
        as_automaton(m, channel=ge)
    with pytest.raises(TypeError, match=names("design")):
        fa.MimicryAttack(design=2)
    with pytest.raises(ValueError, match=names("channel")):
        fa.MimicryAttack(channel=1.5)
