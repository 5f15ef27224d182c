"""Channels: validation that names the argument, reprs, equality, and stationary laws against
hand-derived ones."""

import pickle

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack.model.channels import as_channel, closed_classes


def test_bernoulli_is_the_paper_channel():
    ch = fa.BernoulliChannel(0.5)
    assert repr(ch) == "BernoulliChannel(lam=0.5)"
    assert ch.lam == 0.5 and ch.n_states == 1
    assert ch.P.tolist() == [[1.0]] and ch.low.tolist() == [0.5] and ch.high.tolist() == [1.0]
    assert ch.stationary.tolist() == [1.0] and ch.mean_low == 0.5 and ch.mean_high == 1.0
    assert ch == fa.MarkovChannel([[1.0]], [0.5], [1.0])


@pytest.mark.parametrize("p, q", [(0.1, 0.3), (0.5, 0.5), (0.9, 0.05), (0.0, 0.4), (1.0, 1.0)])
def test_gilbert_elliott_stationary_law(p, q):
    ge = fa.GilbertElliott(p, q, 0.9, 0.2)
    assert_allclose(ge.stationary, [q / (p + q), p / (p + q)], rtol=0, atol=1e-15)
    assert_allclose(ge.mean_low, (q * 0.9 + p * 0.2) / (p + q), rtol=1e-15)


def test_gilbert_elliott_is_the_markov_channel():
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2, high_good=1.0, high_bad=0.7)
    mc = fa.MarkovChannel([[0.9, 0.1], [0.3, 0.7]], [0.9, 0.2], [1.0, 0.7])
    assert ge == mc and hash(ge) == hash(mc) and isinstance(ge, fa.MarkovChannel)
    assert (ge.p, ge.q, ge.lam_good, ge.lam_bad, ge.high_good, ge.high_bad) == (0.1, 0.3, 0.9, 0.2, 1.0, 0.7)
    assert repr(ge) == "GilbertElliott(p=0.1, q=0.3, lam_good=0.9, lam_bad=0.2, high_good=1.0, high_bad=0.7)"
    assert (
        repr(fa.GilbertElliott(0.1, 0.3, 0.9, 0.2))
        == "GilbertElliott(p=0.1, q=0.3, lam_good=0.9, lam_bad=0.2)"
    )
    assert repr(mc) == "MarkovChannel(P=[[0.9, 0.1], [0.3, 0.7]], low=[0.9, 0.2], high=[1.0, 0.7])"
    assert ge != fa.GilbertElliott(0.1, 0.3, 0.9, 0.25)


def test_three_state_stationary_law_by_hand():
    # Birth-death chain: detailed balance pi1 = pi0 * 0.4/0.2, pi2 = pi1 * 0.3/0.6.
    P = [[0.6, 0.4, 0.0], [0.2, 0.2, 0.6], [0.0, 0.3, 0.7]]
    ch = fa.MarkovChannel(P, [0.5, 0.4, 0.1], [1, 1, 1])
    want = np.array([1.0, 2.0, 4.0]) / 7.0
    assert_allclose(ch.stationary, want, rtol=1e-14)
    assert_allclose(ch.stationary @ ch.P, ch.stationary, atol=1e-15)
    assert repr(fa.MarkovChannel(np.eye(5)[[1, 2, 3, 4, 0]], [0.5] * 5, [1] * 5)).startswith(
        "MarkovChannel(<5 states>"
    )


def test_transient_states_get_no_mass():
    ch = fa.MarkovChannel([[0.5, 0.5, 0.0], [0.0, 0.2, 0.8], [0.0, 0.6, 0.4]], [0.1, 0.2, 0.3], [1, 1, 1])
    assert ch.stationary[0] == 0.0
    assert_allclose(ch.stationary[1:], [0.6 / 1.4, 0.8 / 1.4], rtol=1e-14)
    assert [c.tolist() for c in closed_classes(ch.P)] == [[1, 2]]


def test_immutable_and_picklable():
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    with pytest.raises(AttributeError):
        ge.p = 0.2
    with pytest.raises(ValueError):
        ge.P[0, 0] = 0.5
    for ch in (ge, fa.BernoulliChannel(0.3), fa.MarkovChannel([[0.5, 0.5], [1, 0]], [0.1, 0.2], [1, 1])):
        back = pickle.loads(pickle.dumps(ch))
        assert back == ch and type(back) is type(ch) and repr(back) == repr(ch)


def test_as_channel():
    assert as_channel(0.25) == fa.BernoulliChannel(0.25)
    ge = fa.GilbertElliott(0.1, 0.3, 0.9, 0.2)
    assert as_channel(ge) is ge
    with pytest.raises(TypeError, match=names("channel")):
        as_channel("0.5")
    with pytest.raises(TypeError, match=names("chan")):
        as_channel(True, name="chan")
    with pytest.raises(ValueError, match=names("channel")):
        as_channel(1.5)


@pytest.mark.parametrize(
    "P, low, high, exc, arg",
    [
        ([[0.5, 0.4]], [0.5], [1.0], ValueError, "P"),  # not square
        ([[0.5, 0.4], [0.5, 0.5]], [0.5, 0.5], [1, 1], ValueError, "P"),  # row sum
        ([[0.5, 0.5 + 1e-11], [0.5, 0.5]], [0.5, 0.5], [1, 1], ValueError, "P"),  # beyond 1e-12
        ([[1.5, -0.5], [0.5, 0.5]], [0.5, 0.5], [1, 1], ValueError, "P"),  # not a probability
        ([[1.0, 0.0], [0.0, 1.0]], [0.5, 0.5], [1, 1], ValueError, "P"),  # two closed classes
        ([[np.nan, 1.0], [0.5, 0.5]], [0.5, 0.5], [1, 1], ValueError, "P"),
        ("abc", [0.5], [1], TypeError, "P"),
        ([[1.0]], [0.5, 0.5], [1.0], ValueError, "low"),
        ([[1.0]], [1.5], [1.0], ValueError, "low"),
        ([[1.0]], [[0.5]], [1.0], ValueError, "low"),
        ([[1.0]], ["a"], [1.0], TypeError, "low"),
        ([[1.0]], [0.5], [], ValueError, "high"),
        ([[1.0]], [0.5], [-0.1], ValueError, "high"),
        ([[1.0]], [0.5], None, TypeError, "high"),
    ],
)
def test_markov_validation_names_the_argument(P, low, high, exc, arg):
    with pytest.raises(exc, match=names(arg)):
        fa.MarkovChannel(P, low, high)


def test_row_sums_within_tolerance_are_accepted():
    ch = fa.MarkovChannel([[0.5, 0.5 + 5e-13], [0.5, 0.5]], [0.5, 0.5], [1, 1])
    assert_allclose(ch.P.sum(axis=1), 1.0, rtol=0, atol=1e-16)


@pytest.mark.parametrize(
    "kwargs, exc, arg",
    [
        (dict(p=1.1), ValueError, "p"),
        (dict(q=-0.1), ValueError, "q"),
        (dict(p="0.1"), TypeError, "p"),
        (dict(lam_good=2.0), ValueError, "lam_good"),
        (dict(lam_bad=True), TypeError, "lam_bad"),
        (dict(high_good=1.2), ValueError, "high_good"),
        (dict(high_bad=float("nan")), ValueError, "high_bad"),
        (dict(p=0.0, q=0.0), ValueError, "p"),
    ],
)
def test_gilbert_elliott_validation_names_the_argument(kwargs, exc, arg):
    args = dict(p=0.1, q=0.3, lam_good=0.9, lam_bad=0.2) | kwargs
    with pytest.raises(exc, match=names(arg)):
        fa.GilbertElliott(**args)


@pytest.mark.parametrize(
    "lam, exc", [(1.5, ValueError), (-0.1, ValueError), ("x", TypeError), (None, TypeError)]
)
def test_bernoulli_validation_names_lam(lam, exc):
    with pytest.raises(exc, match=names("lam")):
        fa.BernoulliChannel(lam)


@pytest.mark.parametrize("seed", range(4))
def test_closed_classes_by_dense_closure_match_the_graph_algorithm(seed):
    """Small channels take a dense transitive closure; it finds the same closed classes as
    scipy's strongly connected components (the route of larger channels)."""
    from scipy.sparse import csr_array
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(seed)
    for _ in range(300):
        n = int(rng.integers(1, 14))
        P = rng.random((n, n)) * (rng.random((n, n)) < rng.uniform(0.05, 0.6))
        g = csr_array((P > 0).astype(float))
        n_comp, label = connected_components(g, directed=True, connection="strong")
        rows, cols = g.nonzero()
        leaves = np.zeros(n_comp, dtype=bool)
        leaves[label[rows][label[rows] != label[cols]]] = True
        expected = sorted(tuple(np.flatnonzero(label == c)) for c in range(n_comp) if not leaves[c])
        assert sorted(tuple(c) for c in closed_classes(P)) == expected
