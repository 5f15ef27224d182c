"""The sensor's optimal power policy (fakeack.optimal): the LP against the online schedule's closed
form, the exact cost of a holding-time policy against an explicit chain written here from the
protocol, and the errors."""

from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from fakeack.optimal import HoldingTimePolicy, optimal_power_policy
from fakeack.optimal.power import _automaton_cost

SYSTEM = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
TWO = [(1.0, 0.5), (3.0, 1.0)]
THREE = [(1.0, 0.5), (2.0, 0.8), (3.0, 1.0)]
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
GE_LEVELS = [(1.0, [0.9, 0.2]), (3.0, [1.0, 1.0])]
# Ratios the online schedule meets at lam = 0.5 (at most (1-lam)/(2-lam) = 1/3), with its mu.
RANDOMISED = [Fraction(1, 10), Fraction(1, 5), Fraction(1, 4)]  # mu < 1
PURE = [Fraction(1, 7), Fraction(1, 3)]  # mu = 1


# --- the explicit chain over (tau, c), sharing no code with the package ------------------------


def gth(M):
    """Stationary law of a row-stochastic matrix by Grassmann-Taksar-Heyman elimination (no
    subtractions: tiny tail probabilities keep their relative accuracy)."""
    M = np.array(M, dtype=float)
    n = M.shape[0]
    for k in range(n - 1, 0, -1):
        s = M[k, :k].sum()
        M[:k, k] /= s
        M[:k, :k] += np.outer(M[:k, k], M[k, :k])
    x = np.zeros(n)
    x[0] = 1.0
    for k in range(1, n):
        x[k] = x[:k] @ M[:k, k]
    return x / x.sum()


def brute_force(system, p, energies, arrivals, P):
    """J and energy of a holding-time policy by the explicit chain over (tau_k, c_{k+1}).

    p: (T+1, K, L); arrivals (K, L); P (K, K). tau is kept exactly up to N, past the point where
    the tail's mass times its trace falls below 1e-16 (the last level loops on itself).
    """
    p, arrivals, P = np.asarray(p, float), np.asarray(arrivals, float), np.asarray(P, float)
    T, K = p.shape[0] - 1, P.shape[0]
    A, Q = np.atleast_2d(system.A), np.atleast_2d(system.Q)
    rho2 = max(abs(np.linalg.eigvals(A))) ** 2
    worst_loss = max(1 - p[T, c] @ arrivals[c] for c in range(K))
    decay = worst_loss * rho2
    if decay >= 1:
        return None  # the tail may carry an infinite cost: not truncated here
    N = T + 1 if decay == 0 else T + 1 + int(np.ceil(np.log(1e-16) / np.log(decay)))
    if N > 400:
        return None  # a heavy (or infinite) tail: not truncated here
    n = (N + 1) * K
    M = np.zeros((n, n))
    energy_of = np.zeros(n)
    for tau in range(N + 1):
        row = min(tau, T)
        for c in range(K):
            s = tau * K + c
            arrive = float(p[row, c] @ arrivals[c])
            energy_of[s] = float(p[row, c] @ energies)
            for c2 in range(K):
                M[s, c2] += arrive * P[c, c2]
                M[s, min(tau + 1, N) * K + c2] += (1 - arrive) * P[c, c2]
    pi = gth(M)
    X, traces = np.array(system.pbar), []
    for _ in range(N + 1):
        traces.append(np.trace(X))
        X = A @ X @ A.T + Q
    j = float(pi @ np.repeat(traces, K))
    return j, float(pi @ energy_of)


def as3(policy):
    return policy.p if policy.p.ndim == 3 else policy.p[:, None, :]


def threshold(z0, mu, levels=2):
    """The online schedule as a holding-time policy: level 0 below z0, level -1 from z0 + 1."""
    rows = [[1.0] + [0.0] * (levels - 1)] * z0
    rows.append([1.0 - mu] + [0.0] * (levels - 2) + [mu])
    rows.append([0.0] * (levels - 1) + [1.0])
    return rows


# --- (a) two levels on the paper's channel: the online schedule is optimal -------------------


@pytest.mark.parametrize("ratio", RANDOMISED + PURE)
def test_two_levels_match_the_online_schedule(ratio):
    budget = 1 + 2 * ratio
    res = optimal_power_policy(SYSTEM, 0.5, TWO, float(budget))
    j_on = fa.j_online(SYSTEM, 0.5, *fa.design_online(0.5, ratio))
    assert res.j == pytest.approx(j_on, rel=1e-10, abs=0)
    assert res.j_lp == pytest.approx(j_on, rel=1e-7, abs=0)
    assert res.energy_per_step == pytest.approx(float(budget), rel=1e-9)
    # a threshold in tau, randomising at one tau at most
    high = res.policy.p[:, 1]
    assert np.all(np.diff(high) >= 0)
    assert np.sum((high > 0) & (high < 1)) <= 1
    assert res.tail_bound == 0.0  # the high level always arrives: tau never passes the threshold + 1


def test_scaled_lp_at_tau_max_200():
    res = optimal_power_policy(SYSTEM, 0.5, TWO, 1 + 2 / 10, tau_max=200)
    j_on = fa.j_online(SYSTEM, 0.5, *fa.design_online(0.5, Fraction(1, 10)))
    assert res.tau_max == 200
    assert res.j == pytest.approx(j_on, rel=1e-10, abs=0)
    assert res.j_lp == pytest.approx(j_on, rel=1e-7, abs=0)


def test_slack_budget_always_transmits_at_high_power():
    res = optimal_power_policy(SYSTEM, 0.5, TWO, 10.0)
    assert res.j == pytest.approx(float(np.trace(SYSTEM.pbar)), rel=1e-12)  # tau = 0 always
    assert res.energy_per_step == pytest.approx(3.0)


def test_budget_at_the_cheapest_level_is_j_max():
    res = optimal_power_policy(SYSTEM, 0.5, TWO, 1.0)
    assert res.j == pytest.approx(fa.j_max(SYSTEM, 0.5), rel=1e-10)
    assert res.tail_bound <= 1e-12 * res.j


# --- (b) a third level ---------------------------------------------------------------------


@pytest.mark.parametrize("ratio", RANDOMISED)
def test_third_level_helps_where_the_online_schedule_randomises(ratio):
    assert fa.design_online(0.5, ratio).mu < 1
    two = optimal_power_policy(SYSTEM, 0.5, TWO, float(1 + 2 * ratio))
    three = optimal_power_policy(SYSTEM, 0.5, THREE, float(1 + 2 * ratio))
    assert three.j < two.j - 1e-3
    assert np.any(three.policy.p[:, 1] > 0)  # it uses the middle level
    j, energy = brute_force(SYSTEM, as3(three.policy), [1, 2, 3], [[0.5, 0.8, 1.0]], [[1.0]])
    assert three.j == pytest.approx(j, rel=1e-10)
    assert energy == pytest.approx(float(1 + 2 * ratio), rel=1e-9)


@pytest.mark.parametrize("ratio", PURE)
def test_third_level_does_not_help_where_the_online_schedule_is_pure(ratio):
    assert fa.design_online(0.5, ratio).mu == 1
    two = optimal_power_policy(SYSTEM, 0.5, TWO, float(1 + 2 * ratio))
    three = optimal_power_policy(SYSTEM, 0.5, THREE, float(1 + 2 * ratio))
    assert three.j == pytest.approx(two.j, rel=1e-10)


# --- (c) channel-state information on a bursty channel ------------------------------------


@pytest.mark.parametrize("ratio", [Fraction(1, 20), Fraction(1, 10), Fraction(1, 7)])
def test_csi_beats_the_flag_ack_design(ratio):
    design = fa.design_online(GE, ratio)
    j_flag = fa.j_online(SYSTEM, GE, *design)
    res = optimal_power_policy(SYSTEM, GE, GE_LEVELS, float(1 + 2 * ratio), csi=True)
    assert res.j < j_flag - 0.05
    assert res.policy.p.shape[1] == 2
    j, energy = brute_force(SYSTEM, res.policy.p, [1, 3], [[0.9, 1.0], [0.2, 1.0]], GE.P)
    assert res.j == pytest.approx(j, rel=1e-10)
    assert energy <= float(1 + 2 * ratio) * (1 + 1e-9)


def test_state_free_levels_on_a_markov_channel_reduce_to_the_paper():
    # Arrivals that do not depend on the state: the channel state is irrelevant, csi or not.
    bern = optimal_power_policy(SYSTEM, 0.5, TWO, 1 + 2 / 5 / 2)
    for csi in (False, True):
        res = optimal_power_policy(SYSTEM, GE, TWO, 1 + 2 / 5 / 2, csi=csi)
        assert res.j == pytest.approx(bern.j, rel=1e-10)


# --- (d) the exact cost of a holding-time policy ---------------------------------------------


@pytest.mark.parametrize("ratio", RANDOMISED + PURE)
def test_automaton_cost_of_the_online_schedule(ratio):
    z0, mu = fa.design_online(0.5, ratio)
    aut = HoldingTimePolicy(threshold(z0, mu), TWO).automaton()
    assert _automaton_cost(SYSTEM, aut.K0, aut.K1) == pytest.approx(
        fa.j_online(SYSTEM, 0.5, z0, mu), rel=1e-12
    )
    assert aut.energy_per_step == pytest.approx(float(1 + 2 * ratio), rel=1e-12)


def test_automaton_cost_of_the_online_schedule_on_a_bursty_channel():
    z0, mu = fa.design_online(GE, Fraction(1, 10))
    aut = HoldingTimePolicy(threshold(z0, mu), GE_LEVELS).automaton(GE)
    assert _automaton_cost(SYSTEM, aut.K0, aut.K1) == pytest.approx(
        fa.j_online(SYSTEM, GE, z0, mu), rel=1e-10
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_automaton_cost_of_random_policies_against_the_explicit_chain(seed):
    rng = np.random.default_rng(seed)
    p = rng.dirichlet(np.ones(3), size=(6, 2))  # tau_max = 5, depends on the state, with a tail
    levels = [(1.0, [0.7, 0.5]), (2.0, [0.85, 0.6]), (4.0, [0.95, 0.9])]
    ch = fa.MarkovChannel([[0.8, 0.2], [0.4, 0.6]], [0.5, 0.5], [1, 1])
    aut = HoldingTimePolicy(p, levels).automaton(ch)
    j, energy = brute_force(SYSTEM, p, [1, 2, 4], [[0.7, 0.85, 0.95], [0.5, 0.6, 0.9]], ch.P)
    assert _automaton_cost(SYSTEM, aut.K0, aut.K1) == pytest.approx(j, rel=1e-10)
    assert aut.energy_per_step == pytest.approx(energy, rel=1e-10)


def test_automaton_cost_two_dimensional_system():
    system = fa.LinearSystem([[1.1, 0.2], [0.0, 0.9]], [[1.0, 0.0]], np.eye(2) * 0.5, 0.3)
    p = [[1, 0], [0.3, 0.7], [0.1, 0.9]]
    aut = HoldingTimePolicy(p, [(1.0, 0.6), (2.0, 0.9)]).automaton()
    j, _ = brute_force(system, np.asarray(p)[:, None, :], [1, 2], [[0.6, 0.9]], [[1.0]])
    assert _automaton_cost(system, aut.K0, aut.K1) == pytest.approx(j, rel=1e-10)


def test_automaton_cost_diverges():
    # always the cheapest level at loss 0.75: 0.75 * 1.44 > 1 (Model note 5)
    aut = HoldingTimePolicy([[1.0, 0.0]], [(1.0, 0.25), (3.0, 1.0)]).automaton()
    assert _automaton_cost(SYSTEM, aut.K0, aut.K1) == float("inf")


# --- (f) the LP value and the exact cost agree within the tail bound --------------------------


@pytest.mark.parametrize(
    ("channel", "levels", "csi", "budget", "tau_max"),
    [
        (0.5, TWO, False, 1.0, 30),  # always the cheapest level: a tail past every truncation
        (0.5, [(1.0, 0.5), (2.0, 0.7)], False, 1.3, 12),  # no level always arrives
        (GE, [(1.0, [0.9, 0.2]), (3.0, [1.0, 0.7])], True, 1.2, 10),
    ],
)
def test_lp_and_exact_cost_agree_within_the_tail_bound(channel, levels, csi, budget, tau_max):
    res = optimal_power_policy(SYSTEM, channel, levels, budget, csi=csi, tau_max=tau_max)
    tol = 1e-9 * res.j
    assert 0 < res.tail_bound < np.inf
    assert res.j_lp - tol <= res.j <= res.j_lp + res.tail_bound + tol
    auto = optimal_power_policy(SYSTEM, channel, levels, budget, csi=csi)
    assert auto.tail_bound <= 1e-12 * auto.j
    assert auto.j_lp - tol <= auto.j <= auto.j_lp + auto.tail_bound + tol
    assert res.j_lp <= auto.j_lp + tol  # a coarser truncation is a looser relaxation


def test_tail_bound_is_tight_on_the_paper_channel():
    # always cheapest, tau_max = 30: the bound counts Pr[tau >= 30] where the loss is Pr[tau = 30]
    res = optimal_power_policy(SYSTEM, 0.5, TWO, 1.0, tau_max=30)
    gap = res.j - res.j_lp
    assert gap <= res.tail_bound <= 2.5 * gap


# --- (e) errors name the argument ------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"budget": 0.5}, "budget"),
        ({"information": "flag"}, "information"),
        ({"tau_max": 0}, "tau_max"),
        ({"levels": []}, "levels"),
        ({"levels": [(1.0, 1.5)]}, "levels"),
        ({"levels": [(-1.0, 0.5)]}, "levels"),
        ({"channel": GE, "levels": GE_LEVELS}, "csi"),
        ({"channel": GE, "levels": [(1.0, [0.5, 0.5, 0.5])]}, "levels"),
        ({"channel": "x"}, "channel"),
    ],
)
def test_errors_name_the_argument(kwargs, name):
    args = {"channel": 0.5, "levels": TWO, "budget": 1.5} | kwargs
    with pytest.raises((ValueError, TypeError), match=f"^{name}"):
        optimal_power_policy(SYSTEM, args.pop("channel"), args.pop("levels"), args.pop("budget"), **args)


@pytest.mark.parametrize(
    ("p", "levels", "name"),
    [
        ([[0.5, 0.4]], TWO, "p"),
        ([[1.2, -0.2]], TWO, "p"),
        ([[1.0, 0.0, 0.0]], TWO, "p"),
        ([1.0, 0.0], TWO, "p"),
        ([[1.0, 0.0]], [(1.0,)], "levels"),
        ([[1.0, 0.0]], "ab", "levels"),
    ],
)
def test_policy_errors_name_the_argument(p, levels, name):
    with pytest.raises((ValueError, TypeError), match=f"^{name}"):
        HoldingTimePolicy(p, levels)


def test_a_budget_that_affords_no_finite_cost_is_refused():
    # lam = 0.25 at the cheapest level only: (1 - lam) rho(A)^2 = 1.08 >= 1, J diverges
    levels = [(1.0, 0.25), (3.0, 1.0)]
    with pytest.raises(ValueError, match="^tau_max: .* infinite cost"):
        optimal_power_policy(SYSTEM, 0.25, levels, 1.0)
    res = optimal_power_policy(SYSTEM, 0.25, levels, 1.0, tau_max=50)
    assert res.j == np.inf and res.tail_bound == np.inf and np.isfinite(res.j_lp)


def test_state_dependent_policy_needs_its_channel():
    with pytest.raises(ValueError, match="^channel"):
        HoldingTimePolicy([[1.0, 0.0]], GE_LEVELS).automaton()


@pytest.mark.parametrize(
    ("channel", "levels", "arrivals", "csi"),
    [
        (0.5, THREE, [[0.5, 0.8, 1.0]], False),
        (
            GE,
            [(1.0, [0.9, 0.2]), (2.0, [0.95, 0.6]), (3.0, [1.0, 1.0])],
            [[0.9, 0.95, 1.0], [0.2, 0.6, 1.0]],
            True,
        ),
    ],
)
def test_no_random_policy_within_the_budget_beats_the_lp(channel, levels, arrivals, csi):
    # The LP is a relaxation: every policy meeting the budget costs at least j_lp.
    budget = 1.6
    res = optimal_power_policy(SYSTEM, channel, levels, budget, csi=csi)
    rng = np.random.default_rng(5)
    K = len(arrivals)
    P = np.ones((1, 1)) if K == 1 else GE.P
    feasible = 0
    for _ in range(150):
        p = rng.dirichlet(np.full(3, 0.3), size=(5, K))
        out = brute_force(SYSTEM, p, [1, 2, 3], arrivals, P)
        if out is None:
            continue
        j, energy = out
        if energy <= budget:
            feasible += 1
            assert j >= res.j_lp * (1 - 1e-9)
    assert feasible >= 10


def test_a_policy_that_never_arrives_in_its_tail():
    # the sensor never transmits: all mass ends at tau >= tau_max, and J diverges
    aut = HoldingTimePolicy([[1.0, 0.0], [1.0, 0.0]], [(0.0, 0.0), (3.0, 1.0)]).automaton()
    assert aut.stationary.tolist() == [0.0, 1.0]
    assert aut.energy_per_step == 0.0
    assert _automaton_cost(SYSTEM, aut.K0, aut.K1) == np.inf
    # from tau = 0 it always arrives, from tau >= 1 never: two closed classes, no stationary law
    with pytest.raises(ValueError, match="^p: .* closed class"):
        HoldingTimePolicy([[0.0, 1.0], [1.0, 0.0]], [(0.0, 0.0), (3.0, 1.0)]).automaton()
