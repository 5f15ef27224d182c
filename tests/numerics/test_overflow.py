"""Costs at the edges of the double range: ``inf`` (IEEE overflow) or an exact finite value, never
NaN, and never an undocumented exception.

Every case below is a corner found by auditing the public functions (long periods, long blocked
runs, tiny λ, ρ(A) at the stability bound, huge noise, long memories). Where a test asserts
``inf``, a lower bound computed here in logarithms shows that the exact value lies beyond the
double range (about e^709.78); where it asserts a finite value, an independent computation
(plain numpy, `tests/reference.py`) gives it. The property test at the end pins each corner as an
``@example`` so that the derandomized CI run always visits it.
"""

import math
import warnings
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

import fakeack as fa
import reference as ref
from conftest import FUZZ

LOG_DOUBLE_MAX = math.log(np.finfo(float).max)  # 709.78


@pytest.fixture(scope="module")
def big_a():
    """A = 30: (1 - λ) ρ(A)² = 450 at λ = 1/2, so a^τ Tr h^τ(P̄) passes 1e308 near τ = 117."""
    return fa.LinearSystem(30.0, 1.0, 1.0, 1.0)


def log_trace_lower_bound(A, pbar, tau):
    """log Tr h^τ(P̄) >= log(A^(2τ) P̄) for a scalar system (h adds Q >= 0 at every step)."""
    return 2 * tau * math.log(abs(A)) + math.log(pbar)


# ---------------------------------------------------------------- j_offline (a silent NaN, fixed)


def test_j_offline_long_period_is_inf_not_nan(paper):
    """The case that was NaN: with p/q = 1/16384 there is no long block (m = 0), and
    0 * (cost of the absent block) was 0 * inf. J is finite but beyond the double range:
    J >= a^τ Tr h^τ(P̄) / q at τ = q - 1 (one term of the only block)."""
    lam, q = 0.25, 16384
    log_bound = (
        math.log(1 - lam) * (q - 1) + log_trace_lower_bound(1.2, paper.pbar[0, 0], q - 1) - math.log(q)
    )
    assert log_bound > LOG_DOUBLE_MAX + 500  # e^1250: far beyond a double
    assert fa.j_offline(paper, lam, Fraction(1, q)) == math.inf


def test_j_offline_just_below_the_overflow_is_exact(paper):
    """q = 1024 (J ~ 2.3e33) against the period average of E Tr P_k by propagating the τ law."""
    lam, q = 0.25, 1024
    tr = ref.traces(1.2, 0.8, paper.pbar, q)
    pattern = [1] + [0] * (q - 1)
    expect = ref.offline_direct(tr, lam, pattern, periods=2)
    assert 1e33 < expect < 1e34
    assert_allclose(fa.j_offline(paper, lam, Fraction(1, q)), expect, rtol=1e-10)


def test_j_offline_with_both_block_kinds_overflowing(big_a):
    """2/2049 has m = 1 long and n = 1 short block; both overflow (formerly NaN: 1 * inf + ...
    was fine but 0 * inf appears for 1/1024, checked too)."""
    for ratio in (Fraction(2, 2049), Fraction(1, 1024)):
        assert fa.j_offline(big_a, 0.5, ratio) == math.inf


# ---------------------------------------------------------------- attacked costs


def test_long_blocked_runs_are_inf_not_nan(paper):
    """Blocking 9999 of 10000 flags at λ = 1/4 (a ρ² = 1.08), formerly NaN for μ = 1 and μ < 1
    (inf - inf of the segments' prefix sums). Lower bound: level r of the chain is entered only
    by r blocked flags in a row and holds the holding time τ = r z0 + 1 with weight a^τ relative
    to a fresh start (README, the structured stationary law), while the normaliser is at most
    t/λ (each level's mass is at most Σ a^τ = 1/λ)."""
    lam, z0, r, t = 0.25, 2, 9999, 10_000
    tau = r * z0 + 1
    log_bound = (
        tau * math.log(1 - lam) + log_trace_lower_bound(1.2, paper.pbar[0, 0], tau) - math.log(t / lam)
    )
    assert log_bound > LOG_DOUBLE_MAX + 500
    assert fa.j_attack(paper, lam, z0, r, t) == math.inf
    # Mixed memory: the same walk, τ at least r z0 + 1 after r blocked flags (r = 2999 keeps
    # the O(r^2) cost small; λ = 0.2 makes a ρ² = 1.152).
    lam, r, t = 0.2, 2999, 3000
    tau = r * z0 + 1
    log_bound = (
        tau * math.log(1 - lam) + log_trace_lower_bound(1.2, paper.pbar[0, 0], tau) - math.log(t / lam)
    )
    assert log_bound > LOG_DOUBLE_MAX
    assert fa.j_attack(paper, lam, z0, r, t, mu=0.4) == math.inf
    # tiny λ: every step without arrival, so the walk climbs to τ = 3000 > 1950, where
    # Tr h^τ(P̄) alone passes the double range (formerly NaN).
    assert fa.j_attack(paper, 1e-6, 2, 999, 1000) == math.inf


def test_finite_attack_against_the_independent_chain_near_overflow(big_a):
    """z0 = 60 at λ = 1/2 with A = 30: the weighted traces overflow past τ ≈ 117; blocking 2 of 3
    flags reaches τ = 180, blocking 1 of 3 τ = 120, both by losses alone from the fresh state
    (0, 0, 0) of the independent chain (tests/reference.py). So J >= π(0,0,0) a^τ Tr h^τ(P̄) at
    that τ, beyond the double range; without attack (τ <= 60) J is finite and matches the chain."""
    lam, z0 = 0.5, 60
    for mask, beyond in (([1, 1, 0], True), ([1, 0, 0], True), ([0], False)):
        states, T = ref.explore_mask_chain(lam, z0, mask)
        pi = ref.stationary_dense(T)
        taus = np.array([s[0] for s in states])
        got = fa.j_attack_pattern(big_a, lam, z0, mask) if any(mask) else fa.j_online(big_a, lam, z0)
        if beyond:
            tau = int(taus.max())
            assert states[0] == (0, 0, 0) and pi[0] > 0.05
            log_bound = (
                math.log(pi[0]) + tau * math.log(1 - lam) + log_trace_lower_bound(30.0, big_a.pbar[0, 0], tau)
            )
            assert log_bound > LOG_DOUBLE_MAX
            assert got == math.inf
        else:
            tr = ref.traces(30.0, 1.0, big_a.pbar, int(taus.max()))
            assert_allclose(got, pi @ tr[taus], rtol=1e-9)


def test_limit_sweep_threshold_and_decision_never_nan(big_a):
    """J_on beyond the double range (z0 = 1000) gave J_inf(0) = NaN; a sweep with segments
    past the overflow had NaN entries; J_offline = NaN leaked into beta_bar and choose_schedule."""
    assert fa.j_online(big_a, 0.5, 1000) == math.inf
    assert fa.j_attack_limit(big_a, 0.5, 1000, 0.0) == math.inf
    assert fa.j_attack_limit(big_a, 0.5, 1000, 0.5) == math.inf  # J_max diverges here
    sw = fa.beta_sweep(big_a, 0.5, Fraction(1, 7), t_max=200)
    assert not np.isnan(sw.j_attack).any()
    assert np.isinf(sw.j_attack).any() and np.isfinite(sw.j_attack).any()
    finite = np.flatnonzero(np.isfinite(sw.j_attack))[::50]
    for i in finite:
        assert_allclose(
            sw.j_attack[i], fa.j_attack(big_a, 0.5, sw.z0, int(sw.r[i]), int(sw.t[i]), mu=sw.mu), rtol=1e-12
        )
    bar = fa.beta_bar(big_a, 0.25, Fraction(1, 1000), t_max=200)
    assert bar.j_offline == math.inf and bar.j_max == math.inf and not math.isnan(bar.limit)
    d = fa.choose_schedule(big_a, 0.25, Fraction(1, 1000), 0.3)
    assert d.j_offline == math.inf and not math.isnan(d.beta_bar)
    assert d.schedule == "offline"  # J_inf(0.3) diverges (J_max = inf), J_off is only huge


def test_stability_bound_and_extreme_lambda_stay_finite(paper):
    """ρ(A) a hair inside the bound a ρ² < 1 (J_max finite but large), tiny and near-one λ."""
    lam = 0.25
    A = (1 - 1e-6) / math.sqrt(1 - lam)
    s = fa.LinearSystem(A, 0.7, 0.8, 0.8)
    jmax = fa.j_max(s, lam)
    assert math.isfinite(jmax) and jmax > 1e5
    for lam_, z0, r, t in [(lam, 2, 59, 60), (1e-12, 1, 1, 2), (1 - 1e-9, 2, 1, 5)]:
        j = fa.j_attack(s, lam_, z0, r, t)
        assert math.isfinite(j) and j > 0


# ---------------------------------------------------------------- exact curves


def test_offline_curve_with_unreached_infinite_traces(paper):
    """The offline curve multiplied unreached holding times (probability 0) by traces beyond the
    double range: every entry was NaN for a period of 4096 at λ = 1/2. The reference propagates
    the τ law in numpy and skips zero probabilities."""
    lam, q, horizon = 0.5, 4096, 3000
    c = fa.expected_trace_curve(paper, lam, fa.OfflineSchedule(Fraction(1, q)), horizon)
    assert np.isfinite(c.trace).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the plain traces overflow near τ = 1950
        tr = ref.traces(1.2, 0.8, paper.pbar, horizon)
    law = np.zeros(horizon + 1)
    law[0] = 1.0
    expect = [tr[0]]
    for _ in range(horizon - 1):
        law = np.concatenate(([lam * law.sum()], (1 - lam) * law[:-1]))
        reached = law > 0
        expect.append(law[reached] @ tr[reached])
    assert_allclose(c.trace, expect, rtol=1e-9)


# ---------------------------------------------------------------- detection


def test_detection_with_astronomical_flag_intervals():
    """z0 = 1000 at λ = 1/2: the mean interval is 2^1001-ish and its variance beyond the double
    range (formerly OverflowError from mean**2 in flag_interval_moments and m**3 in
    detect_attack); z0 = 500 fits (m ~ 6.5e150) but m**3 did not."""
    m, v = fa.flag_interval_moments(0.5, 1000)
    assert_allclose(m, 1 / fa.online_high_power_rate(0.5, 1000), rtol=1e-9)
    assert v == math.inf
    with pytest.raises(ValueError, match="z0"):
        fa.detect_attack(0, 10**6, 0.5, 1000)
    # z0 = 500: about 1.5e-145 flags expected in 10^6 steps. The count test's exact law (below 100
    # expected flags) would take 6.5e9 operations: refused, naming the window. A short window
    # expecting less than a flag keeps its exact p-value, but has no budget estimate.
    with pytest.raises(ValueError, match="n_steps = 1000000: the exact count law needs"):
        fa.detect_attack(0, 10**6, 0.5, 500)
    d = fa.detect_attack(1, 1000, 0.5, 50, alternative="greater")
    assert d.attack_detected and 0 < d.p_value < 1e-9 and math.isnan(d.beta_hat)
    with pytest.raises(ValueError, match="z0"):
        fa.estimate_beta(3, 10**6, 0.5, 1100)  # the attack-free flag rate 2^-1100 underflows to 0


def test_estimate_beta_when_the_two_regimes_have_equal_rates():
    """λ = 1 - 1e-9, z0 = 1, μ = 0: f_on = λa²/(1 - a³) and f_blk = λa²/(1 - a²) agree to the
    last bit (a = 1e-9), and 1 + ρ/f_blk - ρ/f_on was 0 once ρ/f passed 2^53 (ZeroDivisionError).
    With equal rates ρ(β) = (1 - β) f, so β̂ = 1 - ρ/f, clipped to [0, 1]."""
    lam = 1 - 1e-9
    f_on = fa.flag_rates(lam, 1, None, 0.0)[0]
    f_blk = fa.flag_rates(lam, 1, fa.MaskBlocking([1]), 0.0)[0]
    assert f_on == f_blk
    n = 4 * 10**18  # f n = 4 flags expected
    for delivered in (0, 1, 3):
        assert fa.estimate_beta(delivered, n, lam, 1, 0.0) == pytest.approx(
            1 - delivered / n / f_on, rel=1e-12
        )
    # ρ/f = 1e16 (formerly 1/0) needs a window expecting 1e-15 flags: refused as uninformative.
    with pytest.raises(ValueError, match="n_steps = 1000: fewer than one flag-ACK"):
        fa.estimate_beta(10, 1000, lam, 1, 0.0)


def test_a_deterministic_flag_count_is_one_sided(monkeypatch):
    """λ = 1e-20: every interval is z0 + 1 steps, so the variance is 0, and more flags than
    expected was flagged as an attack (z = -inf); an attacker can only remove flags. (At that λ
    the all-blocked flag rate that beta_hat needs is refused by the core, a documented
    ValueError, so the zero-variance branch runs with those moments substituted at λ = 1/2.)"""
    from fakeack.detection import count as detection

    assert fa.flag_interval_moments(1e-20, 4) == (5.0, 0.0)
    monkeypatch.setattr(detection, "flag_interval_moments", lambda lam, z0, mu: (5.0, 0.0))
    more = fa.detect_attack(201, 1000, 0.5, 4)
    assert not more.attack_detected and more.z_score == math.inf and more.p_value == 1.0
    fewer = fa.detect_attack(199, 1000, 0.5, 4)
    assert fewer.attack_detected and fewer.z_score == -math.inf
    assert not fa.detect_attack(200, 1000, 0.5, 4).attack_detected


# ---------------------------------------------------------------- property with every corner pinned

A_VALUES = st.sampled_from([0.5, 0.99, 1.2, 3.0, 30.0])


@settings(max_examples=60 * FUZZ, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example(A=1.2, lam=0.25, p=1, q=16384, z0=2, t=10_000, r=9999, mu=1.0)  # j_offline's former NaN
@example(A=1.2, lam=0.05, p=1, q=1024, z0=2, t=1000, r=999, mu=0.4)  # mixed memory past the overflow
@example(A=1.2, lam=1e-6, p=1, q=2, z0=2, t=1000, r=999, mu=1.0)  # tiny λ
@example(A=30.0, lam=0.5, p=1, q=1024, z0=1000, t=3, r=2, mu=1.0)  # J_on beyond range: J_inf(0) was NaN
@example(A=30.0, lam=0.5, p=1, q=2049, z0=60, t=3, r=1, mu=0.5)
@example(A=0.99, lam=1 - 1e-9, p=1, q=3, z0=1, t=2, r=1, mu=0.0)
@given(
    A=A_VALUES,
    lam=st.floats(1e-12, 1 - 1e-9),
    p=st.integers(1, 3),
    q=st.integers(2, 2**14),
    z0=st.integers(1, 60),
    t=st.integers(2, 3000),
    r=st.integers(0, 2999),
    mu=st.floats(0.0, 1.0),
)
def test_costs_are_never_nan(A, lam, p, q, z0, t, r, mu):
    """Every cost is a number >= 0 or +inf, whatever the corner; J_on <= J_attack <= J_max."""
    s = _system(A)
    r = r % t
    if mu < 1 and r > 1000:
        r = 1000  # keep the O(r^2) mixed-memory case fast
    j_off = fa.j_offline(s, lam, Fraction(p, q) if p < q else Fraction(1, q))
    j_on = fa.j_online(s, lam, z0, mu)
    j_att = fa.j_attack(s, lam, z0, r, t, mu=mu)
    j_lim = fa.j_attack_limit(s, lam, z0, r / t, mu)
    j_max = fa.j_max(s, lam)
    for j in (j_off, j_on, j_att, j_lim, j_max):
        assert not math.isnan(j) and j >= 0
    assert j_on <= j_att * (1 + 1e-9) and j_att <= j_max * (1 + 1e-9)


_SYSTEMS = {}


def _system(A):
    if A not in _SYSTEMS:
        _SYSTEMS[A] = fa.LinearSystem(A, 1.0, 1.0, 1.0)
    return _SYSTEMS[A]
