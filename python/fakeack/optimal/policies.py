r"""The sensor's power policies that depend on the holding time :math:`\tau` (and the channel state).

A policy of this kind sees, at step k, :math:`\tau_{k-1}` (the steps since the last arrival,
known from per-packet ACKs) and possibly the channel state :math:`c_k`, and picks one of several
transmit power levels at random. Only :math:`\min(\tau_{k-1}, \tau_{\max})` matters: the last row
of the policy holds for every :math:`\tau \ge \tau_{\max}`, so the policy is a finite automaton
over :math:`e = (\min(\tau_{k-1}, \tau_{\max}), c_k)` and its exact cost comes from the engine's
coupled Stein equations (docs page "The exact engine").
"""

from __future__ import annotations

import numbers
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._internal.types import FloatArray
from .._internal.validate import as_real
from ..engine.chains import ScenarioChain
from ..model.channels import Channel, as_channel, gth_stationary

__all__ = [
    "HoldingTimePolicy",
    "PolicyAutomaton",
    "Levels",
    "as_levels",
    "stationary_law",
]

#: Largest deviation of a row of ``p`` from summing to 1 that is accepted (then renormalised away).
ROW_SUM_TOL = 1e-9

#: One power level: its energy per step and its arrival probability (one number, or one per state).
LevelLike = tuple[float, float | Sequence[float]]


class Levels(NamedTuple):
    """Power levels as arrays."""

    energy: FloatArray
    """``(L,)`` energy per step of each level."""
    arrival: FloatArray
    """``(L, K)`` arrival probability of each level in each channel state (K = 1: state-free)."""


def _number(name: str, x: object) -> float:
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (numbers.Real, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__}")
    return as_real(name, x)


def as_levels(levels: object, name: str = "levels") -> Levels:
    """Power levels read from a sequence of ``(energy, arrival)`` pairs.

    ``arrival`` is one probability, or one per channel state (the same number of states for every
    level that gives a list; a single number then holds in every state).

    Raises
    ------
    TypeError, ValueError
        Naming ``levels`` (and the entry), for anything else.
    """
    if isinstance(levels, (str, bytes)) or not isinstance(levels, Sequence):
        raise TypeError(f"{name} must be a sequence of (energy, arrival probability) pairs")
    if len(levels) == 0:
        raise ValueError(f"{name} must hold at least one power level")
    energies: list[float] = []
    arrivals: list[FloatArray] = []
    for i, item in enumerate(levels):
        where = f"{name}[{i}]"
        if isinstance(item, (str, bytes)) or not isinstance(item, Sequence) or len(item) != 2:
            raise TypeError(f"{where} must be a pair (energy, arrival probability), got {item!r}")
        energy = _number(f"{where} energy", item[0])
        if energy < 0.0:
            raise ValueError(f"{where} energy must be non-negative, got {energy}")
        raw = item[1]
        if isinstance(raw, (numbers.Real, np.integer, np.floating)) and not isinstance(raw, (bool, np.bool_)):
            arr = np.array([_number(f"{where} arrival", raw)])
        else:
            try:
                arr = np.asarray(raw, dtype=np.float64)
            except (TypeError, ValueError):
                raise TypeError(f"{where} arrival must be a probability or one per channel state") from None
            if arr.ndim != 1 or arr.size == 0:
                raise ValueError(f"{where} arrival must be a number or a 1-D list, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)) or np.any((arr < 0.0) | (arr > 1.0)):
            raise ValueError(f"{where} arrival probabilities must lie in [0, 1], got {arr.tolist()}")
        energies.append(energy)
        arrivals.append(arr)
    sizes = {a.size for a in arrivals if a.size > 1}
    if len(sizes) > 1:
        raise ValueError(f"{name}: per-state arrival probabilities of different lengths {sorted(sizes)}")
    k = sizes.pop() if sizes else 1
    table = np.array([np.broadcast_to(a, (k,)) for a in arrivals], dtype=np.float64)
    energy_arr = np.array(energies, dtype=np.float64)
    energy_arr.flags.writeable = False
    table.flags.writeable = False
    return Levels(energy_arr, table)


def stationary_law(K: sp.csr_array) -> FloatArray:
    r"""The stationary law :math:`\pi K = \pi`, :math:`\sum \pi = 1` of a row-stochastic sparse matrix
    with one closed class, by a sparse LU solve with the last balance equation replaced by the
    normalisation (clipped at 0: entries of order the rounding error can come out negative)."""
    n = K.shape[0]
    M = (sp.identity(n, format="csr") - K).T.tolil()
    M[n - 1, :] = np.ones(n)
    rhs = np.zeros(n)
    rhs[n - 1] = 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", spla.MatrixRankWarning)
        try:
            pi = np.asarray(spla.spsolve(M.tocsc(), rhs), dtype=np.float64)
        except spla.MatrixRankWarning:
            pi = np.full(n, np.nan)
    if not np.all(np.isfinite(pi)):
        raise ValueError(
            "p: the policy's automaton has no unique stationary law (more than one closed class)"
        )
    pi = np.clip(pi, 0.0, None)
    return pi / pi.sum()


def _stationary_by_levels(loss: FloatArray, P: FloatArray) -> FloatArray | None:
    r"""The stationary law of a policy's automaton from its level structure, to full relative
    accuracy in the tail (a sparse solve leaves entries near the rounding error of the largest).

    Between arrivals the chain runs through t = 0, 1, ..., T by the loss blocks
    :math:`B_t = \mathrm{diag}(\text{loss}_t) P` and loops at T. From an arrival in state c the
    expected visits to level t are row c of :math:`H_t = B_0 \cdots B_{t-1}` (t < T) and of
    :math:`H_{T-1} B_{T-1} (I - B_T)^{-1}` at T; the channel state at arrivals is a Markov chain
    with :math:`R = \sum_t H_t\,\mathrm{diag}(1 - \text{loss}_t) P`, and the law is
    :math:`\mu H_t` normalised, :math:`\mu R = \mu`. Only sums and products of non-negative
    numbers, except :math:`(I - B_T)^{-1}`. None when the loop at T never ends (no arrival).
    """
    n_t, k = loss.shape
    H = np.eye(k)
    occ = np.empty((n_t, k, k))
    for t in range(n_t - 1):
        occ[t] = H
        H = H @ (loss[t][:, None] * P)
    loop = np.eye(k) - loss[-1][:, None] * P
    try:
        occ[-1] = np.linalg.solve(loop.T, H.T).T
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(occ[-1])) or np.any(occ[-1] < -1e-12):
        return None
    R = np.einsum("tij,tj,jk->ik", occ, 1.0 - loss, P)
    R = np.clip(R, 0.0, None)
    R /= R.sum(axis=1, keepdims=True)
    try:
        mu = gth_stationary(R)
    except ValueError:
        return None
    pi = np.clip(np.einsum("i,tij->tj", mu, occ), 0.0, None).ravel()
    return pi / pi.sum()


class PolicyAutomaton(NamedTuple):
    r"""A holding-time policy as the engine's automaton over :math:`e = (\min(\tau_{k-1},
    \tau_{\max}), c_k)`, state index ``t * K + c``."""

    K0: sp.csr_array
    """Transitions on which the packet is lost (:math:`\\tau \\to \\tau + 1`)."""
    K1: sp.csr_array
    """Transitions on which the packet arrives (:math:`\\tau \\to 0`)."""
    stationary: FloatArray
    """The stationary law of e (its mass at ``t = tau_max`` is :math:`\\Pr[\\tau \\ge \\tau_{\\max}]`)."""
    energy_per_step: float
    """The long-run average energy per step."""


@dataclass(frozen=True, eq=False, init=False)
class HoldingTimePolicy:
    r"""A randomised power policy driven by the holding time :math:`\tau` since the last arrival.

    At step k the sensor, knowing :math:`\tau_{k-1}` from per-packet ACKs (and with channel-state
    information also :math:`c_k`), transmits at level l with probability ``p[t, l]`` (or
    ``p[t, c, l]``), :math:`t = \min(\tau_{k-1}, \tau_{\max})`; the packet then arrives with the
    level's probability (in state :math:`c_k`) and :math:`\tau_k = 0` on arrival, else
    :math:`\tau_{k-1} + 1`.

    Parameters
    ----------
    p : array_like, shape (tau_max + 1, L) or (tau_max + 1, K, L)
        Level probabilities; every row sums to 1 (within 1e-9, then renormalised). The last row
        holds for :math:`\tau \ge \tau_{\max}`. A 3-D ``p`` depends on the channel state.
    levels : sequence of (energy, arrival) pairs
        The L power levels: the energy spent per step at that level (non-negative) and the
        probability that its packet arrives, one number or one per channel state.

    Raises
    ------
    TypeError, ValueError
        Naming ``p`` or ``levels`` for a wrong shape, a probability outside [0, 1] or a row that
        does not sum to 1.

    Examples
    --------
    >>> pol = HoldingTimePolicy([[1, 0], [1, 0], [0, 1]], [(1.0, 0.5), (3.0, 1.0)])
    >>> pol.tau_max, str(pol)
    (2, 'tau 0-1: level 0; tau >= 2: level 1')
    >>> round(pol.automaton().energy_per_step, 12)   # high power a fraction 1/7 of the steps
    1.285714285714
    """

    p: FloatArray
    """Level probabilities, ``(tau_max + 1, L)`` or ``(tau_max + 1, K, L)`` (read-only)."""
    levels: Levels
    """The power levels: ``levels.energy`` ``(L,)`` and ``levels.arrival`` ``(L, K)``."""

    def __init__(self, p: npt.ArrayLike, levels: Sequence[LevelLike] | Levels) -> None:
        lv = levels if isinstance(levels, Levels) else as_levels(levels)
        if isinstance(p, (str, bytes)):
            raise TypeError("p must be an array of probabilities")
        try:
            arr = np.array(p, dtype=np.float64)
        except (TypeError, ValueError):
            raise TypeError("p must be an array of probabilities") from None
        n_levels, n_states = lv.arrival.shape
        if arr.ndim not in (2, 3):
            raise ValueError(f"p must be 2-D (tau, level) or 3-D (tau, state, level), got {arr.ndim}-D")
        if arr.shape[-1] != n_levels:
            raise ValueError(f"p must have one column per level ({n_levels}), got shape {arr.shape}")
        if arr.ndim == 3 and n_states > 1 and arr.shape[1] != n_states:
            raise ValueError(
                f"p must have one row per channel state ({n_states}) of levels, got shape {arr.shape}"
            )
        if arr.shape[0] == 0 or (arr.ndim == 3 and arr.shape[1] == 0):
            raise ValueError(f"p must not be empty, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)) or np.any((arr < 0.0) | (arr > 1.0)):
            raise ValueError("p: probabilities must lie in [0, 1]")
        sums = arr.sum(axis=-1)
        bad = np.abs(sums - 1.0) > ROW_SUM_TOL
        if np.any(bad):
            where = tuple(int(i) for i in np.argwhere(bad)[0])
            raise ValueError(f"p: row {where} sums to {float(sums[where])!r}, not 1")
        arr = arr / sums[..., None]
        arr.flags.writeable = False
        object.__setattr__(self, "p", arr)
        object.__setattr__(self, "levels", lv)

    @property
    def tau_max(self) -> int:
        r""":math:`\tau_{\max}`: the last row of ``p`` holds from there on."""
        return int(self.p.shape[0]) - 1

    @property
    def uses_state(self) -> bool:
        """Whether the policy depends on the channel state (a 3-D ``p``)."""
        return self.p.ndim == 3

    def _tables(self, channel: Channel | None) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``p`` as ``(T+1, K, L)``, the arrivals ``(K, L)`` and the channel's ``P``."""
        n_levels, k_levels = self.levels.arrival.shape
        k_policy = self.p.shape[1] if self.uses_state else 1
        if channel is None:
            if max(k_levels, k_policy) > 1:
                raise ValueError(
                    "channel: the policy or its levels depend on a channel state; give the channel"
                )
            P = np.ones((1, 1))
        else:
            P = np.asarray(channel.P)
        k = P.shape[0]
        if k_levels not in (1, k) or k_policy not in (1, k):
            raise ValueError(
                f"channel: {k} states, but the policy or its levels have {max(k_levels, k_policy)}"
            )
        p3 = np.broadcast_to(
            self.p if self.uses_state else self.p[:, None, :], (self.p.shape[0], k, n_levels)
        )
        arrival = np.broadcast_to(self.levels.arrival.T, (k, n_levels))
        return p3, arrival, P

    def automaton(self, channel: Channel | float | None = None) -> PolicyAutomaton:
        r"""The engine's automaton of this policy on a channel: loss and arrival transitions over
        :math:`e = (\min(\tau_{k-1}, \tau_{\max}), c_k)`, and the stationary energy per step.

        From e = (t, c) the sensor picks level l with ``p[t, c, l]``; the packet arrives with
        probability ``arrival[l, c]`` (then f = (0, c')) or is lost (f = (min(t+1, tau_max), c')),
        and the channel moves to c' by its ``P``. The channel's own ``low`` and ``high`` are not
        used: the levels carry the arrival probabilities.

        Parameters
        ----------
        channel : Channel or float, optional
            The channel whose state process drives per-state arrivals (None: one state).

        Returns
        -------
        PolicyAutomaton
            ``K0``, ``K1`` (sparse, ``(T+1)K`` square), the stationary law and the energy per step.
        """
        ch = None if channel is None else as_channel(channel, "channel")
        p3, arrival, P = self._tables(ch)
        n_t, k, _ = p3.shape
        loss = np.einsum("tcl,cl->tc", p3, 1.0 - arrival)  # (T+1, K)
        src = np.arange(n_t * k).reshape(n_t, k)
        nxt = np.minimum(np.arange(n_t) + 1, n_t - 1)
        rows = np.repeat(src.ravel(), k)  # e = (t, c) -> (., c') for every c'
        c_to = np.tile(np.arange(k), n_t * k)
        t_from, c_from = np.divmod(rows, k)
        move = P[c_from, c_to]
        loss_w = loss[t_from, c_from] * move
        n = n_t * k
        K0 = sp.csr_array((loss_w, (rows, nxt[t_from] * k + c_to)), shape=(n, n))
        K1 = sp.csr_array(((1.0 - loss[t_from, c_from]) * move, (rows, c_to)), shape=(n, n))
        K0.eliminate_zeros()
        K1.eliminate_zeros()
        pi = _stationary_by_levels(loss, P)
        if pi is None:
            pi = stationary_law(sp.csr_array(K0 + K1))
        energy = float(pi @ (p3 @ self.levels.energy).ravel())
        return PolicyAutomaton(K0, K1, pi, energy)

    def scenario_chain(self, channel: Channel | float) -> ScenarioChain:
        r"""This sensor as a :class:`fakeack.Scenario` schedule: :meth:`automaton` with the state
        before step 1, :math:`(\tau_0 = 0, c_1)`, :math:`c_1` stationary.

        ``fa.Scenario(system, channel, policy)`` solves it by the coupled Stein equations
        :math:`Z_e = \bar P + (w_e - 1) Q + \sum_f K_0[e, f] A Z_f A'`; its
        ``energy_per_step()`` is :math:`\sum_{t,c} \pi(t, c) \sum_l p[t, c, l]\, e_l` and
        ``cost_curve`` starts from :math:`\tau_0 = 0`. The policy has L power levels, not a
        high and a low one, and reads per-packet ACKs: the scenario's ``high_power_rate`` and
        ``flag_rates`` raise ValueError.

        Parameters
        ----------
        channel : Channel or float
            The channel whose state process drives per-state arrivals.

        Returns
        -------
        fakeack.engine.chains.ScenarioChain
            States ``t * K + c`` labelled ``tau=t c=c`` (``tau>=T`` for the last row).

        Examples
        --------
        >>> import fakeack as fa
        >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
        >>> pol = HoldingTimePolicy([[1, 0], [1, 0], [0, 1]], [(1.0, 0.5), (3.0, 1.0)])
        >>> sc = fa.Scenario(s, 0.5, pol)   # the online schedule z0 = 2, mu = 1 (Theorem 4.5)
        >>> bool(abs(sc.cost() - fa.Scenario(s, 0.5, fa.OnlineDesign(2)).cost()) < 1e-12)
        True
        >>> round(sc.energy_per_step(), 12)
        1.285714285714
        """
        ch = as_channel(channel, "channel")
        aut = self.automaton(ch)
        p3, _, _ = self._tables(ch)
        n_t, k, _ = p3.shape
        init = np.zeros(n_t * k)
        init[:k] = ch.stationary
        last = n_t - 1
        labels = [f"tau{'>=' if t == last else '='}{t} c={c}" for t in range(n_t) for c in range(k)]
        energy = np.asarray(p3 @ self.levels.energy, dtype=np.float64).ravel()
        return ScenarioChain(aut.K0, aut.K1, init, labels, aut.stationary, energy=energy)

    def __repr__(self) -> str:
        return f"HoldingTimePolicy(<p of shape {self.p.shape}>, levels={len(self.levels.energy)})"

    def __str__(self) -> str:
        if self.uses_state:
            return "; ".join(f"state {c}: {_rows(self.p[:, c, :])}" for c in range(self.p.shape[1]))
        return _rows(self.p)


def _action(row: FloatArray) -> str:
    on = [(int(i), float(row[i])) for i in np.flatnonzero(row > 0.0)]
    if len(on) == 1:
        return f"level {on[0][0]}"
    return " + ".join(f"{v:.6g} level {i}" for i, v in on)


def _rows(p: FloatArray) -> str:
    """``tau a-b: action`` runs of equal rows, the last one open-ended."""
    parts: list[str] = []
    start = 0
    last = p.shape[0] - 1
    for t in range(1, p.shape[0] + 1):
        if t <= last and np.array_equal(p[t], p[start]):
            continue
        if t - 1 == last:
            span = f"tau >= {start}"
        elif t - 1 == start:
            span = f"tau {start}"
        else:
            span = f"tau {start}-{t - 1}"
        parts.append(f"{span}: {_action(p[start])}")
        start = t
    return "; ".join(parts)
