"""fa.robust_design: the online design within the energy budget of least worst-case J under blocking.

Checked against a brute-force scan written here (fa.worst_attack over designs built by hand), the
closed-form high-power rate of the online schedule, Theorem 4.5's J_on at beta = 0,
Proposition 3.1's J_off and, for fixed memories (mu = 1), the consecutive-blocking limit
fa.j_attack_limit, which is the worst attack on the paper's example.
"""

from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER, PAPER_LAM
from fakeack.optimal.robust import robust_design

S = fa.LinearSystem(**PAPER)
RATIO = Fraction(1, 10)  # design_online(0.5, 1/10) = (2, 5/11)
A_LOSS = 1 - PAPER_LAM


def rate(z0, mu):
    """The attack-free high-power rate of (z0, mu) on the paper's channel (closed form)."""
    a = A_LOSS
    return PAPER_LAM * a**z0 * (mu + (1 - mu) * a) / (1 - mu * a ** (z0 + 1) - (1 - mu) * a ** (z0 + 2))


@pytest.fixture(scope="module")
def half():
    return robust_design(S, PAPER_LAM, RATIO, 0.5, extra_memory=1, mu_points=2)


def test_beta_zero_gives_the_nominal_design_and_j_on():
    r = robust_design(S, PAPER_LAM, RATIO, 0.0, extra_memory=1, mu_points=2)
    assert r.design == r.nominal == fa.design_online(PAPER_LAM, RATIO)
    assert r.j_worst == pytest.approx(fa.j_online(S, PAPER_LAM, 2, 5 / 11), rel=1e-10)


def test_designs_meet_the_budget_by_the_closed_form_rate(half):
    mu_star = 5 / 11
    expected = [(2, mu_star), (2, mu_star / 2), (3, 1.0), (3, 0.5)]
    assert np.array([(d.z0, d.mu) for d in half.designs]) == pytest.approx(np.array(expected), rel=1e-12)
    rates = [rate(z0, mu) for z0, mu in expected]
    assert half.high_power_rate == pytest.approx(rates, rel=1e-10)
    assert np.all(half.high_power_rate <= float(RATIO) * (1 + 1e-12))
    assert half.high_power_rate[0] == pytest.approx(float(RATIO), rel=1e-12)


def test_brute_force_scan_agrees(half):
    # Every design of the search and a finer one, by fa.worst_attack directly.
    fine = [(2, m) for m in np.linspace(5 / 11, 5 / 44, 4)] + [(3, m) for m in np.linspace(1.0, 0.25, 4)]
    js = {zm: fa.worst_attack(S, PAPER_LAM, fa.OnlineDesign(*zm), 0.5).j for zm in fine}
    for d, j in zip(half.designs, half.j_worst_all, strict=True):
        assert j == pytest.approx(fa.worst_attack(S, PAPER_LAM, d, 0.5).j, rel=1e-10)
    assert min(js.values()) >= half.j_worst * (1 - 1e-10)
    assert half.design == fa.OnlineDesign(3, 1.0)
    # Spending less energy on a fixed memory beats the nominal randomised design under attack.
    assert half.j_worst < half.j_nominal_worst
    assert half.j_nominal_worst == pytest.approx(half.j_worst_all[0])


def test_fixed_memory_entries_are_the_consecutive_blocking_limit(half):
    i = half.designs.index(fa.OnlineDesign(3, 1.0))
    assert half.j_worst_all[i] == pytest.approx(fa.j_attack_limit(S, PAPER_LAM, 3, 0.5), rel=1e-9)
    assert np.all(half.j_worst_all <= half.j_lp * (1 + 1e-9))
    assert half.j_free[i] == pytest.approx(fa.j_online(S, PAPER_LAM, 3, 1.0), rel=1e-10)


def test_offline_comparison(half):
    assert half.j_offline == pytest.approx(fa.j_offline(S, PAPER_LAM, RATIO), rel=1e-12)
    assert half.j_offline < half.j_worst  # at beta = 1/2 the offline schedule beats every design


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        (dict(beta=1.5), ValueError, "^beta"),
        (dict(beta="x"), TypeError, "^beta"),
        (dict(extra_memory=-1), ValueError, "^extra_memory"),
        (dict(mu_points=0), ValueError, "^mu_points"),
        (dict(ratio=2.0), ValueError, "^ratio"),
    ],
)
def test_bad_arguments_are_named(kwargs, exc, match):
    args = dict(ratio=RATIO, beta=0.5) | kwargs
    with pytest.raises(exc, match=match):
        robust_design(
            S,
            PAPER_LAM,
            args["ratio"],
            args["beta"],
            **{k: v for k, v in kwargs.items() if k not in ("ratio", "beta")},
        )


def test_on_a_bursty_channel_the_robust_design_beats_the_fall_back():
    s = fa.LinearSystem(A=1.05, C=0.7, Q=0.8, R=0.8)
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    r = robust_design(s, ge, RATIO, 0.5, extra_memory=1, mu_points=2)
    assert r.nominal == fa.design_online(ge, RATIO)
    assert r.design == fa.OnlineDesign(2, 1.0)
    assert r.j_worst == pytest.approx(fa.worst_attack(s, ge, fa.OnlineDesign(2, 1.0), 0.5).j, rel=1e-10)
    assert r.j_offline == pytest.approx(fa.j_offline(s, ge, RATIO), rel=1e-10)
    assert r.j_worst < r.j_offline < r.j_nominal_worst
    assert np.all(r.high_power_rate <= float(RATIO) * (1 + 1e-9))
