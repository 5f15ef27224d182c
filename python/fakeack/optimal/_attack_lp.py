r"""The linear program of :func:`fakeack.optimal.worst_attack` over the occupation measure of
(t, e, d, a): t = min(τ_k, T), e the attack-free state, d the steps since the last flag-ACK the
sensor received (capped at G; G = 1 when no stealth constraint needs it), a the sensor's next
power. Also the attack-free law of the gaps between flag-ACKs, which the stealth constraints use.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, cast

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.optimize import linprog

from .._fakeack import ConvergenceError
from .._internal.types import FloatArray
from ..model.channels import Channel, gth_stationary
from ..model.system import LinearSystem
from .power import LP_TOL, MASS_TOL, PROB_TOL
from .state_policy import StatePolicy, Steps

__all__ = ["LpSolution", "solve", "attack_free_gaps", "hazards", "scale", "GAP_TAIL"]

#: The gap-law constraint stops where the attack-free tail of the gaps falls below this (gaps
#: beyond share one row). The constraint is imposed on the hazards, whose coefficients are of
#: order 1 however small the tail: the law's own entries would fall below the smallest matrix
#: entry HiGHS keeps (1e-9) and, in rows spanning 1 to 1e-9, make its bases ill-conditioned.
GAP_TAIL = 1e-12
#: The smallest scale of the gap-law program's columns at a gap d (the attack-free tail there).
D_FLOOR = 1e-6
#: Rows of the LP's solution below this share of its value are taken as unvisited.
SHARE_TOL = 1e-14
#: Longest gap law computed.
MAX_GAP = 100_000


class LpSolution(NamedTuple):
    """The LP's value, its policy and the rigorous bound of its truncation."""

    j_lp: float
    policy: StatePolicy
    tail_bound: float


def attack_free_gaps(steps: Steps, tail: float = GAP_TAIL) -> tuple[FloatArray, float]:
    r"""The law of the gaps between consecutive flag-ACKs without attack: entry i is
    :math:`\Pr[\text{gap} = i + 1]`, the last entry :math:`\Pr[\text{gap} \ge G]` with G the
    first length whose tail is below ``tail``; and the attack-free rate of flag-ACKs per step.

    The channel state at a flag-ACK has the Palm law (the stationary law of the attack-free
    chain of e on the flag states, normalised); from there the sensor transmits at high power and
    then at low power until the next flag-ACK, whose step is the gap.
    """
    K, S = steps.n_states, steps.slots
    flags = np.arange(K) * S + S - 1
    high = np.zeros(K * S, dtype=bool)
    high[flags] = True  # without attack the power is high exactly after a flag-ACK
    step = np.where(high[:, None], steps.loss[1] + steps.arrival[1], steps.loss[0] + steps.arrival[0])
    pi = gth_stationary(step)
    u = np.zeros(K * S)
    u[flags] = pi[flags] / pi[flags].sum()
    step_high = steps.loss[1] + steps.arrival[1]
    step_low = steps.loss[0] + steps.arrival[0]
    out: list[float] = []
    u = u @ step_high
    while len(out) < MAX_GAP:
        out.append(float(u[flags].sum()))
        u[flags] = 0.0
        rest = float(u.sum())
        if rest < tail:
            out.append(rest)
            break
        u = u @ step_low
    else:
        raise ValueError(f"design: the attack-free gaps have a tail above {tail} beyond {MAX_GAP} steps")
    return np.array(out), float(pi[flags].sum())


def hazards(law: FloatArray) -> FloatArray:
    r"""The hazards of a gap law ``law`` (as :func:`attack_free_gaps` gives it):
    :math:`h(l) = \Pr[\text{gap} = l \mid \text{gap} \ge l]`, entry l - 1 (1 for the last
    entry, every gap >= G; 0 where the law is 0). The tails are summed from the smallest
    entries up, so each hazard keeps its relative precision where the tail is tiny."""
    tail = np.cumsum(law[::-1])[::-1]
    return np.divide(law, tail, out=np.zeros_like(law), where=tail > 0.0)


def scale(g: float, rho: float) -> float:
    r"""The column scale s: masses fall like :math:`g^t` and costs grow like :math:`\rho^{2t}`, so
    :math:`s = \sqrt{g/\rho^2}` (:math:`\sqrt g` when :math:`\rho \le 1`) leaves both scaled
    masses and scaled costs falling like :math:`(g\rho^2)^{t/2}`: the solver's tolerances then
    resolve the deep rows as well as the masses allow (with s = g the costs of the deep rows fall
    below HiGHS's dual tolerance long before the masses do)."""
    if g == 0.0:
        return 1.0  # no loss at all: tau stays 0, any scale does
    return math.sqrt(g / rho**2) if rho > 1.0 else math.sqrt(g)


def tail_cost(system: LinearSystem, g: float, s: float, T: int) -> float:
    r""":math:`s^T\,g\,\mathrm{Tr}\,W` (the tail's upper cost, scaled by :math:`s^T`), with
    :math:`s^T(h(X) - X) = (\sqrt s A)^T (h(\bar P) - \bar P) (\sqrt s A')^T`."""
    A, Q = system.A, system.Q
    D = A @ system.pbar @ A.T + Q - system.pbar
    if np.min(np.linalg.eigvalsh((D + D.T) / 2)) < -1e-12 * max(1.0, float(np.abs(D).max())):
        raise ValueError("system: h(P̄) - P̄ is not positive semidefinite, the traces do not grow")
    M = np.linalg.matrix_power(math.sqrt(s) * A, T)
    W = sla.solve_discrete_lyapunov(math.sqrt(g) * A, M @ D @ M.T)
    return float(g * np.trace(W))


def solve(
    system: LinearSystem,
    ch: Channel,
    steps: Steps,
    budgets: tuple[float, float],
    g: float,
    T: int,
    gaps: tuple[FloatArray, float] | None,
    min_gap: int,
) -> LpSolution:
    """The LP (docstring of :func:`fakeack.optimal.worst_attack`); ``gaps`` the gap law to meet and
    the rate of flag-ACKs it implies (None: none), ``min_gap`` the shortest gap allowed (1: any)."""
    beta, phi = budgets
    s = scale(g, system.spectral_radius)
    K, S = steps.n_states, steps.slots
    E, n_t = K * S, T + 1
    G = gaps[0].size if gaps is not None else max(min_gap, 1)
    flag_e = np.arange(K) * S + S - 1
    quiet_e = (np.arange(K)[:, None] * S + np.arange(S - 1)[None, :]).ravel()
    nxt = np.stack([np.minimum(np.arange(G) + 1, G - 1), np.zeros(G, dtype=np.intp)])  # (a, d)
    ny = n_t * E * G * 2
    iy = np.arange(ny).reshape(n_t, E, G, 2)
    counter = [ny]

    def block_of(*shape: int) -> npt.NDArray[np.intp]:
        start = counter[0]
        counter[0] += int(np.prod(shape))
        return np.arange(start, counter[0]).reshape(shape)

    isig = block_of(n_t, K)
    ib, if_ = block_of(n_t), block_of(n_t)
    iarr = block_of(n_t, K, G) if G > 1 else None
    ih = block_of(n_t, G) if gaps is not None else None
    ireach = block_of(G) if gaps is not None else None
    # Under the gap law the mass at d is the attack-free rate times P[gap > d], down to
    # GAP_TAIL. If HiGHS fails on the program as built, it is solved again with the columns at
    # d scaled by that tail (floored at D_FLOOR, keeping every matrix entry above HiGHS's 1e-9)
    # and so the rows that balance d: the same program, on which HiGHS's bases and absolute
    # tolerances (1e-10, on bounds too) behave differently; each of the two fails where the
    # other solves on some HiGHS version or channel.
    gap_tail = np.cumsum(gaps[0][::-1])[::-1] if gaps is not None else np.ones(G)  # P[gap > d]
    dscale = np.maximum(gap_tail, D_FLOOR)
    colscale: list[tuple[npt.NDArray[np.intp], npt.NDArray[Any]]] = [(iy, dscale[None, None, :, None])]
    rowscale: list[tuple[npt.NDArray[np.intp], npt.NDArray[Any]]] = []
    rows: list[npt.NDArray[Any]] = []
    cols: list[npt.NDArray[Any]] = []
    vals: list[npt.NDArray[Any]] = []
    nrow = [0]

    def put(r: object, c: object, v: object) -> None:
        r_, c_, v_ = np.broadcast_arrays(np.asarray(r), np.asarray(c), np.asarray(v, dtype=np.float64))
        rows.append(r_.ravel())
        cols.append(c_.ravel())
        vals.append(v_.ravel())

    def new_rows(*shape: int) -> npt.NDArray[np.intp]:
        start = nrow[0]
        nrow[0] += int(np.prod(shape))
        return np.arange(start, nrow[0]).reshape(shape)

    def cumulative(r: npt.NDArray[np.intp], v: npt.NDArray[np.intp]) -> None:
        """v(t) - (terms put separately) - s v(t+1) = 0 on rows r (leading axis t)."""
        put(r, v, 1.0)
        put(r[:-1], v[1:], -s)

    # Balance of (t, e2, d2), t = 1..T: the loss flow in from t - 1 (and from T itself at t = T).
    brow = new_rows(T, E, G)
    rowscale.append((brow, dscale))
    put(brow[:, :, :, None], iy[1:], 1.0)
    e_, e2_, a_ = np.nonzero(np.moveaxis(steps.loss, 0, 2))
    w = steps.loss[a_, e_, e2_]
    d = np.arange(G)
    to = brow[:, e2_[:, None], nxt[a_][:, :]]  # (T, nnz, G)
    put(to, iy[:-1, e_[:, None], d[None, :], a_[:, None]], -(w / s)[None, :, None])
    put(to[-1], iy[T, e_[:, None], d[None, :], a_[:, None]], -w[:, None])
    # The channel's stationary marginal through cumulative masses sigma(t, c).
    srow = new_rows(n_t, K)
    cumulative(srow, isig)
    put(srow[:, :, None], iy.reshape(n_t, K, S * G * 2), -1.0)
    sig0 = new_rows(K)
    put(sig0, isig[0], 1.0)
    b_eq_parts = [(sig0, np.asarray(ch.stationary))]
    if iarr is not None:
        # Arrivals into (0, c2, d2) summed over every t; one row per c2 follows from the marginal.
        arow = new_rows(n_t, K, G)
        cumulative(arow, iarr)
        rowscale.append((arow, dscale))
        colscale.append((iarr, dscale))
        e_, f_, a_ = np.nonzero(np.moveaxis(steps.arrival, 0, 2))
        w = steps.arrival[a_, e_, f_]
        put(
            arow[:, (f_ // S)[:, None], nxt[a_]],
            iy[:, e_[:, None], d[None, :], a_[:, None]],
            -w[None, :, None],
        )
        zrow = new_rows(K, G - 1)
        rowscale.append((zrow, dscale[1:]))
        put(zrow[:, :, None], iy[0, np.arange(K) * S][:, 1:, :], 1.0)
        put(zrow, iarr[0][:, 1:], -1.0)
    # Budgets: blocked - beta * sent over flags, forged - phi * quiet over quiet steps (<= 0).
    for iv, states, bad, good, share in ((ib, flag_e, 0, 1, beta), (if_, quiet_e, 1, 0, phi)):
        r = new_rows(n_t)
        cumulative(r, iv)
        put(r[:, None, None], iy[:, states][..., bad], -(1.0 - share))
        put(r[:, None, None], iy[:, states][..., good], share)
    if ih is not None and ireach is not None and gaps is not None:
        # The received gaps' law as hazards: of the gaps that reach length l + 1, the share
        # delivered there is the attack-free h(l + 1) = P[gap = l + 1 | gap > l], and gaps start at
        # the attack-free rate (a law of mean m is received once every m steps in the long run;
        # without it, delivering nothing would meet the law vacuously). With R(l) the rate of
        # gaps that reach l + 1 (the deliveries at l and beyond), this is the marginal law with
        # coefficients of order 1 (GAP_TAIL).
        law, rate = gaps
        hazard = hazards(law)
        hrow = new_rows(n_t, G)
        cumulative(hrow, ih)
        rowscale.append((hrow, dscale))
        colscale += [(ih, dscale), (ireach, dscale)]
        put(hrow[:, None, :], iy[:, :, :, 1], -1.0)
        crow = new_rows(G)  # R(l) - deliveries at l - R(l + 1) = 0
        put(crow, ireach, 1.0)
        put(crow, ih[0], -1.0)
        put(crow[:-1], ireach[1:], -1.0)
        rowscale.append((crow, dscale))
        zrow = new_rows(G - 1)  # deliveries at l - h(l + 1) R(l) = 0; the last follows
        rowscale.append((zrow, dscale[:-1]))
        put(zrow, ih[0][:-1], 1.0)
        put(zrow, ireach[:-1], -hazard[:-1])
        rrow = new_rows(1)
        put(rrow, ireach[:1], 1.0)
        b_eq_parts.append((rrow, np.array([rate])))
    n_eq, nvar = nrow[0], counter[0]
    csc, rsc = np.ones(nvar), np.ones(n_eq)
    for idx, f in colscale:
        csc[idx] = np.broadcast_to(f, idx.shape)
    for idx, f in rowscale:
        rsc[idx] = np.broadcast_to(f, idx.shape)
    ij = (np.concatenate(rows).astype(np.intp), np.concatenate(cols).astype(np.intp))
    entries = np.concatenate(vals)
    b_eq = np.zeros(n_eq)
    for r, v in b_eq_parts:
        b_eq[r] = v
    with np.errstate(over="ignore"):
        wt = np.asarray(system.weighted_traces(s, T), dtype=np.float64)  # s^t tr_t
    tail = tail_cost(system, g, s, T) if g > 0.0 else 0.0
    unit = np.append(wt[:-1], wt[-1] + tail)
    cost = np.zeros(nvar)
    cost[:ny] = np.repeat(unit, E * G * 2)
    lower, upper = np.zeros(nvar), np.full(nvar, np.inf)
    lower[ny:] = -np.inf
    upper[[ib[0], if_[0]]] = 0.0
    allowed = np.ones((E, G, 2), dtype=bool)
    allowed[:, : max(min_gap, 1) - 1, 1] = False  # no gap shorter than min_gap
    if beta == 0.0:
        allowed[flag_e, :, 0] = False
    if phi == 0.0:
        allowed[quiet_e, :, 1] = False
    live = _recurrent_candidates(steps, n_t, nxt, allowed)
    upper[iy[~live].ravel()] = 0.0
    upper[iy[:, np.broadcast_to(~allowed, (E, G, 2))].ravel()] = 0.0
    bounds = np.column_stack([lower, upper])
    for scaled in (False, True) if gaps is not None else (False,):
        c_, r_ = (csc, rsc) if scaled else (np.ones(nvar), np.ones(n_eq))
        res = linprog(
            -cost * c_,
            # HiGHS takes sparse matrices; the stubs list only dense ones
            A_eq=cast(Any, sp.csr_array((entries * c_[ij[1]] / r_[ij[0]], ij), shape=(n_eq, nvar))),
            b_eq=b_eq / r_,
            bounds=cast(Any, bounds),
            method="highs",
            options={
                "primal_feasibility_tolerance": LP_TOL,
                "dual_feasibility_tolerance": LP_TOL,
                # Presolve fails (status "Not Set") on the plain LP's deep, tiny-cost columns near
                # tau_max = 200; the stealth LPs need it to drop their many states fixed at 0.
                "presolve": G > 1,
            },
        )
        if res.status in (0, 2):
            break
    if res.status == 2:
        raise ValueError(
            "forge_budget: HiGHS finds the stealth program infeasible: no attacker within these budgets "
            "delivers flag-ACKs with the attack-free gaps at the attack-free rate; raise forge_budget or beta"
        )
    if res.status != 0:
        raise ConvergenceError(f"the worst-attack LP (tau_max = {T}) was not solved: {res.message}")
    assert res.x is not None and res.fun is not None  # status 0: solved
    j_lp = float(-res.fun)
    # The policy's ratios are read on masses relative to the attack-free tail at d (absolute
    # masses would leave the deep gaps unvisited and their law unmet).
    y = np.clip(res.x[:ny].reshape(n_t, E, G, 2) * c_[:ny].reshape(n_t, E, G, 2), 0.0, None)
    y = y / gap_tail[None, None, :, None]
    # Rows whose share of the objective is below the solver's resolution count as unvisited.
    share_ok = y.sum(axis=3) * unit[:, None, None] > SHARE_TOL * j_lp
    policy = _policy(np.where(share_ok[..., None], y, 0.0), K, S)
    bound = float(tail * (g / s) ** T) if g > 0.0 else 0.0  # g^T g Tr W: Pr[tau >= T] <= g^T
    return LpSolution(j_lp, policy, bound)


def _recurrent_candidates(
    steps: Steps, n_t: int, nxt: npt.NDArray[np.intp], allowed: npt.NDArray[np.bool_]
) -> npt.NDArray[np.bool_]:
    """``(n_t, E, G)``: the states (t, e, d) reachable from the arrival states (t = 0, quiet count
    0, any d) by allowed actions. Every class recurrent under some policy holds an arrival state
    (the loss probability is below 1 everywhere), so the LP's measure lives on these; the rest
    (states the protocol never enters, or enters only once at the start) are fixed at 0."""
    K, S = steps.n_states, steps.slots
    E, G = K * S, nxt.shape[1]
    reach = np.zeros((n_t, E, G), dtype=bool)
    reach[0, np.arange(K) * S, :] = True
    move = [(steps.loss[a] > 0.0, steps.arrival[a] > 0.0) for a in (0, 1)]
    frontier = reach.copy()
    while frontier.any():
        new = np.zeros_like(reach)
        for a in (0, 1):
            src = frontier & allowed[None, :, :, a]  # (n_t, E, G)
            if not src.any():
                continue
            lost, arrived = move[a]
            # e -> e2 by a boolean product, then d -> nxt[a][d], t -> t + 1 (capped) or 0.
            via_loss = np.einsum("ted,ef->tfd", src.astype(np.int8), lost.astype(np.int8)) > 0
            via_arr = np.einsum("ted,ef->fd", src.astype(np.int8), arrived.astype(np.int8)) > 0
            shifted = np.zeros_like(reach)
            shifted[1:] |= via_loss[:-1]
            shifted[-1] |= via_loss[-1]
            shifted[0] |= via_arr
            moved = np.zeros_like(reach)
            for d in range(G):
                moved[:, :, nxt[a, d]] |= shifted[:, :, d]
            new |= moved
        frontier = new & ~reach
        reach |= new
    return reach


def _policy(y: FloatArray, K: int, S: int) -> StatePolicy:
    """Block and forge probabilities from the scaled occupation measure; a flag row never visited
    repeats the next visited one along t (so that runs read simply), and no forging where unvisited."""
    n_t, _, G, _ = y.shape
    mass = y.sum(axis=3)
    seen = (mass > MASS_TOL).reshape(n_t, K, S, G)
    p_high = np.divide(y[..., 1], mass, out=np.zeros_like(mass), where=mass > MASS_TOL).reshape(n_t, K, S, G)
    block = np.where(seen[:, :, S - 1], 1.0 - p_high[:, :, S - 1], 0.0)  # (n_t, K, G)
    for c in range(K):
        for d in range(G):
            vis = np.flatnonzero(seen[:, c, S - 1, d])
            if vis.size:
                block[:, c, d] = block[
                    vis[np.minimum(np.searchsorted(vis, np.arange(n_t)), vis.size - 1)], c, d
                ]
    forge = np.where(seen[:, :, : S - 1], p_high[:, :, : S - 1], 0.0)  # (n_t, K, S-1, G)
    for arr in (block, forge):
        arr[arr < PROB_TOL] = 0.0
        arr[arr > 1.0 - PROB_TOL] = 1.0
    if K > 1 and np.all(block == block[:, :1]):
        block = block[:, :1]
    if G > 1 and np.all(block == block[..., :1]) and np.all(forge == forge[..., :1]):
        block, forge = block[..., :1], forge[..., :1]
    return StatePolicy(block, forge if np.any(forge > 0.0) else None)
