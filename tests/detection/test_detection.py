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
    return 1 + (1 - a**k) / (lam * a**k), (1 - (2 * k + 1) * lam * a**k - a ** (2 * k + 1)) / (
        lam * a**k
    ) ** 2


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
        mask = (
            list(attack.mask)
            if isinstance(attack, fa.MaskBlocking)
            else [1] * attack[0] + [0] * (attack[1] - attack[0])
        )
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


def test_detect_attack_reports_its_inputs_and_uses_mu():
    """The outcome echoes the observation (delivered flag-ACKs, window, level, alternative), and
    the budget estimate uses the memory probability μ: at μ = 0.4 a delivered rate from the
    regime mix with β = 0.3 (rates from the reference chain and u = a^z0 (μ + (1-μ) a)) is
    estimated as 0.3.

    Kills: the outcome's delivered, n_steps, alpha or alternative replaced or dropped; μ dropped
    from the estimate of β (it would use the μ = 1 rates)."""
    det = fa.detect_attack(1350, 10_000, 0.5, 2, alpha=0.05, alternative="greater")
    assert (det.delivered, det.n_steps, det.alpha, det.alternative) == (1350, 10_000, 0.05, "greater")
    lam, z0, mu, beta = 0.3, 3, 0.4, 0.3
    a = 1 - lam
    u = a**z0 * (mu + (1 - mu) * a)
    f_blk = lam * u / (1 - u)
    T, flag = ref.online_chain(lam, z0, mu)
    f_on = ref.stationary_dense(T) @ flag
    n = 10**12
    rho = (1 - beta) / (beta / f_blk + (1 - beta) / f_on)
    assert fa.detect_attack(round(n * rho), n, lam, z0, mu).beta_hat == pytest.approx(beta, abs=1e-9)


def test_detect_attack_level_is_strict():
    """The hypothesis "no attacker" is rejected when Φ(z) < α, strictly: at α equal to the p-value the count is
    not an alarm, just above it it is.

    Kills: p <= alpha."""
    p = fa.detect_attack(1380, 10_000, 0.5, 2).p_value
    assert p == pytest.approx(norm.cdf((1380 - 10_000 / 7) / math.sqrt(10_000 * 22 / 7**3)), rel=1e-9)
    assert not fa.detect_attack(1380, 10_000, 0.5, 2, alpha=p).attack_detected
    assert fa.detect_attack(1380, 10_000, 0.5, 2, alpha=p * (1 + 1e-12)).attack_detected


def test_detect_attack_window_limits():
    """A window in which at least one flag-ACK is expected without attack is valid (no flag in it
    estimates β = 1); a shorter one says nothing about β: estimate_beta refuses it, naming
    n_steps, and detect_attack reports β̂ as NaN; an empty or negative window or a negative count
    is refused as such.

    Kills: the window's minimum 1 removed (a negative window would fail on a square root), or
    raised to 2, in detect_attack and estimate_beta; the count's minimum 0 removed in
    estimate_beta (β̂ would be clipped to 1); the expected-count floor dropped or off by one."""
    assert fa.detect_attack(0, 7, 0.5, 2).expected == pytest.approx(1.0, rel=1e-14)  # rate 1/7
    # 6/7 of a flag expected: the test still runs (a count can show forging), but β has no estimate.
    assert math.isnan(fa.detect_attack(0, 6, 0.5, 2).beta_hat)
    with pytest.raises(ValueError, match="n_steps = 1: fewer than one flag-ACK"):
        fa.estimate_beta(0, 1, 0.5, 2)
    for n in (0, -5):
        with pytest.raises(ValueError, match="n_steps must be at least 1"):
            fa.detect_attack(0, n, 0.5, 2)
    with pytest.raises(ValueError, match="n_steps must be at least 1"):
        fa.estimate_beta(0, 0, 0.5, 2)
    with pytest.raises(ValueError, match="delivered must be at least 0"):
        fa.estimate_beta(-1, 10, 0.5, 2)
    # No flag-ACK at all: every flag blocked, β̂ = 1 exactly, from the shortest valid window on.
    for lam, z0, mu in [(0.5, 2, 1.0), (0.3, 3, 0.4), (0.8, 1, 0.0), (0.45, 5, 0.7), (0.1, 2, 0.25)]:
        m, _ = fa.flag_interval_moments(lam, z0, mu)  # the attack-free rate is 1/m
        n = math.ceil(m - 1e-9)  # m = 31 exactly at (0.8, 1, 0), up to rounding
        assert fa.estimate_beta(0, n, lam, z0, mu) == 1.0
        if n > 1:
            with pytest.raises(ValueError, match="fewer than one flag-ACK"):
                fa.estimate_beta(0, n - 1, lam, z0, mu)


def test_delivered_rate_uses_mu():
    """Without attack the delivered rate is 1/m, m the mean interval between flag-ACKs; μ = 0 is
    the fixed memory z0 + 1 (run formula, k = 4 losses in a row at λ = 0.45).

    Kills: μ dropped from delivered_flag_rate."""
    m, _ = run_moments(0.45, 4)
    assert fa.delivered_flag_rate(0.45, 3, None, 0.0) == pytest.approx(1 / m, rel=1e-12)


def test_detection_rates_reports_its_inputs_and_defaults():
    """The record echoes the simulation's size, level and burn-in; the documented defaults are
    1000-step windows, 2000 runs and seed 1.

    Kills: runs, n_steps, alpha or burn_in replaced or dropped in the record; the defaults of
    n_steps, runs and seed changed."""
    r = fa.detection_rates(0.5, 2, (1, 5), n_steps=50, runs=7, alpha=0.2, seed=4, burn_in=3)
    assert (r.runs, r.n_steps, r.alpha, r.burn_in) == (7, 50, 0.2, 3)
    assert fa.detection_rates(0.5, 2, (1, 5), runs=2).n_steps == 1000
    assert fa.detection_rates(0.5, 2, (1, 5), n_steps=20).runs == 2000
    assert fa.detection_rates(0.5, 2, (1, 5), n_steps=60, runs=300) == fa.detection_rates(
        0.5, 2, (1, 5), n_steps=60, runs=300, seed=1
    )


def test_detection_rates_attacked_windows_use_the_next_seed():
    """The attacked windows are simulated from seed + 1: under an attack that blocks nothing they
    are the attack-free windows of seed + 1 (and not those of seed - 1 or seed + 2, which
    differ here).

    Kills: seed - 1 or seed + 2 for the attacked windows."""
    kw = dict(n_steps=200, runs=300, alpha=0.2)
    nothing = fa.MaskBlocking([0])
    rates = {s: fa.detection_rates(0.5, 2, nothing, seed=s, **kw).false_alarm for s in (4, 6, 7)}
    assert len(set(rates.values())) == 3
    assert fa.detection_rates(0.5, 2, nothing, seed=5, **kw).detection == rates[6]


def test_detection_rates_standard_errors_and_spread():
    """The reported standard errors are the binomial sqrt(p (1 - p) / runs) of each rate; the
    spread of the estimates is the sample standard deviation, defined from two windows on.

    Kills: p (1 + p), p (2 - p), max(p (1 - p), 1) or multiplying by runs in the standard error;
    ddof = 2 in the spread (infinite or NaN with two windows)."""
    runs = 400
    r = fa.detection_rates(0.5, 2, (1, 5), n_steps=300, runs=runs, alpha=0.05, seed=2)
    assert 0 < r.false_alarm < 1 and 0 < r.detection < 1
    for p, se in ((r.false_alarm, r.false_alarm_stderr), (r.detection, r.detection_stderr)):
        assert se == pytest.approx(math.sqrt(p * (1 - p) / runs), rel=1e-12)
    two = fa.detection_rates(0.5, 2, (1, 5), n_steps=300, runs=2, seed=2)
    assert math.isfinite(two.beta_hat_std) and two.beta_hat_std >= 0


def test_detection_rates_estimates_use_mu():
    """At μ = 0.4 the mean estimate of β under the 1/5 pattern is near the inversion at the exact
    delivered rate with the μ = 0.4 regime rates (0.2 here); with the μ = 1 rates it would be 0.49.

    Kills: μ dropped from the per-window estimates."""
    lam, z0, mu = 0.5, 2, 0.4
    a = 1 - lam
    u = a**z0 * (mu + (1 - mu) * a)
    f_blk = lam * u / (1 - u)
    T, flag = ref.online_chain(lam, z0, mu)
    f_on = ref.stationary_dense(T) @ flag
    rate = fa.delivered_flag_rate(lam, z0, (1, 5), mu)
    b = (1 - rate / f_on) / (1 + rate / f_blk - rate / f_on)
    r = fa.detection_rates(lam, z0, (1, 5), n_steps=1000, runs=400, mu=mu, seed=3)
    assert abs(r.beta_hat_mean - b) < 0.02 and abs(b - 0.2) < 0.01


def test_detection_rates_argument_limits():
    """Windows of one step and two runs are the smallest valid sizes, seed 0 is valid; empty
    windows, a single run, a negative burn-in, and runs above 2^24 or seeds outside [0, 2^63]
    are refused, each before the next argument is read (here an invalid test name or level).

    Kills: the minimum of n_steps, runs, seed or burn_in removed or moved (n_steps >= 2,
    runs >= 3, seed >= 1); the maximum of runs or seed raised (2 << 24, 1 << 25, 3^63, 2^64) or
    left at the package-wide 2^62."""
    small = fa.detection_rates(0.5, 2, (1, 5), n_steps=1, runs=2, seed=0)
    assert (small.n_steps, small.runs) == (1, 2)
    assert fa.detection_rates(0.5, 2, (1, 5), n_steps=20, runs=5, seed=2**63).runs == 5
    bad = [
        (dict(n_steps=0), "n_steps must be at least 1"),
        (dict(n_steps=0, test="interval"), "n_steps must be at least 1"),
        (dict(runs=1), "runs must be at least 2"),
        (dict(burn_in=-1), "burn_in must be at least 0"),
        (dict(runs=(1 << 24) + 1, alpha=2.0), "runs must be at most"),
        (dict(seed=-1, test="none"), "seed must be at least 0"),
        (dict(seed=2**63 + 1, test="none"), "seed must be at most"),
    ]
    for kw, msg in bad:
        with pytest.raises(ValueError, match=msg):
            fa.detection_rates(0.5, 2, (1, 5), **kw)


def test_interval_test_rates_are_two_sided():
    """The interval test is two-sided: it is the default for it, and a one-sided alternative is
    refused.

    Kills: the default alternative "less" for every test (or a misspelt "two-sided"); the check
    of the interval test's alternative skipped."""
    r = fa.detection_rates(0.5, 2, (1, 5), n_steps=700, runs=20, test="interval")
    assert (r.test, r.alternative) == ("interval", "two-sided")
    with pytest.raises(ValueError, match="alternative: the interval test is two-sided"):
        fa.detection_rates(0.5, 2, (1, 5), n_steps=700, runs=20, test="interval", alternative="less")


def test_interval_moments_beyond_the_double_range():
    """With λ = 1/2 and z0 = 600 (μ = 1) the mean interval, 1 + (1 - a^600)/(λ a^600) ≈ 2^601 by
    the run formula, is a double but its square is not: the mean is exact and the variance inf;
    at z0 = 1100 (μ = 1 and μ = 1/2) both are inf. None of these warns: inf is the documented
    answer.

    Kills: the overflow or the invalid-operation warnings left on (inf - inf and 0 · inf arise
    at μ = 1/2)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m, v = fa.flag_interval_moments(0.5, 600)
        assert m == pytest.approx(1 + (1 - 0.5**600) / (0.5 * 0.5**600), rel=1e-9) and v == math.inf
        assert fa.flag_interval_moments(0.5, 1100) == (math.inf, math.inf)
        assert fa.flag_interval_moments(0.5, 1100, 0.5) == (math.inf, math.inf)
