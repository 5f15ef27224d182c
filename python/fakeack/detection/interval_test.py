"""The interval test: Pearson's X² of the gaps between received flag-ACKs in a window, binned against
their exact attack-free law, and its one-shot decision (:func:`detect_intervals`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq

from .._internal.types import FloatArray, IntArray
from .._internal.validate import as_int, as_probability
from ..model.schedules import OnlineDesign, check_online
from . import _quadform
from .count import LAM_RANGE_POINTS, check_lam_range
from .flags import as_gaps, attack_free_min_gap, flag_interval_moments
from .intervals import design_walk

__all__ = [
    "IntervalTest",
    "interval_test",
    "IntervalDetection",
    "detect_intervals",
]

#: Smallest expected count per bin of the interval test.
MIN_EXPECTED = 5.0

_TESTS: dict[tuple[float, OnlineDesign, int, float], IntervalTest] = {}


@dataclass(frozen=True)
class IntervalTest:
    """The interval test for windows of ``n_steps`` steps at level ``alpha`` (see
    :func:`interval_test`)."""

    edges: IntArray
    """Lower edges of the bins of gap lengths (steps); the last bin is open above."""
    expected: FloatArray
    """Attack-free expected number of delivered flag-ACKs per bin in a window (n p_i / m)."""
    weights: FloatArray
    """Eigenvalues λ_j of the statistic's attack-free law Σ λ_j χ²_1."""
    critical: float
    """Alarm when the statistic exceeds this value."""
    alpha: float
    n_steps: int
    lam: float
    z0: int
    mu: float

    @property
    def design(self) -> OnlineDesign:
        """The online schedule ``(z0, mu)`` the test is for."""
        return OnlineDesign(self.z0, self.mu)

    def counts(self, gaps: npt.ArrayLike) -> FloatArray:
        """Observed flag-ACKs per bin, from the gap before each one (steps since the previous)."""
        g = as_gaps(gaps)
        idx = np.searchsorted(self.edges, g, side="right") - 1
        return np.bincount(idx, minlength=len(self.edges)).astype(float)

    def statistic(self, gaps: npt.ArrayLike) -> float:
        """Pearson's statistic Σ_i (O_i - E_i)² / E_i of a window's gaps."""
        o = self.counts(gaps)
        return float(np.sum((o - self.expected) ** 2 / self.expected))

    def p_value(self, statistic: float) -> float:
        """P(statistic >= value | no attack), from its weighted chi-square law."""
        w = self.weights[None]
        return float(_quadform.tail(w, np.zeros_like(w), 0.0, float(statistic))[0])


def _bins(pmf: FloatArray, scale: float) -> IntArray:
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


def _null(lam: float, design: OnlineDesign, n: int) -> tuple[IntArray, FloatArray, float, FloatArray]:
    """Bins, attack-free Palm bin probabilities, mean gap and bin-count covariance per step."""
    w0 = design_walk(lam, design)
    x = 64
    while True:
        pmf = w0.pmf(x)[:, 0, 0]
        if 1.0 - pmf.sum() < 1e-13 or x >= 20_000:
            break
        x *= 2
    edges = _bins(pmf, n / w0.mean)
    p0, sigma0 = w0.time_covariance(edges)
    return edges, p0, w0.mean, sigma0


def interval_test(lam: float, z0: int, n_steps: int, alpha: float = 0.01, mu: float = 1.0) -> IntervalTest:
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
    normal with the exact mean and covariance of ``fakeack.detection.intervals``, so
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

    Raises
    ------
    ValueError
        For a bad argument (naming it), or a window in which fewer than 100 flag-ACKs are
        expected without attack (naming ``n_steps``): the normal approximation of the bin counts
        does not hold there.
    """
    lam, design = check_online(lam, z0, mu)
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    alpha = as_probability("alpha", alpha)
    return cached_interval_test(lam, design, n, alpha)


#: Fewest expected flag-ACKs per window for the interval test: below, its normal approximation of
#: the bin counts is off (200-step windows of the paper's example, 29 flags: a detection
#: probability of 0.031 where simulation gives 0.014; z0 = 50: a 1% false-alarm rate where the
#: truth is 4e-13), and the count test's exact law is the honest tool.
MIN_EXPECTED_FLAGS = 100


def cached_interval_test(lam: float, design: OnlineDesign, n: int, alpha: float) -> IntervalTest:
    """:func:`interval_test` of validated arguments, kept for reuse."""
    key = (lam, design, n, alpha)
    if key in _TESTS:
        return _TESTS[key]
    m, _ = flag_interval_moments(lam, design.z0, design.mu)
    if not n / m >= MIN_EXPECTED_FLAGS:
        raise ValueError(
            f"n_steps = {n}: the interval test needs at least {MIN_EXPECTED_FLAGS} expected flag-ACKs per "
            f"window, this one expects {n / m:.3g} (lam={lam}, z0={design.z0}); use a window of at "
            f"least {math.ceil(MIN_EXPECTED_FLAGS * m)} steps, or the count test, whose law is exact "
            "there"
        )
    edges, p0, m0, sigma0 = _null(lam, design, n)
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
    test = IntervalTest(edges, n * p0 / m0, weights, crit, alpha, n, lam, design.z0, design.mu)
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
    observed: FloatArray
    """Flag-ACKs per bin."""
    expected: FloatArray
    """Attack-free expectation per bin."""
    edges: IntArray
    """Lower edges of the bins (gap lengths in steps)."""
    n_steps: int
    alpha: float
    short_gap: bool = False
    """Whether a gap was shorter than any possible without attack (the support check)."""


def detect_intervals(
    gaps: npt.ArrayLike,
    n_steps: int,
    lam: float,
    z0: int,
    mu: float = 1.0,
    alpha: float = 0.01,
    *,
    support: bool = True,
    lam_range: tuple[float, float] | None = None,
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
    support : bool, optional
        Also alarm at any gap shorter than the attack-free minimum (z0 + 1 steps; z0 + 2 when
        mu = 0), which no attack-free window holds: the false-alarm rate stays alpha, and a forger
        that ignores the minimum is caught (default True).
    lam_range : (float, float), optional
        A sensor that knows only that lam lies in [lo, hi]: the window alarms only where the
        test of every lam of the range alarms (at 9 points, ends included), so the false-alarm
        rate is at most alpha at each of them, and ``p_value`` is the largest over the range;
        ``statistic``, ``critical``, ``observed`` and ``expected`` stay those at ``lam``.

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
    alarm = stat > test.critical
    if lam_range is not None:
        span = check_lam_range(lam_range)
        for x in np.linspace(span[0], span[1], LAM_RANGE_POINTS):
            t = interval_test(float(x), z0, n_steps, alpha, mu)
            o_x = t.counts(gaps)
            stat_x = float(np.sum((o_x - t.expected) ** 2 / t.expected))
            alarm = alarm and stat_x > t.critical
            p = max(p, t.p_value(stat_x))
    g = as_gaps(gaps)
    short = (
        bool(support) and bool(g.size) and int(g.min()) < attack_free_min_gap(OnlineDesign(test.z0, test.mu))
    )
    return IntervalDetection(
        alarm or short,
        stat,
        p,
        test.critical,
        o,
        test.expected,
        test.edges,
        test.n_steps,
        test.alpha,
        short,
    )
