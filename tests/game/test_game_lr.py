"""The likelihood-ratio window test in the game: the closed-loop kernel's windows against the exact
law of the statistic, the payoff formula against the closed loop, the game and the stealthy
frontier reading the test's exact detection probabilities, and the policy's arguments checked."""

import math
from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER

LAM, RATIO, Z0 = 0.5, Fraction(1, 7), 2
SYSTEM = fa.LinearSystem(**PAPER)
CAREFUL = fa.FlagInjection(0.05, min_gap=Z0 + 1)


@pytest.mark.parametrize(
    "attack, alternative",
    [
        (None, None),
        (fa.RandomBlocking(0.3), None),
        (CAREFUL, None),
        # Tuned to the careful forger, the test sees it; forged flags here never make a gap
        # shorter than z0 + 1, so the +inf of the support check stays out of it.
        (CAREFUL, CAREFUL),
        # A forger that ignores the gaps: the statistic's +inf (the support check) decides.
        (fa.FlagInjection(0.02), None),
    ],
)
def test_closed_loop_windows_follow_the_exact_law(attack, alternative):
    """Stationary windows of the protocol (the compiled kernel, its statistic accumulated step by
    step) alarm as often as the statistic's exact law says (the law itself is checked against
    protocol windows written from the description in tests/detection/test_likelihood.py)."""
    n, runs = 300, 3000
    test = fa.likelihood_ratio_test(LAM, Z0, n, 0.02, alternative=alternative or fa.RandomBlocking(0.2))
    exact = test.detection_probability(attack)
    kw = {} if alternative is None else {"lr_alternative": alternative}
    r = fa.detection_rates(LAM, Z0, attack or fa.RandomBlocking(0.0), n, runs, alpha=0.02, test="lr", **kw)
    got, se = (r.false_alarm, r.false_alarm_stderr) if attack is None else (r.detection, r.detection_stderr)
    se = max(se, math.sqrt(exact * (1 - exact) / runs), 1.0 / runs)
    assert abs(got - exact) <= 4 * se + 0.003, (got, exact, se)
    assert r.test == "lr"


def test_payoff_against_the_closed_loop():
    """J, the online fraction and the alarm rate of game_payoff's renewal average against the
    closed loop, with fall-backs (the first window back online, which waits for a flag-ACK, is
    the formula's only neglect)."""
    n = 200
    policy = fa.SensorPolicy("lr", 0.05, 2)
    for attack in (None, fa.RandomBlocking(0.3)):
        pay = fa.game_payoff(SYSTEM, LAM, RATIO, policy, attack, n)
        sim = fa.simulate_game(
            SYSTEM, LAM, RATIO, policy, attack, horizon=400 * n, runs=256, seed=5, n_steps=n
        )
        assert abs(sim.j - pay.j) <= 4 * sim.stderr + 0.005 * pay.j, (attack, sim.j, pay.j)
        assert abs(sim.online - pay.online) <= 0.01, (attack, sim.online, pay.online)
        # The first window back online reads less than a stationary one (it waits for a
        # flag-ACK), so the closed loop alarms a little less often: 0.682 against d = 0.711
        # under RandomBlocking(0.3), after every second window.
        assert pay.detection - 0.04 <= sim.alarm_rate <= pay.detection + 4 * sim.alarm_stderr, (
            attack,
            sim,
            pay,
        )


def test_game_reads_the_exact_detection_probabilities():
    n, attacks = 200, [None, fa.RandomBlocking(0.5), CAREFUL]
    g = fa.solve_game(SYSTEM, LAM, RATIO, n, [0.01, 0.05], [1], attacks, tests=("count", "lr"))
    lr_rows = [i for i, p in enumerate(g.policies) if p.test == "lr"]
    # One lr policy per (alpha, fallback): the harmful rule does not apply to it.
    assert len(lr_rows) == 2 and all(g.policies[i].rule == "any" for i in lr_rows)
    for i in lr_rows:
        p = g.policies[i]
        for k, a in enumerate(attacks):
            d = fa.detection_probability(LAM, Z0, a, n, p.alpha, "lr")
            assert g.detection[i, k] == pytest.approx(d, abs=1e-12)
        j_att = np.array([fa.j_attack(SYSTEM, LAM, Z0, attack=a or "0/1") for a in attacks])
        d = g.detection[i]
        assert np.allclose(g.payoff[i], (j_att + d * g.j_offline) / (1 + d), rtol=1e-12)
    # Without an attacker the sensor never tests: J_on.
    clean = fa.solve_game(SYSTEM, LAM, RATIO, n, 0.05, 1, attacks, tests="lr", attack_prior=0.0)
    assert clean.value == pytest.approx(clean.j_online, rel=1e-9)


def test_stealthy_frontier_with_the_lr_test():
    f = fa.stealthy_frontier(SYSTEM, LAM, Z0, 200, 0.05, "lr", "random", 0.5, grid=5)
    test = fa.likelihood_ratio_test(LAM, Z0, 200, 0.05)
    d_all, _ = f.candidates
    assert d_all.size == 5
    for beta, d in zip(np.linspace(0, 1, 5), d_all, strict=True):
        assert d == pytest.approx(test.detection_probability(fa.RandomBlocking(beta)), abs=1e-12)
    assert f.detection <= 0.5
    with pytest.raises(ValueError, match="lr_alternative"):
        fa.stealthy_frontier(SYSTEM, LAM, Z0, 200, 0.05, "count", "random", 0.5, lr_alternative=CAREFUL)


def test_policy_arguments():
    p = fa.SensorPolicy("lr", 0.01, 2)
    assert (
        str(p) == "lr test against RandomBlocking(beta=0.2) at alpha=0.01, 2 windows offline after any alarm"
    )
    assert p.lr_alternative == fa.RandomBlocking(0.2) and not p.support
    pmf = fa.SensorPolicy("lr", 0.01, 1, lr_alternative=[0.0, 0.0, 0.5, 0.5])
    assert hash(pmf) == hash(fa.SensorPolicy("lr", 0.01, 1, lr_alternative=(0.0, 0.0, 0.5, 0.5)))
    assert "a gap law on 1..4" in str(pmf)
    for kw, name in [
        ({"rule": "harmful"}, "rule"),
        ({"support": True}, "support"),
        ({"alternative": "less"}, "alternative"),
    ]:
        with pytest.raises(ValueError, match=f"^{name}"):
            fa.SensorPolicy("lr", 0.01, 1, **kw)
    with pytest.raises(ValueError, match="^lr_alternative"):
        fa.SensorPolicy("count", 0.01, 1, lr_alternative=CAREFUL)
    with pytest.raises(TypeError, match="alternative"):
        fa.SensorPolicy("lr", 0.01, 1, lr_alternative=fa.PeriodicBlocking(1, 3))
    with pytest.raises(TypeError, match="alpha and fallback"):
        fa.SensorPolicy("lr", 0.01)
    with pytest.raises(ValueError, match="^lr_alternative"):
        fa.solve_game(SYSTEM, LAM, RATIO, 100, 0.01, 1, [None], tests="count", lr_alternative=CAREFUL)
    with pytest.raises(ValueError, match="^support"):
        fa.detection_rates(LAM, Z0, "1/3", 100, 10, test="lr", support=False)
    with pytest.raises(ValueError, match="^lr_alternative"):
        fa.detection_rates(LAM, Z0, "1/3", 100, 10, test="count", lr_alternative=CAREFUL)
