"""The schedules' analyses under a channel: j_online, j_max, design_online, offline_schedule,
j_offline and the offline search (fakeack.model.offline).

Expected values come from

- the i.i.d. reduction: a Gilbert-Elliott channel with p + q = 1 and high_good = high_bad = 1 draws
  its state afresh at every step, so it is the paper's channel with
  lam = pi_good lam_good + pi_bad lam_bad (docs, "The exact engine"), to 1e-12;
- the old code path, bit for bit: the compiled core's structured formulas called directly;
- closed forms on GilbertElliott(p, q, 1, 0) (a low-power packet arrives iff the state is good, a
  high-power packet always), derived in the tests' docstrings;
- brute force over every pattern (not only necklaces) for the offline search;
- the explicit chain of tests/engine/reference_engine.py for a 3-state channel.
"""

import doctest
import itertools
import math
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack.model import design as design_mod
from fakeack.model import offline
from fakeack.model.schedules import OnlineDesign, design_online, j_max, j_offline, j_online, offline_schedule
from fakeack.model.system import compiled

sys.path.insert(0, str(Path(__file__).parent.parent / "engine"))
import reference_engine as ref  # noqa: E402

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
TR = S.h_traces(600)
#: A bursty channel: bad runs of mean length 10, nothing arrives at low power there.
BURSTY = fa.GilbertElliott(0.1, 0.1, 1, 0)
#: A 3-state channel with a lossy high-power state (not reversible: cyclic transitions).
M3 = fa.MarkovChannel(
    [[0.9, 0.1, 0.0], [0.2, 0.6, 0.2], [0.0, 0.5, 0.5]], low=[0.9, 0.5, 0.05], high=[1.0, 1.0, 0.7]
)
#: A nearly cyclic channel on which the evenly spread offline pattern is not the best.
CYCLIC = fa.MarkovChannel(
    [[0.05, 0.9, 0.05], [0.05, 0.05, 0.9], [0.9, 0.05, 0.05]], low=[0.9, 0.0, 0.0], high=[1.0, 0.2, 1.0]
)


def iid_pair(p, lam_good, lam_bad):
    """A Gilbert-Elliott channel with p + q = 1 and its i.i.d. lam."""
    q = 1.0 - p
    return fa.GilbertElliott(p, q, lam_good, lam_bad), q * lam_good + p * lam_bad


IID = [iid_pair(0.3, 0.9, 0.2), iid_pair(0.6, 0.8, 0.4)]


# --- closed forms on GilbertElliott(p, q, 1, 0) ------------------------------------------------


def ge_rate(p, q, z0, mu=1.0):
    """High-power rate of (z0, mu) on GilbertElliott(p, q, 1, 0), no attack.

    Flags come only in bad runs (a run of B bad steps, P(B >= n) = a^(n-1), a = 1 - q; runs start
    at rate pi_good p = pq/(p+q)). After a reset the detector flags after z0 losses (prob mu) or
    z0 + 1, and the next step is high power (one bad step that arrives): a cycle of m = z0 + 1 or
    z0 + 2 steps, its flag at its last step but one. The j-th flag of the run, at S_j - 1 (S_j the
    sum of j cycles), falls in the run iff B >= S_j - 1, so E[flags per run] =
    sum_j E[a^(S_j - 2)] = phi / (a^2 (1 - phi)) with phi = E[a^m] = mu a^(z0+1) + (1-mu) a^(z0+2).
    """
    a = 1.0 - q
    phi = mu * a ** (z0 + 1) + (1.0 - mu) * a ** (z0 + 2)
    return p * q / (p + q) * phi / (a * a * (1.0 - phi))


def ge_j_online(p, q, z0):
    """J of (z0, 1) on GilbertElliott(p, q, 1, 0): good steps cost tr_0; in a bad run the holding
    time runs 1, 2, ..., z0, 0 (the high-power step), 1, ... so its i-th step costs
    tr_(i mod (z0+1)), reached with P(B >= i) = a^(i-1). J = pi_good [tr_0 + p sum_i a^(i-1)
    tr_(i mod (z0+1))], the sum over a period of z0 + 1 divided by 1 - a^(z0+1)."""
    a, pg = 1.0 - q, q / (p + q)
    period = sum(a ** (r - 1) * TR[r] for r in range(1, z0 + 1)) + a**z0 * TR[0]
    return pg * (TR[0] + p * period / (1.0 - a ** (z0 + 1)))


def ge_j_pattern(p, q, pattern):
    """J of an offline pattern on GilbertElliott(p, q, 1, 0). At a step d steps after the last
    high-power one (d = 0 at one), the holding time is min(d, time since the last good step),
    and P(time since the last good step >= t) = pi_bad a^(t-1) for t >= 1, so
    E tr_tau = tr_0 + sum_{t=1}^{d} (tr_t - tr_(t-1)) pi_bad a^(t-1); J is the mean over phases."""
    a, pb, L = 1.0 - q, p / (p + q), len(pattern)
    total = 0.0
    for phase in range(L):
        d = next(t for t in range(L) if pattern[(phase - t) % L])
        total += TR[0] + sum((TR[t] - TR[t - 1]) * pb * a ** (t - 1) for t in range(1, d + 1))
    return total / L


def ge_j_all_low(p, q):
    """The brief's closed form: J = q/(p+q) [tr_0 + p sum_{t>=1} (1-q)^(t-1) tr_t] (the holding
    time is the time since the last good step)."""
    a = 1.0 - q
    return q / (p + q) * (TR[0] + p * sum(a ** (t - 1) * TR[t] for t in range(1, len(TR))))


# --- Bernoulli: bit for bit, whichever way the channel is written ------------------------------


def test_bernoulli_bit_for_bit():
    core = compiled(S)
    for lam in (0.5, 0.3, 0.85):
        spellings = (lam, fa.BernoulliChannel(lam))
        for z0, mu in ((2, 1.0), (3, 0.4)):
            old = core.j_online(lam, z0, mu)
            assert j_online(S, lam=lam, z0=z0, mu=mu) == old
            assert all(j_online(S, c, z0, mu) == old for c in spellings)
        assert all(j_max(S, c) == core.j_max(lam) for c in spellings) and j_max(S, lam=lam) == core.j_max(lam)
        for r in (Fraction(1, 7), Fraction(2, 5)):
            old = core.j_offline(lam, r.numerator, r.denominator)
            assert j_offline(S, lam=lam, ratio=r) == old
            assert all(j_offline(S, c, r) == old for c in spellings)
            assert all(offline_schedule(r, c).tolist() == offline_schedule(r).tolist() for c in spellings)


def test_bernoulli_design_is_the_exact_one():
    """The paper's example, and mu from the closed form in exact rationals (Model note 2: the rate
    is linear-fractional in mu): mu = (rho (1 - a^(z0+2)) - lam a^(z0+1)) / ((1-a) a^z0 (lam + rho a))."""
    assert design_online(0.5, "1/7") == (2, 1.0) == design_online(lam=0.5, ratio="1/7")
    lam, rho = Fraction(1, 2), Fraction(1, 5)
    a, z0 = 1 - lam, 1
    mu = (rho * (1 - a ** (z0 + 2)) - lam * a ** (z0 + 1)) / ((1 - a) * a**z0 * (lam + rho * a))
    for c in (0.5, lam, fa.BernoulliChannel(0.5)):
        assert design_online(c, rho) == (1, float(mu))
        assert OnlineDesign.design(c, rho) == (1, float(mu))
    # A Fraction lam is used exactly (not rounded to a float first).
    tiny = Fraction(1, 3)
    assert design_online(tiny, "1/9") == design_mod.design_paper(tiny, Fraction(1, 9))


# --- the i.i.d. reduction ----------------------------------------------------------------------


@pytest.mark.parametrize("ge, lam", IID)
def test_iid_reduction(ge, lam):
    for z0, mu in ((1, 1.0), (2, 1.0), (3, 0.35)):
        assert_allclose(j_online(S, ge, z0, mu), j_online(S, lam, z0, mu), rtol=1e-12)
    assert_allclose(j_max(S, ge), j_max(S, lam), rtol=1e-12)
    for r in ("1/7", "2/5"):
        assert_allclose(j_offline(S, ge, r), j_offline(S, lam, r), rtol=1e-12)
        assert offline_schedule(r, ge, system=S).tolist() == offline_schedule(r).tolist()
    for r in ("1/7", "3/17"):
        d_ge, d_iid = design_online(ge, r), design_online(lam, r)
        assert d_ge.z0 == d_iid.z0 and abs(d_ge.mu - d_iid.mu) < 1e-10


# --- closed forms under bursts -----------------------------------------------------------------


@pytest.mark.parametrize("p, q", [(0.1, 0.1), (0.2, 0.5), (0.05, 0.3)])
def test_bursty_closed_forms(p, q):
    ge = fa.GilbertElliott(p, q, 1, 0)
    for z0 in (1, 2, 5):
        assert_allclose(j_online(S, ge, z0), ge_j_online(p, q, z0), rtol=1e-12)
    for pat in ("1000000", "1010000", "110", "1001000100"):
        assert_allclose(j_offline(S, ge, pattern=pat), ge_j_pattern(p, q, [int(c) for c in pat]), rtol=1e-12)
    expected = ge_j_all_low(p, q) if (1 - q) * 1.44 < 1 else math.inf
    assert_allclose(j_max(S, ge), expected, rtol=1e-12)
    assert_allclose(j_offline(S, ge, pattern="0"), expected, rtol=1e-12)


def test_the_bursty_channels_reference_numbers():
    """Sanity checks against rough reference figures: the online rate about 0.166 (1/7 i.i.d.) and the evenly
    spread pattern about 3.94 (2.09 i.i.d.)."""
    assert abs(fa.high_power_rate(BURSTY, 2) - 0.166) < 5e-4
    assert abs(j_offline(S, BURSTY, pattern="1000000") - 3.94) < 5e-3
    assert abs(j_offline(S, 0.5, "1/7") - 2.09) < 5e-3


# --- the design under a channel ------------------------------------------------------------------


@pytest.mark.parametrize("ratio", ["1/7", "1/5", "1/12", Fraction(3, 41)])
def test_design_meets_the_budget_on_the_bursty_channel(ratio):
    z0, mu = design_online(BURSTY, ratio)
    assert abs(ge_rate(0.1, 0.1, z0, mu) - float(Fraction(ratio))) < 1e-12
    assert ge_rate(0.1, 0.1, z0 + 1) < float(Fraction(ratio)) <= ge_rate(0.1, 0.1, z0)  # the bracket


def test_design_with_a_fixed_memory_returns_mu_one():
    """On GilbertElliott(p, 0, 1, 0) the bad state is closed: a flag every z0 + 1 steps, rate
    1/(z0 + 1), met with equality by z0 = 9 at ratio 1/10."""
    assert design_online(fa.GilbertElliott(0.1, 0.0, 1, 0), "1/10") == (9, 1.0)


@pytest.mark.parametrize("ratio", ["1/9", "1/5", "2/23"])
def test_design_meets_the_budget_on_a_three_state_channel(ratio):
    """Against the explicit chain of reference_engine (no formula of the engine): its rate of
    steps at high power."""
    z0, mu = design_online(M3, ratio)
    chain = ref.Chain(M3.P, M3.low, M3.high, ("online", z0, mu))
    assert abs(ref.rates(chain)[0] - float(Fraction(ratio))) < 1e-12
    assert abs(fa.Scenario(S, M3, OnlineDesign(z0, mu)).high_power_rate() - float(Fraction(ratio))) < 1e-12


def test_design_rate_is_not_linear_fractional_in_mu_on_a_markov_channel():
    """Why bisection: on the 3-state channel the rate at mu = 1/2 is not what the linear-fractional
    interpolation through mu = 0, 1 and a third point predicts."""

    def f(mu):
        return fa.high_power_rate(M3, 2, mu=mu)

    # A linear-fractional g(mu) = (a + b mu)/(1 + c mu) is fixed by three values; check a fourth.
    m = [0.0, 0.3, 1.0]
    y = [f(x) for x in m]
    A = np.array([[1.0, x, -yi * x] for x, yi in zip(m, y, strict=True)])
    a, b, c = np.linalg.solve(A, y)
    assert abs((a + b * 0.6) / (1 + c * 0.6) - f(0.6)) > 1e-9
    # On the paper's channel the same test passes (Model note 2).
    yb = [fa.high_power_rate(0.5, 2, mu=x) for x in m]
    Ab = np.array([[1.0, x, -yi * x] for x, yi in zip(m, yb, strict=True)])
    ab, bb, cb = np.linalg.solve(Ab, yb)
    assert abs((ab + bb * 0.6) / (1 + cb * 0.6) - fa.high_power_rate(0.5, 2, mu=0.6)) < 1e-12


# --- the offline search ------------------------------------------------------------------------


def all_patterns(L, w):
    for ones in itertools.combinations(range(L), w):
        pat = [0] * L
        for i in ones:
            pat[i] = 1
        yield pat


def brute_force(evaluate, q, p, max_period):
    """The least J over every pattern (all of them, not necklaces) of period kq <= max_period."""
    return min(evaluate(pat) for k in range(1, max_period // q + 1) for pat in all_patterns(k * q, k * p))


def test_necklace_enumeration_counts():
    """Lyndon compositions against the Moebius formula and against a brute-force canonical count."""
    for zeros, ones in [(6, 1), (5, 2), (8, 3), (6, 4), (5, 5), (9, 3)]:
        got = list(offline.necklaces(zeros, ones))
        assert len(got) == len(set(got)) == offline.lyndon_count(zeros + ones, ones)
        L = zeros + ones
        classes = set()
        for pat in all_patterns(L, ones):
            rots = {tuple(pat[i:] + pat[:i]) for i in range(L)}
            if len(rots) == L:  # aperiodic
                classes.add(min(rots))
        assert len(classes) == len(got)
        assert all(sum(g) == zeros and len(g) == ones for g in got)


@pytest.mark.parametrize(("p", "q"), [(0.1, 0.1), (0.3, 0.2)])
@pytest.mark.parametrize("ratio", ["1/3", "2/5", "2/7"])
def test_search_against_brute_force_on_gilbert_elliott(p, q, ratio):
    """Exhaustive over necklaces (and reversal pairs: two states are reversible) against every
    pattern, each by the closed form ge_j_pattern (independent of the engine). On this channel J
    is a sum over the gaps of a convex function of the gap, so the evenly spread pattern wins."""
    r = Fraction(ratio)
    res = offline.offline_search(S, fa.GilbertElliott(p, q, 1, 0), r, max_period=12)
    best = brute_force(lambda pat: ge_j_pattern(p, q, pat), r.denominator, r.numerator, 12)
    assert_allclose(res.j, best, rtol=1e-12)
    assert res.even_is_optimal and res.exhaustive and res.exhaustive_period == res.max_period
    assert res.pattern.tolist() == offline_schedule(r).tolist()


@pytest.mark.parametrize("ratio", ["1/3", "2/7", "1/4"])
def test_search_against_brute_force_on_a_cyclic_channel(ratio):
    """A non-reversible channel: necklaces only, against every pattern by the engine."""
    r = Fraction(ratio)
    mp = 12 if r.denominator <= 4 else 14
    res = offline.offline_search(S, CYCLIC, r, max_period=mp)
    best = brute_force(lambda pat: j_offline(S, CYCLIC, pattern=pat), r.denominator, r.numerator, mp)
    assert_allclose(res.j, best, rtol=1e-12)
    assert_allclose(j_offline(S, CYCLIC, pattern=res.pattern), res.j, rtol=1e-12)
    assert res.pattern.sum() * r.denominator == len(res.pattern) * r.numerator


def test_even_is_not_always_optimal():
    """On CYCLIC, 101000 beats 100 (checked by the explicit chain of reference_engine)."""
    res = offline.offline_search(S, CYCLIC, "1/3", max_period=9)
    assert not res.even_is_optimal and "".join(map(str, res.pattern)) == "101000"
    assert_allclose(res.j, j_ref_of(CYCLIC, [1, 0, 1, 0, 0, 0]), rtol=1e-9)
    assert_allclose(res.j_even, j_ref_of(CYCLIC, [1, 0, 0]), rtol=1e-9)
    assert res.j < res.j_even * (1 - 1e-3)
    assert offline_schedule("1/3", CYCLIC, system=S, max_period=9).tolist() == [1, 0, 1, 0, 0, 0]
    assert j_offline(S, CYCLIC, "1/3", max_period=9) == res.j


def j_ref_of(ch, pattern):
    return ref.cost(ref.Chain(ch.P, ch.low, ch.high, ("offline", pattern)), S.A, S.Q, S.pbar)


def test_rotations_and_reversals():
    """Rotations have the same J on every channel; reversals on reversible channels (two states,
    or birth-death), not on the cyclic one."""
    pat = [1, 1, 0, 1, 0, 0, 0, 1, 0, 0, 0]
    birth_death = fa.MarkovChannel(
        [[0.8, 0.2, 0.0], [0.3, 0.5, 0.2], [0.0, 0.6, 0.4]], low=[0.9, 0.4, 0.0], high=[1.0, 0.8, 0.5]
    )
    for ch in (BURSTY, M3, CYCLIC, birth_death):
        j = j_offline(S, ch, pattern=pat)
        for i in range(len(pat)):
            assert_allclose(j_offline(S, ch, pattern=pat[i:] + pat[:i]), j, rtol=1e-12)
    for ch in (BURSTY, fa.GilbertElliott(0.2, 0.4, 0.7, 0.1, 1.0, 0.6), birth_death):
        assert offline._reversible(ch)
        assert_allclose(j_offline(S, ch, pattern=pat[::-1]), j_offline(S, ch, pattern=pat), rtol=1e-12)
    assert not offline._reversible(CYCLIC)
    assert abs(j_offline(S, CYCLIC, pattern=pat[::-1]) - j_offline(S, CYCLIC, pattern=pat)) > 1e-3


def test_search_on_the_paper_channel_confirms_theorem_3_1():
    for r in ("1/7", "2/5", "3/8"):
        res = offline.offline_search(S, 0.5, r)
        assert res.even_is_optimal and res.exhaustive
        assert_allclose(res.j, j_offline(S, 0.5, r), rtol=1e-12)


def test_default_periods_and_the_local_search():
    """By default the longest exhaustive period within max_patterns; beyond it (a large q here),
    the local search, flagged as not exhaustive, never worse than the evenly spread pattern."""
    res = offline.offline_search(S, BURSTY, "1/7")
    assert res.max_period == res.exhaustive_period == 28  # 1 + 6 + 63 + 728 necklaces; 9275 more at 35
    assert res.n_searched < 1 + 6 + 63 + 728 + 1  # reversal pairs evaluated once
    big = offline.offline_search(S, CYCLIC, "13/100")
    assert big.max_period == 100 and big.exhaustive_period == 0 and not big.exhaustive
    assert big.j <= big.j_even and big.pattern.sum() * 100 == 13 * len(big.pattern)
    part = offline.offline_search(S, CYCLIC, "1/3", max_period=12, max_patterns=10)
    assert part.exhaustive_period == 6 and part.max_period == 12 and not part.exhaustive
    assert_allclose(j_offline(S, CYCLIC, pattern=part.pattern), part.j, rtol=1e-12)
    html = res._repr_html_()
    assert "<table" in html and "1000000" in html
    assert "OfflineSearch(ratio=1/7, pattern='1000000'" in repr(res)


def test_offline_module_doctest():
    scope = {n: getattr(fa, n) for n in fa.__all__}
    result = doctest.testmod(offline, extraglobs=scope, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and result.attempted > 0


# --- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "exc", "arg"),
    [
        (lambda: fa.GilbertElliott(1.5, 0.1, 1, 0), ValueError, "p"),
        (lambda: fa.GilbertElliott(0.1, -0.2, 1, 0), ValueError, "q"),
        (lambda: fa.GilbertElliott(0.0, 0.0, 1, 0), ValueError, "p"),
        (
            lambda: fa.MarkovChannel([[1, 0], [0, 1]], [0.5, 0.5], [1, 1]),
            ValueError,
            "P",
        ),  # two closed classes
        (lambda: fa.MarkovChannel([[0.5, 0.4], [0.2, 0.8]], [0.5, 0.5], [1, 1]), ValueError, "P"),  # row sum
    ],
)
def test_bad_channels_name_the_argument(make, exc, arg):
    with pytest.raises(exc, match=names(arg)):
        make()


def test_bad_arguments_name_the_argument():
    with pytest.raises(ValueError, match=names("ratio")):
        design_online(BURSTY, "1/2")  # above f(1, 1) = 0.263
    with pytest.raises(ValueError, match=names("ratio")):
        design_online(fa.GilbertElliott(0.1, 0.0, 1, 0), Fraction(1, 10**6))  # memory > 2^16
    with pytest.raises(ValueError, match=names("ratio")):
        design_online(0.5, "9/10")
    # A number is the paper's lam, and its errors name lam, as before channels; a channel object
    # or anything else is named channel.
    with pytest.raises(ValueError, match=names("lam")):
        j_online(S, 1.5, 2)
    with pytest.raises(ValueError, match=names("lam")):
        j_online(S, 0.0, 2)  # the paper's formulas need lam in (0, 1)
    with pytest.raises(ValueError, match=names("channel")):
        j_online(S, fa.BernoulliChannel(1.0), 2)
    with pytest.raises(ValueError, match=names("lam")):
        j_max(S, lam=1.0)
    with pytest.raises(TypeError, match=names("channel")):
        j_offline(S, "x", "1/7")
    with pytest.raises(TypeError, match=names("lam")):
        j_online(S, 0.5, 2, lam=0.5)
    with pytest.raises(TypeError, match=names("pattern")):
        j_offline(S, BURSTY, "1/7", pattern="1000000")
    with pytest.raises(TypeError, match=names("z0")):
        j_online(S, BURSTY)
    with pytest.raises(TypeError, match=names("system")):
        offline_schedule("1/7", BURSTY)
    with pytest.raises(ValueError, match=names("max_period")):
        offline.offline_search(S, BURSTY, "1/7", max_period=5)
    with pytest.raises(ValueError, match=names("ratio")):
        offline.offline_search(S, BURSTY, "7/7")
    with pytest.raises(ValueError, match=names("pattern")):
        j_offline(S, BURSTY, pattern="10x")
