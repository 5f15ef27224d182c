"""The delay frontier: each family's J from the exact costs, the CUSUM's delays from its run
lengths at the threshold of the stated ARL0, and the windowed count test at the same false-alarm
rate; mimicry is seen at the false-alarm rate by both."""

from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER

SYSTEM = fa.LinearSystem(**PAPER)


@pytest.fixture(scope="module")
def random_family():
    return fa.delay_frontier(SYSTEM, 0.5, Fraction(1, 7), 2e4, "random", window=200, grid=3)


def test_the_random_family(random_family):
    f = random_family
    betas = [a.beta for a in f.attacks]
    assert betas == pytest.approx([0.1, 0.5, 0.9])
    expected_j = [fa.j_attack(SYSTEM, 0.5, 2, attack=a) for a in f.attacks]
    np.testing.assert_allclose(f.j, expected_j, rtol=1e-12)
    assert np.all(np.diff(f.cusum_delay) < 0)  # more blocking, sooner seen
    arl0 = fa.cusum_run_length(0.5, fa.OnlineDesign(2), f.cusum)
    assert arl0.mean == pytest.approx(2e4, rel=0.02)
    assert f.alpha == pytest.approx(0.01)
    d = fa.detection_probability(0.5, 2, f.attacks[1], 200, 0.01, "count")
    assert f.window_delay[1] == pytest.approx(100 + 200 / d)


def test_mimicry_waits_for_a_false_alarm():
    f = fa.delay_frontier(SYSTEM, 0.5, Fraction(1, 7), 2e4, "mimicry", window=200)
    assert f.cusum_delay[0] == pytest.approx(2e4, rel=0.02)
    assert f.window_detection[0] == pytest.approx(fa.detection_probability(0.5, 2, None, 200, 0.01, "count"))


def test_bad_arguments_name_themselves():
    with pytest.raises(ValueError, match="family"):
        fa.delay_frontier(SYSTEM, 0.5, Fraction(1, 7), family="loud")
    with pytest.raises(ValueError, match="window"):
        fa.delay_frontier(SYSTEM, 0.5, Fraction(1, 7), 500, window=1000)
    with pytest.raises(ValueError, match="grid"):
        fa.delay_frontier(SYSTEM, 0.5, Fraction(1, 7), grid=0)
