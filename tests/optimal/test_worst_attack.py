"""The worst attack on the flag-ACKs (fakeack.optimal.worst_attack) and the attackers that read the
holding time (StatePolicy): the product automaton against the built-in engine and against the
explicit reference chain with an attacker written here from the protocol, the LP's value against
its own policy's exact J, the paper's attack families and random blocking, and the errors."""

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import fakeack as fa
from fakeack.optimal.attack import worst_attack
from fakeack.optimal.state_policy import StatePolicy

sys.path.insert(0, str(Path(__file__).parent.parent / "engine"))
import reference_engine as ref  # noqa: E402

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
PAPER = fa.OnlineDesign(2)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.4)
#: Relative tolerance of statements that go through the LP (HiGHS's tolerances are 1e-10).
LP_RTOL = 1e-9
#: The truncation of the mu = 0.5 gap-law test (its program has 4 x 202 states per tau).
TAU_MU_HALF = 20


# --- StatePolicy against independent routes ------------------------------------------------------


@pytest.mark.parametrize("beta", [0.0, 0.3, 0.5, 1.0])
@pytest.mark.parametrize(
    "channel, design", [(0.5, PAPER), (0.5, fa.OnlineDesign(3, 0.4)), (GE, fa.OnlineDesign(2, 0.7))]
)
def test_constant_blocking_is_random_blocking(channel, design, beta):
    """Blocking every genuine flag-ACK with probability beta, whatever tau, is RandomBlocking(beta)
    in the built-in engine (whose automaton knows nothing of tau)."""
    pol = StatePolicy(np.full(9, beta))
    want = fa.Scenario(S, channel, design, fa.RandomBlocking(beta)).cost()
    assert pol.cost(S, channel, design) == pytest.approx(want, rel=1e-10)
    assert pol.automaton(channel, design).blocked_fraction == pytest.approx(beta, abs=1e-12)


class GapTau:
    """An attacker of the reference chain that sees only the flag-ACKs and infers tau from the
    gaps (mu = 1): a flag-ACK z0 steps after the previous one follows z0 more losses; a later one
    follows an arrival and z0 losses. It blocks with ``block[min(tau, T)]``."""

    def __init__(self, block, z0):
        self.block, self.z0 = list(block), z0

    def initial(self):
        return [(1.0, (0, 0))]

    def step(self, state, flag):
        tau_last, since = state
        since = min(since + 1, self.z0 + 1)
        if not flag:
            return [(1.0, False, (tau_last, since))]
        tau = tau_last + self.z0 if since == self.z0 else self.z0
        tau = min(tau, len(self.block) - 1)
        p = self.block[tau]
        return [(x, d, (tau, 0)) for x, d in ((p, False), (1.0 - p, True)) if x > 0.0]


@pytest.mark.parametrize("z0", [1, 2, 3])
def test_tau_dependent_policy_against_reference_chain(z0):
    """A policy that blocks by tau (mu = 1): its product automaton's J equals the explicit chain
    over (tau, e) with an attacker that reads tau off the flag-ACK gaps."""
    rng = np.random.default_rng(z0)
    block = rng.uniform(size=13)
    block[-1] = 1.0
    pol = StatePolicy(block)
    chain = ref.Chain([[1.0]], [0.5], [1.0], ("online", z0, 1.0), GapTau(block, z0))
    want = ref.cost(chain, S.A, S.Q, S.pbar)
    assert pol.cost(S, 0.5, fa.OnlineDesign(z0)) == pytest.approx(want, rel=1e-9)


def test_state_policy_validates():
    with pytest.raises(ValueError, match="^block"):
        StatePolicy([0.5, 1.5])
    with pytest.raises(TypeError, match="^block"):
        StatePolicy("half")
    with pytest.raises(ValueError, match="^forge"):
        StatePolicy([0.5, 0.5], forge=[0.1])
    with pytest.raises(ValueError, match="^block"):
        StatePolicy(np.full((3, 3), 0.5)).automaton(GE, PAPER)
    with pytest.raises(TypeError, match="^design"):
        StatePolicy([0.5]).automaton(0.5, (2, 1.0))


# --- the worst attack -------------------------------------------------------------------------------


def check_bracket(w, beta):
    """j_lp - tail_bound <= j <= j_lp, within the budget."""
    assert w.j <= w.j_lp * (1 + LP_RTOL)
    assert w.j >= (w.j_lp - w.tail_bound) * (1 - LP_RTOL)
    assert w.blocked_fraction <= beta + 1e-9
    assert w.forged_fraction == 0.0


@pytest.mark.parametrize("beta", [0.1, 0.25, 0.5, 0.75])
def test_paper_example_beats_every_family(beta):
    """On the paper's example: above j_attack_limit, every periodic attack of budget <= beta with
    t <= 60, and random blocking; and the flag-only automaton has the same J."""
    w = worst_attack(S, 0.5, PAPER, beta, tau_max=200)
    check_bracket(w, beta)
    floor = w.j * (1 + LP_RTOL)
    assert fa.j_attack_limit(S, 0.5, 2, beta) <= floor
    assert fa.j_attack(S, 0.5, 2, attack=fa.RandomBlocking(beta)) <= floor
    best = max(
        fa.j_attack(S, 0.5, 2, attack=fa.PeriodicBlocking(r, t))
        for t in range(1, 61)
        for r in range(0, t)
        if r <= beta * t
    )
    assert best <= floor
    assert w.automaton is not None
    assert fa.Scenario(S, 0.5, PAPER, w.automaton).cost() == pytest.approx(w.j, rel=1e-10)


@pytest.mark.parametrize(
    "channel, design", [(0.5, fa.OnlineDesign(2, 0.5)), (GE, PAPER), (GE, fa.OnlineDesign(3, 0.6))]
)
def test_other_channels_and_designs(channel, design):
    """The bracket and the families on a randomised memory and on a Gilbert-Elliott channel, where
    the state-aware attacker beats consecutive blocking's limit."""
    beta = 0.5
    w = worst_attack(S, channel, design, beta)
    check_bracket(w, beta)
    assert w.tail_bound <= 1e-12 * w.j
    limit = fa.j_attack_limit(S, channel, design.z0, beta, design.mu)
    assert limit <= w.j * (1 + LP_RTOL)
    assert fa.Scenario(S, channel, design, fa.RandomBlocking(beta)).cost() <= w.j * (1 + LP_RTOL)
    for r, t in [(1, 2), (2, 4), (5, 10)]:
        assert fa.Scenario(S, channel, design, fa.PeriodicBlocking(r, t)).cost() <= w.j * (1 + LP_RTOL)
    assert w.automaton is None  # mu < 1 or a state-dependent policy: the gaps do not reveal enough


def test_budget_ends():
    """beta = 0 is the attack-free J; beta = 1 blocks everything: RandomBlocking(1)."""
    w0 = worst_attack(S, 0.5, PAPER, 0.0)
    assert w0.j == pytest.approx(fa.Scenario(S, 0.5, PAPER).cost(), rel=1e-12)
    w1 = worst_attack(S, GE, PAPER, 1.0)
    assert w1.j == pytest.approx(fa.Scenario(S, GE, PAPER, fa.RandomBlocking(1.0)).cost(), rel=1e-10)


def test_forging_raises_the_optimum():
    """Forging is a further choice: the optimum with a forging budget is at least the one without,
    and its policy's exact J stays within the LP's bracket."""
    w = worst_attack(S, 0.5, PAPER, 0.25, tau_max=150)
    wf = worst_attack(S, 0.5, PAPER, 0.25, forge_budget=0.1, tau_max=150)
    assert wf.j_lp >= w.j_lp * (1 - LP_RTOL)
    assert wf.j <= wf.j_lp * (1 + LP_RTOL)
    assert wf.j >= (wf.j_lp - wf.tail_bound) * (1 - LP_RTOL)
    assert wf.forged_fraction <= 0.1 + 1e-9


@pytest.mark.parametrize("bad", [-0.1, 1.5])
def test_errors(bad):
    with pytest.raises(ValueError, match="^beta"):
        worst_attack(S, 0.5, PAPER, bad)
    with pytest.raises(ValueError, match="^forge_budget"):
        worst_attack(S, 0.5, PAPER, 0.5, forge_budget=bad)
    with pytest.raises(ValueError, match="^information"):
        worst_attack(S, 0.5, PAPER, 0.5, information="flags")
    with pytest.raises(ValueError, match="^stealth"):
        worst_attack(S, 0.5, PAPER, 0.5, stealth="invisible")
    with pytest.raises(TypeError, match="^design"):
        worst_attack(S, 0.5, (2, 1.0), 0.5)
    with pytest.raises(ValueError, match="^channel"):
        worst_attack(S, 0.3, PAPER, 0.5)  # loss 0.7 at low power, 0.7 * 1.44 >= 1
    with pytest.raises(ValueError, match="^tau_max"):
        worst_attack(S, 0.5, PAPER, 0.5, tau_max=0)


# --- stealth -----------------------------------------------------------------------------------------


def test_attack_free_gap_law_against_the_flag_process():
    """The gap law the stealth constraint uses equals the Palm law of the engine's flag process,
    pi D1 D0^(l-1) D1 1 / pi D1 1 (a different route: the engine's automaton of E)."""
    from fakeack.model.channels import as_channel
    from fakeack.optimal._attack_lp import attack_free_gaps
    from fakeack.optimal.state_policy import protocol_steps

    for channel, design in [(0.5, PAPER), (GE, fa.OnlineDesign(3, 0.6))]:
        law, rate = attack_free_gaps(protocol_steps(as_channel(channel), design))
        fp = fa.flag_process(channel, design)
        D0, D1 = fp.D0.toarray(), fp.D1.toarray()
        v = fp.stationary @ D1
        assert rate == pytest.approx(v.sum(), rel=1e-12)
        v = v / v.sum()
        for gap in range(1, 30):
            assert law[gap - 1] == pytest.approx(v @ D1.sum(axis=1), abs=1e-13)
            v = v @ D0


def flag_palm_law(D0, D1, pi, n):
    """The Palm law of the gaps of the Markov arrival process (D0, D1) with stationary law pi:
    gap l (l = 1..n - 1) has probability pi D1 D0^(l-1) D1 1 / pi D1 1, the last entry every gap
    >= n. Steps are counted by powers of D0, not read off any state."""
    v = pi @ D1
    v = v / v.sum()
    one = np.ones(D1.shape[0])
    out = []
    for _ in range(n - 1):
        out.append(float(v @ (D1 @ one)))
        v = v @ D0
    out.append(float(v.sum()))
    return np.array(out)


def attack_free_palm_law(channel, design, n):
    """The attack-free gap law from the engine's flag process (fa.flag_process)."""
    fp = fa.flag_process(channel, design)
    return flag_palm_law(fp.D0.toarray(), fp.D1.toarray(), fp.stationary, n)


def received_palm_law(policy, channel, design, n):
    """The law of the gaps the sensor receives under a StatePolicy, from the Markov arrival
    process of its chain over (min(tau, T), e, d) written here from the protocol's steps: D1 the
    steps on which the policy delivers a flag-ACK (the sensor's next power high), D0 the others;
    the stationary law by power iteration of the lazy chain."""
    from fakeack.model.channels import as_channel
    from fakeack.optimal.state_policy import protocol_steps

    ch = as_channel(channel)
    steps = protocol_steps(ch, design)
    hi = policy.high_probability(ch, design)  # (n_t, E, G)
    n_t, E, G = hi.shape
    idx = np.arange(n_t * E * G).reshape(n_t, E, G)
    parts = {0: [], 1: []}
    d = np.arange(G)
    for t in range(n_t):
        for a, p in ((0, 1.0 - hi[t]), (1, hi[t])):  # p: (E, G)
            d2 = np.zeros(G, dtype=int) if a else np.minimum(d + 1, G - 1)
            for kernel, t2 in ((steps.loss[a], min(t + 1, n_t - 1)), (steps.arrival[a], 0)):
                e, f = np.nonzero(kernel)
                parts[a].append(
                    (idx[t, e[:, None], d], idx[t2, f[:, None], d2], p[e] * kernel[e, f][:, None])
                )
    n_states = idx.size
    D = []
    for a in (0, 1):
        r, c, v = (np.concatenate([y.ravel() for y in x]) for x in zip(*parts[a], strict=True))
        D.append(sp.csr_array((v, (r, c)), shape=(n_states, n_states)))
    K = (D[0] + D[1]).T.tocsr()
    pi = np.full(n_states, 1.0 / n_states)
    for _ in range(20_000):
        nxt = 0.5 * (pi + K @ pi)
        if np.abs(nxt - pi).sum() < 1e-16:
            break
        pi = nxt
    pi = nxt / nxt.sum()
    return flag_palm_law(D[0], D[1], pi, n)


def test_gap_law_beats_mimicry():
    """Mimicry meets the gap law (beta = 1, forging allowed), so the stealthy optimum is at least
    its J; the optimal policy's received gaps, from its own chain, have the attack-free law (the
    engine's flag process) to 1e-14, out to where its tail falls below 1e-12."""
    w = worst_attack(S, 0.5, PAPER, 1.0, forge_budget=1.0, stealth="gap-law", tau_max=200)
    mimicry = fa.Scenario(S, 0.5, PAPER, fa.MimicryAttack()).cost()
    assert w.j >= mimicry
    assert w.j <= w.j_lp * (1 + LP_RTOL)
    assert w.j >= (w.j_lp - w.tail_bound) * (1 - LP_RTOL)
    G = w.received_gaps.size
    law = attack_free_palm_law(0.5, PAPER, G)
    assert law[-1] < 1e-12 <= law[-2] + law[-1]  # the constraint's length: the tail at 1e-12
    got = received_palm_law(w.policy, 0.5, PAPER, G)
    np.testing.assert_allclose(got, law, rtol=0, atol=1e-14)
    np.testing.assert_allclose(w.received_gaps, law, rtol=0, atol=1e-14)


def test_gap_law_randomised_memory():
    """mu = 0.5: the gap law's program solves (its law has coefficients of order 1), the optimum
    is at least mimicry's J, and the received gaps have the attack-free law."""
    design = fa.OnlineDesign(2, 0.5)
    w = worst_attack(S, 0.5, design, 1.0, forge_budget=1.0, stealth="gap-law", tau_max=TAU_MU_HALF)
    mimicry = fa.Scenario(S, 0.5, design, fa.MimicryAttack()).cost()
    assert w.j >= mimicry
    assert w.j <= w.j_lp * (1 + LP_RTOL)
    assert w.j >= (w.j_lp - w.tail_bound) * (1 - LP_RTOL)
    law = attack_free_palm_law(0.5, design, w.received_gaps.size)
    assert law[-1] < 1e-12 <= law[-2] + law[-1]
    got = received_palm_law(w.policy, 0.5, design, law.size)
    np.testing.assert_allclose(got, law, rtol=0, atol=1e-9)  # HiGHS: 1e-10 on masses of rate 0.1


@pytest.mark.parametrize("design", [PAPER, fa.OnlineDesign(2, 0.5), fa.OnlineDesign(3, 0.6)])
def test_gap_law_without_forging_is_attack_free(design):
    """Without forging on an i.i.d. channel, blocking lengthens the received gaps, so the gap law
    at the attack-free rate leaves only the attack-free policy: J_on, exactly, whatever HiGHS."""
    w = worst_attack(S, 0.5, design, 1.0, stealth="gap-law", tau_max=30)
    assert w.j == pytest.approx(fa.Scenario(S, 0.5, design).cost(), rel=1e-12)
    assert w.j_lp == w.j and w.tail_bound == 0.0
    assert w.blocked_fraction == 0.0 and w.forged_fraction == 0.0
    np.testing.assert_allclose(
        w.received_gaps, attack_free_palm_law(0.5, design, w.received_gaps.size), atol=1e-14
    )


def test_support_forbids_short_gaps():
    """With stealth='support' no flag-ACK reaches the sensor sooner than the attack-free minimum
    gap (z0 + 1 when high power always arrives); a plain random blocker would deliver gaps of z0."""
    w = worst_attack(S, 0.5, PAPER, 0.5, forge_budget=0.2, stealth="support", tau_max=80)
    assert w.received_gaps[:2].sum() == pytest.approx(0.0, abs=1e-12)
    assert w.j <= w.j_lp * (1 + LP_RTOL)
    assert w.j >= (w.j_lp - w.tail_bound) * (1 - LP_RTOL)
    plain = worst_attack(S, 0.5, PAPER, 0.5, tau_max=80)
    assert w.j_lp <= plain.j_lp * (1 + LP_RTOL)  # a constraint can only lower the optimum


@pytest.mark.parametrize("min_gap", [1, 3, 5])
@pytest.mark.parametrize("channel, design", [(0.5, PAPER), (GE, fa.OnlineDesign(3, 0.6))])
def test_gap_axis_against_flag_injection(channel, design, min_gap):
    """A policy that reads the received gap: forging with probability gamma once min_gap steps
    have passed since the last flag-ACK received, and blocking with probability b, is the built-in
    FlagInjection(gamma, RandomBlocking(b), min_gap)."""
    gamma, b = 0.2, 0.3
    forge = np.zeros((1, 1, 1, min_gap))
    forge[..., -1] = gamma
    pol = StatePolicy(np.full((1, 1, min_gap), b), forge)
    attack = fa.FlagInjection(gamma, fa.RandomBlocking(b), min_gap=min_gap)
    want = fa.Scenario(S, channel, design, attack).cost()
    assert pol.cost(S, channel, design) == pytest.approx(want, rel=1e-10)
    aut = pol.automaton(channel, design)
    assert aut.blocked_fraction == pytest.approx(b, abs=1e-12)
    if min_gap > 1:  # no forged flag-ACK before min_gap, no genuine one before z0
        short = aut.received_gaps[: min(min_gap, design.z0) - 1].sum()
        assert short == pytest.approx(0.0, abs=1e-14)


def test_truncation_errs_on_the_safe_side():
    """A short truncation's j_lp still bounds the optimum found with a long one, and its own
    policy's J lies within its tail bound (here far from negligible)."""
    long = worst_attack(S, 0.5, PAPER, 0.5, tau_max=200)
    for T in (4, 8, 16):
        short = worst_attack(S, 0.5, PAPER, 0.5, tau_max=T)
        assert short.tail_bound > 1e-6
        assert short.j_lp >= long.j * (1 - LP_RTOL)
        assert short.j <= long.j * (1 + LP_RTOL)
        assert short.j >= (short.j_lp - short.tail_bound) * (1 - LP_RTOL)
