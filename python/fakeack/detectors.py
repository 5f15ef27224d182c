"""The sensor's two tests for a fake-ACK attacker and their detection probability per window.

* The **count test** (:func:`fakeack.detect_attack`) compares how many flag-ACKs reached the sensor
  in a window of n steps with the attack-free count (renewal central limit theorem).
* The **interval test** (:func:`detect_intervals`) also looks at *when* they came: Pearson's
  goodness-of-fit statistic over bins of the exact attack-free gap law.

:func:`detection_probability` gives the probability that either test raises an alarm in one window
under any attack (``None``: the false-alarm rate), from the exact laws of
``fakeack.intervals`` and the stated normal approximations.

(Over 450 lines: both tests and their power share the gap-law bins and moments; the
detection_probability part is the next to move to a module of its own.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq
from scipy.special import ndtr

from . import _quadform
from ._validate import as_int, as_probability, as_real
from .attacks import as_attack
from .detection import _count_law, _regime_rates, flag_interval_moments
from .intervals import walk
from .schedules import _check_online

__all__ = [
    "ALTERNATIVES",
    "TESTS",
    "IntervalDetection",
    "IntervalTest",
    "count_alarm_bounds",
    "detect_intervals",
    "detection_probability",
    "harmful_count_bound",
    "interval_test",
]

#: The sensor's tests.
TESTS = ("count", "interval")
#: Alternatives of the count test (as in scipy.stats): fewer flags, more flags, either.
ALTERNATIVES = ("less", "greater", "two-sided")
#: Smallest expected count per bin of the interval test.
MIN_EXPECTED = 5.0


def check_alternative(alternative: Any) -> str:
    """A valid ``alternative`` of the count test."""
    if alternative not in ALTERNATIVES:
        raise ValueError(f"alternative must be one of {ALTERNATIVES}, got {alternative!r}")
    return alternative


def check_test(test: Any) -> str:
    """A valid test name."""
    if test not in TESTS:
        raise ValueError(f"test must be one of {TESTS}, got {test!r}")
    return test


def count_p_value(z: float, alternative: str) -> float:
    """p-value of the count test's z score (normal approximation)."""
    if alternative == "less":
        return float(ndtr(z))
    if alternative == "greater":
        return float(ndtr(-z))
    return float(min(1.0, 2.0 * min(ndtr(z), ndtr(-z))))


def count_z(delivered: int, n: int, m: float, v: float) -> float:
    """(delivered - n/m) / sqrt(n v / m³): the count test's z score (as :func:`detect_attack`)."""
    expected = n / m
    sd = math.sqrt(n / m) * math.sqrt(v) / m  # m**3 alone may overflow
    if sd > 0:
        return (delivered - expected) / sd
    return 0.0 if delivered == expected else math.copysign(math.inf, delivered - expected)


def count_alarm_bounds(
    lam: Any, z0: Any, n_steps: Any, alpha: Any, alternative: str = "less", mu: Any = 1.0
) -> tuple[int, int]:
    """The count test's alarm region as integers: alarm iff N <= lo or N >= hi.

    ``lo = -1`` when no count is too low, ``hi = n_steps + 1`` when none is too high. The region
    is the one :func:`fakeack.detect_attack` uses, found by evaluating its p-value at the
    boundary counts (so the two agree exactly).
    """
    lam, z0, mu = _check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    alpha = as_probability("alpha", alpha)
    alternative = check_alternative(alternative)
    _count_law(n, lam, z0, mu)  # ValueError naming z0 when flags are too rare to test
    m, v = flag_interval_moments(lam, z0, mu)

    def alarm(d: int, side: str) -> bool:
        z = count_z(d, n, m, v)
        if side == "low" and z >= 0:
            return False
        if side == "high" and z <= 0:
            return False
        return count_p_value(z, alternative) < alpha

    # p-values are monotone on each side of the mean; bisection on integers.
    mean = n / m
    lo = -1
    if alternative != "greater":
        a, b = -1, min(n, math.floor(mean))  # alarm(a) holds by convention, look for the last
        if alarm(0, "low"):
            a = 0
            while b - a > 1:
                c = (a + b) // 2
                a, b = (c, b) if alarm(c, "low") else (a, c)
            lo = b if alarm(b, "low") else a
    hi = n + 1
    if alternative != "less":
        a, b = max(0, math.ceil(mean)), n
        if alarm(n, "high"):
            while b - a > 1:
                c = (a + b) // 2
                a, b = (a, c) if alarm(c, "high") else (c, b)
            hi = a if alarm(a, "high") else b
    return lo, hi


def harmful_count_bound(lam: Any, z0: Any, n_steps: Any, beta_bar: Any, mu: Any = 1.0) -> int:
    """Largest count N whose estimated budget (:func:`fakeack.estimate_beta`) exceeds ``beta_bar``.

    The estimate decreases with N, so "estimated budget above β̄" is N <= this bound
    (-1 when no count qualifies).
    """
    lam, z0, mu = _check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1)
    bb = as_real("beta_bar", beta_bar)
    f_on, f_blk = _regime_rates(lam, z0, mu)

    def beta_hat(d: int) -> float:  # fakeack.estimate_beta's formula
        rho = d / n
        if rho >= f_on:
            return 0.0
        b = (1.0 - rho / f_on) / (1.0 + rho / f_blk - rho / f_on)
        return min(max(b, 0.0), 1.0)

    if not beta_hat(0) > bb:
        return -1
    a, b = 0, n
    if beta_hat(n) > bb:
        return n
    while b - a > 1:
        c = (a + b) // 2
        a, b = (c, b) if beta_hat(c) > bb else (a, c)
    return a


@dataclass(frozen=True)
class IntervalTest:
    """The interval test for windows of ``n_steps`` steps at level ``alpha`` (see
    :func:`interval_test`)."""

    edges: np.ndarray
    """Lower edges of the bins of gap lengths (steps); the last bin is open above."""
    expected: np.ndarray
    """Attack-free expected number of delivered flag-ACKs per bin in a window (n p_i / m)."""
    weights: np.ndarray
    """Eigenvalues λ_j of the statistic's attack-free law Σ λ_j χ²_1."""
    critical: float
    """Alarm when the statistic exceeds this value."""
    alpha: float
    n_steps: int
    lam: float
    z0: int
    mu: float

    def counts(self, gaps: Any) -> np.ndarray:
        """Observed flag-ACKs per bin, from the gap before each one (steps since the previous)."""
        g = np.asarray(gaps)
        if g.ndim != 1:
            raise ValueError(f"gaps must be a 1-D sequence of positive integers, got shape {g.shape}")
        if g.size and (g.dtype.kind not in "iu" or g.min() < 1):
            if g.dtype.kind == "f" and np.all(np.isfinite(g)) and np.all(g == np.round(g)) and g.min() >= 1:
                g = g.astype(np.int64)
            else:
                raise ValueError("gaps must be positive integers (steps since the previous flag-ACK)")
        idx = np.searchsorted(self.edges, g, side="right") - 1
        return np.bincount(idx, minlength=len(self.edges)).astype(float)

    def statistic(self, gaps: Any) -> float:
        """Pearson's statistic Σ_i (O_i - E_i)² / E_i of a window's gaps."""
        o = self.counts(gaps)
        return float(np.sum((o - self.expected) ** 2 / self.expected))

    def p_value(self, statistic: float) -> float:
        """P(statistic >= value | no attack), from its weighted chi-square law."""
        w = self.weights[None]
        return float(_quadform.tail(w, np.zeros_like(w), 0.0, float(statistic))[0])


def _bins(pmf: np.ndarray, scale: float) -> np.ndarray:
    """Lower edges of bins of consecutive gap lengths with expected counts >= MIN_EXPECTED."""
    edges = [1]
    acc = 0.0
    remaining = scale
    for x, p in enumerate(pmf, start=1):
        acc += scale * p
        remaining -= scale * p
        if remaining < MIN_EXPECTED:
            break
        if acc >= MIN_EXPECTED:
            edges.append(x + 1)
            acc = 0.0
    return np.array(edges, dtype=np.int64)


def _null(lam: float, z0: int, mu: float, n: int) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Bins, attack-free Palm bin probabilities, mean gap and bin-count covariance per step."""
    w0 = walk(lam, z0, None, mu)
    x = 64
    while True:
        pmf = w0.pmf(x)[:, 0, 0]
        if 1.0 - pmf.sum() < 1e-13 or x >= 20_000:
            break
        x *= 2
    edges = _bins(pmf, n / w0.mean)
    p0, sigma0 = w0.time_covariance(edges)
    return edges, p0, w0.mean, sigma0


def interval_test(lam: Any, z0: Any, n_steps: Any, alpha: Any = 0.01, mu: Any = 1.0) -> IntervalTest:
    r"""The interval test for windows of ``n_steps`` steps: bins, expected counts, critical value.

    **The statistic.** The gaps between flag-ACKs reaching the sensor are binned by length, bins
    of consecutive lengths merged until each holds at least 5 expected flags per window under no
    attack (the last bin is open above). With :math:`O_i` the flags in the window whose gap
    (steps since the previous flag-ACK) falls in bin i and :math:`E_i = n p_i / m` the attack-free
    expectation (p the exact gap law, m its mean; :func:`fakeack.flag_interval_law`), the
    statistic is Pearson's :math:`X^2 = \sum_i (O_i - E_i)^2 / E_i`.

    **Why this test.** A likelihood-ratio test needs the attack's law, which the sensor does not
    know; a goodness-of-fit test against the exact attack-free law catches any change of shape:
    blocking lengthens gaps, forging shortens them, and rate matching
    (:func:`fakeack.rate_matching_attack`) mixes both while keeping the mean, so the count test
    cannot see it.
    Expected counts from the window length (not from the observed number of gaps) make the test
    see the count too: an attacker who removes every flag leaves :math:`X^2 = \sum E_i`, an alarm.

    **Its law.** The bin counts over a fixed time are not multinomial (the number of gaps is
    random, and the gaps are serially dependent under a periodic attack), so :math:`X^2` is not
    :math:`\chi^2`. By the Markov renewal central limit theorem the counts are asymptotically
    normal with the exact mean and covariance of ``fakeack.intervals``, so
    :math:`X^2 \approx \sum_j \lambda_j (Z_j + b_j)^2` (a generalised chi-square) with
    :math:`\lambda_j` the eigenvalues of :math:`D^{-1/2} \Sigma D^{-1/2}` (D = diag(E)) and b the
    attack's mean shift in that basis; without attack b = 0 and the weights are near 1. Tails use
    the saddlepoint approximation of Lugannani and Rice (Kuonen 1999).

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    n_steps : int
        Window length in steps.
    alpha : float, optional
        False-alarm probability per window, in (0, 1) (default 0.01).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).

    Returns
    -------
    IntervalTest
    """
    lam, z0, mu = _check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    alpha = as_probability("alpha", alpha)
    return _interval_test(lam, z0, mu, n, alpha)


_TESTS: dict[tuple, IntervalTest] = {}


def _interval_test(lam: float, z0: int, mu: float, n: int, alpha: float) -> IntervalTest:
    key = (lam, z0, mu, n, alpha)
    if key in _TESTS:
        return _TESTS[key]
    edges, p0, m0, sigma0 = _null(lam, z0, mu, n)
    scale = np.sqrt(p0 / m0)
    M0 = sigma0 / np.outer(scale, scale)
    weights = np.clip(np.linalg.eigvalsh(0.5 * (M0 + M0.T)), 0.0, None)
    w = weights[None]

    def excess(c: float) -> float:
        return float(_quadform.tail(w, np.zeros_like(w), 0.0, c)[0]) - alpha

    hi = max(1.0, weights.sum())
    while excess(hi) > 0:
        hi *= 2.0
    crit = brentq(excess, 0.0, hi, xtol=1e-10, rtol=1e-12)
    test = IntervalTest(edges, n * p0 / m0, weights, crit, alpha, n, lam, z0, mu)
    if len(_TESTS) > 256:
        _TESTS.clear()
    _TESTS[key] = test
    return test


@dataclass(frozen=True)
class IntervalDetection:
    """Outcome of :func:`detect_intervals`."""

    attack_detected: bool
    statistic: float
    """Pearson's X² of the window."""
    p_value: float
    """P[X² at least this large | no attacker] (weighted chi-square law, saddlepoint tail)."""
    critical: float
    observed: np.ndarray
    """Flag-ACKs per bin."""
    expected: np.ndarray
    """Attack-free expectation per bin."""
    edges: np.ndarray
    """Lower edges of the bins (gap lengths in steps)."""
    n_steps: int
    alpha: float


def detect_intervals(
    gaps: Any, n_steps: Any, lam: Any, z0: Any, mu: Any = 1.0, alpha: Any = 0.01
) -> IntervalDetection:
    r"""Test for a fake-ACK attacker from *when* flag-ACKs arrived in a window of ``n_steps`` steps.

    Pearson's goodness-of-fit statistic of the gaps against the exact attack-free gap law, with the
    window's expected counts; :func:`interval_test` explains the choice and its null law.

    Parameters
    ----------
    gaps : sequence of int
        For each flag-ACK received in the window, the steps since the flag-ACK before it (the first
        one's gap reaches back before the window). From the steps k_0 < k_1 < ... < k_N at which
        flags came, k_0 the last one before the window: ``numpy.diff([k_0, k_1, ..., k_N])``.
    n_steps : int
        Window length in steps.
    lam, z0, mu
        The online schedule's parameters.
    alpha : float
        False-alarm probability per window, in (0, 1).

    Examples
    --------
    >>> import numpy as np, fakeack
    >>> rng = np.random.default_rng(0)
    >>> law = fakeack.flag_interval_law(0.5, 2)
    >>> gaps = rng.choice(np.arange(1, len(law.pmf) + 1), size=140, p=law.pmf / law.pmf.sum())
    >>> detect_intervals(gaps, 1000, 0.5, 2).attack_detected
    False
    """
    test = interval_test(lam, z0, n_steps, alpha, mu)
    o = test.counts(gaps)
    if o.sum() > test.n_steps:
        raise ValueError(f"gaps: more flag-ACKs ({int(o.sum())}) than steps ({test.n_steps})")
    stat = float(np.sum((o - test.expected) ** 2 / test.expected))
    p = test.p_value(stat)
    return IntervalDetection(
        stat > test.critical, stat, p, test.critical, o, test.expected, test.edges, test.n_steps, test.alpha
    )


# ---------------------------------------------------------------------------------------------
# Detection probabilities.


def _count_moments(lam: float, z0: int, mu: float, n: int, attack: Any) -> tuple[float, float]:
    """(mean, sd) of a stationary window's count under the attack (:func:`flag_count_moments`)."""
    w = walk(lam, z0, attack, mu)
    if w.endless:
        return 0.0, 0.0
    _, sig = w.time_covariance(np.array([1]))
    return n / w.mean, math.sqrt(max(n * float(sig[0, 0]), 0.0))


def _count_alarm(bounds: tuple[int, int], n: int, moments: tuple[float, float], harm: int | None) -> float:
    """P(count alarm) for a normal count with continuity correction; with ``harm``, only alarms
    with N <= harm (an estimated budget above β̄)."""
    lo, hi = bounds
    mean, sd = moments
    if harm is not None:
        hi_region = (hi, harm) if hi <= harm else None
        lo = min(lo, harm)
    else:
        hi_region = (hi, n)

    def cdf(k: float) -> float:  # P(N <= k)
        if sd == 0.0:
            return float(mean <= k + 0.5)
        return float(ndtr((k + 0.5 - mean) / sd))

    p = cdf(lo) if lo >= 0 else 0.0
    if hi_region is not None and hi_region[0] <= n:
        p += cdf(hi_region[1]) - cdf(hi_region[0] - 1)
    return min(max(p, 0.0), 1.0)


def _count_probability(lam, z0, mu, n, alpha, alternative, attack, harm):
    bounds = count_alarm_bounds(lam, z0, n, alpha, alternative, mu)
    return _count_alarm(bounds, n, _count_moments(lam, z0, mu, n, attack), harm)


def _attack_form(test: IntervalTest, attack: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """(mean, covariance) of y = D^-1/2 (O - E) under the attack; None when no flag gets through."""
    w = walk(test.lam, test.z0, attack, test.mu)
    if w.endless:
        return None
    n = test.n_steps
    m0 = n / test.expected.sum()
    p0 = test.expected / test.expected.sum()
    pa, sigma_a = w.time_covariance(test.edges)
    scale = np.sqrt(p0 / m0)
    mean = math.sqrt(n) * (pa / w.mean - p0 / m0) / scale
    cov = sigma_a / np.outer(scale, scale)
    return mean, cov


_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(24)


class _Form:
    """The interval statistic under one attack, ready for tails at any critical value.

    X² = y'y with y ~ N(mean, cov) (:func:`_attack_form`). For the harmful rule the count enters
    as s = ŵ'y (ŵ = sqrt(p0), N - n/m0 = sqrt(n/m0) s): X² = s² + |y_⊥|², and given s the
    projection y_⊥ is normal with a mean linear in s and a fixed covariance, so
    P(X² > c, s <= s_hi) is an integral over s of generalised chi-square tails (Gauss-Legendre,
    split where s² crosses c).
    """

    def __init__(self, test: IntervalTest, attack: Any):
        form = _attack_form(test, attack)
        self.none = form is None  # no flag: O = 0, X² = Σ E deterministic, N = 0
        self.total = float(test.expected.sum())
        if self.none:
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

    def rows_any(self, c: float) -> tuple:
        """Rows (lam, b, delta, x, weight) whose weighted tails sum to P(X² > c)."""
        return self.lam[None], self.b[None], np.array([self.delta]), np.array([c]), np.ones(1)

    def rows_joint(self, c: float, s_hi: float) -> tuple | float:
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


def _sum_tails(batches: list) -> np.ndarray:
    """Σ weight · tail per batch (a batch is a probability, or rows from :class:`_Form`), in one
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
        lam[at:at + size, : r[0].shape[1]] = r[0]
        b[at:at + size, : r[1].shape[1]] = r[1]
        at += size
    delta = np.concatenate([r[2] for _, r in rows])
    x = np.concatenate([r[3] for _, r in rows])
    w = np.concatenate([r[4] for _, r in rows])
    seg = np.concatenate([np.full(len(r[2]), j) for j, (_, r) in enumerate(rows)])
    sums = np.bincount(seg, weights=w * _quadform.tail(lam, b, delta, x), minlength=len(rows))
    for j, (i, _) in enumerate(rows):
        out[i] = sums[j]
    return np.clip(out, 0.0, 1.0)


def _interval_batch(test: IntervalTest, form: _Form, harm: int | None) -> tuple | float:
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


def _interval_probability(test: IntervalTest, attack: Any, harm: int | None) -> float:
    return float(_sum_tails([_interval_batch(test, _Form(test, attack), harm)])[0])


def _joint_tail(test: IntervalTest, attack: Any, s_hi: float) -> float:
    """P(X² > c and ŵ'y <= s_hi) under the attack (for the tests)."""
    form = _Form(test, attack)
    return float(_sum_tails([form.rows_joint(test.critical, s_hi)])[0])


def detection_probability(
    lam: Any,
    z0: Any,
    attack: Any,
    n_steps: Any,
    alpha: Any,
    test: str = "count",
    alternative: str = "two-sided",
    mu: Any = 1.0,
    *,
    beta_bar: Any = None,
) -> float:
    r"""Probability that the sensor's test raises an alarm in one window of ``n_steps`` steps.

    The window lies in the stationary regime of the attack (the attacker's counter and the
    detector's memory at its start follow their long-run law), as in a repeated game; ``attack``
    ``None`` gives the false-alarm rate.

    * ``test="count"``: the count N of flag-ACKs reaching the sensor is taken as normal with the
      exact stationary mean n/m and the Markov renewal variance :math:`n s^2/m^3`
      (:func:`fakeack.flag_count_moments`; serial covariances included under a periodic attack),
      with a continuity correction; the alarm region is the one :func:`fakeack.detect_attack`
      uses for ``alternative``.
    * ``test="interval"``: the bin counts of :func:`interval_test` are taken as normal with their
      exact mean and Markov renewal covariance; Pearson's statistic is then a generalised
      chi-square whose tail is computed by the saddlepoint method.

    Both are large-sample approximations (many flags per window); the tests check them against
    the closed-loop Monte Carlo (:func:`fakeack.detection_rates`).

    Parameters
    ----------
    lam : float
        Arrival probability :math:`\lambda \in (0, 1)` at low power.
    z0 : int
        Memory length of the event detector.
    attack : None or attack
        Any attack (periodic or mask blocking, random blocking, flag injection, rate matching).
    n_steps : int
        Window length in steps.
    alpha : float
        False-alarm level of the test, in (0, 1).
    test : {"count", "interval"}
        The sensor's test.
    alternative : {"two-sided", "less", "greater"}
        Alternative of the count test (default two-sided). The interval test's statistic is
        two-sided by construction and takes only ``"two-sided"``.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    beta_bar : float, optional
        Count only alarms whose estimated budget (:func:`fakeack.estimate_beta` of the window's
        count) exceeds ``beta_bar``: the harmful alarms of a sensor that falls back only from
        harmful attacks.

    Returns
    -------
    float

    Examples
    --------
    >>> p = detection_probability(0.5, 2, None, 1000, 0.01)
    >>> 0.005 < p < 0.015
    True
    """
    lam, z0, mu = _check_online(lam, z0, mu)
    att = as_attack(attack)
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    alpha = as_probability("alpha", alpha)
    test = check_test(test)
    alternative = check_alternative(alternative)
    harm = None if beta_bar is None else harmful_count_bound(lam, z0, n, beta_bar, mu)
    if test == "count":
        return _count_probability(lam, z0, mu, n, alpha, alternative, att, harm)
    if alternative != "two-sided":
        raise ValueError(
            f"alternative: the interval test is two-sided by construction, got {alternative!r}"
        )
    return _interval_probability(_interval_test(lam, z0, mu, n, alpha), att, harm)


def simulate_windows(
    lam: float, z0: int, mu: float, attack: Any, n: int, runs: int, seed: int, test: str, alpha: float,
    alternative: str, burn_in: int, progress: bool | None = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Alarms (0/1) and delivered flag-ACKs of ``runs`` simulated windows of ``n`` steps, one per run,
    after ``burn_in`` untested steps, by the closed-loop kernel (the sensor never falls back)."""
    from . import _fakeack
    from .attacks import core_attack
    from .detection import _any_system
    from .montecarlo import _Progress

    if test == "count":
        lo, hi = count_alarm_bounds(lam, z0, n, alpha, alternative, mu)
        args = ("count", lo, hi, [], [], 0.0, None, 0)
    else:
        t = _interval_test(lam, z0, mu, n, alpha)
        args = ("interval", -1, 0, [int(e) for e in t.edges], [float(e) for e in t.expected],
                float(t.critical), None, 0)
    bar = _Progress(runs, progress)
    burn_in = -(-burn_in // n) * n  # whole windows, so that the measured window is one window
    try:
        out = _fakeack.simulate_game(
            _any_system()._core, lam, 1, 2, z0, mu, core_attack(attack), *args, n, n, burn_in, runs, seed, bar
        )
    finally:
        bar.close()
    return out["alarms"], out["delivered"]
