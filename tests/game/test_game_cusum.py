"""The CUSUM policy in the closed loop (fa.simulate_game with SensorPolicy("cusum")): its alarm rate
per online step against a plain simulation of the protocol's rules, a statistic that never
alarms plays the never-tested policy, and the arguments checked (the policy's, the statistic's
increments, the compiled kernel's)."""

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER
from fakeack import _fakeack

LAM, RATIO = 0.5, Fraction(1, 7)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
SYSTEM = fa.LinearSystem(**PAPER)
INF = math.inf


@dataclass(frozen=True)
class Statistic:
    """A CUSUM statistic with fixed increments, whatever the channel and design."""

    flag: tuple[float, ...]
    quiet: tuple[float, ...]
    threshold: float

    def increments(self, channel, design):
        assert isinstance(design, fa.OnlineDesign)
        return np.array(self.flag), np.array(self.quiet)


# Gaps below z0 + 1 = 3 need forgery, so their +inf never fires here; a quiet step adds more as
# the gap grows, a flag-ACK after a short gap takes off.
STAT = Statistic((INF, INF, -0.5, -0.25, 0.05, 0.1), (0.0, 0.02, 0.1, 0.2, 0.3, 0.35), 3.0)
NEVER = Statistic((-INF,) * 3, (-INF,) * 3, 1.0)


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


def plain(stat, fallback, n, beta, runs, horizon, burn_in, seed):
    """The CUSUM game from the protocol's rules, all runs at once, with numpy's generator: per run
    (alarms, online steps) over the measured horizon. The paper's channel (high power always
    arrives, low power with probability λ), the detector's zero count z (reset by an arrival, 1
    after a lost step that followed a flag), a flag at z = z0 with probability μ and always
    beyond, each genuine flag-ACK blocked with probability β."""
    design = fa.design_online(LAM, RATIO)
    z0, mu = design.z0, design.mu
    pattern = np.asarray(fa.offline_schedule(RATIO)) == 1
    inc_flag, inc_quiet = np.array(stat.flag), np.array(stat.quiet)
    rng = np.random.default_rng(seed)
    z = np.zeros(runs, dtype=np.int64)
    flagged = np.zeros(runs, dtype=bool)
    acked = np.ones(runs, dtype=bool)  # the initial condition: high power at step 1
    last = np.zeros(runs, dtype=np.int64)  # the step of the last flag-ACK (the start counts)
    w = np.zeros(runs)
    dormant = np.zeros(runs, dtype=bool)
    left = np.zeros(runs, dtype=np.int64)  # offline steps left
    pos = np.zeros(runs, dtype=np.int64)  # offline pattern position
    alarms = np.zeros(runs, dtype=np.int64)
    online_steps = np.zeros(runs, dtype=np.int64)
    for k in range(1, burn_in + horizon + 1):
        online = left == 0
        high = np.where(online, acked, pattern[pos % pattern.size])
        arrived = high | (rng.random(runs) < LAM)
        z = np.where(arrived, 0, np.where(flagged, 1, z + 1))
        flag = (z > z0) | ((z == z0) & (rng.random(runs) < mu))
        ack = flag & (rng.random(runs) >= beta)
        y = np.minimum(k - last, inc_flag.size) - 1
        running = online & ~dormant
        stepped = np.maximum(w + np.where(ack, inc_flag[y], inc_quiet[y]), 0.0)
        alarm = running & (stepped >= stat.threshold)
        w = np.where(running & ~alarm, stepped, np.where(alarm, 0.0, w))
        dormant = (dormant & ~(online & ack)) | alarm
        pos = np.where(online, 0, pos + 1)
        left = np.where(alarm, fallback * n, np.where(online, left, left - 1))
        if k > burn_in:
            alarms += alarm
            online_steps += online
        last = np.where(ack, k, last)
        flagged, acked = flag, ack
    return alarms, online_steps


def ratio_se(num, den):
    r = num.sum() / den.sum()
    return r, math.sqrt(np.var(num - r * den, ddof=1) * len(num)) / den.sum()


@pytest.mark.parametrize("beta", [0.0, 0.3])
def test_alarm_rate_matches_a_plain_simulation(system, beta):
    """Alarms per online step without attack (the false-alarm rate) and under random blocking,
    within 4 standard errors of the plain simulation; fall-backs of 2 windows of 40 steps."""
    attack = None if beta == 0 else fa.RandomBlocking(beta)
    policy = fa.SensorPolicy("cusum", fallback=2, cusum=STAT)
    sim = fa.simulate_game(
        system, LAM, RATIO, policy, attack, horizon=4000, runs=400, seed=3, n_steps=40, burn_in=200
    )
    alarms, online = plain(STAT, 2, 40, beta, 1000, 4000, 200, seed=11)
    r, se = ratio_se(alarms.astype(float), online.astype(float))
    tol = 4 * math.hypot(se, sim.alarms_per_online_step_stderr)
    assert abs(sim.alarms_per_online_step - r) < tol, (sim.alarms_per_online_step, r, tol)
    assert 0.005 < r < 0.1
    # The per-run arrays and the summaries agree.
    assert sim.alarms_per_run.sum() / sim.online_steps_per_run.sum() == sim.alarms_per_online_step
    assert sim.online_steps_between_alarms == pytest.approx(1 / sim.alarms_per_online_step, rel=1e-12)
    assert sim.online == pytest.approx(sim.online_steps_per_run.mean() / 4000, rel=1e-12)
    # Every alarm falls back, and each is counted per step at which the statistic ran.
    assert sim.fallback_rate == sim.alarm_rate > sim.alarms_per_online_step
    assert 0.05 < 1 - sim.online < 0.9


def test_a_statistic_that_never_alarms_plays_the_never_tested_policy(system):
    """Every increment -inf: W stays 0. On a Markov channel both policies run on the same kernel
    and agree bit for bit; on the paper's channel, within 4 standard errors."""
    never, cusum = fa.SensorPolicy("never"), fa.SensorPolicy("cusum", fallback=3, cusum=NEVER)
    args = dict(horizon=3000, runs=64, seed=5, n_steps=100, burn_in=300)
    for attack in (None, fa.RandomBlocking(0.3)):
        a = fa.simulate_game(system, GE, RATIO, never, attack, **args)
        b = fa.simulate_game(system, GE, RATIO, cusum, attack, **args)
        assert (a.j, a.high_power, a.online) == (b.j, b.high_power, b.online)
        assert np.array_equal(a.delivered_per_run, b.delivered_per_run)
        assert b.alarms_per_online_step == 0.0 and b.online_steps_between_alarms == math.inf
    a = fa.simulate_game(system, LAM, RATIO, never, **args)
    b = fa.simulate_game(system, LAM, RATIO, cusum, **args)
    assert abs(a.j - b.j) < 4 * math.hypot(a.stderr, b.stderr)
    assert b.online == 1.0 and b.alarms_per_online_step == 0.0


def test_the_increments_come_from_the_played_channel_and_design(system):
    """increments() is called with the played channel and the online design of the game; on a
    Markov channel too, where every flag-ACK alarming (+inf) sends the sensor offline."""
    seen = []

    @dataclass(frozen=True)
    class Recorded(Statistic):
        def increments(self, channel, design):
            seen.append((channel, design))
            return super().increments(channel, design)

    stat = Recorded((INF,), (-INF,), 1.0)
    policy = fa.SensorPolicy("cusum", fallback=1, cusum=stat)
    sim = fa.simulate_game(system, GE, RATIO, policy, horizon=2000, runs=8, seed=1, n_steps=50, burn_in=0)
    (channel, design), *_ = seen
    assert channel == GE and design == fa.design_online(GE, RATIO)
    # Each alarm starts 50 offline steps; online, the sensor waits for one flag-ACK to restart
    # the statistic and alarms at the next.
    assert sim.alarms_per_run.min() > 0
    assert (2000 - sim.online_steps_per_run).max() <= 50 * sim.alarms_per_run.max()
    assert sim.alarm_rate == sim.fallback_rate


def test_policy_arguments():
    p = fa.SensorPolicy("cusum", fallback=2, cusum=STAT)
    assert (p.test, p.fallback, p.alpha, p.rule, p.support, p.cusum) == ("cusum", 2, None, "any", False, STAT)
    assert str(p) == "CUSUM (h=3), 2 windows offline after an alarm"
    assert p == fa.SensorPolicy("cusum", fallback=2, cusum=STAT) and not p.special
    with pytest.raises(TypeError, match="cusum"):
        fa.SensorPolicy("cusum", fallback=2)
    with pytest.raises(TypeError, match="^cusum"):
        fa.SensorPolicy("cusum", fallback=2, cusum=object())
    with pytest.raises(ValueError, match="^alpha"):
        fa.SensorPolicy("cusum", 0.01, 2, cusum=STAT)
    with pytest.raises(ValueError, match="^rule"):
        fa.SensorPolicy("cusum", fallback=2, rule="harmful", cusum=STAT)
    with pytest.raises(ValueError, match="^support"):
        fa.SensorPolicy("cusum", fallback=2, support=True, cusum=STAT)
    with pytest.raises(ValueError, match="^fallback"):
        fa.SensorPolicy("cusum", fallback=-1, cusum=STAT)
    with pytest.raises(ValueError, match="^cusum"):
        fa.SensorPolicy("count", 0.01, 2, cusum=STAT)


def test_the_payoff_needs_a_cusum_test(system):
    with pytest.raises(TypeError, match="^policy"):
        fa.game_payoff(system, LAM, RATIO, fa.SensorPolicy("cusum", fallback=1, cusum=STAT), None, 100)


@pytest.mark.parametrize(
    ("stat", "match"),
    [
        (Statistic((1.0, math.nan), (0.0, 0.0), 1.0), "^cusum: inc_flag"),
        (Statistic((1.0,), (math.nan,), 1.0), "^cusum: inc_quiet"),
        (Statistic((1.0, 2.0), (0.0,), 1.0), "^cusum: inc_flag and inc_quiet"),
        (Statistic((), (), 1.0), "^cusum: inc_flag"),
        (Statistic((1.0,), (1.0,), 0.0), "^cusum.threshold"),
        (Statistic((1.0,), (1.0,), INF), "^cusum.threshold"),
    ],
)
def test_bad_increments_name_the_argument(system, stat, match):
    policy = fa.SensorPolicy("cusum", fallback=1, cusum=stat)
    with pytest.raises(ValueError, match=match):
        fa.simulate_game(system, LAM, RATIO, policy, horizon=100, runs=1, seed=0, burn_in=0)


def test_the_kernel_checks_its_cusum_argument(system):
    design = fa.design_online(LAM, RATIO)
    sys = fa.model.system.compiled(system)

    def run(kind, cusum, min_gap=0):
        return _fakeack.simulate_game(
            sys, LAM, 1, 7, design.z0, design.mu, None, kind, -1, 0, [], [], 0.0, None, 1,
            10, 100, 0, 1, 0, lambda _: None, min_gap=min_gap, cusum=cusum,
        )  # fmt: skip

    good = ([1.0], [1.0], 2.0)
    out = run("cusum", good)
    assert out["alarms"][0] > 0 and 0 < out["online_steps"][0] < 100
    with pytest.raises(ValueError, match="^cusum"):
        run("cusum", None)
    with pytest.raises(ValueError, match="^cusum"):
        run("count", good)
    with pytest.raises(ValueError, match="^min_gap"):
        run("cusum", good, min_gap=3)
    with pytest.raises(ValueError, match="^threshold"):
        run("cusum", ([1.0], [1.0], -1.0))
    with pytest.raises(ValueError, match="^inc_quiet"):
        run("cusum", ([1.0], [1.0, 2.0], 1.0))


def test_increments_as_an_object_with_flag_and_quiet(system):
    """increments() may give an object with ``flag`` and ``quiet`` (fakeack.CusumIncrements) as
    well as a pair: the same game, bit for bit."""

    @dataclass(frozen=True)
    class Tables:
        flag: np.ndarray
        quiet: np.ndarray

    @dataclass(frozen=True)
    class AsObject(Statistic):
        def increments(self, channel, design):
            return Tables(*super().increments(channel, design))

    args = dict(horizon=2000, runs=16, seed=2, n_steps=40, burn_in=0)
    pair = fa.SensorPolicy("cusum", fallback=2, cusum=STAT)
    obj = fa.SensorPolicy("cusum", fallback=2, cusum=AsObject(STAT.flag, STAT.quiet, STAT.threshold))
    a = fa.simulate_game(system, LAM, RATIO, pair, **args)
    b = fa.simulate_game(system, LAM, RATIO, obj, **args)
    assert np.array_equal(a.alarms_per_run, b.alarms_per_run) and a.j == b.j
    assert a.alarms_per_run.sum() > 0


@pytest.mark.parametrize("attack", [None, fa.RandomBlocking(0.5), fa.FlagInjection(0.05, min_gap=3)], ids=str)
def test_the_closed_loop_alarms_at_the_run_length(attack):
    """After each fall-back the statistic restarts at W = 0 at the first delivered flag-ACK, the
    renewal start of fa.cusum_run_length: the steps it runs per alarm are its mean run length.
    (An attacker with a phase, e.g. periodic blocking, keeps its phase through the fall-back, so
    there the restart is not the attacker's start state.)"""
    test = fa.CusumTest(fa.RandomBlocking(0.5), 2.5)
    arl = fa.cusum_run_length(LAM, fa.OnlineDesign(2), test, attack)
    policy = fa.SensorPolicy("cusum", fallback=1, cusum=test)
    sim = fa.simulate_game(SYSTEM, LAM, RATIO, policy, attack, 400_000, 64, seed=7, n_steps=100)
    rate_se = sim.alarm_stderr
    assert abs(sim.alarm_rate - 1 / arl.mean) < 4 * rate_se + arl.error / arl.mean**2, (sim.alarm_rate, arl)


@pytest.mark.parametrize(
    ("attack", "fallback"), [(fa.RandomBlocking(0.2), 2), (fa.RandomBlocking(0.5), 4), (None, 8)], ids=str
)
def test_the_closed_loop_agrees_with_the_cusum_payoff(attack, fallback):
    """J and the online fraction of the renewal average against the closed loop (windows of 1000
    steps offline; the formula neglects the transients at each switch, as for the windowed tests)."""
    test = fa.CusumTest(fa.RandomBlocking(0.5), 4.0)
    policy = fa.SensorPolicy("cusum", fallback=fallback, cusum=test)
    p = fa.game_payoff(SYSTEM, LAM, RATIO, policy, attack, 1000)
    sim = fa.simulate_game(SYSTEM, LAM, RATIO, policy, attack, 2_000_000, 64, seed=11, n_steps=1000)
    assert abs(sim.online - p.online) < 0.01, (sim.online, p.online)
    assert abs(sim.j - p.j) < 4 * sim.stderr + 0.005 * p.j, (sim.j, sim.stderr, p.j)
