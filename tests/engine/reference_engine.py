"""The exact engine written again, from the protocol alone, as the explicit chain over (tau, e).

Plain numpy/scipy; nothing from fakeack is used (the tests pass P̄ from ``fa.LinearSystem`` in).
It builds the joint chain of the holding time tau and everything else, e, by breadth-first
exploration of the protocol's rules, truncates tau where the remaining tail mass is negligible,
solves its stationary law by a sparse linear solve, and sums J = sum pi(tau, e) Tr h^tau(P̄)
with h(X) = A X A' + Q. It shares no formula with the engine's Stein equations.

One step k of the protocol (the order of rust/src/montecarlo/kernel/reference.rs, the Monte
Carlo kernel every other route is tested against):

1. the sensor's power: online, high iff a flag-ACK reached it at the end of step k-1 (high at
   k = 1); offline, the pattern's symbol for step k (first symbol = step 1);
2. the packet arrives with probability ``high[c_k]`` or ``low[c_k]``; tau_k = 0 on arrival, else
   tau_{k-1} + 1; the cost of step k is Tr h^{tau_k}(P̄);
3. online: the detector's zero count z restarts at an arrival and grows by one at a loss; with
   probability mu the memory has z0 bits at this step (z0 + 1 otherwise), and a flag-ACK is sent
   iff z >= the memory length, i.e. surely at z = z0 + 1 and with probability mu at z = z0; after
   a flag-ACK the count restarts (z = 0);
4. the attacker sees "flag" (a genuine flag-ACK was sent) or "quiet" and decides whether the sensor
   receives one ("deliver") and its next state; a delivered flag-ACK means high power at k+1;
5. the channel moves c_k -> c_{k+1} by P.

Initial condition (the paper's): c_1 has the stationary law of P, high power at k = 1, zero count
0 (memory all ones), the attacker in its start state (a mimicry attacker's virtual system starts
the same way, with its own c_1 drawn from the stationary law).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

TAIL = 1e-13
MAX_LEVELS = 20_000
MAX_STATES = 3_000_000


# --- attackers -------------------------------------------------------------------------------
# initial() -> [(p, state)]; step(state, flag) -> [(p, deliver, next_state)].


class NoAttack:
    def initial(self):
        return [(1.0, 0)]

    def step(self, a, flag):
        return [(1.0, flag, 0)]


class Mask:
    """Block the genuine flag-ACK counted sigma (mod len(mask)) iff mask[sigma]."""

    def __init__(self, mask):
        self.mask = [bool(b) for b in mask]

    def initial(self):
        return [(1.0, 0)]

    def step(self, s, flag):
        if not flag:
            return [(1.0, False, s)]
        return [(1.0, not self.mask[s], (s + 1) % len(self.mask))]


class Random:
    def __init__(self, beta):
        self.beta = beta

    def initial(self):
        return [(1.0, 0)]

    def step(self, a, flag):
        if not flag:
            return [(1.0, False, 0)]
        return [(self.beta, False, 0), (1.0 - self.beta, True, 0)]


class Inject:
    """Forge with probability gamma on a quiet step if k - k_last >= min_gap (k_last: the last step
    whose flag-ACK reached the sensor, 0 at the start). State (block state, k - k_last capped)."""

    def __init__(self, gamma, block=None, min_gap=1):
        self.gamma, self.block, self.m = gamma, block or NoAttack(), min_gap

    def initial(self):
        return [(p, (b, 1)) for p, b in self.block.initial()]

    def step(self, state, flag):
        b, d = state
        if flag:
            return [(p, dv, (b2, 1 if dv else min(d + 1, self.m))) for p, dv, b2 in self.block.step(b, True)]
        out = []
        for p, dv, b2 in self.block.step(b, False):
            assert not dv
            if d >= self.m:
                out += [
                    (p * self.gamma, True, (b2, 1)),
                    (p * (1 - self.gamma), False, (b2, min(d + 1, self.m))),
                ]
            else:
                out.append((p, False, (b2, min(d + 1, self.m))))
        return out


def stationary(P):
    """Stationary law of a row-stochastic P with one closed class (least squares on pi (P - I) = 0)."""
    P = np.asarray(P, dtype=float)
    n = P.shape[0]
    M = np.vstack([P.T - np.eye(n), np.ones((1, n))])
    b = np.zeros(n + 1)
    b[-1] = 1.0
    pi = np.linalg.lstsq(M, b, rcond=None)[0]
    pi[np.abs(pi) < 1e-15] = 0.0
    return pi / pi.sum()


def detector(z, arrive, z0, mu):
    """[(p, flag, z_after)] for a zero count z before the step."""
    z1 = 0 if arrive else z + 1
    if z1 >= z0 + 1:
        return [(1.0, True, 0)]
    if z1 == z0:
        return [(mu, True, 0), (1.0 - mu, False, z1)]
    return [(1.0, False, z1)]


class Mimicry:
    """Delivers the flag-ACKs of its own virtual attack-free system (channel, z0, mu)."""

    def __init__(self, P, low, high, z0, mu):
        self.P, self.low, self.high, self.z0, self.mu = np.asarray(P, float), low, high, z0, mu

    def initial(self):
        pi = stationary(self.P)
        return [(pi[c], (c, 0, True)) for c in range(len(pi)) if pi[c] > 0]

    def step(self, state, flag):
        c, z, h = state
        pa = self.high[c] if h else self.low[c]
        out = []
        for arrive, p1 in ((True, pa), (False, 1 - pa)):
            for p2, fl, z2 in detector(z, arrive, self.z0, self.mu):
                for c2 in np.flatnonzero(self.P[c] > 0):
                    out.append((p1 * p2 * self.P[c, c2], fl, (int(c2), z2, fl)))
        return out


class Automaton:
    def __init__(self, flag, quiet, start=0):
        self.flag, self.quiet, self.start = flag, quiet, start

    def initial(self):
        return [(1.0, self.start)]

    def step(self, s, flag):
        return list((self.flag if flag else self.quiet)[s])


# --- the chain of e ----------------------------------------------------------------------------


class Chain:
    """The automaton E of everything but tau, explored from the initial law.

    ``schedule`` is ``("online", z0, mu)`` or ``("offline", pattern)``. Each transition carries
    (arrive, flag, deliver, high) flags: K0 holds the losses, K1 the arrivals.
    """

    def __init__(self, P, low, high, schedule, attacker=None):
        self.P = np.asarray(P, dtype=float)
        self.low, self.high = list(map(float, low)), list(map(float, high))
        self.schedule = schedule
        self.attacker = attacker or NoAttack()
        pi = stationary(self.P)
        if schedule[0] == "online":
            init = [
                (pc * pa, (c, 0, True, a))
                for c, pc in enumerate(pi)
                if pc > 0
                for pa, a in self.attacker.initial()
            ]
        else:
            init = [(pc, (c, 0)) for c, pc in enumerate(pi) if pc > 0]
        self.states, index = [], {}
        rows, cols, vals, tags = [], [], [], []

        def ix(x):
            if x not in index:
                index[x] = len(self.states)
                self.states.append(x)
            return index[x]

        self.init = {}
        for p, x in init:
            self.init[ix(x)] = self.init.get(ix(x), 0.0) + p
        i = 0
        while i < len(self.states):
            for p, arrive, flag, deliver, high, y in self.step(self.states[i]):
                if p > 0:
                    rows.append(i)
                    cols.append(ix(y))
                    vals.append(p)
                    tags.append((arrive, flag, deliver, high))
            i += 1
        n = len(self.states)
        self.n = n
        self.rows, self.cols = np.array(rows), np.array(cols)
        self.vals, self.tags = np.array(vals), np.array(tags, dtype=bool).reshape(-1, 4)
        self.x0 = np.zeros(n)
        for k, p in self.init.items():
            self.x0[k] = p

    def step(self, x):
        """[(p, arrive, flag, deliver, high_now, next_x)] of one step from pre-step state x."""
        out = []
        if self.schedule[0] == "offline":
            pattern = self.schedule[1]
            c, j = x
            h = bool(pattern[j])
            pa = self.high[c] if h else self.low[c]
            for arrive, p1 in ((True, pa), (False, 1 - pa)):
                for c2 in np.flatnonzero(self.P[c] > 0):
                    out.append(
                        (p1 * self.P[c, c2], arrive, False, False, h, (int(c2), (j + 1) % len(pattern)))
                    )
            return out
        _, z0, mu = self.schedule
        c, z, h, a = x
        pa = self.high[c] if h else self.low[c]
        for arrive, p1 in ((True, pa), (False, 1 - pa)):
            for p2, flag, z2 in detector(z, arrive, z0, mu):
                for p3, deliver, a2 in self.attacker.step(a, flag):
                    for c2 in np.flatnonzero(self.P[c] > 0):
                        p = p1 * p2 * p3 * self.P[c, c2]
                        out.append((p, arrive, flag, bool(deliver), h, (int(c2), z2, bool(deliver), a2)))
        return out

    def matrix(self, mask):
        m = mask
        return sp.csr_array((self.vals[m], (self.rows[m], self.cols[m])), shape=(self.n, self.n))

    @property
    def K0(self):
        return self.matrix(~self.tags[:, 0])

    @property
    def K1(self):
        return self.matrix(self.tags[:, 0])

    def closed_classes(self):
        K = (self.K0 + self.K1).tocsr()
        ncomp, lab = connected_components(K, directed=True, connection="strong")
        r, c = K.nonzero()
        leaves = set(lab[r][lab[r] != lab[c]].tolist())
        return [np.flatnonzero(lab == k) for k in range(ncomp) if k not in leaves]

    def absorption(self):
        """[(alpha, class)]: the probability of ending in each closed class from the initial law."""
        classes = self.closed_classes()
        if len(classes) == 1:
            return [(1.0, classes[0])]
        K = (self.K0 + self.K1).toarray()
        closed = np.concatenate(classes)
        trans = np.setdiff1d(np.arange(self.n), closed)
        N = np.linalg.inv(np.eye(len(trans)) - K[np.ix_(trans, trans)])
        out = []
        for cl in classes:
            hit = N @ K[np.ix_(trans, cl)].sum(axis=1)
            out.append((float(self.x0[cl].sum() + self.x0[trans] @ hit), cl))
        return [(a, cl) for a, cl in out if a > 0]


def traces(A, Q, pbar, n):
    """[Tr h^i(P̄)] for i = 0..n (inf past the double range)."""
    A, Q = np.atleast_2d(A).astype(float), np.atleast_2d(Q).astype(float)
    X = np.array(np.atleast_2d(pbar), dtype=float)
    out = np.empty(n + 1)
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(n + 1):
            out[i] = np.trace(X) if np.all(np.isfinite(X)) else math.inf
            X = A @ X @ A.T + Q
    out[np.isnan(out)] = math.inf
    return out


def spectral_radius(M):
    M = M.toarray() if sp.issparse(M) else np.asarray(M)
    return float(max(abs(np.linalg.eigvals(M)))) if M.size else 0.0


def gth(K):
    """Stationary law of a dense irreducible row-stochastic K by GTH state reduction."""
    A = np.array(K, dtype=float)
    n = A.shape[0]
    for k in range(n - 1, 0, -1):
        s = A[k, :k].sum()
        A[:k, k] /= s
        A[:k, :k] += np.outer(A[:k, k], A[k, :k])
    x = np.zeros(n)
    x[0] = 1.0
    for k in range(1, n):
        x[k] = x[:k] @ A[:k, k]
    return x / x.sum()


class Solution:
    """The stationary law of the explicit chain of (tau, e) on each closed class of E.

    Its balance equations are pi(tau + 1, .) = pi(tau, .) K0 and pi(0, .) = sum_tau pi(tau, .) K1
    = pi_E K1, with pi_E the stationary law of E (by GTH). They are solved level by level, which
    keeps the relative accuracy of every tiny probability (a global sparse solve of the truncated
    chain leaves absolute errors near 1e-17, which traces of 1e20 at large tau would magnify;
    :func:`explicit_law` is that solve, used as a cross-check where the traces stay small). Levels
    are added until the mass left is below ``tail`` and, with the traces ``tr`` given, until the
    tail's share of J, estimated as m_T tr_T / (1 - rho(K0) rho(A)^2), is below ``tail``. When
    rho(K0) rho(A)^2 >= 1, nothing is summed and ``infinite`` is set.
    """

    def __init__(self, chain, rho_a2=0.0, tr=None, tail=TAIL):
        self.chain = chain
        self.parts = []
        self.infinite = False
        K0, K1 = chain.K0, chain.K1
        classes = []
        for alpha, cl in chain.absorption():
            k0, k1 = K0[cl][:, cl], K1[cl][:, cl]
            self._check_arrivals(k0, k1)
            classes.append((alpha, cl, k0, k1, spectral_radius(k0)))
        # J is the long-run mean of E Tr P_k, so transient states count too: a loss loop among
        # them that the chain leaves with probability rho_T^k only, while the trace grows like
        # rho(A)^(2k), makes E Tr P_k diverge even though almost every path ends in a closed
        # class (the closed classes' radii alone would miss it).
        # K0 is block triangular (closed classes never lead back), so its spectrum is that of the
        # transient block and the classes' blocks.
        closed = np.zeros(K0.shape[0], dtype=bool)
        for _, cl, *_ in classes:
            closed[cl] = True
        transient = np.flatnonzero(~closed)
        rho_t = spectral_radius(K0[transient][:, transient]) if transient.size else 0.0
        self.rho_k0 = max(max(c[-1] for c in classes), rho_t)
        self.index = self.rho_k0 * rho_a2
        if self.index >= 1.0:
            self.infinite = True
            return
        t = tr(256) if tr is not None else None
        for alpha, cl, k0, k1, r in classes:
            pe = gth((k0 + k1).toarray())
            row = pe @ k1  # pi(0, .)
            k0t = k0.T.tocsr()
            rows, total = [], 0.0
            while True:
                rows.append(row)
                m = row.sum()
                if t is not None and len(rows) > len(t):
                    t = tr(2 * len(t))
                if t is not None and m > 0:
                    with np.errstate(over="ignore"):
                        total += m * t[len(rows) - 1]
                done = m <= tail * 1e-3 and (
                    t is None or m == 0 or m * t[len(rows) - 1] <= tail * 1e-3 * (1 - self.index) * total
                )
                if done or len(rows) >= MAX_LEVELS:
                    break
                row = k0t @ row
            if not done:
                raise RuntimeError(f"reference: tail mass {m:.3g} after {len(rows)} levels")
            self.parts.append((alpha, cl, np.array(rows), r))

    @staticmethod
    def _check_arrivals(k0, k1):
        """rho(K0) < 1: from every state of the class an arrival is reachable through losses."""
        leaky = np.asarray(k1.sum(axis=1)).ravel() > 0
        reach = leaky.copy()
        g = k0.tocsc()
        while True:  # states with a K0 edge into reach
            new = reach | (np.asarray(g @ reach.astype(float)).ravel() > 0)
            if (new == reach).all():
                break
            reach = new
        if not reach.all():
            raise ValueError("no arrival is reachable from some state (rho(K0) = 1)")

    def law(self):
        """[(alpha, class, pi[tau, e])]."""
        return self.parts

    def tau_law(self):
        """P(tau = 0..L-1) over all classes (the last entry holds the truncated tail)."""
        L = max(pi.shape[0] for _, _, pi, _ in self.parts)
        out = np.zeros(L)
        for a, _, pi, _ in self.parts:
            out[: pi.shape[0]] += a * pi.sum(axis=1)
        return out

    def pi_e(self):
        out = np.zeros(self.chain.n)
        for a, cl, pi, _ in self.parts:
            out[cl] += a * pi.sum(axis=0)
        return out


def explicit_law(k0, k1, levels):
    """The stationary law pi[tau, e] of the explicit chain of (tau, e), tau truncated at levels - 1
    (that level lumps tau >= levels - 1), by one sparse linear solve."""
    n = k0.shape[0]
    k0, k1 = k0.tocoo(), k1.tocoo()
    L = levels
    rows, cols, vals = [], [], []
    for tau in range(L):
        rows.append(tau * n + k1.row)
        cols.append(k1.col)
        vals.append(k1.data)
        rows.append(tau * n + k0.row)
        cols.append(min(tau + 1, L - 1) * n + k0.col)
        vals.append(k0.data)
    N = L * n
    if N > MAX_STATES:
        raise RuntimeError(f"reference: {N} states")
    T = sp.csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N))
    M = (sp.csr_array(sp.identity(N, format="csr")) - T).T.tolil()  # scipy 1.10 has no eye_array
    M[N - 1, :] = np.ones(N)
    b = np.zeros(N)
    b[-1] = 1.0
    Mc = M.tocsc()
    x = spla.spsolve(Mc, b)
    x = x + spla.spsolve(Mc, b - Mc @ x)  # one step of iterative refinement
    x[x < 0] = 0.0
    return (x / x.sum()).reshape(L, n)


def cost(chain, A, Q, pbar, rho_a2=None):
    """J = sum pi(tau, e) tr_tau; inf when rho(K0) rho(A)^2 >= 1."""
    if rho_a2 is None:
        rho_a2 = spectral_radius(np.atleast_2d(A)) ** 2
    sol = Solution(chain, rho_a2, tr=lambda n: traces(A, Q, pbar, n))
    if sol.infinite:
        return math.inf
    law = sol.tau_law()
    tr = traces(A, Q, pbar, len(law))
    keep = law > 0
    with np.errstate(over="ignore"):
        return float(np.sum(law[keep] * tr[: len(law)][keep]))


def rates(chain, sol=None):
    """(high-power rate, sent, delivered, forged) per step in the long run."""
    sol = sol or Solution(chain)
    pe = sol.pi_e()
    w = pe[chain.rows] * chain.vals
    arrive, flag, deliver, high = chain.tags.T
    return (
        float(w[high].sum()),
        float(w[flag].sum()),
        float(w[deliver].sum()),
        float(w[deliver & ~flag].sum()),
    )


def delivered_law(chain, length):
    """{pattern: P(the sensor receives flag-ACKs per pattern on `length` consecutive steps)}."""
    sol = Solution(chain)
    pe = sol.pi_e()
    deliver = chain.tags[:, 2]
    D = [chain.matrix(~deliver), chain.matrix(deliver)]
    out = {}

    def walk(v, prefix):
        if len(prefix) == length:
            out["".join(map(str, prefix))] = float(v.sum())
            return
        for s in (0, 1):
            walk(v @ D[s], prefix + [s])

    walk(pe, [])
    return out


def curve(chain, A, Q, pbar, horizon):
    """(E Tr P_k, J_k) for k = 1..horizon from the initial law."""
    K0, K1 = chain.K0.toarray(), chain.K1.toarray()
    tr = traces(A, Q, pbar, horizon)
    law = np.zeros((horizon + 1, chain.n))  # law[tau, e] before the step
    law[0] = chain.x0
    out = np.empty(horizon)
    for k in range(horizon):
        new = np.zeros_like(law)
        new[0] = law.sum(axis=0) @ K1
        new[1:] = law[:-1] @ K0
        law = new
        m = law.sum(axis=1)
        keep = m > 0
        out[k] = np.sum(m[keep] * tr[keep])
    return out, np.cumsum(out) / np.arange(1, horizon + 1)


def attacker_from(flag: Sequence, quiet: Sequence, start: int) -> Automaton:
    return Automaton([list(map(tuple, f)) for f in flag], [list(map(tuple, q)) for q in quiet], start)
