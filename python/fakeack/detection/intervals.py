"""The gaps between flag-ACKs reaching the sensor, exactly, under any attack.

A flag-ACK that reaches the sensor (genuine and not blocked, or forged) makes it use high power on
the next step, so the packet arrives and the detector's memory restarts: each gap starts afresh.
Without attack, or under an attack with no counter (:class:`fakeack.RandomBlocking`, a
:class:`fakeack.FlagInjection` without a periodic part), the gaps are therefore i.i.d. A periodic
attack keeps a counter σ of genuine flags, and the gap after a delivered flag depends on the value
σ has then: the gaps form a *Markov renewal process*, with the counter at the start of a gap as
its type. Everything below is exact for that process (no simulation, no truncation beyond the
1e-16 tails of finite sums).

One gap, from the step after a delivered flag (memory reset, zero count z = 0, counter σ) until
the next delivered flag, is an absorbing walk over (z, σ), z = 0..z0+1: at z the detector sends a
genuine flag with probability f(z) (μ at z0, 1 at z0 + 1, else 0), which the attacker blocks with
probability b(σ) (mask[σ] or β) and which advances σ; a blocked flag restarts the memory (z = 0 on
an arrival, 1 on a loss); with no genuine flag a forged one comes with probability γ; otherwise an
arrival resets z and a loss adds one. The gap's length X is the number of steps the walk visits,
the absorbing one included; with Q the transient part, A the absorption into each next type and
N = (I - Q)^-1, P(X = x, next type) = e' Q^(x-1) A, E[X; next] = e' N² A and
E[X²; next] = e' (I + Q) N³ A.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._internal.types import FloatArray, IntArray
from .._internal.validate import as_int
from ..attacks.kinds import (
    Attack,
    AttackLike,
    FlagInjection,
    MaskBlocking,
    PeriodicBlocking,
    RandomBlocking,
    as_attack,
)
from ..model.schedules import OnlineDesign, check_online

__all__ = [
    "IntervalLaw",
    "flag_interval_law",
    "FlagCount",
    "flag_count_moments",
]


#: Largest (z0 + 2) x period of the gap walk solved (a sparse LU of this size, and one dense row
#: per counter value).
MAX_WALK_STATES = 200_000
#: Largest (z0 + 2) x period x period: the dense rows the moments need.
MAX_WALK_ENTRIES = 20_000_000


def _blocking(attack: Attack | None) -> tuple[list[float], float]:
    """(block probability per counter value, forging probability γ) of a validated attack."""
    if attack is None:
        return [0.0], 0.0
    gamma = 0.0
    if isinstance(attack, FlagInjection):
        if attack.min_gap > 1:
            raise ValueError(
                f"attack: FlagInjection with min_gap={attack.min_gap} is computed only by fakeack.Scenario "
                "(the exact engine); the gap laws take min_gap=1"
            )
        gamma, attack = attack.gamma, attack.block
        if attack is None:
            return [0.0], gamma
    if isinstance(attack, RandomBlocking):
        return [attack.beta], gamma
    if isinstance(attack, (PeriodicBlocking, MaskBlocking)):
        return [1.0 if b else 0.0 for b in attack.mask], gamma
    raise TypeError(f"attack: unsupported attack {type(attack).__name__}")


class _Walk:
    """The gap walk of one (λ, z0, μ, attack): the Markov renewal process of delivered flags.

    Types are counter values σ = 0..t-1 (t = 1 without a periodic part). ``kernel[σ, σ']`` is the
    embedded chain of types, ``pi`` its stationary law (restricted to the types that recur),
    ``mean_x[σ, σ']`` = E[X; next = σ' | σ] and ``second_x`` likewise for X².
    """

    def __init__(self, lam: float, design: OnlineDesign, attack: Attack | None) -> None:
        z0, mu = design
        block, gamma = _blocking(attack)
        t = len(block)
        width = z0 + 2
        n = width * t
        if n > MAX_WALK_STATES or n * t > MAX_WALK_ENTRIES:
            raise ValueError(
                f"attack: a period of {t} flag-ACKs with z0 = {z0} gives a gap walk of {n} states "
                f"x {t} types, above the limit ({MAX_WALK_STATES} states, {MAX_WALK_ENTRIES} entries)"
            )
        a = 1.0 - lam
        rows, cols, vals = [], [], []
        absorb = np.zeros((n, t))
        for sigma in range(t):
            nxt = (sigma + 1) % t
            b = block[sigma]
            for z in range(width):
                s = sigma * width + z
                f = 1.0 if z == z0 + 1 else (mu if z == z0 else 0.0)
                if f > 0.0:
                    absorb[s, nxt] += f * (1.0 - b)
                    rows += [s, s]
                    cols += [nxt * width, nxt * width + 1]
                    vals += [f * b * lam, f * b * a]
                if f < 1.0:
                    absorb[s, sigma] += (1.0 - f) * gamma
                    rows += [s, s]
                    cols += [sigma * width, sigma * width + z + 1]
                    vals += [(1.0 - f) * (1.0 - gamma) * lam, (1.0 - f) * (1.0 - gamma) * a]
        self.lam, self.z0, self.mu, self.t, self.width, self.n = lam, z0, mu, t, width, n
        self.Q = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
        self.A = absorb
        self.starts = np.arange(t) * width
        # A walk that can never be absorbed (every genuine flag blocked, none forged): no gap ends.
        self.endless = not np.any(absorb > 0.0)
        if self.endless:
            return
        lu = spla.splu(sp.identity(n, format="csc") - self.Q.tocsc())
        # Row vectors e_σ' N^k for the start states, by transposed solves.
        e = np.zeros((n, t))
        e[self.starts, np.arange(t)] = 1.0
        # scipy-stubs' SuperLU.solve lacks scipy's `trans` argument.
        r1 = lu.solve(e, trans="T")  # type: ignore[call-overload]
        r2 = lu.solve(r1, trans="T")  # type: ignore[call-overload]
        r3 = lu.solve(r2, trans="T")  # type: ignore[call-overload]
        self.kernel = r1.T @ absorb  # P(next = σ' | σ)
        self.mean_x = r2.T @ absorb  # E[X; next = σ' | σ]
        # e' (I + Q) N^3 A; Q and N commute, so it is e' N^3 (I + Q) A.
        self.second_x = r3.T @ absorb + r3.T @ (self.Q @ absorb)
        self.pi = _stationary(self.kernel)
        self.mean = float(self.pi @ self.mean_x.sum(axis=1))
        self.second = float(self.pi @ self.second_x.sum(axis=1))
        self._pmf = np.zeros((0, t, t))
        self._rows = np.zeros((t, n))  # e' Q^(x-1) for the start states, x = pmf length + 1
        self._rows[np.arange(t), self.starts] = 1.0

    def pmf(self, x_max: int) -> FloatArray:
        """P(X = x, next = σ' | σ) for x = 1..x_max, shape (x_max, t, t)."""
        have = self._pmf.shape[0]
        if x_max > have:
            out = [self._pmf]
            rows = self._rows
            QT = self.Q.T.tocsr()
            for _ in range(have, x_max):
                out.append((rows @ self.A)[None])
                rows = (QT @ rows.T).T
            self._rows = rows
            self._pmf = np.concatenate(out, axis=0)
        return self._pmf[:x_max]

    def bin_moments(self, edges: IntArray) -> tuple[FloatArray, FloatArray]:
        """Per bin: P(B = i, next = σ' | σ) and E[X; B = i, next = σ' | σ], shapes (k, t, t).

        Bin i holds the gaps in [edges[i], edges[i+1]), the last one [edges[-1], inf).
        """
        edges = np.asarray(edges, dtype=np.int64)
        k = len(edges)
        x_last = int(edges[-1])
        pmf = self.pmf(x_last - 1)
        x = np.arange(1, x_last)[:, None, None]
        prob = np.zeros((k, self.t, self.t))
        mean = np.zeros((k, self.t, self.t))
        for i in range(k - 1):
            lo, hi = int(edges[i]), int(edges[i + 1])
            prob[i] = pmf[lo - 1 : hi - 1].sum(axis=0)
            mean[i] = (x[lo - 1 : hi - 1] * pmf[lo - 1 : hi - 1]).sum(axis=0)
        prob[-1] = np.clip(self.kernel - prob[:-1].sum(axis=0), 0.0, None)
        mean[-1] = np.clip(self.mean_x - mean[:-1].sum(axis=0), 0.0, None)
        return prob, mean

    def time_covariance(self, edges: IntArray) -> tuple[FloatArray, FloatArray]:
        """(p, Σ): Palm bin probabilities and the asymptotic covariance per step of the bin counts.

        Over n steps the counts O of delivered flags whose gap falls in each bin have mean
        n p / m and covariance ≈ n Σ, by the Markov renewal central limit theorem:
        Σ = AsyVar(W) / m for the sequence W_j = e_{B_j} - (X_j / m) p of the gaps, whose
        asymptotic covariance is Var_π(W) + C + C' with
        C = Σ_{l≥1} Cov(W_0, W_l) = E_π[W_0 h(σ_1)'], h = (I - P + 1π')^-1 g the solution of the
        Poisson equation for g(σ) = E[W | σ] (π g = 0).
        """
        prob, mean_b = self.bin_moments(edges)
        t, m, pi = self.t, self.mean, self.pi
        p = np.einsum("s,ist->i", pi, prob)
        q = np.einsum("s,ist->i", pi, mean_b)  # E_π[X; B = i]
        var0 = np.diag(p) - (np.outer(q, p) + np.outer(p, q)) / m + np.outer(p, p) * self.second / m**2
        # Joint conditional means of W with the next type: E[W 1{next = σ'} | σ], shape (t, t, k).
        w_joint = np.transpose(prob, (1, 2, 0)) - self.mean_x[:, :, None] * p[None, None, :] / m
        g = w_joint.sum(axis=1)  # (t, k)
        fund = np.eye(t) - self.kernel + np.outer(np.ones(t), pi)
        h = np.linalg.solve(fund, g)
        C = np.einsum("s,sui,uj->ij", pi, w_joint, h)
        sigma = (var0 + C + C.T) / m
        return p, 0.5 * (sigma + sigma.T)


def _stationary(P: FloatArray) -> FloatArray:
    """Stationary law of a stochastic matrix with one recurrent class (types that are never the
    start of a gap get zero mass)."""
    n = P.shape[0]
    if n == 1:
        return np.ones(1)
    M = P.T - np.eye(n)
    M[0] = 1.0  # one balance equation replaced by the normalisation
    rhs = np.zeros(n)
    rhs[0] = 1.0
    pi = np.linalg.solve(M, rhs)
    pi = np.clip(pi, 0.0, None)
    out: FloatArray = pi / pi.sum()
    return out


@functools.lru_cache(maxsize=4096)
def _walk(lam: float, design: OnlineDesign, attack: Attack | None) -> _Walk:
    return _Walk(lam, design, attack)


def walk(lam: float, z0: int, attack: AttackLike = None, mu: float = 1.0) -> _Walk:
    """The (cached) gap walk of a schedule and attack, validated here."""
    lam, design = check_online(lam, z0, mu)
    return design_walk(lam, design, attack)


def design_walk(lam: float, design: OnlineDesign, attack: AttackLike = None) -> _Walk:
    """The (cached) gap walk of a validated schedule, under any attack."""
    return _walk(lam, design, as_attack(attack))


@dataclass(frozen=True)
class IntervalLaw:
    """The law of the gaps between flag-ACKs reaching the sensor (see :func:`flag_interval_law`)."""

    pmf: FloatArray
    """P(X = x) for x = 1..len(pmf) (a gap drawn at a typical delivered flag, the Palm law)."""
    tail: float
    """P(X > len(pmf))."""
    mean: float
    """E[X] = 1 / (flag-ACKs reaching the sensor per step)."""
    variance: float
    """Var(X) of one gap."""
    asymptotic_variance: float
    """lim Var(X_1 + ... + X_k) / k: ``variance`` plus twice the gaps' serial covariances (equal to
    ``variance`` when the gaps are i.i.d.: no attack, or an attack without a counter)."""
    iid: bool
    """True when the gaps are i.i.d."""


def flag_interval_law(
    lam: float, z0: int, attack: AttackLike = None, mu: float = 1.0, x_max: int | None = None
) -> IntervalLaw:
    r"""Exact law of the gaps between flag-ACKs reaching the sensor, under any attack.

    Each delivered flag restarts the detector's memory (the sensor's high-power packet arrives),
    so the gaps are i.i.d. without attack or under an attack with no counter; under a periodic
    attack they form a Markov renewal process whose type is the attacker's counter at the start
    of a gap. The law here is the one of a gap at a typical delivered flag (the stationary type
    law π of the embedded chain); its moments come from the fundamental matrix of the absorbing
    gap walk (the module docstring has the walk and the formulas), its serial covariances from
    the Poisson equation of the embedded chain.

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    attack : None or attack, optional
        Any attack (periodic or mask blocking, random blocking, flag injection).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    x_max : int, optional
        Longest gap whose probability is listed (default: until the tail is below 1e-15, at most
        10000 steps).

    Returns
    -------
    IntervalLaw

    Raises
    ------
    ValueError
        When no flag-ACK ever reaches the sensor (every flag blocked, none forged): the gap is
        infinite.

    Examples
    --------
    >>> law = flag_interval_law(0.5, 2)
    >>> round(law.mean, 12) == 7.0 and law.iid
    True
    """
    w = walk(lam, z0, attack, mu)
    if w.endless:
        raise ValueError("attack: no flag-ACK ever reaches the sensor, so the gap is infinite")
    if x_max is None:
        x = 64
        while x < 10_000:
            pmf = np.einsum("s,xst->x", w.pi, w.pmf(x))
            if 1.0 - pmf.sum() < 1e-15:
                break
            x *= 2
        x_max = min(x, 10_000)
    x_max = as_int("x_max", x_max, minimum=1, maximum=10**6)
    pmf = np.einsum("s,xst->x", w.pi, w.pmf(x_max))
    tail = max(1.0 - float(pmf.sum()), 0.0)
    var = w.second - w.mean**2
    edges = np.array([1])  # one bin: W = 1 - X/m, whose asymptotic variance is s²/m²
    _, sig = w.time_covariance(edges)
    asy = float(sig[0, 0]) * w.mean**3
    iid = w.t == 1
    return IntervalLaw(pmf, tail, w.mean, max(var, 0.0), max(asy, 0.0), iid)


@dataclass(frozen=True)
class FlagCount:
    """Mean and variance of the flag-ACKs reaching the sensor in a window (see
    :func:`flag_count_moments`)."""

    mean: float
    variance: float
    n_steps: int


def flag_count_moments(
    lam: float, z0: int, n_steps: int, attack: AttackLike = None, mu: float = 1.0
) -> FlagCount:
    r"""Mean and (asymptotic) variance of the flag-ACKs reaching the sensor in ``n_steps`` steps.

    In the stationary regime the count N over n steps has mean :math:`n/m` exactly (m the mean
    gap, :func:`flag_interval_law`) and, by the Markov renewal central limit theorem, variance
    :math:`n s^2/m^3 + O(1)` with :math:`s^2` the gaps' asymptotic variance (their variance plus
    twice their serial covariances). Without attack, and under attacks with no counter, the gaps
    are i.i.d. and this is the renewal formula :math:`n v/m^3` that :func:`fakeack.detect_attack`
    uses; under a periodic attack the serial covariances matter (the gaps are Markov-modulated by
    the attacker's counter). With no flag-ACK ever reaching the sensor, N = 0.

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    n_steps : int
        Window length in steps.
    attack : None or attack, optional
        Any attack.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).

    Examples
    --------
    >>> c = flag_count_moments(0.5, 2, 7000)
    >>> round(c.mean, 9)
    1000.0
    """
    n = as_int("n_steps", n_steps, minimum=1)
    w = walk(lam, z0, attack, mu)
    if w.endless:
        return FlagCount(0.0, 0.0, n)
    _, sig = w.time_covariance(np.array([1]))
    return FlagCount(n / w.mean, n * float(sig[0, 0]), n)
