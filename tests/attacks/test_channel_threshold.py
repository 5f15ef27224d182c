"""Periodic blocking, the thresholds and the decision under Markov channels.

Independent routes: the exact engine (``fa.Scenario``, the product automaton) for single periods
and masks, the i.i.d. functions for a Gilbert-Elliott channel with p + q = 1 (then the channel
state is i.i.d. and, with high_good = high_bad, the arrivals are those of lam = pi_good lam_good +
pi_bad lam_bad), and the defining equations of the thresholds.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa

SYS = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
# J_max finite here: always low, the loss chain diag(0.3, 0.8) P has spectral radius ~0.52 < 1/1.44.
GE = fa.GilbertElliott(0.1, 0.4, 0.7, 0.2)
BURSTY = fa.GilbertElliott(0.1, 0.1, 1.0, 0.0)
THREE = fa.MarkovChannel([[0.7, 0.2, 0.1], [0.3, 0.3, 0.4], [0.0, 0.5, 0.5]], [0.9, 0.4, 0.05], [1, 1, 1])
# p + q = 1: c_k i.i.d. with P(good) = 1 - p = 0.7, so lam = 0.7 * 0.6 + 0.3 * 0.2 = 0.48.
IID_GE = fa.GilbertElliott(0.3, 0.7, 0.6, 0.2)
IID_LAM = 0.7 * 0.6 + 0.3 * 0.2
RATIO = Fraction(1, 7)


def rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


@pytest.mark.parametrize("channel", [GE, BURSTY, THREE], ids=["ge", "bursty", "three"])
def test_sweep_matches_the_engine_fraction_by_fraction(channel: fa.Channel) -> None:
    d = fa.OnlineDesign(2, 0.6)
    sw = fa.beta_sweep(SYS, channel, RATIO, t_max=25, z0=d.z0, mu=d.mu)
    assert np.all(np.diff(sw.beta) > 0)
    for i in range(0, len(sw), 23):
        r, t = int(sw.r[i]), int(sw.t[i])
        want = fa.Scenario(SYS, channel, d, fa.PeriodicBlocking(r, t)).cost()
        assert rel(float(sw.j_attack[i]), want) < 1e-11, (r, t)
    assert sw.channel == channel
    assert rel(sw.j_online, fa.Scenario(SYS, channel, d).cost()) < 1e-13


def test_masks_and_worst_mask_match_the_engine() -> None:
    d = fa.OnlineDesign(2)
    mask = [1, 0, 1, 1, 0, 0]
    want = fa.Scenario(SYS, GE, d, fa.MaskBlocking(mask)).cost()
    assert rel(fa.j_attack_pattern(SYS, GE, 2, mask), want) < 1e-11
    res = fa.worst_mask(SYS, GE, 2, 6, 3)
    brute = max(
        fa.Scenario(SYS, GE, d, fa.MaskBlocking([b >> i & 1 for i in range(6)])).cost()
        for b in range(64)
        if bin(b).count("1") == 3
    )
    assert rel(res.j, brute) < 1e-11
    assert rel(res.j_consecutive, fa.Scenario(SYS, GE, d, fa.PeriodicBlocking(3, 6)).cost()) < 1e-11
    assert res.mask.sum() == 3
    with pytest.raises(ValueError, match="j_max"):
        fa.j_attack_pattern(SYS, GE, 2, [1, 1])


def test_iid_gilbert_elliott_reduces_to_the_paper_channel() -> None:
    """p + q = 1 with high_good = high_bad: every function gives the i.i.d. value (1e-12; the
    designs differ by the rounding of a root, 1e-15)."""
    d = fa.OnlineDesign(2, 0.6)
    a = fa.beta_sweep(SYS, IID_GE, RATIO, t_max=30, z0=2, mu=0.6)
    b = fa.beta_sweep(SYS, IID_LAM, RATIO, t_max=30, z0=2, mu=0.6)
    np.testing.assert_array_equal(a.r, b.r)
    np.testing.assert_allclose(a.j_attack, b.j_attack, rtol=1e-12)
    assert (
        rel(fa.j_attack_limit(SYS, IID_GE, 2, 0.3, 0.6), fa.j_attack_limit(SYS, IID_LAM, 2, 0.3, 0.6)) < 1e-12
    )
    wa = fa.worst_mask(SYS, IID_GE, 2, 7, 3, 0.6)
    wb = fa.worst_mask(SYS, IID_LAM, 2, 7, 3, 0.6)
    assert rel(wa.j, wb.j) < 1e-12 and rel(wa.j_consecutive, wb.j_consecutive) < 1e-12
    ba = fa.beta_bar(SYS, IID_GE, RATIO, z0=d.z0, mu=d.mu)
    bb = fa.beta_bar(SYS, IID_LAM, RATIO, z0=d.z0, mu=d.mu)
    assert ba.finite == bb.finite
    assert abs(ba.limit - bb.limit) < 1e-12
    for x, y in [(ba.j_offline, bb.j_offline), (ba.j_online, bb.j_online), (ba.j_max, bb.j_max)]:
        assert rel(x, y) < 1e-12
    ca = fa.choose_schedule(SYS, IID_GE, RATIO, 0.25, z0=2, mu=0.6)
    cb = fa.choose_schedule(SYS, IID_LAM, RATIO, 0.25, z0=2, mu=0.6)
    assert ca.schedule == cb.schedule and abs(ca.beta_bar - cb.beta_bar) < 1e-12


def test_the_paper_channel_keeps_its_values_bit_for_bit() -> None:
    for ch in (0.5, fa.BernoulliChannel(0.5)):
        assert fa.beta_bar(SYS, ch, RATIO) == fa.beta_bar(SYS, lam=0.5, ratio=RATIO)
        a = fa.beta_sweep(SYS, ch, RATIO, t_max=20)
        b = fa.beta_sweep(SYS, lam=0.5, ratio=RATIO, t_max=20)
        np.testing.assert_array_equal(a.j_attack, b.j_attack)
        assert fa.j_attack_limit(SYS, ch, 2, 0.2) == fa.j_attack_limit(SYS, lam=0.5, z0=2, beta=0.2)
        assert fa.choose_schedule(SYS, ch, RATIO, 0.1) == fa.choose_schedule(
            SYS, lam=0.5, ratio=RATIO, beta=0.1
        )


def test_limit_threshold_is_the_root_and_the_decision_follows_it() -> None:
    bar = fa.beta_bar(SYS, GE, RATIO)
    d = fa.design_online(GE, RATIO)
    assert 0 < bar.limit < 1
    j_at = fa.j_attack_limit(SYS, GE, d.z0, bar.limit, d.mu)
    assert rel(j_at, bar.j_offline) < 1e-9
    assert rel(bar.j_offline, fa.j_offline(SYS, GE, RATIO)) < 1e-15
    below = fa.choose_schedule(SYS, GE, RATIO, bar.limit * 0.99)
    above = fa.choose_schedule(SYS, GE, RATIO, min(1.0, bar.limit * 1.01))
    assert (below.schedule, above.schedule) == ("online", "offline")
    # The finite threshold: the smallest swept r/t whose J reaches J_off, checked by the engine.
    assert bar.finite is not None
    r, t = bar.finite.numerator, bar.finite.denominator
    assert fa.Scenario(SYS, GE, d, fa.PeriodicBlocking(r, t)).cost() >= bar.j_offline
    sw = fa.beta_sweep(SYS, GE, RATIO, t_max=bar.t_max)
    i = int(np.flatnonzero((sw.r == r) & (sw.t == t))[0])
    assert np.all(sw.j_attack[:i] < bar.j_offline)


def test_large_period_limit_is_approached_by_long_periods() -> None:
    """J(k, 5k) tends to J_inf(1/5) as the period grows (the switches between the two regimes
    cost O(1) per period, so the gap shrinks like 1/k)."""
    d = fa.OnlineDesign(2)
    lim = fa.j_attack_limit(SYS, GE, 2, Fraction(1, 5))
    gaps = [abs(fa.j_attack_pattern(SYS, GE, 2, [1] * k + [0] * (4 * k)) - lim) for k in (10, 40, 160)]
    assert gaps[0] > gaps[1] > gaps[2]
    assert gaps[2] < 0.3 * gaps[1] and gaps[2] / lim < 2e-3
    # The two regimes it mixes, by the engine.
    on = fa.Scenario(SYS, GE, d)
    blk = fa.Scenario(SYS, GE, d, fa.RandomBlocking(1.0))
    f_on, f_blk = on.flag_rates().sent, blk.flag_rates().sent
    want = (0.2 * blk.cost() / f_blk + 0.8 * on.cost() / f_on) / (0.2 / f_blk + 0.8 / f_on)
    assert rel(lim, want) < 1e-13


def test_unstable_blocked_regime() -> None:
    """On GilbertElliott(0.1, 0.1, 1, 0) the always-low sensor is unstable ((1 - q) 1.44 > 1): any
    positive budget in the large-period limit is infinite and the limit threshold is 0."""
    assert math.isinf(fa.j_attack_limit(SYS, BURSTY, 2, 0.01))
    assert fa.beta_bar(SYS, BURSTY, RATIO).limit == 0.0
    sw = fa.beta_sweep(SYS, BURSTY, RATIO, t_max=40)
    assert np.all(np.isfinite(sw.j_attack)) and not np.any(np.isnan(sw.j_attack))


def test_lossy_high_power_goes_through_the_engine_within_bounds() -> None:
    ch = fa.GilbertElliott(0.1, 0.4, 0.7, 0.2, high_good=0.95, high_bad=0.9)
    d = fa.OnlineDesign(2)
    sw = fa.beta_sweep(SYS, ch, RATIO, t_max=6, z0=2, mu=1.0)
    i = int(np.flatnonzero((sw.r == 1) & (sw.t == 5))[0])
    assert sw.j_attack[i] == fa.Scenario(SYS, ch, d, fa.PeriodicBlocking(1, 5)).cost()
    with pytest.raises(ValueError, match="t_max"):
        fa.beta_sweep(SYS, ch, RATIO, t_max=201, z0=2)
    with pytest.raises(ValueError, match="^t: "):
        fa.worst_mask(SYS, ch, 2, 13, 2)


def test_bad_arguments_name_themselves() -> None:
    with pytest.raises(TypeError, match="not both"):
        fa.beta_bar(SYS, GE, RATIO, lam=0.5)
    with pytest.raises(TypeError, match="ratio"):
        fa.beta_bar(SYS, GE)
    with pytest.raises(TypeError, match="missing the channel"):
        fa.choose_schedule(SYS, ratio=RATIO, beta=0.1)
    with pytest.raises(TypeError, match="beta"):
        fa.choose_schedule(SYS, GE, RATIO)
    with pytest.raises(TypeError, match="z0"):
        fa.worst_mask(SYS, GE, t=5, blocked=1)
    with pytest.raises(ValueError, match="lam"):
        fa.beta_bar(SYS, lam=1.5, ratio=RATIO)
