"""Detecting the attacker from delivered flag-ACKs."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa


@pytest.mark.parametrize("lam,z0,mu", [(0.5, 2, 1.0), (0.3, 3, 0.4), (0.8, 1, 0.0)])
def test_interval_mean_is_inverse_rate(lam, z0, mu):
    m, v = fa.flag_interval_moments(lam, z0, mu)
    assert_allclose(m, 1 / fa.online_high_power_rate(lam, z0, mu), rtol=1e-12)
    assert v > 0


def test_interval_moments_by_series():
    # Independent: distribution of the interval by propagating the zero count until absorption.
    lam, z0, mu = 0.4, 2, 0.7
    a = 1 - lam
    law = np.zeros(z0 + 2)
    law[0] = 1.0  # after the high-power step: memory restarted
    pmf = [0.0]  # P[X = 1] = 0: the high-power step itself never flags
    for _ in range(4000):
        new = np.zeros_like(law)
        stop = 0.0
        for z, p in enumerate(law):
            new[0] += lam * p
            zz = z + 1
            f = mu if zz == z0 else (1.0 if zz == z0 + 1 else 0.0)
            if zz <= z0 + 1:
                stop += a * p * f
                if zz < z0 + 2:
                    new[zz] += a * p * (1 - f)
        pmf.append(stop)
        law = new
    pmf = np.array(pmf)
    k = np.arange(1, len(pmf) + 1)
    mean, second = (pmf * k).sum(), (pmf * k * k).sum()
    m, v = fa.flag_interval_moments(lam, z0, mu)
    assert_allclose([m, v], [mean, second - mean**2], rtol=1e-10)


def test_delivered_rate_against_chain_and_simulation(paper):
    for attack in [(1, 5), (2, 3), fa.MaskBlocking([1, 0, 1, 1, 0])]:
        rate = fa.delivered_flag_rate(0.5, 2, attack)
        mask = list(attack.mask) if isinstance(attack, fa.MaskBlocking) else [1] * attack[0] + [0] * (attack[1] - attack[0])
        # Independent: the general chain's stationary law, probability of an unblocked flag.
        states, T = fa.general_attack_chain(0.5, 2, mask)
        pi = fa.stationary_gth(T)
        z, sigma = states[:, 1], states[:, 2]
        open_flag = np.array([not mask[s] for s in sigma])
        assert_allclose(rate, pi[(z == 2) & open_flag].sum(), rtol=1e-12)
        res = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 4000, 1000, seed=3, attack=attack)
        assert res.flags_sent - res.flags_blocked == pytest.approx(rate, rel=0.01)
    assert fa.delivered_flag_rate(0.5, 2) == pytest.approx(1 / 7)


def test_detect_attack_on_expected_counts():
    n = 10_000
    clean = fa.detect_attack(round(n / 7), n, 0.5, 2)
    assert not clean.attack_detected and abs(clean.z_score) < 0.1 and clean.beta_hat < 0.01
    rate = fa.delivered_flag_rate(0.5, 2, (1, 2))
    hit = fa.detect_attack(round(n * rate), n, 0.5, 2)
    assert hit.attack_detected and hit.p_value < 1e-6
    # Large-period patterns are estimated without bias.
    rate = fa.delivered_flag_rate(0.5, 2, (300, 1000))
    assert fa.estimate_beta(round(10**7 * rate), 10**7, 0.5, 2) == pytest.approx(0.3, abs=0.01)


def test_detection_rates_by_simulation():
    r = fa.detection_rates(0.5, 2, (1, 5), n_steps=2000, runs=2000, alpha=0.05, seed=11)
    # False alarms near alpha (normal approximation of a renewal count).
    assert abs(r.false_alarm - 0.05) < 0.02
    assert r.detection > 0.5
    strong = fa.detection_rates(0.5, 2, (2, 3), n_steps=2000, runs=500, alpha=0.01, seed=12)
    assert strong.detection > 0.99 and strong.false_alarm < 0.03
    assert 0.3 < strong.beta_hat_mean < 0.8


def test_detection_bad_input():
    with pytest.raises(ValueError, match="delivered"):
        fa.detect_attack(11, 10, 0.5, 2)
    with pytest.raises(ValueError, match="alpha"):
        fa.detect_attack(1, 10, 0.5, 2, alpha=1.0)
    with pytest.raises(ValueError, match="attack"):
        fa.detection_rates(0.5, 2, None)
    with pytest.raises(TypeError, match="delivered"):
        fa.detect_attack(1.5, 10, 0.5, 2)
