"""fa.Scenario.from_automaton: an automaton given as K0 and K1 gives the cost of the scenario it was
exported from, the cost of the explicit chain of (tau, e) for one built by hand, and refuses bad
matrices naming them."""

import math
import threading
import time

import numpy as np
import pytest
import reference_engine as ref
import scipy.sparse as sp
from numpy.testing import assert_allclose, assert_array_equal

import fakeack as fa
from conftest import names

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
VEC = fa.LinearSystem(np.array([[1.1, 0.3], [0.0, 0.8]]), np.array([[1.0, 0.5]]), np.eye(2), 1.0)
GE = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)


def rebuilt(sc, system, channel):
    """The scenario rebuilt from its automaton, starting as it does: its initial states are the
    first ones, one per channel state, weighted by the channel's stationary law."""
    labels, K0, K1 = sc.automaton()
    k = channel.n_states
    assert [lab.split()[0] for lab in labels[:k]] == [f"c={c}" for c in range(k)]
    init = np.zeros(len(labels))
    init[:k] = channel.stationary
    return fa.Scenario.from_automaton(system, K0, K1, init=init, labels=labels)


BUILT_IN = {
    "paper channel, 1/5 blocking": (0.5, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5)),
    "Gilbert-Elliott, mimicry": (GE, fa.OnlineDesign(3, 0.6), fa.MimicryAttack(design=fa.OnlineDesign(2))),
    "Gilbert-Elliott, offline 2/7": (GE, fa.OfflineSchedule("2/7"), None),
}


@pytest.mark.parametrize("case", BUILT_IN)
@pytest.mark.parametrize("system", [S, VEC], ids=["scalar", "2x2"])
def test_a_built_in_scenario_rebuilt_from_its_automaton(case, system):
    channel, schedule, attack = BUILT_IN[case]
    sc = fa.Scenario(system, channel, schedule, attack)
    g = rebuilt(sc, system, fa.BernoulliChannel(channel) if isinstance(channel, float) else channel)
    assert g.channel is None and g.schedule is None and g.attack is None
    assert g.n_states == sc.n_states
    assert_allclose(g.cost(), sc.cost(), rtol=1e-12)
    assert_allclose(g.stability_index(), sc.stability_index(), rtol=1e-12)
    assert_allclose(g.holding_time_law(20), sc.holding_time_law(20), rtol=1e-12, atol=1e-300)
    assert_allclose(g.cost_curve(30).j_k, sc.cost_curve(30).j_k, rtol=1e-12)
    a, b = g.automaton(), sc.automaton()
    assert a.labels == b.labels
    assert (a.K0 != b.K0).nnz == 0 and (a.K1 != b.K1).nnz == 0


def test_the_paper_scenario_needs_no_initial_law():
    """On the paper's channel the scenario starts in state 0, the default."""
    sc = fa.Scenario(S, 0.5, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5))
    _, K0, K1 = sc.automaton()
    g = fa.Scenario.from_automaton(S, K0, K1)
    assert_allclose(g.cost(), sc.cost(), rtol=1e-12)
    assert_allclose(g.cost_curve(10).trace, sc.cost_curve(10).trace, rtol=1e-12)
    assert g.automaton().labels == [str(i) for i in range(sc.n_states)]


def jammer():
    """A reactive jammer: idle (a packet arrives with probability 0.9), it starts jamming with
    probability 0.3 after an arrival it sees; jamming (0.2), it stops with probability 0.5 a step
    into a cooldown (0.7), which returns to idle."""
    arrive = np.array([0.9, 0.2, 0.7])
    move = np.array([[0.7, 0.3, 0.0], [0.0, 0.5, 0.5], [1.0, 0.0, 0.0]])
    move_lost = np.array([[1.0, 0.0, 0.0], [0.0, 0.5, 0.5], [1.0, 0.0, 0.0]])  # unseen: no reaction
    K1 = arrive[:, None] * move
    K0 = (1 - arrive)[:, None] * move_lost
    return K0, K1


class GivenChain:
    """The reference's view of an irreducible automaton given as K0 and K1."""

    def __init__(self, K0, K1):
        self.K0, self.K1 = sp.csr_array(K0), sp.csr_array(K1)
        self.n = K0.shape[0]

    def absorption(self):
        return [(1.0, np.arange(self.n))]


def test_a_jammer_by_hand_against_the_explicit_chain():
    K0, K1 = jammer()
    assert_allclose((K0 + K1).sum(axis=1), 1.0)
    # Stable system: the truncated chain of (tau, e) solved in one sparse solve; its traces stay
    # below Q / (1 - A^2), so the solve's absolute errors stay near 1e-16.
    small = fa.LinearSystem(0.9, 1.0, 1.0, 1.0)
    law = ref.explicit_law(sp.csr_array(K0), sp.csr_array(K1), 150)
    tr = ref.traces(0.9, 1.0, small.pbar, 150)[:150]
    want = float(law.sum(axis=1) @ tr)
    sc = fa.Scenario.from_automaton(small, sp.csr_array(K0), sp.csr_array(K1), labels=["idle", "jam", "cool"])
    assert_allclose(sc.cost(), want, rtol=1e-12)
    assert_allclose(sc.holding_time_law(10)[:10], law.sum(axis=1)[:10], rtol=1e-11)
    # Growing system: the reference's level-by-level solution, which keeps tiny masses accurate.
    want = ref.cost(GivenChain(K0, K1), 1.2, 0.8, S.pbar)
    assert_allclose(fa.Scenario.from_automaton(S, K0, K1).cost(), want, rtol=1e-12)
    # rho(K0) = 0.8 * 0.5 (the jamming state's loss loop): index 0.4 * 1.44.
    assert_allclose(fa.Scenario.from_automaton(S, K0, K1).stability_index(), 0.4 * 1.44, rtol=1e-12)


def test_one_state_geometric_holding_time():
    """tau geometric: J = sum_t lam (1-lam)^t Tr h^t(Pbar) = G Pbar + Q (G-1)/(A^2-1),
    G = lam / (1 - (1-lam) A^2); infinite once (1-lam) A^2 >= 1."""
    pbar = float(S.pbar[0, 0])
    for lam in (0.4, 0.6, 0.9):
        g = lam / (1 - (1 - lam) * 1.44)
        sc = fa.Scenario.from_automaton(S, [[1 - lam]], [[lam]])
        assert_allclose(sc.cost(), g * pbar + 0.8 * (g - 1) / 0.44, rtol=1e-12)
    assert math.isinf(fa.Scenario.from_automaton(S, [[0.8]], [[0.2]]).cost())


def test_what_a_given_automaton_does_not_know():
    sc = fa.Scenario.from_automaton(S, [[0.4]], [[0.6]])
    for call in (sc.high_power_rate, sc.flag_rates, lambda: sc.energy_per_step(2.0, 1.0)):
        with pytest.raises(ValueError, match="no power or flag-ACK information"):
            call()
    assert repr(sc) == (
        "Scenario.from_automaton(system=LinearSystem(A=1.2, C=0.7, Q=0.8, R=0.8), n_states=1)"
    )
    assert "given as K0 and K1" in sc._repr_html_()


K0_OK, K1_OK = np.array([[0.4, 0.0], [0.5, 0.0]]), np.array([[0.0, 0.6], [0.5, 0.0]])


@pytest.mark.parametrize(
    "kwargs, exc, arg",
    [
        (dict(K0="x"), TypeError, "K0"),
        (dict(K0=None), TypeError, "K0"),
        (dict(K1=np.ones((2, 2), dtype=bool)), TypeError, "K1"),
        (dict(K0=[[0.5, 0.5]]), ValueError, "K0"),
        (dict(K1=np.zeros((3, 3))), ValueError, "K1"),
        (dict(K0=np.zeros((0, 0)), K1=np.zeros((0, 0))), ValueError, "K0"),
        (dict(K0=[[0.4, -0.1], [0.5, 0.0]], K1=[[0.0, 0.7], [0.5, 0.0]]), ValueError, "K0"),
        (dict(K1=[[0.0, np.nan], [0.5, 0.0]]), ValueError, "K1"),
        (dict(K1=[[0.0, 0.6 + 1e-10], [0.5, 0.0]]), ValueError, "K0 + K1"),
        (dict(init=[1.0]), ValueError, "init"),
        (dict(init=[1.5, -0.5]), ValueError, "init"),
        (dict(init=[0.5, 0.4]), ValueError, "init"),
        (dict(init=["a", "b"]), TypeError, "init"),
        (dict(labels=["a"]), ValueError, "labels"),
        (dict(labels="ab"), TypeError, "labels"),
        (dict(labels=[1, 2]), TypeError, "labels"),
        (dict(max_states=0), ValueError, "max_states"),
        (dict(max_states=1), ValueError, "K0"),
        # State 1 is never entered from state 0.
        (dict(K0=[[0.4, 0.0], [0.5, 0.0]], K1=[[0.6, 0.0], [0.5, 0.0]]), ValueError, "init"),
        # State 1 loses every packet and stays: rho(K0) = 1.
        (dict(K0=[[0.4, 0.0], [0.0, 1.0]], K1=[[0.0, 0.6], [0.0, 0.0]]), ValueError, "K0: from state 1"),
    ],
)
def test_validation_names_the_argument(kwargs, exc, arg):
    args = dict(K0=K0_OK, K1=K1_OK) | kwargs
    with pytest.raises(exc, match="^" + names(arg)):
        fa.Scenario.from_automaton(S, **args)


def test_a_state_without_arrivals_is_named_by_its_label():
    with pytest.raises(ValueError, match=r"^K0: from state 1 \(jammed\) no packet ever arrives"):
        fa.Scenario.from_automaton(
            S, [[0.4, 0.0], [0.0, 1.0]], [[0.0, 0.6], [0.0, 0.0]], labels=["on", "jammed"]
        )


def test_too_many_states_refused_before_allocating():
    """A sparse matrix of 10^9 states (two entries) is refused from its shape alone; building its
    engine would need gigabytes."""
    n = 10**9
    huge = sp.coo_array((np.array([1.0]), (np.array([0]), np.array([0]))), shape=(n, n))
    with pytest.raises(ValueError, match=names("K0") + ".*refused before allocating"):
        fa.Scenario.from_automaton(S, huge, huge)


def test_sparse_and_dense_give_one_scenario():
    K0, K1 = jammer()
    dense = fa.Scenario.from_automaton(S, K0, K1)
    for conv in (sp.csr_array, sp.coo_array, sp.csc_matrix):
        assert fa.Scenario.from_automaton(S, conv(K0), conv(K1)).cost() == dense.cost()
    assert_array_equal(dense.automaton().K0.toarray(), K0)


def ring(n, p_even=0.3, p_odd=0.7):
    """n states in a ring, each step to the next; a packet arrives with probability p_even from
    even states and p_odd from odd ones."""
    i = np.arange(n)
    p = np.where(i % 2 == 0, p_even, p_odd)
    to = (i + 1) % n
    return sp.csr_array((1 - p, (i, to)), shape=(n, n)), sp.csr_array((p, (i, to)), shape=(n, n))


def alternating_cost(system, pa, pb):
    """J when the arrival probability alternates pa, pb: after a step of either kind (half of all
    steps each) the holding time is t with probability p_t prod_{s<t} (1 - p_s), going back over
    the alternating steps."""
    tr = ref.traces(system.A, system.Q, system.pbar, 400)
    j = 0.0
    for first, second in ((pa, pb), (pb, pa)):
        lost = 1.0
        for t in range(400):
            p_here = first if t % 2 == 0 else second
            j += 0.5 * lost * p_here * tr[t]
            lost *= 1 - p_here
    return j


def test_a_ring_is_its_alternating_pair():
    """A ring of any even length has the holding time of the two alternating states."""
    want = alternating_cost(VEC, 0.3, 0.7)
    for n in (2, 6, 1000):
        assert_allclose(fa.Scenario.from_automaton(VEC, *ring(n)).cost(), want, rtol=1e-12)


def test_gil_released_during_the_solve():
    """Another Python thread keeps running while a solve runs; the automaton grows until one
    solve lasts at least 0.3 s, so the check cannot pass by being too quick to measure.

    Kills: running the solve without releasing the GIL (no py.detach in the binding)."""
    n = 100_000
    while True:
        sc = fa.Scenario.from_automaton(VEC, *ring(n))
        ticks = []
        stop = threading.Event()

        def count(ticks=ticks, stop=stop):
            while not stop.is_set():
                ticks.append(1)
                time.sleep(0.001)

        th = threading.Thread(target=count)
        th.start()
        t0 = time.monotonic()
        sc.cost()
        elapsed = time.monotonic() - t0
        stop.set()
        th.join()
        if elapsed >= 0.3:
            break
        n *= 4
    # At one tick per 1 ms sleep (plus scheduling), a GIL-free call of >= 0.3 s gives >= 60.
    assert len(ticks) > 0.2 * elapsed / 0.001, (len(ticks), elapsed)
