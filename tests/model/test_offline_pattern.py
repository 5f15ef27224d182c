"""OfflineSchedule given by its pattern: exactly one of ratio and pattern, the pattern as 0/1
ints, today's behaviour and repr for a ratio, and the routes that need a ratio say so."""

from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import names


def test_ratio_form_is_unchanged():
    s = fa.OfflineSchedule(Fraction(1, 7))
    assert repr(s) == "OfflineSchedule(ratio=Fraction(1, 7))"
    assert str(s) == "offline 1/7: 1000000"
    assert s.ratio == Fraction(1, 7) and s.high_fraction == Fraction(1, 7)
    assert s.pattern.dtype == np.int64 and s.pattern.tolist() == [1, 0, 0, 0, 0, 0, 0]
    assert s == fa.OfflineSchedule("1/7")


@pytest.mark.parametrize(
    "given", ["1000000", [1, 0, 0, 0, 0, 0, 0], (True,) + (False,) * 6, np.array([1] + [0] * 6)]
)
def test_pattern_forms(given):
    s = fa.OfflineSchedule(pattern=given)
    assert s.ratio is None and s.high_fraction == Fraction(1, 7)
    assert s.pattern.dtype == np.int64 and s.pattern.tolist() == [1, 0, 0, 0, 0, 0, 0]
    assert repr(s) == "OfflineSchedule(pattern='1000000')"
    assert str(s) == "offline pattern: 1000000"
    assert s == fa.OfflineSchedule(pattern="1000000") and hash(s) == hash(
        fa.OfflineSchedule(pattern="1000000")
    )


def test_all_low_and_all_high_patterns_are_valid():
    assert fa.OfflineSchedule(pattern="000").high_fraction == 0
    assert fa.OfflineSchedule(pattern=[1]).pattern.tolist() == [1]
    long = fa.OfflineSchedule(pattern=[1] + [0] * 99)
    assert repr(long) == "OfflineSchedule(pattern=<1 high of 100 steps>)"


def test_pattern_is_a_copy():
    s = fa.OfflineSchedule(pattern="10")
    s.pattern[0] = 0
    assert s.pattern.tolist() == [1, 0]


@pytest.mark.parametrize(
    "kwargs, exc, arg",
    [
        (dict(), TypeError, "pattern"),
        (dict(ratio="1/7", pattern="10"), TypeError, "ratio"),
        (dict(pattern=""), ValueError, "pattern"),
        (dict(pattern="10a"), ValueError, "pattern"),
        (dict(pattern=[1, 2]), ValueError, "pattern"),
        (dict(pattern=[[1, 0]]), ValueError, "pattern"),
        (dict(pattern=[]), ValueError, "pattern"),
        (dict(pattern=["1", "0"]), TypeError, "pattern"),
        (dict(pattern=b"10"), TypeError, "pattern"),
        (dict(ratio=2), ValueError, "ratio"),
    ],
)
def test_validation_names_the_argument(kwargs, exc, arg):
    with pytest.raises(exc, match=names(arg)):
        fa.OfflineSchedule(**kwargs)


def test_pattern_schedules_reach_the_curve(paper):
    s = fa.OfflineSchedule(pattern="100")
    curve = fa.expected_trace_curve(paper, 0.5, s, 10)
    assert np.array_equal(curve.trace, fa.Scenario(paper, 0.5, s).cost_curve(10).trace)
    # fa.simulate takes a pattern on its automaton kernel (tests/montecarlo/test_automaton_mc.py).
