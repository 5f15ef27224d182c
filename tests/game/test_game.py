"""The sensor-attacker game: the payoff formula against the chain of window modes and the
closed-loop Monte Carlo, the detection probabilities against simulated windows, the linear
programs against the minimax conditions, the stealthy frontier, and bad input."""

import math
import os
import signal
import threading
import time
from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa

LAM, RATIO = 0.5, Fraction(1, 7)


def _chain_payoff(j_att, j_off, hp_att, hp_off, d, k):
    """Long-run averages from the chain of window modes: online -> (K offline with prob d)."""
    n = 1 + k
    P = np.zeros((n, n))
    P[0, 0] = 1 - d
    if k:
        P[0, 1] = d
        for i in range(1, k):
            P[i, i + 1] = 1.0
        P[k, 0] = 1.0
    else:
        P[0, 0] = 1.0
    vals, vecs = np.linalg.eig(P.T)
    pi = np.real(vecs[:, np.argmin(abs(vals - 1))])
    pi /= pi.sum()
    return pi[0] * j_att + (1 - pi[0]) * j_off, pi[0] * hp_att + (1 - pi[0]) * hp_off


# ---------------------------------------------------------------------------------------------
# Policies.


def test_policies_print_and_validate():
    assert str(fa.SensorPolicy("offline")) == "always offline"
    assert str(fa.SensorPolicy("never")) == "online, never test"
    p = fa.SensorPolicy("interval", 0.05, 1)
    assert str(p) == "interval test at alpha=0.05, 1 window offline after any alarm"
    assert str(fa.SensorPolicy("count", 0.01, 3, alternative="less")).startswith("count test (less)")
    assert p == fa.SensorPolicy("interval", 0.05, 1) and hash(p) == hash(fa.SensorPolicy("interval", 0.05, 1))
    with pytest.raises(ValueError, match="alpha"):
        fa.SensorPolicy("count", 1.5, 2)
    with pytest.raises(ValueError, match="alpha"):
        fa.SensorPolicy("count", float("nan"), 2)
    with pytest.raises(ValueError, match="fallback"):
        fa.SensorPolicy("count", 0.01, -1)
    with pytest.raises(ValueError, match="rule"):
        fa.SensorPolicy("count", 0.01, 1, "sometimes")
    with pytest.raises(ValueError, match="test"):
        fa.SensorPolicy("shape", 0.01, 1)
    with pytest.raises(ValueError, match="test"):
        fa.SensorPolicy("offline", 0.01, 1)
    with pytest.raises(ValueError, match="alternative"):
        fa.SensorPolicy("interval", 0.01, 1, alternative="less")


# ---------------------------------------------------------------------------------------------
# The payoff formula.


@pytest.mark.parametrize(
    "policy",
    [
        fa.SensorPolicy("count", 0.01, 2, support=False),
        fa.SensorPolicy("interval", 0.05, 3, support=False),
        fa.SensorPolicy("count", 0.01, 4, "harmful", support=False),
        fa.SensorPolicy("interval", 0.01, 1, "harmful", support=False),
        fa.SensorPolicy("count", 0.05, 0, support=False),
        fa.SensorPolicy("never"),
        fa.SensorPolicy("offline"),
    ],
    ids=str,
)
@pytest.mark.parametrize(
    "attack", [None, fa.PeriodicBlocking(1, 5), fa.RandomBlocking(0.4), fa.FlagInjection(0.05)], ids=str
)
def test_payoff_is_the_window_chain_average(paper, policy, attack):
    p = fa.game_payoff(paper, LAM, RATIO, policy, attack, 1000)
    j_off = fa.j_offline(paper, LAM, RATIO)
    if policy.test == "offline":
        assert (p.j, p.high_power, p.online) == (j_off, pytest.approx(1 / 7), 0.0)
        return
    j_att = fa.j_attack(paper, LAM, 2, attack=attack) if attack else fa.j_online(paper, LAM, 2)
    hp_att = fa.high_power_rate(LAM, 2, attack)
    k = 0 if policy.special else policy.fallback
    d = (
        0.0
        if policy.special
        else fa.detection_probability(
            LAM,
            2,
            attack,
            1000,
            policy.alpha,
            policy.test,
            policy.alternative,
            beta_bar=fa.choose_schedule(paper, LAM, RATIO, 0).beta_bar if policy.rule == "harmful" else None,
            support=False,  # the payoff's tests run alone
        )
    )
    j, hp = _chain_payoff(j_att, j_off, hp_att, 1 / 7, d, k)
    assert p.detection == pytest.approx(d, abs=1e-12)
    assert p.j == pytest.approx(j, rel=1e-12) and p.high_power == pytest.approx(hp, rel=1e-12)
    assert p.j_attack == pytest.approx(j_att, rel=1e-12)


def test_weak_attackers_want_to_be_seen_by_any_alarm_but_not_by_harmful_ones(paper):
    # Forging lowers J below J_off, so under rule "any" the alarms it trips raise the payoff;
    # the harmful rule ignores them (the count is high, the estimated budget 0).
    att = fa.FlagInjection(0.05)
    any_ = fa.game_payoff(paper, LAM, RATIO, fa.SensorPolicy("count", 0.01, 4, support=False), att, 1000)
    harm = fa.game_payoff(
        paper, LAM, RATIO, fa.SensorPolicy("count", 0.01, 4, "harmful", support=False), att, 1000
    )
    never = fa.game_payoff(paper, LAM, RATIO, fa.SensorPolicy("never"), att, 1000)
    assert any_.detection > 0.5 and any_.j > never.j
    assert harm.detection < 1e-12 and harm.j == pytest.approx(never.j, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# Detection probabilities against simulated windows.

DETECTION_CASES = [
    (None, "count", 0.01),
    (None, "interval", 0.01),
    (None, "count", 0.05),
    (None, "interval", 0.05),
    (fa.PeriodicBlocking(1, 5), "count", 0.01),
    (fa.PeriodicBlocking(1, 5), "interval", 0.01),
    (fa.PeriodicBlocking(3, 20), "count", 0.01),
    (fa.PeriodicBlocking(3, 20), "interval", 0.01),
    (fa.RandomBlocking(0.15), "count", 0.01),
    (fa.RandomBlocking(0.15), "interval", 0.01),
    (fa.FlagInjection(0.02), "count", 0.01),
    (fa.FlagInjection(0.02), "interval", 0.01),
    (fa.rate_matching_attack(LAM, 2, 0.3), "count", 0.01),
    (fa.rate_matching_attack(LAM, 2, 0.3), "interval", 0.01),
]


@pytest.mark.parametrize("attack,test,alpha", DETECTION_CASES, ids=str)
def test_detection_probability_against_simulated_windows(attack, test, alpha):
    # Attack-free, the critical values come from the null law itself: 40,000 windows. Under attack
    # the formula is a large-sample approximation, checked at the README's 4000 windows (at 40,000
    # the interval test's shows a bias of up to 6%, about 5 standard errors: README).
    n, runs = 1000, 40_000 if attack is None else 4000
    # detection_rates simulates attack-free windows beside; the attack-free case reads those. The
    # formula is the test's alone: without the support check, which sees the forgers here.
    sim = fa.detection_rates(
        LAM,
        2,
        attack or fa.PeriodicBlocking(0, 1),
        n,
        runs,
        alpha=alpha,
        seed=21,
        test=test,
        alternative="two-sided",
        burn_in=n,
        support=False,
    )
    rate, se = (
        (sim.false_alarm, sim.false_alarm_stderr) if attack is None else (sim.detection, sim.detection_stderr)
    )
    p = fa.detection_probability(LAM, 2, attack, n, alpha, test, support=False)  # the simulated test alone
    assert abs(rate - p) <= 3 * max(se, math.sqrt(p * (1 - p) / runs)) + 1e-9, (rate, se, p)
    if attack is None:
        assert 0.5 * alpha <= rate <= 1.5 * alpha


def test_false_alarms_for_longer_windows():
    for test in ("count", "interval"):
        sim = fa.detection_rates(
            LAM,
            2,
            fa.PeriodicBlocking(0, 1),
            5000,
            2000,
            alpha=0.05,
            seed=5,
            test=test,
            alternative="two-sided",
            burn_in=1000,
        )
        assert 0.025 <= sim.false_alarm <= 0.075


def test_detection_rates_default_is_the_one_sided_count_test_of_stationary_windows():
    r = fa.detection_rates(LAM, 2, (1, 5), n_steps=1000, runs=2000, seed=1)
    mixing = fa.flag_process(LAM, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5)).mixing_steps()
    assert (r.test, r.alternative, r.burn_in) == ("count", "less", mixing)
    assert 0.005 <= r.false_alarm <= 0.015 and r.detection > 0.8 and 0.15 < r.beta_hat_mean < 0.25


# ---------------------------------------------------------------------------------------------
# The closed loop against the formula.

CLOSED_LOOP = [
    (fa.SensorPolicy("count", 0.01, 1), fa.PeriodicBlocking(1, 5)),
    (fa.SensorPolicy("count", 0.05, 2), None),
    # The count test with the support check against forgers: d is exact. The interval test's
    # combination with the check is approximate, so its forgers are played without the check.
    (fa.SensorPolicy("count", 0.01, 2), fa.FlagInjection(0.0001)),
    (fa.SensorPolicy("count", 0.01, 1, "harmful"), fa.FlagInjection(0.0001, fa.RandomBlocking(0.35))),
    (fa.SensorPolicy("interval", 0.05, 3, support=False), fa.rate_matching_attack(LAM, 2, 0.2)),
    (fa.SensorPolicy("interval", 0.01, 1, "harmful"), fa.PeriodicBlocking(2, 3)),
    (fa.SensorPolicy("count", 0.01, 1, "harmful"), fa.RandomBlocking(0.35)),
    (fa.SensorPolicy("count", 0.05, 2), fa.RandomBlocking(0.05)),
    (fa.SensorPolicy("interval", 0.05, 4, support=False), fa.FlagInjection(0.005)),
    (fa.SensorPolicy("never"), fa.PeriodicBlocking(2, 3)),
    (fa.SensorPolicy("offline"), fa.PeriodicBlocking(2, 3)),
]


@pytest.mark.parametrize("policy,attack", CLOSED_LOOP, ids=str)
def test_closed_loop_agrees_with_the_payoff(paper, policy, attack):
    # Windows of 10^4 steps: the transients at switches the formula neglects are then below the
    # standard error (the README shows the gap for shorter windows). 10 windows of burn-in and
    # 100 measured: where alarms are certain the window modes cycle deterministically, and with
    # one fall-back window an even number of windows holds whole cycles.
    n = 10_000
    p = fa.game_payoff(paper, LAM, RATIO, policy, attack, n)
    sim = fa.simulate_game(
        paper, LAM, RATIO, policy, attack, 100 * n, 256, seed=31, n_steps=n, burn_in=10 * n
    )
    assert abs(sim.j - p.j) < 4 * sim.stderr, (sim.j, sim.stderr, p.j)
    assert abs(sim.high_power - p.high_power) < 4 * sim.high_power_stderr + 2e-4
    if not policy.special:
        assert abs(sim.fallback_rate - p.detection) < 4 * sim.fallback_stderr + 0.01


def test_closed_loop_is_seeded(paper):
    pol = fa.SensorPolicy("interval", 0.05, 2)
    a = fa.simulate_game(paper, LAM, RATIO, pol, fa.RandomBlocking(0.2), 20_000, 20, seed=3)
    b = fa.simulate_game(paper, LAM, RATIO, pol, fa.RandomBlocking(0.2), 20_000, 20, seed=3)
    c = fa.simulate_game(paper, LAM, RATIO, pol, fa.RandomBlocking(0.2), 20_000, 9, seed=3)
    assert a.j == b.j and np.array_equal(a.delivered_per_run, b.delivered_per_run)
    assert np.array_equal(a.delivered_per_run[:9], c.delivered_per_run)


def test_closed_loop_ctrl_c(paper, monkeypatch):
    import fakeack.game.simulate as game

    fired = {}

    def interrupt():
        fired["t"] = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    class SignalOnFirstReport(game.Progress):
        def __call__(self, done):
            if "thread" not in fired:
                fired["thread"] = threading.Thread(target=interrupt)
                fired["thread"].start()

    monkeypatch.setattr(game, "Progress", SignalOnFirstReport)
    with pytest.raises(KeyboardInterrupt):  # ~10^13 steps: hours if not interrupted
        fa.simulate_game(paper, LAM, RATIO, fa.SensorPolicy("count", 0.01, 1), None, 10**6, 10**7, seed=1)
    assert time.monotonic() - fired["t"] < 1.0
    fired["thread"].join()


# ---------------------------------------------------------------------------------------------
# Solving the game.

ATTACKS = [
    None,
    fa.PeriodicBlocking(1, 5),
    fa.PeriodicBlocking(1, 3),
    fa.RandomBlocking(0.2),
    fa.RandomBlocking(0.3),
    fa.FlagInjection(0.05),
    fa.rate_matching_attack(LAM, 2, 0.2),
]


def test_solution_meets_the_minimax_conditions(paper):
    sol = fa.solve_game(paper, LAM, RATIO, 1000, alphas=[0.01, 0.05], fallbacks=[1, 3], attacks=ATTACKS)
    A = sol.payoff
    assert A.shape == (len(sol.policies), len(ATTACKS)) and sol.attacks == ATTACKS
    assert str(sol.policies[0]) == "always offline" and str(sol.policies[1]) == "online, never test"
    x, y = sol.sensor_strategy, sol.attacker_strategy
    assert x.sum() == pytest.approx(1) and y.sum() == pytest.approx(1) and x.min() >= 0 and y.min() >= 0
    # The sensor's mix holds every attack to the value; the attacker's mix forces it on every policy.
    assert np.all(x @ A <= sol.value + 1e-9) and np.all(A @ y >= sol.value - 1e-9)
    # Best responses and the Stackelberg (pure commitment) outcome.
    assert np.array_equal(sol.best_attack, A.argmax(axis=1))
    assert np.array_equal(sol.best_policy, A.argmin(axis=0))
    i = int(np.argmin(A.max(axis=1)))
    assert sol.stackelberg.policy == sol.policies[i] and sol.stackelberg.payoff == A[i].max()
    assert sol.stackelberg.payoff >= sol.value - 1e-12
    assert "value of the game" in sol.summary()
    # Every entry is the pair's payoff.
    pol, att = sol.policies[5], ATTACKS[3]
    assert A[5, 3] == pytest.approx(fa.game_payoff(paper, LAM, RATIO, pol, att, 1000).j, rel=1e-12)


def test_value_is_offline_or_the_strongest_attack(paper):
    # Each online policy's payoff averages J_att and J_off, so "never" is best against attacks
    # cheaper than offline and "offline" against the others: value = min(J_off, max J_att).
    for attacks in (ATTACKS, ATTACKS + [fa.PeriodicBlocking(2, 3)]):
        sol = fa.solve_game(paper, LAM, RATIO, 1000, [0.01], [1, 4], attacks)
        j_att = [fa.j_attack(paper, LAM, 2, attack=a) if a else fa.j_online(paper, LAM, 2) for a in attacks]
        assert sol.value == pytest.approx(min(sol.j_offline, max(j_att)), rel=1e-9)
        assert sol.stackelberg.payoff == pytest.approx(sol.value, rel=1e-9)


def test_a_game_without_strong_attacks_stays_online(paper):
    # With attacks weaker than the offline schedule's cost, the sensor never needs to go offline.
    sol = fa.solve_game(
        paper, LAM, RATIO, 1000, [0.01], [2], [None, fa.PeriodicBlocking(1, 5)], rules=["harmful"]
    )
    assert sol.value < fa.j_offline(paper, LAM, RATIO)
    assert sol.sensor_strategy[0] < 1e-9


def test_solve_game_bad_input(paper):
    args = (paper, LAM, RATIO, 1000)
    with pytest.raises(ValueError, match="alphas"):
        fa.solve_game(*args, [], [1], ATTACKS)
    with pytest.raises(ValueError, match="fallbacks"):
        fa.solve_game(*args, [0.01], [], ATTACKS)
    with pytest.raises(ValueError, match="attacks"):
        fa.solve_game(*args, [0.01], [1], [])
    with pytest.raises(ValueError, match="tests"):
        fa.solve_game(*args, [0.01], [1], ATTACKS, tests=[])
    with pytest.raises(ValueError, match="rules"):
        fa.solve_game(*args, [0.01], [1], ATTACKS, rules=[])
    with pytest.raises(ValueError, match="alphas"):
        fa.solve_game(*args, [0.0], [1], ATTACKS)
    with pytest.raises(ValueError, match="alphas"):
        fa.solve_game(*args, [float("nan")], [1], ATTACKS)
    with pytest.raises(ValueError, match="fallbacks"):
        fa.solve_game(*args, [0.01], [-1], ATTACKS)
    with pytest.raises(ValueError, match="n_steps"):
        fa.solve_game(paper, LAM, RATIO, 0, [0.01], [1], ATTACKS)
    with pytest.raises(ValueError, match="lam"):
        fa.solve_game(paper, float("nan"), RATIO, 1000, [0.01], [1], ATTACKS)
    with pytest.raises(ValueError, match="n_steps"):
        fa.game_payoff(paper, LAM, RATIO, fa.SensorPolicy("never"), None, 0)
    with pytest.raises(ValueError, match="horizon"):
        fa.simulate_game(paper, LAM, RATIO, fa.SensorPolicy("never"), None, 0, 10, 1)


# ---------------------------------------------------------------------------------------------
# The stealthy frontier.


def test_frontier_is_the_best_admissible_attack(paper):
    f = fa.stealthy_frontier(paper, LAM, 2, 1000, 0.01, "count", "random", 0.05, grid=21)
    d, j = f.candidates
    ok = d <= 0.05
    assert f.j == j[ok].max() and f.detection <= 0.05
    assert f.j == pytest.approx(fa.j_attack(paper, LAM, 2, attack=f.attack))
    # The frontier is increasing in both coordinates and dominates every candidate.
    fd, fj = f.frontier
    assert np.all(np.diff(fd) >= 0) and np.all(np.diff(fj) > 0)
    for di, ji in zip(d, j, strict=True):
        assert ji <= fj[fd <= di + 1e-15].max() + 1e-12


def test_frontier_periodic_family(paper):
    f = fa.stealthy_frontier(paper, LAM, 2, 1000, 0.01, "count", "periodic", 0.5, t_max=8)
    assert len(f.candidates[0]) == 8 * 9 // 2
    assert isinstance(f.attack, fa.PeriodicBlocking) and f.detection <= 0.5
    with pytest.raises(ValueError, match="family"):
        fa.stealthy_frontier(paper, LAM, 2, 1000, 0.01, "count", "masks", 0.5)
    with pytest.raises(ValueError, match="max_detection"):
        fa.stealthy_frontier(paper, LAM, 2, 1000, 0.01, "count", "random", 1.5)


# ---------------------------------------------------------------------------------------------
# The command line.

SMALL_GAME = """
[system]
A = 1.2
C = 0.7
Q = 0.8
R = 0.8
lam = 0.5

[energy]
ratio = "1/7"

[game]
n_steps = 1000
alphas = [0.01]
fallbacks = [2]
attacks = ["none", "1/5", "2/3", "inject:0.05", "match:0.2"]
t_max = 6
grid = 5
runs = 8
horizon = 20000
"""


def test_game_command(tmp_path, capsys):
    import json

    from fakeack.cli import main

    cfg = tmp_path / "game.toml"
    cfg.write_text(SMALL_GAME)
    assert main(["game", str(cfg), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["policies"][:2] == ["always offline", "online, never test"]
    assert len(doc["attacks"]) == 5 and len(doc["payoff"]) == len(doc["policies"])
    # With an attack costlier than the offline schedule in the list, the value is J_off.
    assert doc["value"] == pytest.approx(doc["j_offline"], rel=1e-9)
    assert doc["stackelberg"]["policy"] == "always offline"
    assert len(doc["frontiers"]) == 10 and doc["closed_loop"]  # 5 families for each test
    out = tmp_path / "out"
    assert main(["game", str(cfg), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "value of the game" in text and "Stackelberg" in text
    for stem in ("fig_frontiers", "fig_game_payoff"):
        assert (out / f"{stem}.png").stat().st_size > 1000 and (out / f"{stem}.svg").exists()
    assert (out / "game.json").exists()


def test_game_section_errors_name_the_key(tmp_path, capsys):
    from fakeack.cli import main

    for bad, key in (
        ("alphas = [1.5]", "alphas[0]"),
        ("fallbacks = [-1]", "fallbacks[0]"),
        ("attacks = []", "attacks"),
        ("attacks = ['9/5']", "attacks[0]"),
        ("n_steps = 0", "n_steps"),
        ("tests = ['shape']", "tests[0]"),
        ("windows = 3", "windows"),
    ):
        cfg = tmp_path / "bad.toml"
        cfg.write_text(SMALL_GAME.split("[game]")[0] + "[game]\n" + bad + "\n")
        assert main(["game", str(cfg)]) == 2
        assert f"[game] {key}" in capsys.readouterr().err


def test_example_config_shows_the_game_commented(capsys):
    from fakeack.cli import main

    assert main(["analyze", "--example"]) == 0
    text = capsys.readouterr().out
    assert "# [game]" in text and "# alphas = [0.01, 0.05]" in text


def test_ratio_estimator_and_its_standard_error():
    """The closed-loop alarm and fall-back rates are ratio estimators Σ num / Σ den over runs
    with the delta-method error sqrt(n s²) / Σ den, s² the sample variance (n - 1) of
    num - r den. By hand: num = (1, 2, 4), den = (1, 1, 2) give r = 7/4, residuals
    (-3/4, 1/4, 1/2), s² = 7/16, error sqrt(21/16) / 4; two runs (1, 3) over (1, 1) give r = 2
    and error 1; one run has an infinite error; no tested window at all gives NaN (kills each
    operator and bound of `_ratio_se`)."""
    from fakeack.game.simulate import _ratio_se

    r, se = _ratio_se(np.array([1.0, 2.0, 4.0]), np.array([1.0, 1.0, 2.0]))
    assert r == 1.75 and se == pytest.approx(math.sqrt(21 / 16) / 4, rel=1e-15)
    assert _ratio_se(np.array([1.0, 3.0]), np.array([1.0, 1.0])) == pytest.approx((2.0, 1.0), rel=1e-15)
    assert _ratio_se(np.array([3.0]), np.array([1.0])) == (3.0, math.inf)
    r, se = _ratio_se(np.array([0.0, 0.0]), np.array([0.0, 0.0]))
    assert math.isnan(r) and math.isnan(se)


def test_payoff_with_a_mixed_memory(paper):
    """The game at a budget whose schedule mixes memories (ratio 1/10: z0 = 2, μ = 5/11), so μ
    must reach every part: the attacked cost and energy, the alarm probability of the count test
    (any alarm, and harmful alarms with β̄ at that μ) and the renewal average
    J = (J_att + d K J_off) / (1 + d K), online share 1 / (1 + d K), energy mixed the same way;
    the offline policy and the untested online schedule at their ends (kills μ dropped anywhere,
    and the payoff's fields replaced or swapped)."""
    ratio, n, k = Fraction(1, 10), 1000, 2
    z0, mu = fa.design_online(0.5, ratio)
    assert (z0, mu) == (2, pytest.approx(5 / 11, rel=1e-15))
    attack = fa.RandomBlocking(0.3)
    j_att = fa.j_attack(paper, 0.5, z0, attack=attack, mu=mu)
    hp_att = fa.high_power_rate(0.5, z0, attack, mu)
    j_off = fa.j_offline(paper, 0.5, ratio)
    bb = fa.choose_schedule(paper, 0.5, ratio, 0, z0=z0, mu=mu).beta_bar
    for rule, beta_bar in [("any", None), ("harmful", bb)]:
        g = fa.game_payoff(paper, 0.5, ratio, fa.SensorPolicy("count", 0.01, k, rule=rule), attack, n)
        d = fa.detection_probability(0.5, z0, attack, n, 0.01, "count", mu=mu, beta_bar=beta_bar)
        assert g.detection == pytest.approx(d, rel=1e-12)
        assert (g.j_attack, g.j_offline) == pytest.approx((j_att, j_off), rel=1e-12)
        assert g.online == pytest.approx(1 / (1 + d * k), rel=1e-12)
        assert g.j == pytest.approx((j_att + d * k * j_off) / (1 + d * k), rel=1e-12)
        assert g.high_power == pytest.approx(g.online * hp_att + (1 - g.online) * 0.1, rel=1e-12)
    off = fa.game_payoff(paper, 0.5, ratio, fa.SensorPolicy("offline"), attack, n)
    assert (off.j, off.high_power, off.detection, off.online) == pytest.approx((j_off, 0.1, 0, 0))
    assert (off.j_attack, off.j_offline) == pytest.approx((j_att, j_off), rel=1e-12)
    never = fa.game_payoff(paper, 0.5, ratio, fa.SensorPolicy("never"), None, n)
    assert never.j == pytest.approx(fa.j_online(paper, 0.5, z0, mu), rel=1e-12)
    assert (never.high_power, never.detection, never.online) == pytest.approx((0.1, 0, 1), rel=1e-12)


def test_payoff_beside_an_infinite_offline_cost(paper):
    """At λ = 1/4 and a budget of 1/16384 the offline schedule's cost is beyond the double range
    (inf) while the online one is finite: a sensor that never falls back pays J_on, not
    0 · inf = NaN (kills the online-only branch of the renewal average removed or moved)."""
    ratio = Fraction(1, 16384)
    assert fa.j_offline(paper, 0.25, ratio) == math.inf
    z0, mu = fa.design_online(0.25, ratio)
    never = fa.game_payoff(paper, 0.25, ratio, fa.SensorPolicy("never"), None, 1000)
    assert never.j == pytest.approx(fa.j_online(paper, 0.25, z0, mu), rel=1e-12)


def test_payoff_with_a_given_threshold(paper):
    """A harmful-alarm sensor given β̄ explicitly uses it, not its own (kills the argument
    dropped)."""
    attack = fa.RandomBlocking(0.3)
    policy = fa.SensorPolicy("count", 0.01, 2, rule="harmful")
    own = fa.game_payoff(paper, 0.5, Fraction(1, 7), policy, attack, 1000)
    given = fa.game_payoff(paper, 0.5, Fraction(1, 7), policy, attack, 1000, beta_bar=0.05)
    d = fa.detection_probability(0.5, 2, attack, 1000, 0.01, "count", beta_bar=0.05)
    assert given.detection == pytest.approx(d, rel=1e-12) and given.detection != own.detection
