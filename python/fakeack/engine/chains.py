r"""Sensor policies and attackers that bring their own automaton: the protocol
:class:`fakeack.Scenario` reads them by.

An object that is not one of the engine's built-in schedules or attacks can still be a scenario's
``schedule`` or ``attack`` if it writes itself out as the engine's automaton E: a method
``scenario_chain`` that returns a :class:`ScenarioChain` (its :math:`K_0`, :math:`K_1`, the law of
the state before step 1, a label per state, the long-run law, and per state what the step costs
in energy or does with the flag-ACKs). The engine solves it like any automaton given as
:math:`K_0` and :math:`K_1` (:meth:`fakeack.Scenario.from_automaton`), and the optional per-state
vectors give the power and flag-ACK rates. ``fakeack.HoldingTimePolicy`` (a schedule) and
``fakeack.StatePolicy`` (an attacker) implement it. The engine checks the protocol by the
method's presence, so it needs no import of the classes that implement it.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import breadth_first_order, connected_components

from .._internal.types import FloatArray
from ..attacks.rates import FlagRates
from ..model.channels import Channel
from ..model.schedules import OnlineDesign

__all__ = [
    "ScenarioChain",
    "SchedulePolicy",
    "AttackPolicy",
    "has_chain",
    "reachable",
    "restricted",
    "long_run_law",
    "chain_mean",
    "chain_flag_rates",
]

#: Long-run mass a chain may put on states its initial law never reaches.
_LOST_MASS = 1e-9


class ScenarioChain(NamedTuple):
    r"""A policy as the engine's automaton E: the state e holds everything but the holding time.

    ``K0[e, f]`` is the probability of moving from e to f with the step's packet lost
    (:math:`\tau \to \tau + 1`), ``K1[e, f]`` with it arriving (:math:`\tau \to 0`); the cost is
    the engine's :math:`J = \mathrm{Tr}\sum_e \nu_e Z_e` of the coupled Stein equations.
    """

    K0: sp.csr_array
    """Transitions on which the packet is lost."""
    K1: sp.csr_array
    """Transitions on which the packet arrives."""
    init: FloatArray
    r"""The law of the state before step 1 (:math:`\tau_0 = 0`)."""
    labels: list[str]
    """One readable label per state."""
    stationary: FloatArray | None
    """The long-run law of the states, for the rates (None: computed from ``init``)."""
    energy: FloatArray | None = None
    """Per state, the expected energy of the step that leaves it (a sensor policy's levels)."""
    high: FloatArray | None = None
    """Per state, the probability that the step that leaves it is at high power."""
    flags: tuple[FloatArray, FloatArray, FloatArray] | None = None
    """Per state, flag-ACKs per step: sent by the detector, reaching the sensor, forged."""


class SchedulePolicy(Protocol):
    """A sensor policy a scenario takes as ``schedule`` (``fakeack.HoldingTimePolicy``)."""

    def scenario_chain(self, channel: Channel) -> ScenarioChain:
        """The automaton of this sensor on ``channel``."""
        ...


class AttackPolicy(Protocol):
    """An attacker a scenario takes as ``attack`` (``fakeack.StatePolicy``)."""

    def scenario_chain(self, channel: Channel, design: OnlineDesign) -> ScenarioChain:
        """The automaton of this attacker against the online schedule ``design`` on ``channel``."""
        ...


def has_chain(x: object) -> bool:
    """Whether ``x`` writes itself out as an automaton (a ``scenario_chain`` method)."""
    return callable(getattr(x, "scenario_chain", None))


def reachable(K0: sp.csr_array, K1: sp.csr_array, init: FloatArray) -> np.ndarray:
    """The sorted indices of the states reachable from the support of ``init``."""
    n = K0.shape[0]
    start = np.flatnonzero(init > 0.0)
    graph = sp.coo_array(K0 + K1)
    # One root (index 0) before the initial states: a breadth-first search from it reaches the union.
    rows = np.concatenate([np.zeros(start.size, dtype=np.intp), np.asarray(graph.row) + 1])
    cols = np.concatenate([start + 1, np.asarray(graph.col) + 1])
    aug = sp.csr_array((np.ones(rows.size), (rows, cols)), shape=(n + 1, n + 1))
    order = breadth_first_order(aug, 0, directed=True, return_predecessors=False)
    return np.sort(np.asarray(order[order > 0], dtype=np.intp) - 1)


def restricted(chain: ScenarioChain, role: str) -> ScenarioChain:
    """``chain`` on the states its initial law reaches (the engine requires every state reached),
    with its long-run law."""
    n = chain.K0.shape[0]
    for name, arr in (("init", chain.init), ("stationary", chain.stationary)):
        if arr is not None and np.shape(arr) != (n,):
            raise ValueError(f"{role}: its chain's {name} has shape {np.shape(arr)}, expected {(n,)}")
    if len(chain.labels) != n:
        raise ValueError(f"{role}: its chain has {len(chain.labels)} labels for {n} states")
    init = np.asarray(chain.init, dtype=np.float64)
    keep = reachable(chain.K0, chain.K1, init)
    K0, K1 = sp.csr_array(chain.K0[keep][:, keep]), sp.csr_array(chain.K1[keep][:, keep])
    if chain.stationary is None:
        pi = long_run_law(K0, K1, init[keep])
    else:
        full = np.asarray(chain.stationary, dtype=np.float64)
        lost = float(full.sum() - full[keep].sum())
        if lost > _LOST_MASS:
            raise ValueError(f"{role}: its chain settles where the initial law never leads (mass {lost:.3g})")
        pi = full[keep] / full[keep].sum()

    def cut(v: FloatArray | None) -> FloatArray | None:
        return None if v is None else np.asarray(v)[keep]

    flags = None if chain.flags is None else tuple_cut(chain.flags, keep)
    labels = chain.labels if keep.size == n else [chain.labels[i] for i in keep]
    return ScenarioChain(K0, K1, init[keep], labels, pi, cut(chain.energy), cut(chain.high), flags)


def long_run_law(K0: sp.csr_array, K1: sp.csr_array, init: FloatArray) -> FloatArray:
    r"""The Cesàro limit of the law of e from ``init``: each closed class's stationary law,
    weighted by the chance of ending in it (every state reachable from ``init``).

    The weights are the mass of ``init`` in the class plus :math:`y K_{TC}\mathbf 1`,
    :math:`y = \text{init}_T (I - K_{TT})^{-1}` over the transient states T; a class's law
    solves :math:`\pi K = \pi` with its first state's :math:`\pi` set to 1, then normalised.
    """
    K = sp.csr_array(K0 + K1)
    n = K.shape[0]
    classes = closed_classes_of(K)
    pi = np.zeros(n)
    in_class = np.zeros(n, dtype=bool)
    for members in classes:
        in_class[members] = True
    transient = np.flatnonzero(~in_class)
    y = np.zeros(0)
    if transient.size:
        KTT = K[transient][:, transient]
        M = sp.csc_array((sp.identity(transient.size) - KTT).T)
        y = np.atleast_1d(np.asarray(spla.spsolve(M, init[transient]), dtype=np.float64))
    for members in classes:
        weight = float(init[members].sum())
        if transient.size:
            weight += float(y @ np.asarray(K[transient][:, members].sum(axis=1)).ravel())
        if weight <= 0.0:
            continue
        m = members.size
        if m == 1:
            pi[members] = weight
            continue
        # pi_r = 1 for the first member, the other balance equations for the rest: no dense
        # normalisation row to fill the LU in.
        Kc = K[members][:, members]
        M = sp.csc_array((sp.identity(m) - Kc).T.tocsr()[1:][:, 1:])
        rhs = np.asarray(Kc[[0]][:, 1:].todense()).ravel()
        rest = np.atleast_1d(np.asarray(spla.spsolve(M, rhs), dtype=np.float64))
        law = np.clip(np.concatenate([[1.0], rest]), 0.0, None)
        pi[members] = weight * law / law.sum()
    return pi / pi.sum()


def closed_classes_of(K: sp.csr_array) -> list[np.ndarray]:
    """The closed communicating classes of the transition graph of K."""
    n_comp, label = connected_components(K, directed=True, connection="strong")
    rows, cols = K.nonzero()
    leaves = np.zeros(n_comp, dtype=bool)
    leaves[label[rows][label[rows] != label[cols]]] = True
    return [np.flatnonzero(label == c) for c in range(n_comp) if not leaves[c]]


def tuple_cut(
    flags: tuple[FloatArray, FloatArray, FloatArray], keep: np.ndarray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Each of three per-state vectors on the states ``keep``."""
    return (np.asarray(flags[0])[keep], np.asarray(flags[1])[keep], np.asarray(flags[2])[keep])


def chain_mean(chain: ScenarioChain, values: FloatArray) -> float:
    """The long-run mean of a per-state quantity, :math:`\\sum_e \\pi_e v_e`."""
    assert chain.stationary is not None  # restricted() computes it
    return float(np.asarray(chain.stationary) @ np.asarray(values, dtype=np.float64))


def chain_flag_rates(chain: ScenarioChain) -> FlagRates | None:
    """Long-run flag-ACKs per step from the chain's per-state flags (None if it gives none)."""
    if chain.flags is None:
        return None
    sent, delivered, forged = (chain_mean(chain, v) for v in chain.flags)
    return FlagRates(sent, delivered, forged)
