r"""The long-run jammer that knows :math:`\tau`: a linear program over the occupation measure of
(min(τ, τ_max), jam or not), the exact cost of a policy, and when the supremum is infinite.

State s = min(τ_{k-1}, M) with M = τ_max; in state s the jammer jams with probability x_s, so τ
grows by one with probability :math:`g_s = x_s + (1 - x_s)(1 - \lambda)` and resets to 0
otherwise, and the step costs :math:`(1 - g_s)\,\mathrm{tr}_0 + g_s\,\mathrm{tr}_{\tau+1}`.
min(τ, M) is itself a Markov chain under such a policy, so its occupation measure is exact; only
the cost in state M depends on how far τ is beyond M.
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple

import numpy as np
from scipy.linalg import solve_discrete_lyapunov
from scipy.optimize import linprog

from .._internal.types import FloatArray
from ..model.channels import gth_stationary
from ..model.system import LinearSystem
from ._traces import log_traces

__all__ = ["LongRun", "solve_long_run", "policy_cost", "unbounded_witness"]

#: Occupation masses below this (relative to the unjammed profile) count as unvisited states.
_UNVISITED = 1e-9
#: Relative slack of the check j_lp <= J <= j_lp + tail_bound (HiGHS's tolerances are 1e-7).
_CERTIFY = 1e-6
#: Jam probabilities at τ_max above 1 - this are refined by the rate (see solve_long_run).
_POLISH = 1e-6
#: Floor of the column scale w_s: HiGHS drops matrix entries below 1e-9, and the normalisation
#: and rate rows carry w_s.
_SCALE_FLOOR = 1e-8


class LongRun(NamedTuple):
    """The LP's policy and its figures (see :class:`fakeack.optimal.JammingResult`)."""

    idle_probability: FloatArray
    j_lp: float
    j: float
    tail_bound: float
    jammed_fraction: float


def unbounded_witness(system: LinearSystem, lam: float, rate: float, tau_max: int) -> FloatArray | None:
    r"""A policy within the rate whose J is infinite, or ``None`` when every feasible policy has
    a finite J.

    Beyond M the excess τ - M is geometric with ratio :math:`g_M`, and
    :math:`\mathrm{tr}_{M+j} \ge c\,\rho(A)^{2j}`, so J is infinite exactly when state M is visited
    and :math:`g_M \rho(A)^2 \ge 1`, i.e. :math:`x_M \ge x^* = 1 - (1 - \rho^{-2})/\lambda`. The
    cheapest way to hold :math:`x_M = x^*` jams nowhere below M (jamming below M only raises the
    share of time in state M), costing the jammed fraction :math:`f^* = x^* \pi_M`; with
    λ = 1, M is reached only by jamming, and jamming at τ = 0 with a small enough probability
    makes the fraction as small as wanted.
    """
    rho = system.spectral_radius
    M = tau_max
    if rho < 1.0:
        return None  # traces are bounded by Tr of the Lyapunov solution
    x = np.zeros(M + 1)
    if lam == 0.0 or (1.0 - lam) * rho**2 >= 1.0:
        return x  # unjammed τ already makes J infinite (Model note 5)
    x_star = 1.0 - (1.0 - rho**-2) / lam
    if lam == 1.0:
        if rate == 0.0:
            return None
        x[1:M] = 1.0
        x[M] = x_star
        # A cycle climbing to M lasts M + 1/(1-g) steps with M + g/(1-g) jams; entered with
        # probability p from τ = 0, the fraction is p(M + g/(1-g)) / (1 - p + p(M + 1/(1-g))).
        g = x_star
        jams, length = M + g / (1 - g), M + 1 / (1 - g)
        p = min(1.0, rate / (jams - rate * (length - 1)) if jams > rate * (length - 1) else 1.0)
        x[0] = p
        return x
    a = 1.0 - lam
    below = (1.0 - a**M) / lam  # Σ_{s<M} a^s: unnormalised masses below M
    at_m = a**M / ((1.0 - x_star) * lam) if x_star < 1.0 else math.inf
    share = 1.0 if math.isinf(at_m) else at_m / (below + at_m)
    if x_star * share <= rate:
        x[M] = x_star
        return x
    return None


def policy_cost(system: LinearSystem, lam: float, idle: FloatArray) -> tuple[float, float]:
    r"""Exact long-run J and jammed fraction of the policy that does not jam with probability
    ``idle[s]`` in state s (s < M: τ = s; s = M: τ >= M).

    The policy is given by ``idle = 1 - x`` so that jam probabilities within 1e-16 of 1, which
    optimal policies use at τ_max, keep their precision: :math:`1 - g_s = \lambda\,\mathrm{idle}_s`.

    An independent route from the LP: the stationary law of min(τ, M) by GTH elimination on the
    states reachable from τ = 0, then the geometric tail beyond M in closed form,
    :math:`\sum_{j\ge0} g^j h^j(Y) = W` with :math:`W = gAWA' + Y + \frac{g}{1-g}Q` (a Stein
    equation), :math:`Y = h^{M+1}(\bar P)`. The engine's ``fakeack.Scenario.from_automaton``
    (the attacker as an automaton with jam kernels K0, K1 on the states s) computes the same J
    and can replace this function.
    """
    M = len(idle) - 1
    x = 1.0 - idle
    leave = lam * idle  # 1 - g: τ resets
    g = 1.0 - leave
    # τ = 0 reaches s + 1 from s iff g_s > 0, so the states reachable from 0 are 0..top.
    stops = np.flatnonzero(leave[:M] == 1.0)
    top = int(stops[0]) if stops.size else M
    n = top + 1
    P = np.zeros((n, n))
    for s in range(n):
        up = min(s + 1, M)
        if up < n:
            P[s, up] += g[s]
        P[s, 0] += leave[s]
    pi = gth_stationary(P)
    logtr, Y, scale = log_traces(system, M + 1)
    fraction = float(pi @ x[:n])
    terms = []
    with np.errstate(divide="ignore"):
        for s in range(min(n, M)):
            terms.append(math.log(pi[s] * leave[s]) + logtr[0] if pi[s] * leave[s] > 0 else -math.inf)
            terms.append(math.log(pi[s] * g[s]) + logtr[s + 1] if pi[s] * g[s] > 0 else -math.inf)
        if n == M + 1 and pi[M] > 0:
            gm, lm = g[M], leave[M]
            terms.append(math.log(pi[M] * lm) + logtr[0] if lm > 0 else -math.inf)
            terms.append(_log_tail(system, lm, Y, scale) + math.log(pi[M] * gm) if gm > 0 else -math.inf)
    return _log_sum(terms), fraction


def _log_tail(system: LinearSystem, leave: float, Y: FloatArray, scale: float) -> float:
    r"""log of :math:`E[\mathrm{tr}_{\tau+1} \mid \tau \ge M] = (1-g)\sum_j g^j\,\mathrm{tr}_{M+1+j}`
    with ``leave`` = 1 - g (:math:`h^{M+1}(\bar P) = e^{scale} Y`); for g = 1, the limit of the
    traces."""
    g = 1.0 - leave
    rho2 = system.spectral_radius**2
    # At g rho^2 = 1 the series diverges; a policy built to sit there (the LP's witness) lands
    # within rounding of it on either side, where the Lyapunov solve is singular.
    if g * rho2 >= 1.0 - 1e-12:
        return math.inf
    A, Q = system.A, system.Q
    if leave == 0.0:  # τ grows for ever: Tr h^i(P̄) -> Tr X_∞, X_∞ = A X_∞ A' + Q
        return math.log(float(np.trace(solve_discrete_lyapunov(A, Q))))
    # W = g A W A' + Y + g/(1-g) Q, everything divided by e^scale.
    rhs = Y + math.exp(-scale) * (g / leave) * Q if scale < 700 else Y
    W = solve_discrete_lyapunov(math.sqrt(g) * A, rhs)
    return math.log(leave) + math.log(float(np.trace(W))) + scale


def _log_sum(terms: list[float]) -> float:
    t = np.array(terms)
    top = float(np.max(t))
    if not math.isfinite(top):
        return 0.0 if top == -math.inf else math.inf
    total = float(np.sum(np.exp(t - top)))
    return math.exp(top) * total if top + math.log(total) < 709.0 else math.inf


def tail_bound(system: LinearSystem, lam: float, rate: float, tau_max: int) -> float:
    r"""A bound on what the LP's frozen cost in state M leaves out, over every feasible policy.

    The LP charges state M as if τ were M there; the true cost exceeds it by
    :math:`\pi_M \sum_j (1-g) g^{j+1} (\mathrm{tr}_{M+1+j} - \mathrm{tr}_{M+1}) \ge 0`. If
    ρ(A) < 1 the traces increase to :math:`\mathrm{Tr}\,X_\infty` and the gap is at most
    :math:`\mathrm{Tr}\,A^{M+1}(X_\infty - \bar P)A'^{M+1}`; otherwise (when J is bounded) every
    feasible policy has :math:`g_M \le g_{\max} < \rho^{-2}` and the gap is at most
    :math:`g_{\max} \sum_j g_{\max}^j \mathrm{tr}_{M+1+j}`.
    """
    M = tau_max
    A, Q = system.A, system.Q
    if system.spectral_radius < 1.0:
        D = solve_discrete_lyapunov(A, Q) - system.pbar
        Ak = np.linalg.matrix_power(A, M + 1)
        return max(0.0, float(np.trace(Ak @ D @ Ak.T)))
    a = 1.0 - lam
    if lam == 1.0 or rate == 0.0:
        # lam = 1 is bounded only at rate 0: nobody jams and M is never reached. At rate 0 the
        # hold probability is 0 (g = 1 - lam).
        leave_max = 1.0 if lam == 1.0 else lam
    else:
        # x π_M(x) = rate with no jams below M: 1 - x = b (1 - r) / (b + r S), S = Σ_{s<M} a^s,
        # b = a^M / λ, written so that 1 - g = λ (1 - x) keeps its precision when x is near 1.
        below, beyond = (1.0 - a**M) / lam, a**M / lam
        leave_max = lam * beyond * (1.0 - rate) / (beyond + rate * below)
    g_max = 1.0 - leave_max
    if g_max == 0.0:
        return 0.0
    if leave_max == 0.0:
        return math.inf
    _, Y, scale = log_traces(system, M + 1)
    log_sum = _log_tail(system, leave_max, Y, scale) - math.log(leave_max)
    return _log_sum([math.log(g_max) + log_sum])


def solve_long_run(system: LinearSystem, lam: float, rate: float, tau_max: int) -> LongRun:
    r"""The LP: maximise :math:`\sum c(s, a)\,y(s, a)` over occupation measures y of (s, a) with
    balance, :math:`\sum y = 1` and :math:`\sum_s y(s, 1) \le` rate.

    Scaling: the variables are :math:`z = y / w_s` with :math:`w_s = (1-\lambda)^s` (floored), the
    masses of the unjammed chain up to a constant, and each balance row is divided by its w, so
    the balance coefficients are 1 and :math:`1/(1-\lambda)` and the objective coefficients
    :math:`w_s\,\mathrm{tr}_{s+1}` stay of the size of J (divided by their largest) instead of
    growing like :math:`\rho(A)^{2s}`.
    """
    M = tau_max
    logtr, _, _ = log_traces(system, M + 1)
    q = 1.0 - lam
    s_idx = np.arange(M + 1)
    with np.errstate(divide="ignore"):
        logw = np.maximum(
            s_idx * math.log(q) if q > 0 else np.where(s_idx == 0, 0.0, -np.inf), math.log(_SCALE_FLOOR)
        )
    w = np.exp(logw)
    # Costs c(s, 1) = tr_{s+1}; c(s, 0) = λ tr_0 + (1-λ) tr_{s+1}; state M frozen at tr_{M+1}.
    up = np.exp(logw + logtr[1:])
    cost = np.empty(2 * (M + 1))
    cost[0::2] = lam * w * math.exp(logtr[0]) + q * up
    cost[1::2] = up
    unit = float(np.max(cost))
    # Balance of states 1..M, row t divided by w_t (state 0's row follows from the others and the
    # normalisation): z(t,·) = (w_{t-1}/w_t)(q z(t-1,0) + z(t-1,1)) [+ q z(M,0) + z(M,1) at t = M].
    A_eq = np.zeros((M + 1, 2 * (M + 1)))
    for t in range(1, M + 1):
        ratio = math.exp(logw[t - 1] - logw[t])
        A_eq[t - 1, 2 * t : 2 * t + 2] = 1.0
        A_eq[t - 1, 2 * (t - 1) : 2 * t] -= (q * ratio, ratio)
    A_eq[M - 1, 2 * M : 2 * M + 2] -= (q, 1.0)
    A_eq[M, :] = np.repeat(w, 2)
    b_eq = np.zeros(M + 1)
    b_eq[-1] = 1.0
    A_ub = np.zeros((1, 2 * (M + 1)))
    A_ub[0, 1::2] = w
    attempts: tuple[tuple[Literal["highs", "highs-ipm"], dict[str, bool]], ...] = (
        ("highs", {}),
        ("highs", {"presolve": False}),
        ("highs-ipm", {}),
    )
    for method, options in attempts:
        # HiGHS's presolve, and at times its simplex, give up (status "Not Set") on a few long
        # chains whose far states carry the floored scale; its interior-point solver does not.
        res = linprog(  # type: ignore[call-overload]  # the stubs type method="highs" alone
            -cost / unit,
            A_ub=A_ub,
            b_ub=[rate],
            A_eq=A_eq,
            b_eq=b_eq,
            bounds=(0, None),
            method=method,
            options=options,
        )
        if res.status == 0:
            break
    if res.status != 0 or res.x is None or res.fun is None:
        raise RuntimeError(f"rate: the jamming LP failed ({res.message})")
    z = np.asarray(res.x).reshape(M + 1, 2)
    total = z.sum(axis=1)
    visited = total > _UNVISITED
    idle = np.where(visited, z[:, 0] / np.where(visited, total, 1.0), 1.0)
    idle = np.clip(idle, 0.0, 1.0)
    j_lp = -float(res.fun) * unit
    bound = tail_bound(system, lam, rate, M)
    polish = bool(visited[M] and idle[M] < _POLISH)
    if polish:
        # The optimum reaches τ_max rarely and then jams with a probability so close to 1
        # (1 - x ~ (1-λ)^τ_max) that the LP's solution cannot resolve it (its masses on the way
        # up are below HiGHS's tolerances): fix it by the rate, which such a policy meets (a
        # hair inside, so that rounding cannot push the fraction over).
        idle[M] = _idle_for_rate(lam, idle, rate * (1.0 - 1e-12))
        if idle[M] == 0.0 and rate < 1.0:
            hint = max(1, int(600.0 / -math.log(1.0 - lam))) if lam < 1.0 else 1
            raise ValueError(
                f"tau_max = {M}: the optimal policy reaches tau_max with a probability below the double "
                f"range and then jams with a probability within it of 1; use tau_max <= {hint} at lam = {lam}"
            )
    j, fraction = policy_cost(system, lam, idle)
    for _ in range(0 if polish else 3):
        if fraction <= rate:
            break
        # HiGHS meets the rate within its tolerance (1e-7): shrink the policy into it.
        idle = 1.0 - (1.0 - idle) * (rate / fraction)
        j, fraction = policy_cost(system, lam, idle)
    if not (j_lp * (1.0 - _CERTIFY) - 1e-12 <= j <= (j_lp + bound) * (1.0 + _CERTIFY) + 1e-12):
        raise RuntimeError(
            f"rate: the LP's policy has J = {j!r}, outside [j_lp, j_lp + tail_bound] = "
            f"[{j_lp!r}, {j_lp + bound!r}]; the LP solution cannot be certified"
        )
    return LongRun(idle, j_lp, j, bound, fraction)


def _idle_for_rate(lam: float, idle: FloatArray, rate: float) -> float:
    r"""The idle probability u at τ_max that brings the jammed fraction to ``rate``.

    Per cycle from τ = 0 the chain reaches s < M with probability :math:`P_s = \prod_{t<s} g_t`
    and stays in M for :math:`1/(\lambda u)` steps once there, so the fraction is
    :math:`(a + P_M (1-u)/(\lambda u)) / (b + P_M/(\lambda u))` with :math:`a = \sum P_s x_s`,
    :math:`b = \sum P_s` (s < M); it equals r at
    :math:`u = P_M (1 - r) / (P_M + \lambda (r b - a))`, computed in logarithms (P_M underflows).
    """
    M = len(idle) - 1
    with np.errstate(divide="ignore"):
        log_g = np.log1p(-lam * idle[:M])
    log_p = np.concatenate(([0.0], np.cumsum(log_g)))
    p_below = np.exp(log_p[:M])
    slack = lam * (rate * p_below.sum() - p_below @ (1.0 - idle[:M]))
    if slack <= 0.0 or rate >= 1.0:
        return float(idle[M])
    log_pm = float(log_p[M])
    log_u = log_pm + math.log1p(-rate) - float(np.logaddexp(log_pm, math.log(slack)))
    return min(1.0, math.exp(log_u))
