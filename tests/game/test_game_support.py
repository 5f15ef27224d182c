"""The support check in the closed loop (SensorPolicy(..., support=True), the default): an alarm at
any gap between flag-ACKs reaching the sensor shorter than the attack-free minimum. Invisible
without forging (blocking never shortens a gap), its alarm rate against the exact short-gap
probability of the flag process on the paper's channel and on a Gilbert-Elliott channel, and the
compiled kernel's argument checked."""

import math

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER
from fakeack import _fakeack
from fakeack.detection.rates import paper_min_gap

LAM, RATIO = 0.5, "1/7"
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


def test_the_policy_field():
    p = fa.SensorPolicy("count", 0.01, 2)
    assert p.support and str(p) == "count test at alpha=0.01, 2 windows offline after any alarm"
    q = fa.SensorPolicy("count", 0.01, 2, support=False)
    assert not q.support and p != q
    assert str(q) == "count test at alpha=0.01, 2 windows offline after any alarm, without the support check"
    assert not fa.SensorPolicy("never").support and not fa.SensorPolicy("offline").support
    with pytest.raises(ValueError, match="takes no alpha, fallback or support"):
        fa.SensorPolicy("never", support=True)
    with pytest.raises(TypeError, match="support must be True or False"):
        fa.SensorPolicy("count", 0.01, 2, support="no")


@pytest.mark.parametrize(("z0", "mu"), [(1, 1.0), (2, 1.0), (3, 0.5), (2, 0.0), (4, 0.3)])
def test_the_paper_channels_minimum_gap_in_closed_form(z0, mu):
    design = fa.OnlineDesign(z0, mu)
    assert paper_min_gap(design) == fa.flag_process(0.3, design).min_gap


@pytest.mark.parametrize(
    "attack",
    [
        None,
        fa.PeriodicBlocking(1, 5),
        fa.PeriodicBlocking(3, 4),
        fa.MaskBlocking([1, 0, 1, 1, 0]),
        fa.RandomBlocking(0.3),
    ],
    ids=str,
)
@pytest.mark.parametrize("test", ["count", "interval"])
def test_without_short_gaps_the_check_changes_nothing(system, attack, test):
    """Blocking only removes flag-ACKs, and a gap from a delivered one to the next genuine flag is
    at least z0 + 1 (the delivery makes the next packet arrive and restarts the memory): no gap
    becomes shorter, so the runs are the same bit for bit, fall-backs included."""
    on, off = fa.SensorPolicy(test, 0.05, 2), fa.SensorPolicy(test, 0.05, 2, support=False)
    a = fa.simulate_game(system, LAM, RATIO, on, attack, 20_000, 16, seed=5, burn_in=2000)
    b = fa.simulate_game(system, LAM, RATIO, off, attack, 20_000, 16, seed=5, burn_in=2000)
    assert _same(a, b) and a.fallback_rate > 0  # offline stretches, and returns from them
    assert fa.detection_probability(LAM, 2, attack, 1000, 0.01, test="support") == 0.0


def test_without_short_gaps_the_check_changes_nothing_on_a_markov_channel(system):
    pol = fa.SensorPolicy("count", 0.05, 1)
    for attack in (None, fa.RandomBlocking(0.2)):
        a = fa.simulate_game(system, GE, RATIO, pol, attack, 20_000, 16, seed=6)
        b = fa.simulate_game(
            system, GE, RATIO, fa.SensorPolicy("count", 0.05, 1, support=False), attack, 20_000, 16, seed=6
        )
        assert _same(a, b)


def _same(a, b):
    """The two simulations are the same, bit for bit."""
    fields = ("j", "high_power", "online", "alarm_rate", "fallback_rate")
    same = all(getattr(a, f) == getattr(b, f) for f in fields)
    return same and np.array_equal(a.delivered_per_run, b.delivered_per_run)


@pytest.mark.parametrize(("gamma", "n"), [(0.0005, 1000), (0.002, 200)])
@pytest.mark.parametrize("channel", [LAM, GE], ids=["paper", "gilbert-elliott"])
def test_the_closed_loops_support_alarms_are_the_short_gap_probability(system, channel, gamma, n):
    """A count test at a level so small it never alarms, no fall-back: the alarms are the support
    check's, in stationary windows after a burn-in."""
    pol = fa.SensorPolicy("count", 1e-12, 0)
    attack = fa.FlagInjection(gamma)
    g = fa.simulate_game(system, channel, RATIO, pol, attack, 20 * n, 512, seed=9, n_steps=n, burn_in=3 * n)
    design = fa.design_online(channel, RATIO)
    process = fa.flag_process(channel, design, attack)
    gap = fa.flag_process(channel, design).min_gap
    assert gap == design.z0 + 1  # high-power packets always arrive on both
    p = process.short_gap_probability(n, gap)
    assert 0.05 < p < 0.95
    assert abs(g.alarm_rate - p) < 4 * g.alarm_stderr, (g.alarm_rate, g.alarm_stderr, p)
    assert g.fallback_rate == g.alarm_rate  # rule "any", fall-back of 0 windows


def test_support_alarms_trigger_the_fall_back_as_any_alarm(system):
    """Against a forger of every quiet step every window alarms: with 2 offline windows a third of
    the windows are online. Under the harmful rule none triggers (the count is far above what an
    attack-free window has, so the estimated budget is negative)."""
    attack = fa.FlagInjection(0.5)
    n = 100
    g = fa.simulate_game(
        system, LAM, RATIO, fa.SensorPolicy("count", 1e-12, 2), attack, 30 * n, 8, seed=1, n_steps=n
    )
    assert g.alarm_rate == 1.0 and g.online == pytest.approx(1 / 3, abs=1e-12)
    h = fa.simulate_game(
        system,
        LAM,
        RATIO,
        fa.SensorPolicy("count", 1e-12, 2, "harmful"),
        attack,
        30 * n,
        8,
        seed=1,
        n_steps=n,
    )
    assert h.alarm_rate == 1.0 and h.fallback_rate == 0.0 and h.online == 1.0


def _kernel(min_gap, kind="count", **kw):
    """Windows of 10 steps, one offline window after any alarm, and a flag-ACK on every step (a
    forgery where the detector sends none)."""
    args = dict(lo=-1, hi=10**6, window=10, horizon=100, runs=4)
    args.update(kw)
    return _fakeack.simulate_game(
        fa.LinearSystem(**PAPER)._core,
        LAM,
        1,
        7,
        2,
        1.0,
        _fakeack.Attack.injection(1.0, None),
        kind,
        args["lo"],
        args["hi"],
        [],
        [],
        0.0,
        None,
        1,
        args["window"],
        args["horizon"],
        0,
        args["runs"],
        1,
        lambda done: None,
        min_gap=min_gap,
    )


def test_the_kernels_argument():
    assert _kernel(0)["alarms"].sum() == 0
    # Every gap is short of 3: every online window alarms (its first gap after an offline window
    # is not checked, the nine others are), so windows alternate online and offline.
    out = _kernel(3)
    assert np.array_equal(out["alarms"], out["tested"]) and out["tested"].sum() == 4 * 5
    for bad, match in [(-1, "min_gap: must be non-negative"), (2**42 + 1, "min_gap: must be at most")]:
        with pytest.raises(ValueError, match=match):
            _kernel(bad)
    with pytest.raises(ValueError, match='min_gap: the policy "online" tests nothing'):
        _kernel(3, kind="online")
    assert _kernel(1, kind="offline")["tested"].sum() == 0  # 1 is no check
    assert math.isfinite(_kernel(10**6)["cost"].mean())


@pytest.mark.parametrize(
    ("policy", "attack"),
    [
        (fa.SensorPolicy("count", 0.01, 2), fa.FlagInjection(0.0004)),
        (fa.SensorPolicy("count", 0.01, 2, "harmful"), fa.FlagInjection(0.002, fa.RandomBlocking(0.3))),
        (fa.SensorPolicy("count", 0.05, 1, alternative="less"), fa.FlagInjection(0.01, min_gap=3)),
        (fa.SensorPolicy("interval", 0.01, 2), fa.FlagInjection(0.2)),
    ],
    ids=str,
)
def test_the_payoffs_detection_is_detection_probabilitys_with_the_check(system, policy, attack):
    """game_payoff's d is the window's alarm probability of detection_probability, the support
    check included (the closed loop checks both in test_game.py)."""
    n, beta_bar = (1000 if policy.test == "interval" else 200), 0.2
    p = fa.game_payoff(system, LAM, RATIO, policy, attack, n, beta_bar=beta_bar)
    d = fa.detection_probability(
        LAM,
        2,
        attack,
        n,
        policy.alpha,
        policy.test,
        policy.alternative,
        beta_bar=beta_bar if policy.rule == "harmful" else None,
    )
    assert p.detection == pytest.approx(d, abs=1e-12) and p.detection > 0.02
    alone = fa.SensorPolicy(
        policy.test, policy.alpha, policy.fallback, policy.rule, policy.alternative, False
    )
    alone = fa.game_payoff(system, LAM, RATIO, alone, attack, n, beta_bar=beta_bar)
    assert alone.detection <= p.detection  # the check only adds alarms


def test_the_payoffs_interval_test_with_the_check_is_detection_probabilitys(system):
    policy = fa.SensorPolicy("interval", 0.01, 2, "harmful")
    for attack in (fa.FlagInjection(0.0004), fa.FlagInjection(0.001, fa.RandomBlocking(0.2))):
        p = fa.game_payoff(system, LAM, RATIO, policy, attack, 1000, beta_bar=0.1)
        d = fa.detection_probability(LAM, 2, attack, 1000, 0.01, "interval", beta_bar=0.1)
        assert p.detection == pytest.approx(d, abs=1e-12) and d > 0.005


@pytest.mark.parametrize("test", ["count", "interval"])
def test_mimicry_is_seen_at_the_false_alarm_rate_and_costs_the_attack_free_energy(system, test):
    """Mimicry delivers the attack-free flag process: d is the test's false-alarm rate and the
    sensor is at high power 1/7 of the time, while J exceeds the offline schedule's."""
    policy = fa.SensorPolicy(test, 0.01, 2)
    p = fa.game_payoff(system, LAM, RATIO, policy, fa.MimicryAttack(), 1000)
    assert p.detection == pytest.approx(fa.detection_probability(LAM, 2, None, 1000, 0.01, test), abs=1e-12)
    assert p.high_power == pytest.approx(p.online / 7 + (1 - p.online) / 7, abs=1e-12)
    assert p.j_attack == pytest.approx(fa.j_attack(system, LAM, 2, attack=fa.MimicryAttack()), rel=1e-12)
    assert p.j_attack > p.j_offline
    sol = fa.solve_game(system, LAM, RATIO, 1000, 0.01, 2, [None, fa.MimicryAttack()], [test], ["any"])
    assert sol.best_attack[sol.policies.index(policy)] == 1  # unseen and the most harmful


def test_the_matrix_games_policies_run_the_check_unless_told_not_to(system):
    naive = fa.FlagInjection(0.05)
    sol = fa.solve_game(system, LAM, RATIO, 1000, 0.01, 2, [naive], ["count"], ["any"])
    assert all(p.support for p in sol.policies if not p.special)
    assert sol.detection[2:, 0].min() > 1 - 1e-6  # the naive forger is seen in every window
    off = fa.solve_game(system, LAM, RATIO, 1000, 0.01, 2, [naive], ["count"], ["any"], support=False)
    assert not any(p.support for p in off.policies) and off.detection[2:, 0].max() < 0.999
    with pytest.raises(TypeError, match="support must be True or False"):
        fa.solve_game(system, LAM, RATIO, 1000, 0.01, 2, [naive], ["count"], support=1)
    careful = fa.FlagInjection(0.01, min_gap=3)
    p = fa.game_payoff(system, LAM, RATIO, fa.SensorPolicy("interval", 0.01, 2), careful, 1000)
    assert p.detection == pytest.approx(
        fa.detection_probability(LAM, 2, careful, 1000, 0.01, "interval"), abs=1e-14
    )


@pytest.mark.parametrize("beta_bar", [0.1, 0.3])
def test_the_closed_loop_confirms_the_harmful_rule_with_the_check(system, beta_bar):
    """With no fall-back every window is tested, so the rate of triggering alarms is the window's
    d: the count test with the support check under the harmful rule (a short gap triggers only
    with N <= harm), exact in detection_probability, against 100,000 closed-loop windows."""
    attack = fa.FlagInjection(0.002, fa.RandomBlocking(0.3))
    d = fa.detection_probability(LAM, 2, attack, 200, 0.01, beta_bar=beta_bar)
    any_alarm = fa.detection_probability(LAM, 2, attack, 200, 0.01)
    policy = fa.SensorPolicy("count", 0.01, 0, "harmful")
    g = fa.simulate_game(
        system, LAM, RATIO, policy, attack, 200 * 100, 1000, seed=5, n_steps=200, beta_bar=beta_bar
    )
    assert 0.1 < d < any_alarm - 0.005
    assert abs(g.fallback_rate - d) < 4 * g.fallback_stderr, (g.fallback_rate, g.fallback_stderr, d)
