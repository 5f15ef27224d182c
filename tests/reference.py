"""Independent reference implementations for the tests: plain numpy/scipy, written from the
paper's rules (as corrected in the README's Model notes), sharing no code with fakeack."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def pbar_scipy(A, C, Q, R):
    """Posterior steady-state covariance from scipy's DARE (the dual, control form)."""
    A, C, Q, R = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (A, C, Q, R))
    prior = sla.solve_discrete_are(A.T, C.T, Q, R)
    S = C @ prior @ C.T + R
    return prior - prior @ C.T @ np.linalg.solve(S, C @ prior)


def traces(A, Q, pbar, n):
    """[Tr h^i(P̄)] for i = 0..n by plain iteration."""
    A, Q = np.atleast_2d(A), np.atleast_2d(Q)
    X = np.array(pbar, dtype=float)
    out = [np.trace(X)]
    for _ in range(n):
        X = A @ X @ A.T + Q
        out.append(np.trace(X))
    return np.array(out)


def explore_chain(lam, z0, r, t, mu=1.0):
    """Breadth-first exploration of the attack chain from (0, 0) by rules 1)-4) (Model note 3:
    the first r of every t flags are blocked). Returns (states list, dense row-stochastic T)."""
    a = 1.0 - lam

    def succ(tau, sigma):
        if tau == 0 or tau % z0 != 0:
            return [((0, sigma), lam), ((tau + 1, sigma), a)]
        if sigma < r:
            return [((0, sigma + 1), lam), ((tau + 1, sigma + 1), a)]
        return [((0, (sigma + 1) % t), 1.0)]

    index = {(0, 0): 0}
    order = [(0, 0)]
    i = 0
    while i < len(order):
        for s, _ in succ(*order[i]):
            if s not in index:
                index[s] = len(order)
                order.append(s)
        i += 1
    n = len(order)
    T = np.zeros((n, n))
    for s, k in index.items():
        for d, p in succ(*s):
            T[k, index[d]] += p
    return order, T


def stationary_dense(T):
    """Stationary law of a dense row-stochastic matrix: solve pi (T - I) = 0 with sum(pi) = 1."""
    n = T.shape[0]
    M = T.T - np.eye(n)
    M[-1, :] = 1.0
    b = np.zeros(n)
    b[-1] = 1.0
    x = np.linalg.solve(M, b)
    # Two steps of iterative refinement with residuals in extended precision: plain LU leaves
    # relative errors ~1e-8 on tiny probabilities, which large traces then weight.
    Ml = M.astype(np.longdouble)
    for _ in range(2):
        r = (b - Ml @ x.astype(np.longdouble)).astype(np.float64)
        x = x + np.linalg.solve(M, r)
    return x


def online_chain(lam, z0, mu):
    """Holding-time chain of the unattacked online schedule with variable memory (Model note 2):
    a flag at tau = z0 with probability mu, always at tau = z0 + 1. Returns (T, flag_prob per state)."""
    a = 1.0 - lam
    n = z0 + 2
    T = np.zeros((n, n))
    flag = np.zeros(n)
    for tau in range(n):
        f = 0.0 if tau < z0 else (mu if tau == z0 else 1.0)
        flag[tau] = f
        if f > 0:
            T[tau, 0] += f  # high power next step: arrival
        if f < 1:
            T[tau, 0] += (1 - f) * lam
            if tau + 1 < n:
                T[tau, tau + 1] += (1 - f) * a
    return T, flag


def offline_direct(tr, lam, pattern, periods=60):
    """Period average of E Tr P_k under a periodic 0/1 pattern, by propagating the tau law until
    it is periodic-stationary."""
    a = 1.0 - lam
    law = np.zeros(len(tr))
    law[0] = 1.0
    for _ in range(periods):
        total = 0.0
        for g in pattern:
            if g:
                law = np.zeros(len(tr))
                law[0] = 1.0
            else:
                new = np.zeros(len(tr))
                new[0] = lam * law.sum()
                new[1:] = a * law[:-1]
                law = new
            total += law @ tr
    return total / len(pattern)


def explore_mask_chain(lam, z0, mask, mu=1.0, sparse=False):
    """The (tau, zeros, sigma) chain for a periodic blocking mask and memory mix mu (no forging):
    :func:`explore_any_chain` with the mask's 0/1 entries as blocking probabilities."""
    return explore_any_chain(lam, z0, mu, [float(b) for b in mask], 0.0, sparse=sparse)


def explore_any_chain(lam, z0, mu=1.0, block=(0.0,), gamma=0.0, tau_cap=None, sparse=False):
    """The protocol's (tau, zeros, sigma) chain under blocking and forging, by breadth-first
    exploration: the flag counted sigma is blocked with probability block[sigma % len(block)]
    (0/1 for a periodic mask, beta with len(block) == 1 for independent blocking), and on every
    step without a genuine flag a flag is forged with probability gamma (the sensor then uses high
    power and the next step restarts). A step that would pass tau_cap restarts instead: the
    mass beyond the cap must be negligible. Returns (states,
    row-stochastic T: dense, or scipy CSR with sparse=True)."""
    a, t = 1.0 - lam, len(block)
    cap = float("inf") if tau_cap is None else tau_cap

    def st(tau, z, sigma):
        return (tau, z, sigma) if tau <= cap else (0, 0, sigma)

    def succ(state):
        tau, z, sigma = state
        flag = 1.0 if z == z0 + 1 else (mu if z == z0 else 0.0)
        out = []
        if flag > 0:
            nxt, b = (sigma + 1) % t, block[sigma]
            out += [(st(0, 0, nxt), flag * (1 - b) + flag * b * lam), (st(tau + 1, 1, nxt), flag * b * a)]
        if flag < 1:
            out += [
                (st(0, 0, sigma), (1 - flag) * (gamma + (1 - gamma) * lam)),
                (st(tau + 1, z + 1, sigma), (1 - flag) * (1 - gamma) * a),
            ]
        return [(s, p) for s, p in out if p > 0]

    index = {(0, 0, 0): 0}
    order = [(0, 0, 0)]
    i = 0
    while i < len(order):
        for s, _ in succ(order[i]):
            if s not in index:
                index[s] = len(order)
                order.append(s)
        i += 1
    if sparse:
        rows, cols, vals = zip(*((k, index[d], p) for s, k in index.items() for d, p in succ(s)), strict=True)
        T = sp.csr_array((vals, (rows, cols)), shape=(len(order), len(order)))  # duplicates add up
        return order, T
    T = np.zeros((len(order), len(order)))
    for s, k in index.items():
        for d, p in succ(s):
            T[k, index[d]] += p
    return order, T


def stationary_power(T, iterations=2000):
    """Stationary law by power iteration from the uniform law. Each entry is built from products
    of transition probabilities, so tiny entries keep their relative accuracy (a dense solve has
    absolute errors of about 1e-17, too coarse where they meet traces of 1e9)."""
    pi = np.full(T.shape[0], 1.0 / T.shape[0])
    for _ in range(iterations):
        pi = pi @ T
        pi /= pi.sum()
    return pi


def stationary_sparse(T):
    """Stationary law of a sparse row-stochastic matrix: pin one balance equation to the
    normalisation and solve with scipy's sparse LU."""
    n = T.shape[0]
    A = sp.lil_matrix(T.T - sp.identity(n, format="csr"))  # scipy 1.10 has no eye_array
    A[0, :] = 1.0
    b = np.zeros(n)
    b[0] = 1.0
    return spla.spsolve(A.tocsc(), b)


def memory_chain_all_blocked(lam, z0, mu=1.0):
    """Zeros in the detector's memory when every flag is blocked: from z zeros a flag goes out
    with probability 1 (z = z0 + 1), mu (z = z0) or 0; a blocked flag resets the memory and the
    step stays low power, so the next count is 0 after an arrival, 1 after a loss that followed a
    flag, z + 1 after a loss without one. Returns (dense row-stochastic T, flag probability per
    state); the all-blocked flag rate is pi @ flag."""
    a = 1.0 - lam
    n = z0 + 2
    T = np.zeros((n, n))
    flag = np.array([1.0 if z == z0 + 1 else (mu if z == z0 else 0.0) for z in range(n)])
    for z in range(n):
        T[z, 0] += lam
        T[z, 1] += a * flag[z]
        if flag[z] < 1:
            T[z, z + 1] += a * (1 - flag[z])
    return T, flag


def additive_variance_rate(T, f):
    """Asymptotic variance per step of the sum of f(X_k) along a stationary ergodic chain T:
    sigma^2 = 2 pi(fbar Z fbar) - pi(fbar^2), fbar = f - pi f, Z = (I - T + 1 pi)^-1 (the
    fundamental matrix; Kemeny and Snell). Returns (pi f, sigma^2)."""
    n = T.shape[0]
    pi = stationary_dense(T)
    mean = float(pi @ f)
    fbar = f - mean
    Z = np.linalg.inv(np.eye(n) - T + np.outer(np.ones(n), pi))
    return mean, float(2 * pi @ (fbar * (Z @ fbar)) - pi @ (fbar * fbar))
