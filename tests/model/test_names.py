"""One name per idea: one type for the online design, one high-power-rate function."""

from fractions import Fraction

import pytest

import fakeack as fa
from conftest import names


def test_online_schedule_is_the_online_design():
    assert fa.OnlineSchedule is fa.OnlineDesign
    d = fa.design_online(0.5, Fraction(1, 7))
    assert isinstance(d, fa.OnlineSchedule) and d == fa.OnlineDesign(2, 1.0)
    z0, mu = d  # unpacks like the pair it is
    assert (z0, mu) == (2, 1.0) and str(d) == "online z0=2"
    assert fa.OnlineDesign.design(0.5, "1/7") == d


@pytest.mark.parametrize(("z0", "mu", "name"), [(0, 1.0, "z0"), (2, 1.5, "mu"), (2, -0.1, "mu")])
def test_online_design_validates(z0, mu, name):
    with pytest.raises(ValueError, match=names(name)):
        fa.OnlineDesign(z0, mu)


def test_the_design_object_drives_the_simulation(paper):
    """The design from design_online is the simulation's schedule, with no conversion."""
    d = fa.design_online(0.5, "1/7")
    a = fa.simulate(paper, 0.5, d, 20, 64, seed=3)
    b = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 20, 64, seed=3)
    assert a.j == b.j


def test_one_high_power_rate():
    """Without attack the closed form (1/7 for the paper's design, exactly derived: with a = 1/2,
    lam a^2 / (1 - a^3) = (1/8) / (7/8)); with an attack the chain; the other names agree."""
    assert fa.high_power_rate(0.5, 2) == pytest.approx(1 / 7, rel=1e-15)
    assert fa.online_high_power_rate(0.5, 2) == fa.high_power_rate(0.5, 2, None)
    # the closed form against the attack chain's stationary law without attack
    assert fa.high_power_rate(0.5, 3, None, 0.25) == pytest.approx(
        fa.flag_rates(0.5, 3, None, 0.25).delivered, rel=1e-13
    )
    att = fa.PeriodicBlocking(1, 5)
    assert fa.delivered_flag_rate(0.5, 2, att) == fa.high_power_rate(0.5, 2, att)
    # blocking 1 of every 5 flags delivers 4/5 of those sent
    rates = fa.flag_rates(0.5, 2, att)
    assert rates.delivered == pytest.approx(0.8 * rates.sent, rel=1e-12)
