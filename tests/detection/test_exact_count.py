"""The count test with fewer than 100 expected flag-ACKs per window uses the exact count law;
the interval test refuses such windows. Expected values: a probability tree of the protocol
written from its description (not the engine's automaton), the Monte Carlo of the protocol, and
the definition of the alarm region."""

from functools import cache

import numpy as np
import pytest

import fakeack as fa


def protocol_count_law(lam, z0, mu, n):
    """P(N = c) for the flags sent in steps 1..n from the paper's initial condition (high power at
    k = 1, memory restarted), by a probability tree over (zero count z, next power, flags so far):
    a high-power packet always arrives; a low one with probability lam; an arrival resets z, a
    loss adds 1; at z = z0 a flag goes out with probability mu, at z = z0 + 1 always; a flag makes
    the next packet high power (and restarts the memory)."""

    @cache
    def law(k, z, high):
        # Distribution (as a dict count -> probability) of the flags sent in steps k..n.
        if k > n:
            return {0: 1.0}
        out = {}

        def add(p, z_next, flag):
            for c, q in law(k + 1, 0 if flag else z_next, flag).items():
                out[c + flag] = out.get(c + flag, 0.0) + p * q

        arrive = 1.0 if high else lam
        if arrive > 0:
            add(arrive, 0, 0)
        if arrive < 1:
            z1 = z + 1
            if z1 == z0:
                add((1 - arrive) * mu, z1, 1)
                if mu < 1:
                    add((1 - arrive) * (1 - mu), z1, 0)
            elif z1 >= z0 + 1:
                add(1 - arrive, z1, 1)
            else:
                add(1 - arrive, z1, 0)
        return out

    d = law(1, 0, True)
    return np.array([d.get(c, 0.0) for c in range(max(d) + 1)])


@pytest.mark.parametrize(("lam", "z0", "mu"), [(0.5, 2, 1.0), (0.3, 1, 1.0), (0.6, 2, 0.5)])
def test_the_exact_law_is_the_protocols(lam, z0, mu):
    n = 14
    expect = protocol_count_law(lam, z0, mu, n)
    got = fa.flag_process(lam, fa.OnlineDesign(z0, mu)).count_law(n, start="initial")
    assert len(got) <= len(expect)
    assert np.allclose(np.pad(got, (0, len(expect) - len(got))), expect, atol=1e-14)


@pytest.mark.parametrize("alternative", ["less", "greater", "two-sided"])
def test_the_alarm_region_is_where_the_exact_p_value_is_below_alpha(alternative):
    n, alpha = 300, 0.05
    law = fa.flag_process(0.5, fa.OnlineDesign(2)).count_law(n)
    below, above = np.cumsum(law), np.cumsum(law[::-1])[::-1]
    p = {"less": below, "greater": above, "two-sided": np.minimum(1, 2 * np.minimum(below, above))}[
        alternative
    ]
    lo, hi = fa.detection.count_alarm_bounds(0.5, 2, n, alpha, alternative)
    alarms = set(np.flatnonzero(p < alpha).tolist())
    assert alarms == {c for c in range(len(law)) if c <= lo or c >= hi}
    for d in (0, 20, 43, 60):
        det = fa.detect_attack(d, n, 0.5, 2, alpha=alpha, alternative=alternative)
        assert det.p_value == pytest.approx(min(1.0, p[d]) if d < len(law) else 0.0, rel=1e-12)


@pytest.mark.parametrize(
    "attack", [fa.RandomBlocking(0.2), fa.PeriodicBlocking(1, 5), fa.FlagInjection(0.05)]
)
def test_short_window_detection_probabilities_match_the_monte_carlo(attack):
    """200-step windows (29 expected flags) after a burn-in of 400 steps, 20000 windows each."""
    p = fa.detection_probability(0.5, 2, attack, 200, 0.01, support=False)  # the simulated test alone
    r = fa.detection_rates(
        0.5, 2, attack, n_steps=200, runs=20000, seed=3, alternative="two-sided", burn_in=400, support=False
    )
    assert abs(r.detection - p) < 4 * np.sqrt(p * (1 - p) / 20000)
    assert abs(r.false_alarm - fa.detection_probability(0.5, 2, None, 200, 0.01)) < 4 * np.sqrt(0.01 / 20000)


def test_long_memories_give_the_true_tiny_false_alarm_rate_and_refuse_the_interval_test():
    """z0 = 50 at lam = 1/2: a flag every 2^51 steps or so. A 1000-step window almost never holds
    a flag: the two-sided test alarms only on a count of at least one, P ~ 1000 rate."""
    p = fa.detection_probability(0.5, 50, None, 1000, 0.01)
    rate = fa.flag_rates(0.5, 50).delivered
    assert 0 < p < 1.01 * 1000 * rate
    with pytest.raises(ValueError, match="n_steps = 1000: the interval test needs at least 100"):
        fa.detection_probability(0.5, 50, None, 1000, 0.01, test="interval")
    with pytest.raises(ValueError, match="use a window of at least 700 steps"):
        fa.interval_test(0.5, 2, 699)
    assert fa.interval_test(0.5, 2, 700).n_steps == 700


def test_windows_with_100_expected_flags_keep_the_normal_approximation():
    det = fa.detect_attack(130, 1000, 0.5, 2)  # 142.9 expected
    from scipy.stats import norm

    assert det.p_value == norm.cdf(det.z_score)
