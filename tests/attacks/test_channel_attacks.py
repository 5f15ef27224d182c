"""fa.j_attack on channel objects and on every attack: the paper's channel keeps today's structured
route bit for bit, everything else is the exact engine, checked against the i.i.d. reduction, a
renewal derivation of the mimicry cost, the independent explicit chain of
tests/engine/reference_engine.py and the Monte Carlo of the protocol."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack.attacks import as_automaton
from fakeack.attacks.kinds import core_attack
from fakeack.model.system import compiled
from reference import pbar_scipy, traces

sys.path.insert(0, str(Path(__file__).parent.parent / "engine"))
import reference_engine as ref  # noqa: E402

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)  # bursty: mean bad run 1/q = 3.3 steps
BUILT_IN = [
    fa.PeriodicBlocking(0, 1),
    fa.PeriodicBlocking(1, 5),
    fa.PeriodicBlocking(2, 3),
    fa.MaskBlocking([1, 0, 1, 0, 0]),
    fa.RandomBlocking(0.3),
    fa.FlagInjection(0.1),
    fa.FlagInjection(0.1, fa.RandomBlocking(0.3)),
    fa.FlagInjection(0.2, fa.PeriodicBlocking(1, 3)),
]


def iid(p, lam_good, lam_bad, high=1.0):
    """A Gilbert-Elliott channel with p + q = 1 (the state drawn afresh at every step) and its lam."""
    q = 1.0 - p
    return fa.GilbertElliott(p, q, lam_good, lam_bad, high, high), q / (p + q) * lam_good + p / (
        p + q
    ) * lam_bad


# --- the paper's channel: today's route, bit for bit -----------------------------------------


@pytest.mark.parametrize("attack", BUILT_IN, ids=str)
@pytest.mark.parametrize("mu", [1.0, 0.6])
def test_bernoulli_is_todays_core_call_bit_for_bit(attack, mu):
    old = compiled(S).j_attack(0.5, 2, mu, core_attack(attack))  # the call j_attack made before channels
    assert fa.j_attack(S, 0.5, 2, mu=mu, attack=attack) == old
    assert fa.j_attack(S, lam=0.5, z0=2, mu=mu, attack=attack) == old
    assert fa.j_attack(S, fa.BernoulliChannel(0.5), 2, mu=mu, attack=attack) == old
    assert fa.j_attack(S, 0.5, 2, attack, mu=mu) == old  # an attack object in r's place


def test_bernoulli_r_t_and_spellings_bit_for_bit():
    old = compiled(S).j_attack(0.5, 2, 1.0, core_attack(fa.PeriodicBlocking(1, 5)))
    assert fa.j_attack(S, 0.5, 2, 1, 5) == old
    assert fa.j_attack(S, fa.BernoulliChannel(0.5), 2, 1, 5) == old
    assert fa.j_attack(S, lam=0.5, z0=2, r=1, t=5) == old
    assert fa.j_attack(S, 0.5, 2, attack="1/5") == old


# --- the i.i.d. reduction ----------------------------------------------------------------------


@pytest.mark.parametrize("attack", BUILT_IN, ids=str)
@pytest.mark.parametrize("mu", [1.0, 0.6])
def test_iid_gilbert_elliott_gives_the_bernoulli_value(attack, mu):
    """p + q = 1 and high_good = high_bad = 1: the packet arrives at low power with probability
    lam = pi_good lam_good + pi_bad lam_bad independently at every step, which is the paper's
    channel; the engine (two channel states) meets the structured renewal forms to 1e-12."""
    ge, lam = iid(0.3, 0.6, 0.2)
    assert_allclose(
        fa.j_attack(S, ge, 2, mu=mu, attack=attack), fa.j_attack(S, lam, 2, mu=mu, attack=attack), rtol=1e-12
    )


@pytest.mark.parametrize(
    "attack",
    [
        fa.MimicryAttack(),
        fa.FlagInjection(0.2, fa.RandomBlocking(0.3), min_gap=3),
        fa.PeriodicBlocking(1, 5),
        fa.AttackerAutomaton(
            {
                0: {"flag": [(0.6, True, 0), (0.4, False, 1)], "quiet": [(1.0, False, 0)]},
                1: {"flag": [(1.0, False, 1)], "quiet": [(0.7, False, 1), (0.3, False, 0)]},
            }
        ),
    ],
    ids=str,
)
@pytest.mark.parametrize("high", [1.0, 0.7])
def test_iid_reduction_beyond_the_paper(attack, high):
    """The same reduction for the engine-only attacks and for high-power packets that can be lost:
    the i.i.d. Gilbert-Elliott channel against the one-state channel of the same arrival laws."""
    ge, lam = iid(0.4, 0.8, 0.1, high)
    one = fa.MarkovChannel([[1.0]], [lam], [high])
    assert_allclose(fa.j_attack(S, ge, 3, attack=attack), fa.j_attack(S, one, 3, attack=attack), rtol=1e-12)


# --- mimicry ---------------------------------------------------------------------------------


def mimicry_iid(lam, z0, n=400):
    r"""J under mimicry on the paper's channel, from the renewal structure alone.

    The sensor's power follows the virtual attack-free system, which is independent of the real
    channel. Its high-power steps are renewals: after one, the virtual count restarts and the
    next high step comes L = G + 1 steps later, G the number of low steps until z0 virtual losses
    in a row (mu = 1). In the stationary renewal process the age A (steps since the last high
    step) has P(A = m) = P(L > m) / E L. A real high-power packet always arrives and a real
    low-power one arrives with probability lam independently, so for n >= 1

        P(tau >= n) = (1 - lam)^n P(A >= n),    J = sum_n P(tau >= n) (tr_n - tr_{n-1}).
    """
    tr = traces(S.A, S.Q, pbar_scipy(S.A, S.C, S.Q, S.R), n)
    survival_g = np.zeros(n + 1)  # P(G > m)
    count = np.zeros(z0)  # law of the virtual zero count, not yet absorbed at z0
    count[0] = 1.0
    for m in range(n + 1):
        survival_g[m] = count.sum()
        count = np.concatenate(([lam * count.sum()], (1 - lam) * count[:-1]))
    survival_l = np.concatenate(([1.0], survival_g[:n]))  # P(L > m) = P(G > m - 1)
    age_tail = np.cumsum(survival_l[::-1])[::-1] / survival_l.sum()  # P(A >= n)
    p_tau = (1 - lam) ** np.arange(n + 1) * age_tail
    p_tau[0] = 1.0
    return float(np.sum(p_tau * np.diff(tr, prepend=0.0)))


@pytest.mark.parametrize("lam, z0", [(0.5, 2), (0.5, 1), (0.3, 3), (0.7, 2)])
def test_mimicry_on_the_paper_channel_is_the_renewal_value(lam, z0):
    """The received flag-ACKs have the attack-free law, yet J is not J_on: the high-power steps no
    longer follow the real losses (renewal form of mimicry_iid)."""
    j = fa.j_attack(S, lam, z0, attack=fa.MimicryAttack())
    assert_allclose(j, mimicry_iid(lam, z0), rtol=1e-12)
    assert j > fa.j_online(S, lam, z0) * 1.05
    assert fa.j_attack(S, fa.BernoulliChannel(lam), z0, attack=fa.MimicryAttack(design=(z0, 1.0))) == j


def test_mimicry_on_a_bursty_channel_against_the_monte_carlo():
    """The Monte Carlo of the protocol (fa.simulate's automaton kernel) estimates J_H; the exact
    curve's J_H is within 4 standard errors, and J_H is near the stationary J."""
    att = fa.MimicryAttack()
    res = fa.simulate(S, GE, fa.OnlineDesign(2), 300, 20_000, seed=11, attack=att, progress=False)
    exact = fa.expected_trace_curve(S, GE, fa.OnlineDesign(2), 300, attack=att).j_k[-1]
    assert abs(res.j - exact) < 4 * res.stderr
    j = fa.j_attack(S, GE, 2, attack=att)
    assert abs(exact - j) < 0.02 * j and j > 1.4 * fa.j_attack(S, GE, 2, 0, 1)


def test_mimicry_can_make_the_cost_infinite_on_a_bursty_channel():
    """GilbertElliott(0.05, 0.1, 0.95, 0.1): the virtual system runs on its own channel, so in a
    real bad run the sensor mostly stays at low power. On the states B = (real bad, virtual good,
    sensor low) a step stays in B with a lost packet with probability at least
    (1 - q)(1 - p)(1 - lam_bad)(1 - (1 - lam_good)) (a virtual flag-ACK needs a virtual loss), so
    rho(K0) >= 0.9 * 0.95 * 0.9 * 0.95 = 0.731 (a principal submatrix's smallest row sum) and the
    index is at least 1.053: J is infinite, where without attack it is finite."""
    ch = fa.GilbertElliott(0.05, 0.1, 0.95, 0.1)
    assert fa.Scenario(S, ch, fa.OnlineDesign(2), fa.MimicryAttack()).stability_index() >= 0.731 * 1.44
    assert fa.j_attack(S, ch, 2, attack=fa.MimicryAttack()) == math.inf
    assert math.isfinite(fa.j_attack(S, ch, 2, 0, 1))


# --- the engine against the explicit chain and the automata ------------------------------------


@pytest.mark.parametrize(
    "attack",
    [
        None,
        fa.PeriodicBlocking(1, 5),
        fa.RandomBlocking(0.3),
        fa.FlagInjection(0.1, min_gap=3),
        fa.FlagInjection(0.2, fa.PeriodicBlocking(1, 3), min_gap=2),
    ],
    ids=str,
)
@pytest.mark.parametrize("channel", [GE, fa.GilbertElliott(0.2, 0.4, 0.7, 0.3, 1.0, 0.8), 0.5], ids=repr)
def test_markov_channels_and_min_gap_against_the_explicit_chain(channel, attack):
    """Every channel and any min_gap: the explicit chain over (tau, e) built from the protocol's
    rules (reference_engine.py), which shares no formula with the engine's Stein equations."""
    ch = fa.model.as_channel(channel)
    aut = as_automaton(attack)
    chain = ref.Chain(
        ch.P, ch.low, ch.high, ("online", 2, 1.0), ref.attacker_from(aut.flag, aut.quiet, aut.start)
    )
    want = ref.cost(chain, S.A, S.Q, S.pbar)
    got = fa.j_attack(S, channel, 2, attack=fa.PeriodicBlocking(0, 1) if attack is None else attack)
    assert_allclose(got, want, rtol=1e-9)


@pytest.mark.parametrize(
    "attack", [*BUILT_IN, fa.FlagInjection(0.2, fa.RandomBlocking(0.3), min_gap=3)], ids=str
)
@pytest.mark.parametrize("channel", [0.5, GE], ids=repr)
def test_an_automaton_costs_what_its_built_in_attack_costs(channel, attack):
    """fa.as_automaton writes a built-in attack out; on the paper's channel this compares the
    engine with the structured forms, on a Markov channel two engine inputs."""
    assert_allclose(
        fa.j_attack(S, channel, 2, attack=as_automaton(attack)),
        fa.j_attack(S, channel, 2, attack=attack),
        rtol=1e-11,
    )


def test_mimicry_automaton_and_injection_with_min_gap_in_rs_place():
    mim = fa.j_attack(S, GE, 2, attack=fa.MimicryAttack())
    assert fa.j_attack(S, GE, 2, fa.MimicryAttack()) == mim
    assert_allclose(
        fa.j_attack(S, GE, 2, as_automaton(fa.MimicryAttack(), channel=GE, design=(2, 1.0))), mim, rtol=1e-12
    )
    assert fa.j_attack(S, GE, 2, attack="inject:0.1") == fa.j_attack(S, GE, 2, attack=fa.FlagInjection(0.1))


def test_infinite_cost_on_a_markov_channel_is_inf_never_nan():
    """A bad state that loses every packet, low or high power, and is left with probability
    q = 0.1: rho(K0) >= 1 - q = 0.9 and rho(K0) rho(A)^2 >= 1.296."""
    ch = fa.GilbertElliott(0.1, 0.1, 1.0, 0.0, 1.0, 0.0)
    sc = fa.Scenario(S, ch, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 2))
    assert sc.stability_index() >= 1
    assert fa.j_attack(S, ch, 2, 1, 2) == math.inf


# --- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "call, exc, arg",
    [
        (lambda: fa.j_attack(S, "x", 2, 1, 5), TypeError, "channel"),
        (lambda: fa.j_attack(S, 1.5, 2, 1, 5), ValueError, "channel"),
        (lambda: fa.j_attack(S, 1.0, 2, 1, 5), ValueError, "channel"),  # the structured route's (0, 1)
        (lambda: fa.j_attack(S, fa.BernoulliChannel(0.0), 2, 1, 5), ValueError, "channel"),
        (lambda: fa.j_attack(S, lam=1.5, z0=2, r=1, t=5), ValueError, "lam"),
        (lambda: fa.j_attack(S, lam=1.0, z0=2, r=1, t=5), ValueError, "lam"),
        (lambda: fa.j_attack(S, 0.5, 2, 1, 5, lam=0.5), TypeError, "lam"),
        (lambda: fa.j_attack(S, z0=2, r=1, t=5), TypeError, "channel"),
        (lambda: fa.j_attack(S, GE, r=1, t=5), TypeError, "z0"),
        (lambda: fa.j_attack(S, GE, 0, 1, 5), ValueError, "z0"),
        (lambda: fa.j_attack(S, GE, 2, 1, 5, mu=1.5), ValueError, "mu"),
        (lambda: fa.j_attack(S, GE, 2), TypeError, "attack"),
        (lambda: fa.j_attack(S, GE, 2, 1, 5, attack=fa.MimicryAttack()), TypeError, "attack"),
        (lambda: fa.j_attack(S, GE, 2, attack=[1, 0]), TypeError, "attack"),
        (lambda: fa.j_attack(S, GE, 2, 5, 5), ValueError, "r"),
        (lambda: fa.j_attack("S", GE, 2, 1, 5), TypeError, "system"),
    ],
)
def test_bad_input_names_the_argument(call, exc, arg):
    with pytest.raises(exc, match=names(arg)):
        call()


def test_a_channel_state_that_never_sees_an_arrival_is_the_engines_error():
    """q = 0 and nothing arrives in the bad state: rho(K0) = 1, refused by the engine (naming the
    attack, the part of the scenario it blames when there is one)."""
    ch = fa.GilbertElliott(0.3, 0.0, 1.0, 0.0, 1.0, 0.0)
    with pytest.raises(ValueError, match=r"attack: .*rho\(K0\) = 1"):
        fa.j_attack(S, ch, 2, 1, 5)


@pytest.mark.parametrize("channel", [0.5, GE], ids=repr)
def test_a_mask_blocking_every_flag_is_refused_on_every_channel(channel):
    with pytest.raises(ValueError, match="every flag-ACK") as info:
        fa.j_attack(S, channel, 2, attack=fa.MaskBlocking([1, 1]))
    assert ("j_max" if channel == 0.5 else "OfflineSchedule(pattern='0')") in str(info.value)
