r"""The worst attack on the flag-ACKs: a linear program over the occupation measure of
:math:`(\min(\tau_k, T), e, a)`.

The attacker reads, at the end of every step, :math:`t = \min(\tau_k, T)` and the attack-free
state :math:`e = (c_k, n, \text{flag})` (:mod:`fakeack.optimal.state_policy`), and chooses the
sensor's next power :math:`a` (block a genuine flag-ACK: low; forge one on a quiet step: high).
Over :math:`x(t, e, a)`, the long-run frequency of (t, e, a), the worst attack within a blocking
budget :math:`\beta` solves

.. math::
   \max_x \sum_{t,e,a} x(t,e,a)\,\bar c_t \quad\text{s.t.}\quad
   \sum_{e \in \text{flag}} x(t,e,\text{low}) \le \beta \sum_{e \in \text{flag},a} x(t,e,a)
   \ \text{(summed over t)},

with the balance of the chain for :math:`t \ge 1`, the channel's stationary marginal and
:math:`x \ge 0`; :math:`\bar c_t = \mathrm{Tr}\,h^t(\bar P)` for t < T and an upper bound of
the cost of every :math:`\tau \ge T` at t = T (:func:`worst_attack`).
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

from .._fakeack import ConvergenceError
from .._internal.validate import as_int, as_probability
from ..attacks.automata import AttackerAutomaton
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.schedules import OnlineDesign
from ..model.system import LinearSystem, compiled
from .power import FIRST_TAU, LP_TOL, MASS_TOL, MAX_AUTO_TAU, MAX_TAU, PROB_TOL, TAIL_RTOL
from .state_policy import StatePolicy, Steps, protocol_steps

__all__ = ["WorstAttack", "worst_attack", "INFORMATION", "STEALTH"]

#: Rows of the LP's solution below this share of its value are taken as unvisited.
SHARE_TOL = 1e-14
#: The attackers' information :func:`worst_attack` knows.
INFORMATION = ("eavesdrop",)
#: The stealth constraints :func:`worst_attack` knows (None: no constraint).
STEALTH: tuple[str | None, ...] = (None,)


@dataclass(frozen=True)
class WorstAttack:
    r"""The worst attack within a blocking budget (see :func:`worst_attack`).

    Up to the LP's tolerance (about 1e-9 relative),
    ``j_lp - tail_bound <= j <= J* <= j_lp``, with :math:`J^\star` the supremum of J over every
    attacker within the budgets.
    """

    j: float
    """The exact long-run cost J under ``policy`` (attained)."""
    j_lp: float
    """The LP's optimal value: an upper bound on J under every attacker within the budgets."""
    policy: StatePolicy
    """The optimal attacker (a flag row never visited repeats the next visited one; no forging
    where unvisited)."""
    blocked_fraction: float
    """The long-run fraction of the genuine flag-ACKs that ``policy`` blocks (at most beta)."""
    forged_fraction: float
    """The long-run fraction of quiet steps on which ``policy`` forges a flag-ACK."""
    tail_bound: float
    """A rigorous bound on ``j_lp - j`` from the truncation (see :func:`worst_attack`)."""
    tau_max: int
    """The truncation T: the policy's last row holds for every :math:`\\tau_k \\ge T`."""
    automaton: AttackerAutomaton | None
    """An attacker that sees only the genuine flag-ACKs and acts as ``policy`` (same J), when one
    exists: mu = 1, no forging and blocking independent of the channel state; else None."""


def worst_attack(
    system: LinearSystem,
    channel: ChannelLike,
    design: OnlineDesign,
    beta: float,
    *,
    information: str = "eavesdrop",
    forge_budget: float = 0.0,
    stealth: str | None = None,
    tau_max: int | None = None,
) -> WorstAttack:
    r"""The attack on the flag-ACKs of greatest long-run cost J within a blocking budget, by LP.

    **Model.** At the end of step k the remote detector has sent a genuine flag-ACK or not; the
    attacker, knowing :math:`\tau_k` (the holding time after step k), the channel state
    :math:`c_k`, the detector's zero count and whether a flag-ACK was sent
    (``information="eavesdrop"``, everything about the past that matters for the future),
    blocks the flag-ACK or, on a quiet step, forges one. In the long run it blocks at most a
    fraction ``beta`` of the genuine flag-ACKs and forges on at most a fraction ``forge_budget``
    of the quiet steps. With this information the (min(τ, T), e) chain is a controlled Markov
    chain, so the optimum is an LP over its occupation measure (module docstring), and its value
    bounds every attacker within the budgets, whatever it sees.

    **Scaling.** The masses fall like :math:`g^t` (g the channel's largest loss probability)
    while the traces grow like :math:`\rho(A)^{2t}` (1e32 at t = 200 on the paper's example). The
    LP is solved in :math:`y(t,\cdot) = x(t,\cdot)/s^t`, :math:`s = \sqrt{g/\rho(A)^2}`, so
    that scaled masses and scaled costs both fall like :math:`(g\rho(A)^2)^{t/2}`, with
    cumulative variables :math:`\sigma_t = (\dots)_t + s\,\sigma_{t+1}` for the sums over all t
    (normalisation, budgets), as in :func:`fakeack.optimal.optimal_power_policy`.

    **The tail bound, on the safe side.** For a maximisation the truncation must not lower the
    LP's value: the aggregated state t = T is costed at an upper bound of what every
    :math:`\tau \ge T` costs. In the long run, whatever the attacker does,
    :math:`\Pr[\tau_k \ge T + j] \le m_T g^j` (each of j further losses has conditional
    probability at most g), :math:`m_T = \Pr[\tau_k \ge T]`, and :math:`\mathrm{tr}_i` grows, so
    :math:`E[\mathrm{tr}_\tau; \tau \ge T] \le m_T(\mathrm{tr}_T + g\,\mathrm{Tr}\,W)`,
    :math:`W = g A W A' + h(X) - X`, :math:`X = h^T(\bar P)` (Abel summation; the increments
    are :math:`\mathrm{Tr}\,A^{j-1}(h(X)-X)A'^{j-1} \ge 0`). Every attacker's aggregated
    measure is feasible, so ``j_lp`` is an upper bound on the optimum :math:`J^\star`; the
    optimal policy's exact J is at least its LP cost with the tail term removed, and
    :math:`m_T \le g^T` (T losses in a row), so
    ``j_lp - tail_bound <= j <= J* <= j_lp`` with ``tail_bound`` :math:`= g^T g\,\mathrm{Tr}\,W`,
    a bound that holds for every attacker and falls like :math:`(g\rho(A)^2)^T`.

    Parameters
    ----------
    system : LinearSystem
        The process and its sensor.
    channel : Channel or float
        The packet channel (a float: the paper's low-power arrival probability, high power
        always arriving).
    design : OnlineDesign
        The online schedule's remote detector (z0, mu).
    beta : float
        Largest long-run fraction of the genuine flag-ACKs blocked, in [0, 1].
    information : {"eavesdrop"}, keyword-only, optional
        What the attacker sees: ``"eavesdrop"``, the holding time and the detector's state.
    forge_budget : float, keyword-only, optional
        Largest long-run fraction of quiet steps with a forged flag-ACK, in [0, 1] (default 0).
    stealth : None, keyword-only, optional
        No constraint on what the sensor receives (the only choice).
    tau_max : int, keyword-only, optional
        The truncation T (1 to 4096); None: 64, doubled until ``tail_bound`` is at most 1e-12
        of ``j`` (ValueError past 1024).

    Returns
    -------
    WorstAttack

    Raises
    ------
    TypeError, ValueError
        Naming ``beta`` or ``forge_budget`` outside [0, 1], ``information`` or ``stealth`` not
        known, ``design`` not an OnlineDesign, ``tau_max``; naming ``channel`` when its largest
        loss probability g has :math:`g\rho(A)^2 \ge 1` (an attacker can then make J infinite,
        or nearly so, and the tail bound is infinite).
    ConvergenceError
        If HiGHS does not solve the LP.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> w = worst_attack(s, 0.5, fa.OnlineDesign(2), 0.5, tau_max=100)
    >>> str(w.policy)
    'tau 1-2: block 0.428571; tau >= 3: block'
    >>> abs(w.j / fa.j_attack_limit(s, 0.5, 2, 0.5) - 1) < 1e-9  # consecutive blocking's limit
    True
    >>> w.j_lp - w.tail_bound <= w.j * (1 + 1e-9) and w.j <= w.j_lp * (1 + 1e-9)
    True
    """
    compiled(system)
    ch = as_channel(channel, "channel")
    if not isinstance(design, OnlineDesign):
        raise TypeError(f"design must be an OnlineDesign, got {type(design).__name__}")
    b = as_probability("beta", beta, closed=True)
    phi = as_probability("forge_budget", forge_budget, closed=True)
    if not isinstance(information, str) or information not in INFORMATION:
        raise ValueError(f"information must be one of {INFORMATION}, got {information!r}")
    if stealth not in STEALTH:
        raise ValueError(f"stealth must be one of {STEALTH}, got {stealth!r}")
    g = float(np.max(1.0 - np.minimum(ch.low, ch.high)))
    if g * system.spectral_radius**2 >= 1.0:
        raise ValueError(
            f"channel: its largest loss probability {g:.6g} times rho(A)^2 = {system.spectral_radius**2:.6g} "
            "is at least 1: an attacker who keeps the power low can make J infinite or unbounded"
        )
    steps = protocol_steps(ch, design)
    if tau_max is not None:
        return _solve(
            system, ch, design, steps, b, phi, g, as_int("tau_max", tau_max, minimum=1, maximum=MAX_TAU)
        )
    T = FIRST_TAU
    while True:
        res = _solve(system, ch, design, steps, b, phi, g, T)
        if res.tail_bound <= TAIL_RTOL * res.j:
            return res
        if 2 * T > MAX_AUTO_TAU:
            raise ValueError(
                f"tau_max: the tail beyond tau = {T} is not negligible (bound {res.tail_bound:.3g} against "
                f"J = {res.j:.6g}); give tau_max to accept a truncated answer with its tail_bound"
            )
        T *= 2


def _tail_cost(system: LinearSystem, g: float, scale: float, T: int) -> float:
    r""":math:`s^T\,g\,\mathrm{Tr}\,W` of :func:`worst_attack` (the tail's upper cost, scaled by
    :math:`s^T`): :math:`s^T(h(X) - X) = (\sqrt s A)^T (h(\bar P) - \bar P) (\sqrt s A')^T`."""
    A, Q = system.A, system.Q
    D = A @ system.pbar @ A.T + Q - system.pbar
    if np.min(np.linalg.eigvalsh((D + D.T) / 2)) < -1e-12 * max(1.0, float(np.abs(D).max())):
        raise ValueError("system: h(P̄) - P̄ is not positive semidefinite, the traces do not grow")
    M = np.linalg.matrix_power(math.sqrt(scale) * A, T)
    E = M @ D @ M.T
    W = sla.solve_discrete_lyapunov(math.sqrt(g) * A, E)
    return float(g * np.trace(W))


def _scale(g: float, rho: float) -> float:
    r"""The column scale s: masses fall like :math:`g^t` and costs grow like :math:`\rho^{2t}`, so
    :math:`s = \sqrt{g/\rho^2}` (:math:`\sqrt g` when :math:`\rho \le 1`) leaves both scaled
    masses and scaled costs falling like :math:`(g\rho^2)^{t/2}`: the solver's tolerances then
    resolve the deep rows as well as the masses allow (with s = g the costs of the deep rows fall
    below HiGHS's dual tolerance long before the masses do)."""
    if g == 0.0:
        return 1.0  # no loss at all: tau stays 0, any scale does
    return math.sqrt(g / rho**2) if rho > 1.0 else math.sqrt(g)


def _solve(
    system: LinearSystem,
    ch: Channel,
    design: OnlineDesign,
    steps: Steps,
    beta: float,
    phi: float,
    g: float,
    T: int,
) -> WorstAttack:
    gs = _scale(g, system.spectral_radius)
    K, S = steps.n_states, steps.slots
    E = K * S
    n_t = T + 1
    flag_e = np.arange(K) * S + S - 1
    quiet_e = (np.arange(K)[:, None] * S + np.arange(S - 1)[None, :]).ravel()
    ny = n_t * E * 2
    iy = np.arange(ny).reshape(n_t, E, 2)
    isig = ny + np.arange(n_t * K).reshape(n_t, K)
    ib = ny + n_t * K + np.arange(n_t)
    if_ = ny + n_t * K + n_t + np.arange(n_t)
    nvar = ny + n_t * K + 2 * n_t
    rows: list[npt.NDArray[Any]] = []
    cols: list[npt.NDArray[Any]] = []
    vals: list[npt.NDArray[Any]] = []

    def put(r: object, c: object, v: object) -> None:
        r_, c_, v_ = np.broadcast_arrays(np.asarray(r), np.asarray(c), np.asarray(v, dtype=np.float64))
        rows.append(r_.ravel())
        cols.append(c_.ravel())
        vals.append(v_.ravel())

    # Balance of (t, e2), t = 1..T: the loss flow in from t - 1 (and from T itself at t = T).
    L = np.moveaxis(steps.loss, 0, 2)  # (e, e2, a)
    brow = (np.arange(1, n_t)[:, None] - 1) * E + np.arange(E)[None, :]  # (T, E)
    put(brow[:, :, None], iy[1:], 1.0)
    e_, e2_, a_ = np.nonzero(L)
    w = L[e_, e2_, a_]
    put(brow[:, e2_], iy[:-1, e_, a_], -w[None, :] / gs)
    put(brow[-1, e2_], iy[T, e_, a_], -w)
    r0 = T * E
    # Cumulative masses per channel state: sigma(t, c) = sum y(t, c, .) + g sigma(t+1, c).
    srow = r0 + np.arange(n_t * K).reshape(n_t, K)
    put(srow, isig, 1.0)
    put(srow[:, :, None, None], iy.reshape(n_t, K, S, 2), -1.0)
    put(srow[:-1], isig[1:], -gs)
    r0 += n_t * K
    put(r0 + np.arange(K), isig[0], 1.0)
    r0 += K
    # Cumulative budgets: blocked - beta * sent over flags, forged - phi * quiet over quiet steps.
    put(r0 + np.arange(n_t), ib, 1.0)
    put((r0 + np.arange(n_t))[:, None], iy[:, flag_e, 0], -(1.0 - beta))
    put((r0 + np.arange(n_t))[:, None], iy[:, flag_e, 1], beta)
    put((r0 + np.arange(n_t - 1)), ib[1:], -gs)
    r0 += n_t
    put(r0 + np.arange(n_t), if_, 1.0)
    put((r0 + np.arange(n_t))[:, None], iy[:, quiet_e, 1], -(1.0 - phi))
    put((r0 + np.arange(n_t))[:, None], iy[:, quiet_e, 0], phi)
    put((r0 + np.arange(n_t - 1)), if_[1:], -gs)
    n_eq = r0 + n_t
    ij = (np.concatenate(rows).astype(np.intp), np.concatenate(cols).astype(np.intp))
    A_eq = sp.csr_array((np.concatenate(vals), ij), shape=(n_eq, nvar))
    b_eq = np.zeros(n_eq)
    b_eq[r0 - n_t - K : r0 - n_t] = np.asarray(ch.stationary)
    with np.errstate(over="ignore"):
        wt = np.asarray(system.weighted_traces(gs, T), dtype=np.float64)  # s^t tr_t
    tail = _tail_cost(system, g, gs, T) if g > 0.0 else 0.0
    cost = np.zeros(nvar)
    cost[:ny] = np.repeat(wt, 2 * E)
    cost[iy[T].ravel()] += tail
    lower = np.zeros(nvar)
    upper = np.full(nvar, np.inf)
    lower[ny:] = -np.inf
    upper[ib[0]] = 0.0
    upper[if_[0]] = 0.0
    # States the protocol never enters: at t = 0 only a quiet count 0; at t >= 1 no quiet count 0.
    zero0 = np.ones(E, dtype=bool)
    zero0[np.arange(K) * S] = False
    upper[iy[0][zero0].ravel()] = 0.0
    upper[iy[1:, np.arange(K) * S].ravel()] = 0.0
    # Budgets at their ends are said through the bounds (HiGHS is then spared a face of the set).
    if beta == 0.0:
        upper[iy[:, flag_e, 0].ravel()] = 0.0
    if phi == 0.0:
        upper[iy[:, quiet_e, 1].ravel()] = 0.0
    res = linprog(
        -cost,
        A_eq=cast(Any, A_eq),  # HiGHS takes sparse matrices; the stubs list only dense ones
        b_eq=b_eq,
        bounds=cast(Any, np.column_stack([lower, upper])),
        method="highs",
        options={
            "primal_feasibility_tolerance": LP_TOL,
            "dual_feasibility_tolerance": LP_TOL,
            "presolve": False,
        },
    )
    if res.status != 0:
        raise ConvergenceError(f"the worst-attack LP (tau_max = {T}) was not solved: {res.message}")
    assert res.x is not None and res.fun is not None  # status 0: solved
    y = np.clip(res.x[:ny].reshape(n_t, E, 2), 0.0, None)
    # Rows whose share of the objective is below the solver's resolution are left to chance by
    # HiGHS; they count as unvisited (their choice moves J by less than 1e-13 relative).
    share = y.sum(axis=2) * np.append(wt[:-1], wt[-1] + tail)[:, None]
    policy = _policy(np.where((share > SHARE_TOL * -res.fun)[:, :, None], y, 0.0), K, S)
    aut = policy.automaton(ch, design)
    j = policy.cost(system, ch, design)
    bound = float(tail * (g / gs) ** T) if g > 0.0 else 0.0  # g^T g Tr W: m_T <= g^T
    flag_only = policy.flag_automaton(design)
    return WorstAttack(
        float(j), float(-res.fun), policy, aut.blocked_fraction, aut.forged_fraction, bound, T, flag_only
    )


def _policy(y: npt.NDArray[np.float64], K: int, S: int) -> StatePolicy:
    """Block and forge probabilities from the scaled occupation measure; a flag row never visited
    repeats the next visited one (so that runs read simply), and no forging where unvisited."""
    mass = y.sum(axis=2)
    p_high = np.divide(y[:, :, 1], mass, out=np.zeros_like(mass), where=mass > MASS_TOL)
    p_high = p_high.reshape(-1, K, S)
    seen = (mass > MASS_TOL).reshape(-1, K, S)
    block = np.where(seen[:, :, S - 1], 1.0 - p_high[:, :, S - 1], 0.0)
    for c in range(K):  # unvisited rows repeat the next visited one (the last one after it)
        vis = np.flatnonzero(seen[:, c, S - 1])
        if vis.size:
            nxt = vis[np.minimum(np.searchsorted(vis, np.arange(block.shape[0])), vis.size - 1)]
            block[:, c] = block[nxt, c]
    forge = np.where(seen[:, :, : S - 1], p_high[:, :, : S - 1], 0.0)
    block[block < PROB_TOL] = 0.0
    block[block > 1.0 - PROB_TOL] = 1.0
    forge[forge < PROB_TOL] = 0.0
    forge[forge > 1.0 - PROB_TOL] = 1.0
    if K > 1 and np.all(block == block[:, :1]):
        block = block[:, :1]
    return StatePolicy(block, forge if np.any(forge > 0.0) else None)
