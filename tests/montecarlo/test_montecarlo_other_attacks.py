"""Monte Carlo of independent blocking and forged flag-ACKs against the exact costs and rates.

The references are the analytic renewal forms (``fa.j_attack``, ``fa.high_power_rate``,
``fa.flag_rates``), which share no code with the simulation and are themselves checked against
explicitly built chains in ``test_other_attacks.py``. Runs are few and long (horizon >> runs), so
the start-up transient (J_H - J = O(1/H), about 4e-5 here) and the initial high-power step
(at most 1/H of the rate) stay far below the standard errors.
"""

import math

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER_LAM, random_system

Z0 = 2
RUNS, H = 512, 100_000  # covariance mode: 5e7 steps per case, tens of milliseconds


def two_state():
    """The random 2-state system of these tests: unstable (ρ(A) = 1.15), yet J finite under
    every attack here (each blocked flag's run of losses shrinks the cost terms by 0.3 at most)."""
    return fa.LinearSystem(*random_system(np.random.default_rng(0), 2))


BLOCKS = {
    "none": None,
    "random": fa.RandomBlocking(0.3),
    "periodic": fa.PeriodicBlocking(1, 3),
    "mask": fa.MaskBlocking([1, 0, 1, 1, 0]),
}

# (attack, mu): independent blocking at two budgets and both memory mixes; forging at two rates,
# alone and beside each kind of blocking.
CASES = [(fa.RandomBlocking(beta), mu) for beta in (0.2, 0.7) for mu in (1.0, 0.4)] + [
    (fa.FlagInjection(gamma, block), 1.0) for gamma in (0.05, 0.3) for block in BLOCKS.values()
]
SYSTEMS = {"paper": lambda: fa.LinearSystem(1.2, 0.7, 0.8, 0.8), "two-state": two_state}


def rate_stderr(res):
    """Standard error of the rate of flag-ACKs reaching the sensor, from the per-run counts."""
    per_run = res.delivered_per_run / res.horizon
    return float(per_run.std(ddof=1) / math.sqrt(len(per_run)))


def check_against_exact(system, lam, attack, mu, res):
    j = fa.j_attack(system, lam, Z0, mu=mu, attack=attack)
    assert math.isfinite(res.stderr) and res.stderr > 0
    assert abs(res.j - j) <= 4 * res.stderr, (res.j, j, (res.j - j) / res.stderr)
    # High-power steps: the first one and one after each flag that reached the sensor, genuine
    # or forged; per-run counts give its standard error.
    rate = fa.high_power_rate(lam, Z0, attack, mu)
    se = rate_stderr(res)
    assert abs(res.high_power_rate - rate) <= 4 * se, (res.high_power_rate, rate, se)
    reached = res.flags_sent - res.flags_blocked + res.flags_forged
    assert res.delivered_per_run.sum() == round(reached * res.runs * res.horizon)
    exact = fa.flag_rates(lam, Z0, attack, mu)
    assert abs(res.flags_forged - exact.forged) <= 4 * se + 1e-12
    if isinstance(attack, fa.RandomBlocking):
        assert res.flags_forged == 0
        blocked = res.flags_blocked / res.flags_sent  # a binomial fraction of the flags sent
        n = res.flags_sent * res.runs * res.horizon
        assert abs(blocked - attack.beta) <= 4 * math.sqrt(attack.beta * (1 - attack.beta) / n)


@pytest.mark.parametrize("system_name", SYSTEMS)
@pytest.mark.parametrize(("attack", "mu"), CASES, ids=lambda x: getattr(x, "label", str(x)))
def test_covariance_mode_matches_the_exact_cost_and_rate(system_name, attack, mu):
    system = SYSTEMS[system_name]()
    seed = 100 + 20 * list(SYSTEMS).index(system_name) + CASES.index((attack, mu))
    res = fa.simulate(
        system,
        PAPER_LAM,
        fa.OnlineSchedule(Z0, mu),
        H,
        RUNS,
        seed=seed,
        attack=attack,
        progress=False,
        record_runs=True,
    )
    check_against_exact(system, PAPER_LAM, attack, mu, res)


@pytest.mark.parametrize(
    ("attack", "mu", "seed"),
    [
        (fa.RandomBlocking(0.7), 0.4, 201),
        (fa.FlagInjection(0.3, fa.RandomBlocking(0.3)), 1.0, 202),
        (fa.FlagInjection(0.05, fa.MaskBlocking([1, 0, 1, 1, 0])), 1.0, 203),
    ],
)
def test_state_mode_matches_the_exact_cost_and_rate(attack, mu, seed):
    """Real Gaussian errors (their mean square is Tr E[P_k]) on the lane kernels."""
    system = two_state()
    res = fa.simulate(
        system,
        PAPER_LAM,
        fa.OnlineSchedule(Z0, mu),
        20_000,
        256,
        seed=seed,
        attack=attack,
        mode="state",
        progress=False,
        record_runs=True,
    )
    check_against_exact(system, PAPER_LAM, attack, mu, res)


def test_lane_kernels_in_covariance_mode(paper):
    """A mask with five runs of ones is beyond the bit-sliced kernel: the lane kernels run it."""
    attack = fa.FlagInjection(0.05, fa.MaskBlocking([1, 0] * 5))
    res = fa.simulate(
        paper,
        PAPER_LAM,
        fa.OnlineSchedule(Z0),
        50_000,
        256,
        seed=204,
        attack=attack,
        progress=False,
        record_runs=True,
    )
    check_against_exact(paper, PAPER_LAM, attack, 1.0, res)


def _fields(res):
    return (
        res.j,
        res.stderr,
        res.high_power_rate,
        res.flags_sent,
        res.flags_blocked,
        res.flags_forged,
        res.mean_trace.tobytes(),
        res.j_k.tobytes(),
        res.delivered_per_run.tobytes(),
    )


@pytest.mark.parametrize("mode", ["covariance", "state"])
@pytest.mark.parametrize(
    "attack",
    [
        fa.RandomBlocking(0.4),
        fa.FlagInjection(0.2),
        fa.FlagInjection(0.1, fa.RandomBlocking(0.5)),
        fa.FlagInjection(0.1, fa.PeriodicBlocking(1, 3)),
        fa.FlagInjection(0.1, fa.MaskBlocking([1, 0, 1, 1, 0])),
    ],
    ids=lambda a: a.label,
)
def test_type_a_and_type_b_are_identical(paper, mode, attack):
    """Type A flips ACK bits (1 to 0 to block, 0 to 1 to forge), Type B drops and forges packets:
    different code paths, the same runs draw for draw."""
    a, b = (
        fa.simulate(
            paper,
            0.4,
            fa.OnlineSchedule(Z0, 0.6),
            400,
            700,
            seed=205,
            attack=attack,
            mode=mode,
            protocol=p,
            progress=False,
            record_runs=True,
        )
        for p in "AB"
    )
    assert _fields(a) == _fields(b)
    assert b.flags_blocked > 0 or isinstance(attack, fa.FlagInjection) and attack.block is None
    assert (b.flags_forged > 0) == isinstance(attack, fa.FlagInjection)


def test_rate_matching_hides_the_flag_rate_but_not_the_cost(paper):
    """The injection beside blocking 20% of the flags keeps the rate of flag-ACKs reaching the
    sensor at the attack-free rate, while J stays above J_on."""
    attack = fa.rate_matching_attack(PAPER_LAM, Z0, 0.2)
    res = fa.simulate(
        paper,
        PAPER_LAM,
        fa.OnlineSchedule(Z0),
        H,
        RUNS,
        seed=206,
        attack=attack,
        progress=False,
        record_runs=True,
    )
    reached = res.flags_sent - res.flags_blocked + res.flags_forged
    free = fa.high_power_rate(PAPER_LAM, Z0)  # 1/7: every flag delivered
    se = rate_stderr(res)
    assert abs(reached - free) <= 4 * se, (reached, free, se)
    # Blocking alone would show: 2.5e-2 fewer flags per step, hundreds of standard errors.
    assert free - fa.high_power_rate(PAPER_LAM, Z0, fa.RandomBlocking(0.2)) > 100 * se
    j_on = fa.j_online(paper, PAPER_LAM, Z0)
    assert (res.j - j_on) / res.stderr > 4
    assert abs(res.j - fa.j_attack(paper, PAPER_LAM, Z0, attack=attack)) <= 4 * res.stderr


def test_detection_counts_forged_flags_as_delivered():
    """The flag-count test sees blocking, but not the rate-matching injection beside it; the support
    check sees the injection's flag-ACKs that come too soon after the previous one."""
    blocked = fa.detection_rates(PAPER_LAM, Z0, fa.RandomBlocking(0.2), runs=500, seed=207)
    matching = fa.rate_matching_attack(PAPER_LAM, Z0, 0.2)
    hidden = fa.detection_rates(PAPER_LAM, Z0, matching, runs=500, seed=207, support=False)
    seen = fa.detection_rates(PAPER_LAM, Z0, matching, runs=500, seed=207)
    assert blocked.detection > 0.6
    assert hidden.detection < 0.06
    assert seen.detection > 0.99 and seen.false_alarm == hidden.false_alarm
