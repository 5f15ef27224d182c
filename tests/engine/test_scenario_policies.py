"""fa.Scenario with a sensor policy (HoldingTimePolicy) as its schedule or an attacker that reads the
state (StatePolicy) as its attack: the same J as the optimal room's own evaluation and as
independent derivations (the online schedule's rule written as a holding-time policy, a constant
policy as an offline schedule, a constant blocker as fa.RandomBlocking, a constant forger as
fa.FlagInjection, an explicit tau-law for the cost curve); the rates that need the protocol either
work or refuse naming the argument."""

import numpy as np
import pytest
import scipy.sparse as sp
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack.engine import ScenarioChain

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
PAPER_LEVELS = [(1.0, 0.5), (3.0, 1.0)]  # (delta, lam) and (Delta, 1) on the paper's channel


def traces(n, a2=1.44, q=0.8):
    """Tr h^t(Pbar), t = 0..n, by the scalar recursion tr_{t+1} = A^2 tr_t + Q."""
    tr = [float(S.pbar[0, 0])]
    for _ in range(n):
        tr.append(a2 * tr[-1] + q)
    return np.array(tr)


def online_rule(z0, mu, tau_max=None):
    """The online schedule on the paper's channel as a rule on tau_{k-1}: low below z0, high with
    probability mu at z0 (the detector's count reaches z0), surely beyond (it reaches z0 + 1)."""
    T = tau_max or z0 + 1
    p = np.zeros((T + 1, 2))
    p[:z0, 0] = 1.0
    p[z0] = (1.0 - mu, mu)
    p[z0 + 1 :, 1] = 1.0
    return fa.HoldingTimePolicy(p, PAPER_LEVELS)


@pytest.mark.parametrize("z0, mu", [(2, 1.0), (2, 5 / 11), (1, 0.6), (3, 0.25)])
def test_holding_time_policy_with_the_online_rule_is_the_online_schedule(z0, mu):
    # On the paper's channel a high-power packet always arrives, so a flag-ACK comes exactly when
    # tau reaches z0 (with probability mu) or z0 + 1: the online sensor is this holding-time rule.
    sc = fa.Scenario(S, 0.5, online_rule(z0, mu, tau_max=6))
    online = fa.Scenario(S, 0.5, fa.OnlineDesign(z0, mu))
    assert_allclose(sc.cost(), online.cost(), rtol=1e-12)
    assert_allclose(sc.cost(), fa.j_online(S, 0.5, z0, mu), rtol=1e-12)
    assert_allclose(sc.energy_per_step(), online.energy_per_step(3.0, 1.0), rtol=1e-12)
    assert_allclose(sc.holding_time_law(4), online.holding_time_law(4), atol=1e-14)


def test_constant_holding_time_policies_are_offline_schedules():
    always_high = fa.HoldingTimePolicy([[0.0, 1.0]], PAPER_LEVELS)
    assert_allclose(
        fa.Scenario(S, 0.5, always_high).cost(),
        fa.Scenario(S, 0.5, fa.OfflineSchedule(pattern="1")).cost(),
        rtol=1e-12,
    )
    # Per-state levels and a per-state policy (csi): always the level that arrives like the
    # channel's low power is the always-low offline sensor on the Gilbert-Elliott channel.
    levels = [(1.0, GE.low.tolist()), (3.0, GE.high.tolist())]
    p = np.zeros((3, 2, 2))
    p[..., 0] = 1.0
    sc = fa.Scenario(S, GE, fa.HoldingTimePolicy(p, levels))
    assert_allclose(sc.cost(), fa.Scenario(S, GE, fa.OfflineSchedule(pattern="0")).cost(), rtol=1e-12)
    assert_allclose(sc.energy_per_step(), 1.0, rtol=1e-14)


def test_cost_curve_starts_from_tau_zero():
    # Always low on lam = 0.5: P(tau_k = j) = lam (1 - lam)^j for j < k and (1 - lam)^k at j = k.
    lam, n = 0.5, 12
    tr = traces(n)
    want = [
        sum(lam * (1 - lam) ** j * tr[j] for j in range(k)) + (1 - lam) ** k * tr[k] for k in range(1, n + 1)
    ]
    sc = fa.Scenario(S, lam, fa.HoldingTimePolicy([[1.0, 0.0]], PAPER_LEVELS))
    assert_allclose(sc.cost_curve(n).trace, want, rtol=1e-12)
    assert sc.automaton().labels == ["tau>=0 c=0"]  # tau_max = 0: one row for every tau


@pytest.mark.parametrize("channel, csi", [(0.5, False), (GE, True)])
def test_the_optimal_power_policy_evaluates_the_same(channel, csi):
    levels = PAPER_LEVELS if not csi else [(1.0, [0.9, 0.2]), (3.0, [1.0, 1.0])]
    res = fa.optimal_power_policy(S, channel, levels, 1.2, csi=csi, tau_max=64)
    sc = fa.Scenario(S, channel, res.policy)
    assert_allclose(sc.cost(), res.j, rtol=1e-10)
    assert_allclose(sc.energy_per_step(), res.energy_per_step, rtol=1e-10)


def test_holding_time_policy_refuses_what_it_does_not_have():
    sc = fa.Scenario(S, 0.5, online_rule(2, 1.0))
    with pytest.raises(ValueError, match=names("schedule")):
        sc.high_power_rate()
    with pytest.raises(ValueError, match=names("schedule")):
        sc.flag_rates()
    with pytest.raises(TypeError, match=names("Delta")):
        sc.energy_per_step(3.0, 1.0)
    with pytest.raises(ValueError, match=names("attack")):
        fa.Scenario(S, 0.5, online_rule(2, 1.0), fa.RandomBlocking(0.5))
    with pytest.raises(TypeError, match=names("attack")):
        fa.Scenario(S, 0.5, online_rule(2, 1.0), fa.attacks.RandomJamming(0.1))
    with pytest.raises(TypeError, match=names("Delta")):
        fa.Scenario(S, 0.5, fa.OnlineDesign(2)).energy_per_step()
    assert "high-power rate" not in fa.Scenario(S, 0.5, online_rule(2, 1.0))._repr_html_()


@pytest.mark.parametrize("channel, design", [(0.5, fa.OnlineDesign(2)), (GE, fa.OnlineDesign(2, 0.6))])
def test_state_policy_that_never_blocks_is_the_attack_free_scenario(channel, design):
    sc = fa.Scenario(S, channel, design, fa.StatePolicy([0.0]))
    free = fa.Scenario(S, channel, design)
    assert_allclose(sc.cost(), free.cost(), rtol=1e-12)
    assert_allclose(sc.cost_curve(60).trace, free.cost_curve(60).trace, rtol=1e-12)
    assert_allclose(sc.high_power_rate(), free.high_power_rate(), rtol=1e-12)
    assert_allclose(tuple(sc.flag_rates()), tuple(free.flag_rates()), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("channel, design", [(0.5, fa.OnlineDesign(2)), (GE, fa.OnlineDesign(3, 0.4))])
def test_constant_state_policies_are_the_built_in_attacks(channel, design):
    for pol, attack in [
        (fa.StatePolicy([0.3]), fa.RandomBlocking(0.3)),
        (fa.StatePolicy([0.5], forge=[0.05]), fa.FlagInjection(0.05, fa.RandomBlocking(0.5))),
    ]:
        sc, ref = fa.Scenario(S, channel, design, pol), fa.Scenario(S, channel, design, attack)
        assert_allclose(sc.cost(), ref.cost(), rtol=1e-11)
        assert_allclose(sc.cost_curve(40).trace, ref.cost_curve(40).trace, rtol=1e-11)
        assert_allclose(sc.holding_time_law(6), ref.holding_time_law(6), atol=1e-13)
        assert_allclose(sc.energy_per_step(3.0, 1.0), ref.energy_per_step(3.0, 1.0), rtol=1e-11)
        assert_allclose(tuple(sc.flag_rates()), tuple(ref.flag_rates()), rtol=1e-11, atol=1e-15)
        assert_allclose(sc.cost(), pol.cost(S, channel, design), rtol=1e-12)


def test_the_worst_attack_evaluates_the_same():
    w = fa.worst_attack(S, 0.5, fa.OnlineDesign(2), 0.5, tau_max=64)
    sc = fa.Scenario(S, 0.5, fa.OnlineDesign(2), w.policy)
    assert_allclose(sc.cost(), w.j, rtol=1e-10)
    rates = sc.flag_rates()  # per-state flags of the chain, against the optimal room's fraction
    assert rates.forged == 0.0
    assert_allclose(rates.blocked / rates.sent, w.blocked_fraction, rtol=1e-9)


def test_state_policy_refusals_name_the_argument():
    with pytest.raises(ValueError, match=names("attack")):
        fa.Scenario(S, 0.5, fa.OfflineSchedule("1/7"), fa.StatePolicy([0.5]))
    with pytest.raises(ValueError, match=names("authenticated")):
        fa.Scenario(S, 0.5, fa.OnlineDesign(2), fa.StatePolicy([0.5]), authenticated=True)


class OneState:
    """A sensor policy written from the protocol alone: one state, every packet arrives with lam."""

    def __init__(self, lam):
        self.lam = lam

    def scenario_chain(self, channel):
        K0 = sp.csr_array([[1.0 - self.lam]])
        K1 = sp.csr_array([[self.lam]])
        return ScenarioChain(K0, K1, np.ones(1), ["only"], np.ones(1), energy=np.array([2.0]))


def test_any_object_with_a_scenario_chain_is_a_schedule():
    lam = 0.6
    sc = fa.Scenario(S, 0.5, OneState(lam))  # the channel only supplies its state process
    pbar = float(S.pbar[0, 0])
    assert_allclose(sc.cost(), (lam * pbar + (1 - lam) * 0.8) / (1 - (1 - lam) * 1.44), rtol=1e-12)
    assert sc.energy_per_step() == 2.0


def test_a_scenario_chain_of_the_wrong_kind_is_refused():
    class Bad:
        def scenario_chain(self, channel):
            return (np.eye(1), np.zeros((1, 1)))

    with pytest.raises(TypeError, match=names("schedule")):
        fa.Scenario(S, 0.5, Bad())
    with pytest.raises(TypeError, match=names("schedule")):
        fa.Scenario(S, 0.5, object())
