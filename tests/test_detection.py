"""Detecting the attacker from delivered flag-ACKs, against closed forms and independent chains.

Each test names in its docstring the wrong code it catches ("Kills: ..."); each was checked by
making that change and seeing the test fail.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import norm

import fakeack as fa
import reference as ref


def moments_by_series(lam, z0, mu):
    """Mean and variance of the steps between flags: the interval's distribution, by
    propagating the memory's zero count until it flags (independent of the package's N matrix)."""
    a = 1 - lam
    law = np.zeros(z0 + 2)
    law[0] = 1.0  # after the high-power step: memory restarted
    pmf = [0.0]  # P[X = 1] = 0: the high-power step itself never flags
    for _ in range(6000):
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
    return mean, second - mean**2


def run_moments(lam, k):
    """X = 1 + T, T the wait for k losses in a row (loss probability a = 1 - lam): Feller's run
    formulas E T = (1 - a^k)/(lam a^k), Var T = [1 - (2k+1) lam a^k - a^(2k+1)] / (lam a^k)^2."""
    a = 1 - lam
    return 1 + (1 - a**k) / (lam * a**k), (1 - (2 * k + 1) * lam * a**k - a ** (2 * k + 1)) / (lam * a**k) ** 2


@pytest.mark.parametrize("lam,z0,mu", [(0.5, 2, 1.0), (0.3, 3, 0.4), (0.8, 1, 0.0), (0.4, 2, 0.7)])
def test_interval_moments_against_the_series(lam, z0, mu):
    """Kills: any wrong variance (the former check was only v > 0), e.g. E[T^2] from
    (N - I) N 1 instead of (2N - I) N 1; a mean off the inverse online rate."""
    m, v = fa.flag_interval_moments(lam, z0, mu)
    assert_allclose([m, v], moments_by_series(lam, z0, mu), rtol=1e-10)
    assert_allclose(m, 1 / fa.online_high_power_rate(lam, z0, mu), rtol=1e-12)


def test_interval_moments_closed_form():
    """μ = 1 is a fixed memory: the paper's schedule has m = 7 and v = 22 (run formulas), and
    μ = 0 with z0 is the fixed memory z0 + 1."""
    assert run_moments(0.5, 2) == (7.0, 22.0)
    assert_allclose(fa.flag_interval_moments(0.5, 2), (7.0, 22.0), rtol=1e-12)
    for lam, z0 in [(0.3, 3), (0.8, 1), (0.45, 5)]:
        assert_allclose(fa.flag_interval_moments(lam, z0), run_moments(lam, z0), rtol=1e-11)
        assert_allclose(fa.flag_interval_moments(lam, z0, 0.0), run_moments(lam, z0 + 1), rtol=1e-11)


def test_delivered_rate_against_chain_and_simulation(paper):
    for attack in [(1, 5), (2, 3), fa.MaskBlocking([1, 0, 1, 1, 0])]:
        rate = fa.delivered_flag_rate(0.5, 2, attack)
        mask = list(attack.mask) if isinstance(attack, fa.MaskBlocking) else [1] * attack[0] + [0] * (attack[1] - attack[0])
        # Independent: the reference chain's stationary law, probability of an unblocked flag.
        states, T = ref.explore_mask_chain(0.5, 2, mask)
        pi = ref.stationary_dense(T)
        delivered = np.array([z == 2 and not mask[s] for _, z, s in states])
        assert_allclose(rate, pi[delivered].sum(), rtol=1e-12)
        res = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), 4000, 1000, seed=3, attack=attack)
        assert res.flags_sent - res.flags_blocked == pytest.approx(rate, rel=0.01)
    assert fa.delivered_flag_rate(0.5, 2) == pytest.approx(1 / 7)


def test_detect_attack_z_score_and_p_value():
    """The paper's schedule over n = 10^4 steps: N ~ Normal(n/7, n 22/7^3) without attack (m = 7,
    v = 22 from the run formulas). Counts on both sides of the threshold, not only at the mean,
    where z = 0 whatever the variance.

    Kills: the variance n v/m^2 instead of n v/m^3 (z would be sqrt(7) times smaller: 1350 flags
    would give z = -1.17 and pass unnoticed); p from the upper tail; a two-sided test; a wrong
    comparison with alpha."""
    n = 10_000
    mean, sd = n / 7, math.sqrt(n * 22 / 7**3)
    for d in (1300, 1350, 1380, 1428, 1500):
        det = fa.detect_attack(d, n, 0.5, 2)
        z = (d - mean) / sd
        assert det.z_score == pytest.approx(z, rel=1e-10)
        assert det.p_value == pytest.approx(norm.cdf(z), rel=1e-9)
        assert det.attack_detected == (norm.cdf(z) < 0.01)
        assert det.expected == pytest.approx(mean, rel=1e-14)
    assert fa.detect_attack(1350, n, 0.5, 2).attack_detected  # z = -3.10
    assert not fa.detect_attack(1380, n, 0.5, 2).attack_detected  # z = -1.92: not at 1%,
    assert fa.detect_attack(1380, n, 0.5, 2, alpha=0.05).attack_detected  # but at 5%
    assert not fa.detect_attack(1500, n, 0.5, 2, alpha=0.5).attack_detected  # more flags: never


def test_estimate_beta_inverts_the_regime_mix():
    """Large-period model: a fraction β of flags in the all-blocked regime (flag rate
    f_blk = λu/(1-u), u = a^z0 (μ + (1-μ) a)), 1 - β unattacked (f_on, Model note 2), so the
    delivered rate is ρ(β) = (1-β)/(β/f_blk + (1-β)/f_on); estimate_beta inverts it. The rates
    here come from hand formulas and the reference's memory chain.

    Kills: dropping μ from u (the regime rates), swapping f_on and f_blk, a sign error."""
    for lam, z0, mu in [(0.5, 2, 1.0), (0.3, 3, 0.4)]:
        a = 1 - lam
        u = a**z0 * (mu + (1 - mu) * a)
        f_blk = lam * u / (1 - u)
        T, flag = ref.memory_chain_all_blocked(lam, z0, mu)
        assert_allclose(ref.stationary_dense(T) @ flag, f_blk, rtol=1e-12)
        T, flag = ref.online_chain(lam, z0, mu)
        f_on = ref.stationary_dense(T) @ flag
        n = 10**12
        for beta in (0.0, 0.1, 0.3, 2 / 3, 0.9, 1.0):
            rho = (1 - beta) / (beta / f_blk + (1 - beta) / f_on)
            assert fa.estimate_beta(round(n * rho), n, lam, z0, mu) == pytest.approx(beta, abs=1e-9)


def test_estimate_beta_is_clipped():
    """More flags than an attack-free detector sends: the raw inversion is
    (1 - 1.4)/(1 + 1.2 - 1.4) = -0.5 at ρ = 1/5 (f_on = 1/7, f_blk = 1/6); the estimate is 0.

    Kills: removing the clip to [0, 1] (its upper half is an equivalent mutant: the inversion
    never exceeds 1 for ρ >= 0; tests/MUTANTS.md)."""
    assert fa.estimate_beta(2000, 10_000, 0.5, 2) == 0.0
    assert fa.detect_attack(2000, 10_000, 0.5, 2).beta_hat == 0.0
    assert fa.estimate_beta(0, 10_000, 0.5, 2) == 1.0
    # Large-period patterns are estimated without bias.
    rate = fa.delivered_flag_rate(0.5, 2, (300, 1000))
    assert fa.estimate_beta(round(10**7 * rate), 10**7, 0.5, 2) == pytest.approx(0.3, abs=0.01)


def _count_law_under_attack(lam, z0, mask, n=None):
    """(rate, variance per step[, exact mean count over n steps from the initial state]) of the
    delivered-flag count under a blocking mask (μ = 1), from the reference chain: the fundamental
    matrix for the variance, the propagated law for the mean."""
    states, T = ref.explore_mask_chain(lam, z0, mask)
    f = np.array([1.0 if z == z0 and not mask[s] else 0.0 for _, z, s in states])
    rate, var = ref.additive_variance_rate(T, f)
    if n is None:
        return rate, var
    law, mean = np.eye(len(states))[0], 0.0  # high power at k = 1, counter 0
    for _ in range(n):
        mean += law @ f
        law = law @ T
    return rate, var, mean


def test_count_variance_rate_matches_the_run_formula():
    """The reference's asymptotic variance without attack is v/m^3 = 22/343 (renewal CLT)."""
    rate, var = _count_law_under_attack(0.5, 2, [0])
    assert_allclose([rate, var], [1 / 7, 22 / 343], rtol=1e-10)


def test_detection_rates_by_simulation():
    """False alarms and detection near the renewal-CLT prediction from the reference chain (the
    attacked count ~ Normal(E N, n σ²), E N propagated exactly from the initial state, σ² from
    the fundamental matrix, with a continuity correction: the test rejects N <= floor(n/m +
    Φ^-1(α) sqrt(n v/m^3))), and mean estimates near the inversion at the attacked rate. The
    README's example: 1000-step windows at α = 0.01, detection at β = 1/5 about 86%.

    Kills: the threshold's variance with m^2 instead of m^3 (detection would fall to 0.02%);
    a false-alarm rate computed on the attacked windows; dropping the clip in the mean estimate;
    the former bounds (detection > 0.5 where the rate is 0.9995, 0.3 < mean β̂ < 0.8 around
    2/3) caught none of these."""
    lam, z0, n, alpha = 0.5, 2, 1000, 0.01
    cut = math.floor(n / 7 + norm.ppf(alpha) * math.sqrt(n * 22 / 7**3)) + 0.5
    r = fa.detection_rates(lam, z0, (1, 5), n_steps=n, runs=2000, alpha=alpha, seed=11)
    rate, var, mean = _count_law_under_attack(lam, z0, [1, 0, 0, 0, 0], n)
    predicted = norm.cdf((cut - mean) / math.sqrt(n * var))
    assert 0.8 < predicted < 0.9
    assert abs(r.detection - predicted) < 0.03, (r.detection, predicted)  # 4 binomial SE
    _, _, clean_mean = _count_law_under_attack(lam, z0, [0], n)
    false_alarm = norm.cdf((cut - clean_mean) / math.sqrt(n * 22 / 7**3))
    assert abs(r.false_alarm - false_alarm) < 0.01, (r.false_alarm, false_alarm)
    # mean estimate: the inversion at the attacked rate (large-period model), near 1/5
    f_on, f_blk = 1 / 7, 1 / 6
    b = (1 - rate / f_on) / (1 + rate / f_blk - rate / f_on)
    assert abs(r.beta_hat_mean - b) < 0.01 and abs(r.beta_hat_mean - 0.2) < 0.01
    assert r.beta_hat_std > 0 and r.beta == 0.2
    strong = fa.detection_rates(lam, z0, (2, 3), n_steps=2000, runs=500, alpha=alpha, seed=12)
    rate, _ = _count_law_under_attack(lam, z0, [1, 1, 0])
    b = (1 - rate / f_on) / (1 + rate / f_blk - rate / f_on)
    assert strong.detection == 1.0 and strong.false_alarm < 0.03
    assert abs(strong.beta_hat_mean - b) < 0.005 and abs(strong.beta_hat_mean - 2 / 3) < 0.005


def test_detection_bad_input():
    with pytest.raises(ValueError, match="delivered"):
        fa.detect_attack(11, 10, 0.5, 2)
    with pytest.raises(ValueError, match="alpha"):
        fa.detect_attack(1, 10, 0.5, 2, alpha=1.0)
    with pytest.raises(ValueError, match="attack"):
        fa.detection_rates(0.5, 2, None)
    with pytest.raises(TypeError, match="delivered"):
        fa.detect_attack(1.5, 10, 0.5, 2)
