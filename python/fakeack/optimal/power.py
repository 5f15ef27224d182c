r"""The sensor's optimal power policy: an average-cost constrained MDP solved as a linear program.

The sensor picks one of several power levels l (energy :math:`e_l`, arrival probability
:math:`\lambda_l`, or :math:`\lambda_l(c)` in channel state c) at every step, knowing
:math:`\tau_{k-1}` from per-packet ACKs (and :math:`c_k` with channel-state information). The
cost of step k is :math:`\mathrm{Tr}\,P_k = \mathrm{Tr}\,h^{\tau_k}(\bar P)`, and the long-run
average energy must stay within a budget. Over occupation measures
:math:`x(t, c, l) = \Pr[\min(\tau_{k-1}, T) = t, c_k = c, \text{level } l]` this is the LP

.. math::
   \min_x \sum_{t,c,l} x(t,c,l)\big[\lambda_l(c)\,\mathrm{tr}_0
      + (1-\lambda_l(c))\,\mathrm{tr}_{t+1}\big]
   \quad\text{s.t.}\quad \sum_{t,c,l} e_l\,x(t,c,l) \le \Psi,

with :math:`\mathrm{tr}_i = \mathrm{Tr}\,h^i(\bar P)`, the balance of the chain over (t, c), the
channel's stationary marginal :math:`\sum_{t,l} x(t,c,l) = \pi_c`, and :math:`x \ge 0`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.optimize import linprog
from scipy.sparse.csgraph import breadth_first_order

from .._fakeack import ConvergenceError
from .._internal.types import FloatArray
from .._internal.validate import as_int, as_real
from ..engine.scenario import Scenario
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.system import LinearSystem, compiled
from .policies import HoldingTimePolicy, LevelLike, Levels, as_levels, stationary_law

__all__ = [
    "PowerPolicyResult",
    "optimal_power_policy",
    "TAIL_RTOL",
    "MAX_AUTO_TAU",
    "MAX_TAU",
]

#: The automatic truncation stops once ``tail_bound <= TAIL_RTOL * j``.
TAIL_RTOL = 1e-12
#: First truncation tried, then doubled.
FIRST_TAU = 64
#: The automatic truncation refuses beyond this tau_max.
MAX_AUTO_TAU = 1024
#: Largest tau_max accepted when given.
MAX_TAU = 4096
#: A row of the LP solution whose scaled mass is below this is taken as never visited.
MASS_TOL = 1e-10
#: Level probabilities below this in the LP solution are rounding noise of the solver.
PROB_TOL = 1e-9
#: HiGHS feasibility tolerances (its defaults are 1e-7).
LP_TOL = 1e-10


@dataclass(frozen=True)
class PowerPolicyResult:
    r"""The optimal holding-time power policy (see :func:`optimal_power_policy`).

    The optimum :math:`J^\star` over all policies of the information given satisfies
    ``j_lp <= J* <= j <= j_lp + tail_bound`` (up to the LP's tolerance, about 1e-9 relative).
    """

    j: float
    """The exact long-run cost J of ``policy`` (its whole tail of :math:`\\tau` included)."""
    j_lp: float
    """The LP's optimal value: a lower bound on the optimum."""
    energy_per_step: float
    """The exact long-run energy per step of ``policy`` (within the budget up to the LP's tolerance)."""
    policy: HoldingTimePolicy
    """The optimal policy (rows never visited hold the level most likely to arrive)."""
    tail_bound: float
    """A rigorous bound on ``j - j_lp`` from the truncation at ``tau_max`` (0 when tau never passes it)."""
    tau_max: int
    """The truncation :math:`T`: the policy's last row holds for every :math:`\\tau \\ge T`."""


def optimal_power_policy(
    system: LinearSystem,
    channel: ChannelLike,
    levels: list[LevelLike] | tuple[LevelLike, ...],
    budget: float,
    *,
    information: str = "ack",
    csi: bool = False,
    tau_max: int | None = None,
) -> PowerPolicyResult:
    r"""The power policy of least long-run cost J within an energy budget, by linear programming.

    **Model.** At step k the sensor knows :math:`\tau_{k-1}` (per-packet ACKs,
    ``information="ack"``) and, with ``csi=True``, the channel state :math:`c_k`; it transmits
    at level l, whose packet arrives with probability :math:`\lambda_l` (or :math:`\lambda_l(c_k)`);
    :math:`\tau_k = 0` on arrival, else :math:`\tau_{k-1}+1`; the step costs
    :math:`\mathrm{Tr}\,h^{\tau_k}(\bar P)`, :math:`h(X) = AXA' + Q`; the channel then moves by
    its ``P``. The long-run energy per step must not exceed ``budget``.

    **The LP.** Over the occupation measure :math:`x(t, c, l)` of
    :math:`(\min(\tau_{k-1}, T), c_k, l)` (module docstring). The aggregated state
    :math:`t = T` stands for every :math:`\tau \ge T`, costed at :math:`\mathrm{tr}_{T+1}` after a
    loss, which is at most the true cost; every policy's aggregated measure is feasible, so the LP
    is a relaxation and ``j_lp`` a lower bound on the optimum. A vertex solution randomises in at
    most one state (one constraint besides the balance).

    **Scaling.** Unscaled, the costs :math:`\mathrm{tr}_{t+1}` grow like :math:`\rho(A)^{2t}` while
    the masses fall geometrically, and HiGHS fails on the paper's example from :math:`T = 76`.
    The LP is solved in :math:`y(t,\cdot) = x(t,\cdot)/g^t` with :math:`g` the largest loss
    probability of any level (so :math:`y \le 1`), or :math:`\rho(A)^{-2}` if smaller; the sums
    over all t (normalisation, energy) run through cumulative variables
    :math:`\sigma_t = y_t + g\,\sigma_{t+1}`, so every matrix entry is of order one.

    **The tail bound.** With :math:`m_T = \Pr[\tau \ge T]` under the returned policy and
    :math:`a_T` its largest loss probability in the row :math:`T` (over channel states),
    :math:`\Pr[\tau_k = T+1+j] \le m_T a_T^{j+1}`, so the cost the aggregation leaves out is at
    most :math:`m_T \sum_{j\ge1} a_T^{j+1}\,\mathrm{Tr}\big(h^j(X) - X\big) = m_T\,a_T\,\mathrm{Tr}\,W`,
    :math:`X = h^{T+1}(\bar P)`, where :math:`W = a_T A W A' + \frac{a_T}{1-a_T}(h(X) - X)`
    (``inf`` when :math:`a_T\rho(A)^2 \ge 1`). Hence ``j_lp <= J* <= j <= j_lp + tail_bound``.

    Parameters
    ----------
    system : LinearSystem
        The process and its sensor.
    channel : Channel or float
        The channel; only its state process ``P`` is used (the levels carry the arrival
        probabilities). A float or a one-state channel: arrivals independent over time.
    levels : sequence of (energy, arrival) pairs
        The power levels, as for :class:`HoldingTimePolicy`: energy per step and arrival
        probability, one number or one per channel state.
    budget : float
        Largest long-run energy per step, at least the cheapest level's energy (a budget above
        the dearest level's is slack).
    information : {"ack"}, keyword-only, optional
        What the sensor learns after each step: ``"ack"``, a per-packet acknowledgement.
    csi : bool, keyword-only, optional
        Whether the sensor also knows the channel state (default False). Irrelevant when the
        arrivals do not depend on the state.
    tau_max : int, keyword-only, optional
        The truncation :math:`T \ge 1` (at most 4096). None: 64, doubled until ``tail_bound`` is
        at most 1e-12 of ``j``, refused (ValueError) past 1024.

    Returns
    -------
    PowerPolicyResult

    Raises
    ------
    ValueError
        Naming ``budget`` below the cheapest level; ``information`` other than ``"ack"``;
        ``csi`` False when arrivals depend on the state of a Markov channel (the sensor's belief
        of the state then depends on its whole ACK history, a partially observed problem that an
        LP over :math:`\tau` does not solve exactly; ``csi=True`` gives the full-information
        optimum, a lower bound); ``tau_max`` when the automatic truncation reaches its cap or
        finds only policies of infinite cost (a budget that affords no finite J).
    ConvergenceError
        If HiGHS does not solve the LP.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> res = optimal_power_policy(s, 0.5, [(1.0, 0.5), (3.0, 1.0)], 1 + 2 / 7)
    >>> str(res.policy)
    'tau 0-1: level 0; tau >= 2: level 1'
    >>> round(res.j, 10) == round(fa.j_online(s, 0.5, 2), 10)
    True
    """
    compiled(system)
    ch = as_channel(channel, "channel")
    lv = as_levels(levels)
    budget_v = as_real("budget", budget)
    if information != "ack":
        raise ValueError(f"information must be 'ack' (per-packet acknowledgements), got {information!r}")
    if not isinstance(csi, (bool, np.bool_)):
        raise TypeError(f"csi must be True or False, got {csi!r}")
    k_levels = lv.arrival.shape[1]
    if k_levels not in (1, ch.n_states):
        raise ValueError(
            f"levels: arrival probabilities for {k_levels} states, the channel has {ch.n_states}"
        )
    cheapest = float(lv.energy.min())
    if budget_v < cheapest:
        raise ValueError(f"budget must be at least the cheapest level's energy {cheapest}, got {budget_v}")
    state_dependent = ch.n_states > 1 and bool(np.any(np.ptp(lv.arrival, axis=1) > 0.0))
    if state_dependent and not csi:
        raise ValueError(
            "csi: on this channel the arrivals depend on the channel state, and without channel-state "
            "information the sensor's belief of the state depends on its whole ACK history (a partially "
            "observed problem the LP over tau does not solve exactly); use csi=True for the "
            "full-information optimum, a lower bound"
        )
    use_state = bool(csi) and ch.n_states > 1
    if tau_max is not None:
        return _solve(
            system, ch, lv, budget_v, use_state, as_int("tau_max", tau_max, minimum=1, maximum=MAX_TAU)
        )
    T, prev = FIRST_TAU, None
    while True:
        try:
            res = _solve(system, ch, lv, budget_v, use_state, T)
        except ConvergenceError:
            if prev is None or math.isfinite(prev.j):
                raise
            res = None  # after a diverging policy, masses that outgrow the scaling: the cost diverges
        if res is not None and math.isfinite(res.j) and res.tail_bound <= TAIL_RTOL * res.j:
            return res
        if res is None or 2 * T > MAX_AUTO_TAU:
            if res is None or not math.isfinite(res.j):
                raise ValueError(
                    f"tau_max: up to tau = {T} the LP's policy has an infinite cost (packets lost too often "
                    "where tau is long): the budget may afford no finite cost. Give tau_max to see the "
                    "truncated LP's value"
                )
            raise ValueError(
                f"tau_max: the tail beyond tau = {T} is not negligible (bound {res.tail_bound:.3g} against "
                f"J = {res.j:.6g}); give tau_max to accept a truncated answer with its tail_bound"
            )
        T, prev = 2 * T, res


def _scale(lv: Levels, rho: float) -> float:
    """The geometric scale g of the LP's columns (see :func:`optimal_power_policy`)."""
    worst = float(np.max(1.0 - lv.arrival))
    g = worst if worst > 0.0 else 1.0
    return min(g, 1.0 / rho**2) if rho > 1.0 else g


def _solve(
    system: LinearSystem, ch: Channel, lv: Levels, budget: float, use_state: bool, T: int
) -> PowerPolicyResult:
    if use_state:
        P, pi = np.asarray(ch.P), np.asarray(ch.stationary)
        lam = lv.arrival.T if lv.arrival.shape[1] > 1 else np.repeat(lv.arrival.T, ch.n_states, axis=0)
    else:
        P, pi, lam = np.ones((1, 1)), np.ones(1), lv.arrival[:, :1].T  # the state carries no information
    K, L = lam.shape
    n_t = T + 1
    g = _scale(lv, system.spectral_radius)
    with np.errstate(over="ignore"):
        wt = system.weighted_traces(g, T + 1)  # g^i tr_i
    tr0 = float(wt[0])
    gt = g ** np.arange(n_t, dtype=np.float64)
    cost = lam[None, :, :] * (gt * tr0)[:, None, None] + (1.0 - lam)[None, :, :] * (wt[1:] / g)[:, None, None]
    ny, ns = n_t * K * L, n_t * K
    nvar = ny + ns + n_t
    iy = np.arange(ny).reshape(n_t, K, L)
    isig = ny + np.arange(ns).reshape(n_t, K)
    ieps = ny + ns + np.arange(n_t)
    loss = 1.0 - lam  # (K, L)
    rows: list[npt.NDArray[Any]] = []
    cols: list[npt.NDArray[Any]] = []
    vals: list[npt.NDArray[Any]] = []

    def put(r: object, c: object, v: object) -> None:
        r_, c_, v_ = np.broadcast_arrays(np.asarray(r), np.asarray(c), np.asarray(v, dtype=np.float64))
        rows.append(r_.ravel())
        cols.append(c_.ravel())
        vals.append(v_.ravel())

    # Balance of (t, c') for t = 1..T: mass in = loss flow from t-1 (and from T itself at t = T).
    tt = np.arange(1, n_t)
    brow = (tt - 1)[:, None] * K + np.arange(K)[None, :]  # (T, K)
    put(brow[:, :, None], iy[1:], 1.0)
    flow = loss[:, :, None] * P[:, None, :]  # (c, l, c')
    put(brow[:, None, None, :], iy[:-1, :, :, None], -flow[None] / g)
    put(brow[-1][None, None, :], iy[T][:, :, None], -flow)
    r0 = T * K
    # Cumulative masses sigma(t, c) = sum_l y(t, c, l) + g sigma(t+1, c).
    srow = r0 + np.arange(ns).reshape(n_t, K)
    put(srow, isig, 1.0)
    put(srow[:, :, None], iy, -1.0)
    put(srow[:-1], isig[1:], -g)
    r0 += ns
    put(r0 + np.arange(K), isig[0], 1.0)  # the channel's stationary marginal
    r0 += K
    # Cumulative energies eps(t) = sum_{c,l} e_l y(t, c, l) + g eps(t+1).
    erow = r0 + np.arange(n_t)
    put(erow, ieps, 1.0)
    put(erow[:, None, None], iy, -lv.energy[None, None, :])
    put(erow[:-1], ieps[1:], -g)
    n_eq = r0 + n_t
    ij = (np.concatenate(rows).astype(np.intp), np.concatenate(cols).astype(np.intp))
    A_eq = sp.csr_array((np.concatenate(vals).astype(np.float64), ij), shape=(n_eq, nvar))
    b_eq = np.zeros(n_eq)
    b_eq[r0 - K : r0] = pi
    A_ub: sp.csr_array | None = sp.csr_array(
        (np.ones(1), (np.zeros(1, dtype=np.intp), ieps[:1])), shape=(1, nvar)
    )
    c = np.zeros(nvar)
    c[:ny] = cost.ravel()
    upper = np.full(nvar, np.inf)
    if budget <= float(lv.energy.min()):
        # A budget of exactly the cheapest energy admits only the cheapest levels: said through
        # the bounds, since HiGHS does not solve the LP whose feasible set lies on the budget's face.
        upper[iy[:, :, lv.energy > budget].ravel()] = 0.0
        A_ub = None
    res = linprog(
        c,
        A_ub=cast(Any, A_ub),  # HiGHS takes sparse matrices; the stubs list only dense ones
        b_ub=None if A_ub is None else [budget],
        A_eq=cast(Any, A_eq),
        b_eq=b_eq,
        bounds=cast(Any, np.column_stack([np.zeros(nvar), upper])),
        method="highs",
        # Presolve fails (status "Not Set") on the deep, tiny-cost columns of tau_max near 200;
        # the LP is small and well scaled, so it is solved as it stands.
        options={
            "primal_feasibility_tolerance": LP_TOL,
            "dual_feasibility_tolerance": LP_TOL,
            "presolve": False,
        },
    )
    if res.status != 0:
        raise ConvergenceError(f"the power LP (tau_max = {T}) was not solved: {res.message}")
    assert res.x is not None and res.fun is not None  # status 0: solved
    y = np.clip(res.x[:ny].reshape(n_t, K, L), 0.0, None)
    p = _policy_rows(y, lam, lv.energy)
    policy = HoldingTimePolicy(p if use_state else p[:, 0], lv)
    aut = policy.automaton(ch)
    j = _automaton_cost(system, aut.K0, aut.K1)
    bound = _tail_bound(system, policy, aut.stationary, lam)
    return PowerPolicyResult(float(j), float(res.fun), aut.energy_per_step, policy, bound, T)


def _policy_rows(y: FloatArray, lam: FloatArray, energy: FloatArray) -> FloatArray:
    """Level probabilities from the scaled occupation measure; rows never visited take the level
    most likely to arrive (the cheapest among equals), which changes neither J nor the energy."""
    mass = y.sum(axis=2, keepdims=True)
    p = np.divide(y, mass, out=np.zeros_like(y), where=mass > MASS_TOL)
    p[p < PROB_TOL] = 0.0
    best = np.lexsort((energy[None, :].repeat(lam.shape[0], 0), -lam), axis=1)[:, 0]  # (K,)
    empty = p.sum(axis=2) == 0.0
    t_idx, c_idx = np.nonzero(empty)
    p[t_idx, c_idx, best[c_idx]] = 1.0
    return p / p.sum(axis=2, keepdims=True)


def _tail_bound(system: LinearSystem, policy: HoldingTimePolicy, pi: FloatArray, lam: FloatArray) -> float:
    """The bound m_T a_T Tr W of :func:`optimal_power_policy` on what the truncation leaves out."""
    T = policy.tau_max
    m_T = float(pi[T * (pi.size // (T + 1)) :].sum())  # the automaton's last tau row, every channel state
    row = policy.p[T] if policy.uses_state else np.broadcast_to(policy.p[T], lam.shape)
    a_T = float(np.max(np.sum(row * (1.0 - lam), axis=1)))
    if m_T == 0.0 or a_T == 0.0:
        return 0.0
    if a_T * system.spectral_radius**2 >= 1.0:
        return float("inf")
    A, Q = system.A, system.Q
    X = system.pbar
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(T + 1):
            X = A @ X @ A.T + Q
        E = A @ X @ A.T + Q - X
        if not np.all(np.isfinite(E)):
            return float("inf")
        W = sla.solve_discrete_lyapunov(np.sqrt(a_T) * A, E * (a_T / (1.0 - a_T)))
        return float(m_T * a_T * np.trace(W))


def _automaton_cost(system: LinearSystem, K0: sp.csr_array, K1: sp.csr_array) -> float:
    r"""J of the automaton ``(K0, K1)`` by the exact engine (:meth:`fakeack.Scenario.from_automaton`):
    :math:`Z_e = \bar P + (w_e - 1)Q + \sum_f K_0[e,f] A Z_f A'`, :math:`J = \mathrm{Tr}\sum_e \nu_e Z_e`,
    :math:`\nu = \pi K_1`, :math:`w = (I - K_0)^{-1}\mathbf 1`; ``inf`` when
    :math:`\rho(K_0)\rho(A)^2 \ge 1`. Only the states the chain visits in the long run are
    passed (a policy's unvisited rows, e.g. past a threshold whose level always arrives, are
    unreachable, which the engine refuses)."""
    K0, K1 = sp.csr_array(K0), sp.csr_array(K1)
    K = sp.csr_array(K0 + K1)
    pi = stationary_law(K)
    # The closed class: every state reachable from the likeliest one (the chain is a unichain).
    keep = np.sort(breadth_first_order(K, int(np.argmax(pi)), directed=True, return_predecessors=False))
    sub0, sub1 = K0[keep][:, keep], K1[keep][:, keep]
    if sub1.sum() == 0.0:  # the closed class never arrives: tau grows without end
        return float("inf")
    init = np.clip(pi[keep], 0.0, None)
    return Scenario.from_automaton(system, sub0, sub1, init=init / init.sum()).cost()
