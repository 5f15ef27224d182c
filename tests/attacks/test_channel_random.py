"""Independent blocking and rate matching under Markov channels.

Independent routes: the i.i.d. functions for a Gilbert-Elliott channel with p + q = 1 (the
channel state is then i.i.d., and with high_good = high_bad the arrivals are those of
lam = pi_good lam_good + pi_bad lam_bad), the exact engine at the returned threshold, and the
flag rates the rate-matching attack promises.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa

SYS = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
GE = fa.GilbertElliott(0.1, 0.4, 0.7, 0.2)
IID_GE = fa.GilbertElliott(0.3, 0.7, 0.6, 0.2)
IID_LAM = 0.7 * 0.6 + 0.3 * 0.2
RATIO = Fraction(1, 7)


def test_threshold_is_the_root_under_a_channel() -> None:
    b = fa.beta_bar_random(SYS, GE, RATIO)
    d = fa.design_online(GE, RATIO)
    j_off = fa.j_offline(SYS, GE, RATIO)
    assert 0 < b < 1
    at = fa.Scenario(SYS, GE, d, fa.RandomBlocking(b)).cost()
    assert abs(at - j_off) < 1e-9 * j_off
    assert fa.Scenario(SYS, GE, d, fa.RandomBlocking(b * 0.99)).cost() < j_off


def test_iid_gilbert_elliott_reduces_to_the_paper_channel() -> None:
    a = fa.beta_bar_random(SYS, IID_GE, RATIO, 2, 0.6)
    b = fa.beta_bar_random(SYS, IID_LAM, RATIO, 2, 0.6)
    assert abs(a - b) < 1e-12
    betas = np.linspace(0, 1, 7)
    sa = fa.random_blocking_sweep(SYS, IID_GE, 2, betas, 0.6, gamma=0.05)
    sb = fa.random_blocking_sweep(SYS, IID_LAM, 2, betas, 0.6, gamma=0.05)
    np.testing.assert_allclose(sa.j_attack, sb.j_attack, rtol=1e-12)
    assert sa.channel == IID_GE and sa.lam == pytest.approx(IID_LAM)
    ga = fa.rate_matching_attack(IID_GE, 2, 0.2).gamma
    gb = fa.rate_matching_attack(IID_LAM, 2, 0.2).gamma
    assert abs(ga - gb) < 1e-12


def test_sweep_matches_the_engine_and_the_paper_channel_is_unchanged() -> None:
    betas = [0.0, 0.3, 1.0]
    d = fa.OnlineDesign(2)
    sw = fa.random_blocking_sweep(SYS, GE, 2, betas)
    for b, j in zip(betas, sw.j_attack, strict=True):
        assert j == fa.Scenario(SYS, GE, d, fa.RandomBlocking(b)).cost()
    old = fa.random_blocking_sweep(SYS, lam=0.5, z0=2, betas=betas)
    new = fa.random_blocking_sweep(SYS, fa.BernoulliChannel(0.5), 2, betas)
    np.testing.assert_array_equal(old.j_attack, new.j_attack)
    assert fa.beta_bar_random(SYS, 0.5, RATIO) == fa.beta_bar_random(SYS, lam=0.5, ratio=RATIO)


def test_rate_matching_hides_the_blocking_from_the_count_under_a_channel() -> None:
    d = fa.OnlineDesign(2)
    att = fa.rate_matching_attack(GE, 2, 0.3)
    free = fa.Scenario(SYS, GE, d).flag_rates().delivered
    got = fa.Scenario(SYS, GE, d, att).flag_rates().delivered
    assert abs(got - free) < 1e-12
    assert att.block == fa.RandomBlocking(0.3)


def test_bad_arguments_name_themselves() -> None:
    with pytest.raises(TypeError, match="not both"):
        fa.beta_bar_random(SYS, GE, RATIO, lam=0.5)
    with pytest.raises(TypeError, match="betas"):
        fa.random_blocking_sweep(SYS, GE, 2)
    with pytest.raises(TypeError, match="beta"):
        fa.rate_matching_attack(GE, 2)
    with pytest.raises(ValueError, match="betas"):
        fa.random_blocking_sweep(SYS, GE, 2, [1.5])
