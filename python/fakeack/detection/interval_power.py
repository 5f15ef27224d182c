"""The interval statistic X² under an attack: the bin counts' normal law (from the gap walk or the
flag process), the generalised chi-square tails of X² alone and jointly with the count (the
harmful rule), and its combination with the support check."""

from __future__ import annotations

import math
from typing import TypeAlias

import numpy as np

from .._internal.types import FloatArray
from ..attacks.kinds import Attack, AttackLike, FlagInjection
from ..model.channels import Channel
from . import _quadform
from .gap_bins import bin_rates, conditioned_bin_rates
from .interval_test import IntervalTest
from .intervals import design_walk
from .process import FlagProcess, flag_process

__all__ = [
    "AttackForm",
    "interval_batch",
    "interval_support_probability",
    "sum_tails",
]

#: Rows (lam, b, delta, x, weight) of weighted generalised chi-square tails (:class:`AttackForm`).
Rows: TypeAlias = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]


def _attack_form(
    test: IntervalTest,
    attack: object,
    truth: Channel | None = None,
    moments: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray] | None:
    """(mean, covariance) of y = D^-1/2 (O - E) under the attack (on the true channel, default the
    test's); None when no flag gets through. The gap walk's Markov renewal moments for the
    built-in attacks on the paper's channel, the flag process's (:mod:`.gap_bins`) otherwise."""
    if moments is not None:  # the bin moments per step, given (e.g. of a conditioned chain)
        rates, sigma_a = moments
    elif truth is None and (attack is None or (isinstance(attack, Attack) and not _careful(attack))):
        w = design_walk(test.lam, test.design, attack)
        if w.endless:
            return None
        pa, sigma_a = w.time_covariance(test.edges)
        rates = pa / w.mean
    else:
        process = flag_process(test.lam if truth is None else truth, test.design, attack)
        if process.rate <= 0.0:
            return None
        rates, sigma_a = bin_rates(process, test.edges)
    n = test.n_steps
    m0 = n / test.expected.sum()
    p0 = test.expected / test.expected.sum()
    scale = np.sqrt(p0 / m0)
    mean = math.sqrt(n) * (rates - p0 / m0) / scale
    cov = sigma_a / np.outer(scale, scale)
    return mean, cov


_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(24)


class AttackForm:
    """The interval statistic under one attack, ready for tails at any critical value.

    X² = y'y with y ~ N(mean, cov) (:func:`_attack_form`). For the harmful rule the count enters
    as s = ŵ'y (ŵ = sqrt(p0), N - n/m0 = sqrt(n/m0) s): X² = s² + |y_⊥|², and given s the
    projection y_⊥ is normal with a mean linear in s and a fixed covariance, so
    P(X² > c, s <= s_hi) is an integral over s of generalised chi-square tails (Gauss-Legendre,
    split where s² crosses c).
    """

    def __init__(
        self,
        test: IntervalTest,
        attack: object,
        truth: Channel | None = None,
        moments: tuple[FloatArray, FloatArray] | None = None,
    ) -> None:
        form = _attack_form(test, attack, truth, moments)
        self.none = form is None  # no flag: O = 0, X² = Σ E deterministic, N = 0
        self.total = float(test.expected.sum())
        if form is None:
            return
        mean, cov = form
        self.lam, self.b, self.delta = _quadform.canonical(cov, mean)
        w_hat = np.sqrt(test.expected / self.total)
        var_s = float(w_hat @ cov @ w_hat)
        self.mu_s = float(w_hat @ mean)
        self.sd_s = math.sqrt(max(var_s, 0.0))
        self.count_fixed = var_s <= 1e-14 * max(1.0, float(np.trace(cov)))
        if self.count_fixed:
            return
        P = np.eye(len(mean)) - np.outer(w_hat, w_hat)
        cross = P @ cov @ w_hat
        cond = P @ cov @ P - np.outer(cross, cross) / var_s
        m_0 = P @ mean - cross * self.mu_s / var_s
        m_1 = cross / var_s
        vals, vecs = np.linalg.eigh(0.5 * (cond + cond.T))
        keep = vals > 1e-12 * max(vals.max(initial=0.0), 1e-300)
        self.lam_c = vals[keep]
        root = np.sqrt(self.lam_c)
        p_0, p_1 = vecs[:, keep].T @ m_0, vecs[:, keep].T @ m_1
        self.b_0, self.b_1 = p_0 / root, p_1 / root
        # |m(s)|² - |U'm(s)|², the part of the conditional mean outside the range: a2 s² + a1 s + a0.
        self.a = (m_0 @ m_0 - p_0 @ p_0, 2 * (m_0 @ m_1 - p_0 @ p_1), m_1 @ m_1 - p_1 @ p_1)

    def rows_any(self, c: float) -> Rows:
        """Rows (lam, b, delta, x, weight) whose weighted tails sum to P(X² > c)."""
        return self.lam[None], self.b[None], np.array([self.delta]), np.array([c]), np.ones(1)

    def rows_joint(self, c: float, s_hi: float) -> Rows | float:
        """Rows for P(X² > c, s <= s_hi), or the probability itself when no integral is needed."""
        if self.count_fixed:
            if self.mu_s > s_hi:
                return 0.0
            return self.rows_any(c)
        lo = self.mu_s - 9.0 * self.sd_s
        if s_hi <= lo:
            return 0.0
        hi = min(s_hi, self.mu_s + 9.0 * self.sd_s)
        cuts = sorted({lo, hi, *[r for r in (-math.sqrt(c), math.sqrt(c)) if lo < r < hi]})
        pieces = list(zip(cuts[:-1], cuts[1:], strict=True))
        s = np.concatenate([0.5 * (b - a) * _NODES + 0.5 * (b + a) for a, b in pieces])
        wq = np.concatenate([0.5 * (b - a) * _WEIGHTS for a, b in pieces])
        dens = np.exp(-0.5 * ((s - self.mu_s) / self.sd_s) ** 2) / (self.sd_s * math.sqrt(2 * math.pi))
        b = self.b_0[None] + s[:, None] * self.b_1[None]
        delta = np.maximum(self.a[0] + self.a[1] * s + self.a[2] * s**2, 0.0)
        lam = np.broadcast_to(self.lam_c, b.shape)
        return lam, b, delta, c - s**2, wq * dens


def sum_tails(batches: list[Rows | float]) -> FloatArray:
    """Σ weight · tail per batch (a batch is a probability, or rows from :class:`AttackForm`), in one
    vectorised call."""
    out = np.zeros(len(batches))
    rows = [(i, r) for i, r in enumerate(batches) if not isinstance(r, float)]
    for i, r in enumerate(batches):
        if isinstance(r, float):
            out[i] = r
    if not rows:
        return out
    k = max(r[0].shape[1] for _, r in rows)
    sizes = [len(r[2]) for _, r in rows]
    lam, b = np.zeros((sum(sizes), k)), np.zeros((sum(sizes), k))
    at = 0
    for (_, r), size in zip(rows, sizes, strict=True):
        lam[at : at + size, : r[0].shape[1]] = r[0]
        b[at : at + size, : r[1].shape[1]] = r[1]
        at += size
    delta = np.concatenate([r[2] for _, r in rows])
    x = np.concatenate([r[3] for _, r in rows])
    w = np.concatenate([r[4] for _, r in rows])
    seg = np.concatenate([np.full(len(r[2]), j) for j, (_, r) in enumerate(rows)])
    sums = np.bincount(seg, weights=w * _quadform.tail(lam, b, delta, x), minlength=len(rows))
    for j, (i, _) in enumerate(rows):
        out[i] = sums[j]
    return np.clip(out, 0.0, 1.0)


def interval_batch(test: IntervalTest, form: AttackForm, harm: int | None) -> Rows | float:
    """One attack's rows for the interval test's (harmful) alarm probability."""
    if form.none:
        return float(form.total > test.critical and (harm is None or harm >= 0))
    if harm is None:
        return form.rows_any(test.critical)
    if harm < 0:
        return 0.0
    n = test.n_steps
    m0 = n / form.total
    s_hi = (harm + 0.5 - n / m0) / math.sqrt(n / m0)
    return form.rows_joint(test.critical, s_hi)


def _interval_probability(
    test: IntervalTest, attack: object, harm: int | None, truth: Channel | None = None
) -> float:
    return float(sum_tails([interval_batch(test, AttackForm(test, attack, truth), harm)])[0])


def _careful(attack: object) -> bool:
    """A forger with a minimum gap, which the gap walk does not take (the flag process does)."""
    return isinstance(attack, FlagInjection) and attack.min_gap > 1


def _joint_tail(test: IntervalTest, attack: AttackLike, s_hi: float) -> float:
    """P(X² > c and ŵ'y <= s_hi) under the attack (for the tests)."""
    form = AttackForm(test, attack)
    return float(sum_tails([form.rows_joint(test.critical, s_hi)])[0])


def interval_support_probability(
    test: IntervalTest, process: FlagProcess, min_gap: int, harm: int | None, alone: float
) -> float:
    r"""The interval test with the support check beside it, under the flag process ``process``:
    :math:`P(\text{short gap}) + P(\text{no short gap})\,P_h(X^2 > c)`, with ``harm`` only the
    alarms with :math:`N \le` harm.

    P(short gap) (and its part with N <= harm) is exact; given no short gap the flag process is
    the Doob transform of the chain with the short-gap deliveries removed
    (:func:`.gap_bins.conditioned_bin_rates`), whose bin moments give X²'s normal approximation,
    as the test's own law is computed. ``alone`` (the test without the check) is returned where
    no gap is ever short.
    """
    n = test.n_steps
    p_short = process.short_gap_probability(n, min_gap)
    if p_short == 0.0:
        return alone
    p_s = p_short if harm is None else process.window_alarm_probability(n, min_gap, (-1, n + 1), harm)
    if p_short >= 1.0 - 1e-15:
        return p_s
    rates, sigma, _ = conditioned_bin_rates(process, test.edges, min_gap)
    form = AttackForm(test, None, moments=(rates, sigma))
    p_x = float(sum_tails([interval_batch(test, form, harm)])[0])
    return float(min(max(p_s + (1.0 - p_short) * p_x, 0.0), 1.0))
