"""The detection probability of each test per window under an attack (normal approximations of the
count and of X², with exact gap laws), and simulated detection rates that check them."""

from __future__ import annotations

import math
from typing import Any, TypeAlias, cast

import numpy as np

from .._internal.types import FloatArray
from .._internal.validate import as_int, as_probability, as_real
from ..attacks._args import required
from ..attacks.automata import AttackerAutomaton, MimicryAttack, discard_forgeries
from ..attacks.kinds import Attack, AttackLike, FlagInjection, as_attack
from ..model.channels import Channel, ChannelLike, as_channel, channel_argument, is_paper_channel
from ..model.schedules import OnlineDesign, check_online, check_online_channel
from . import _quadform
from .belief import (
    belief_bounds,
    belief_probability,
    count_alarm_probability,
    count_moments,
    harmful_count,
)
from .count import (
    alarm_bounds,
    check_alternative,
    check_lam_range,
    exact_alarm_probability,
    exact_count_law,
    harmful_bound,
    uses_exact_law,
)
from .gap_bins import bin_rates, conditioned_bin_rates
from .interval_test import IntervalTest, cached_interval_test
from .intervals import design_walk
from .process import FlagProcess, flag_process

__all__ = [
    "TESTS",
    "detection_probability",
]


#: The sensor's tests.
TESTS = ("count", "interval")

#: Rows (lam, b, delta, x, weight) of weighted generalised chi-square tails (:class:`AttackForm`).
Rows: TypeAlias = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]
#: The test arguments of the closed-loop kernel: kind, lo, hi, edges, expected, critical,
#: harmful_at_most, fallback.
KernelTest: TypeAlias = tuple[str, int, int, list[int], list[float], float, int | None, int]


def check_test(test: object) -> str:
    """A valid test name."""
    if test not in TESTS:
        raise ValueError(f"test must be one of {TESTS}, got {test!r}")
    return str(test)


# ---------------------------------------------------------------------------------------------
# Detection probabilities.


def _count_probability(
    lam: float,
    design: OnlineDesign,
    n: int,
    alpha: float,
    alternative: str,
    attack: Attack | None,
    harm: int | None,
) -> float:
    bounds = alarm_bounds(lam, design, n, alpha, alternative)
    if uses_exact_law(n, lam, design):
        return exact_alarm_probability(bounds, exact_count_law(n, lam, design, attack), harm)
    return count_alarm_probability(bounds, n, count_moments(lam, design, n, attack), harm)


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


def detection_probability(
    channel: ChannelLike | None = None,
    z0: int | None = None,
    attack: AttackLike | MimicryAttack | AttackerAutomaton = None,
    n_steps: int | None = None,
    alpha: float | None = None,
    test: str = "count",
    alternative: str = "two-sided",
    mu: float = 1.0,
    *,
    beta_bar: float | None = None,
    true_channel: ChannelLike | None = None,
    lam_range: tuple[float, float] | None = None,
    lam: float | None = None,
    authenticated: bool = False,
    support: bool = True,
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

    **Belief and truth.** The test is calibrated on ``channel``, the channel the sensor believes
    in; ``true_channel`` (any channel) gives the alarm probability when the truth differs, e.g.
    a sensor that assumes lam = 0.5 on a channel of 0.48, or one that assumes i.i.d. losses on a
    bursty channel. With ``lam_range=(lo, hi)`` the sensor knows only that lam lies in the range
    and alarms where the count test of every lam of the range alarms (at 9 points, ends
    included), so its false-alarm rate is at most alpha at each of them. Under a Markov belief
    or truth the count law comes from :func:`fakeack.flag_process` (exact below 100 expected
    flag-ACKs, else normal with the window's exact moments); only the count test is computed
    there.

    Parameters
    ----------
    channel : Channel or float
        The channel the test is calibrated on (a float: the paper's channel of that low-power
        arrival probability).
    z0 : int
        Memory length of the event detector.
    attack : None or attack
        Any attack (periodic or mask blocking, random blocking, flag injection, rate matching,
        :class:`fakeack.MimicryAttack`, :class:`fakeack.AttackerAutomaton`).
    n_steps : int
        Window length in steps.
    alpha : float
        False-alarm level of the test, in (0, 1).
    test : {"count", "interval", "support"}
        The sensor's test. ``"support"`` is the support check: an alarm at any gap between
        flag-ACKs reaching the sensor shorter than the shortest gap possible without attack
        (:attr:`fakeack.FlagProcess.min_gap`, z0 + 1 when high-power packets always arrive), the
        gap that straddles the window's start included; its false-alarm rate is 0, and it is
        exact (a recursion over the engine's automaton and the time since the last flag-ACK).
    alternative : {"two-sided", "less", "greater"}
        Alternative of the count test (default two-sided). The interval test's statistic is
        two-sided by construction and takes only ``"two-sided"``.
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    beta_bar : float, optional
        Count only alarms whose estimated budget (:func:`fakeack.estimate_beta` of the window's
        count) exceeds ``beta_bar``: the harmful alarms of a sensor that falls back only from
        harmful attacks (the paper's channel, belief equal to the truth).
    true_channel : Channel or float, optional
        The channel the window is played on (default ``channel``).
    lam_range : (float, float), optional
        The range of lam the sensor allows for (the paper's channel; ``channel`` is then only
        its default truth).
    lam : float, optional
        The former name of ``channel`` (a float); giving both is a ``TypeError``.
    authenticated : bool, optional
        Whether the sensor authenticates flag-ACKs, rejecting forged ones (default False): only
        the attack's blocking part acts (``fakeack.attacks.discard_forgeries``).
    support : bool, optional
        Whether the count or interval test runs with the support check beside it (default True):
        the window alarms if either does. Only a forger can make a gap shorter than the
        attack-free minimum, so this changes nothing without forgery. Against a forger the count
        test's combined probability :math:`1 - P(\text{no short gap}, lo < N < hi)` is exact
        (:meth:`fakeack.FlagProcess.window_alarm_probability`); the interval test's is
        :math:`p_s + (1 - p_s)\,P_h(X^2 > c)`, with the short-gap probability :math:`p_s` exact
        and X²'s law given no short gap from the flag process conditioned on it (the Doob
        transform of the chain without the short-gap deliveries; ``fakeack.detection.gap_bins``),
        normal as the test's own. ``support=False`` gives the test alone.

    Returns
    -------
    float

    Examples
    --------
    >>> p = detection_probability(0.5, 2, None, 1000, 0.01)
    >>> 0.005 < p < 0.015
    True
    """
    if not isinstance(support, bool):
        raise TypeError(f"support must be True or False, got {support!r}")
    args = (channel, z0, attack, n_steps, alpha, test, alternative, mu)
    kw: dict[str, Any] = {
        "beta_bar": beta_bar,
        "true_channel": true_channel,
        "lam_range": lam_range,
        "lam": lam,
        "authenticated": authenticated,
    }
    if not support or test == "support" or not forges(attack, authenticated):
        return _probability(*args, **kw)
    if test == "count":
        return _count_with_support(args, kw)
    return _interval_with_support(args, kw)


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


def _interval_with_support(args: tuple[Any, ...], kw: dict[str, Any]) -> float:
    """The interval test with the support check (``args`` and ``kw`` as :func:`_probability`
    takes them): :func:`interval_support_probability` on the paper's channel."""
    channel, z0, attack, n_steps, alpha, _, _, mu = args
    alone = _probability(*args, **kw)  # validates every argument, and refuses what it must
    ch, _ = channel_argument(channel, kw["lam"], "detection_probability")
    design = OnlineDesign(cast(int, z0), mu)
    truth = ch if kw["true_channel"] is None else as_channel(kw["true_channel"], "true_channel")
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    harm = None
    if kw["beta_bar"] is not None:
        harm = harmful_count(ch, design, n, kw["beta_bar"], kw["true_channel"], None)
    att = attack if isinstance(attack, (MimicryAttack, AttackerAutomaton)) else as_attack(attack)
    test = cached_interval_test(float(ch.low[0]), design, n, as_probability("alpha", alpha))
    gap = flag_process(ch, design).min_gap
    return interval_support_probability(test, flag_process(truth, design, att), gap, harm, alone)


def forges(attack: object, authenticated: bool) -> bool:
    """Whether the attack may forge flag-ACKs that the sensor accepts (only forgery shortens gaps)."""
    if authenticated or attack is None:
        return False
    if isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        return True
    if isinstance(attack, FlagInjection):
        return attack.gamma > 0
    return isinstance(attack, str) and "inject" in attack


def _count_with_support(args: tuple[Any, ...], kw: dict[str, Any]) -> float:
    """The count test with the support check, from the joint law of short gaps and the count
    (``args`` and ``kw`` as :func:`_probability` takes them)."""
    channel, z0, attack, n_steps, alpha, _, alternative, mu = args
    beta_bar, true_channel, lam_range = kw["beta_bar"], kw["true_channel"], kw["lam_range"]
    ch, _ = channel_argument(channel, kw["lam"], "detection_probability")
    design = OnlineDesign(cast(int, z0), mu)
    truth = ch if true_channel is None else as_channel(true_channel, "true_channel")
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    span = None if lam_range is None else check_lam_range(lam_range)
    level = as_probability("alpha", alpha)
    bounds = belief_bounds(ch, design, n, level, check_alternative(alternative), span)
    harm = None if beta_bar is None else harmful_count(ch, design, n, beta_bar, true_channel, span)
    att = attack if isinstance(attack, (MimicryAttack, AttackerAutomaton)) else as_attack(attack)
    gap = flag_process(ch, design).min_gap
    process = flag_process(truth, design, att)
    if process.min_gap == 0 or process.min_gap >= gap:  # no gap is ever short: the test alone
        return _probability(*args, **kw)
    return process.window_alarm_probability(n, gap, bounds, harm)


def _probability(
    channel: ChannelLike | None,
    z0: int | None,
    attack: AttackLike | MimicryAttack | AttackerAutomaton,
    n_steps: int | None,
    alpha: float | None,
    test: str,
    alternative: str,
    mu: float,
    *,
    beta_bar: float | None,
    true_channel: ChannelLike | None,
    lam_range: tuple[float, float] | None,
    lam: float | None,
    authenticated: bool,
) -> float:
    """:func:`detection_probability` of one test, without the support check beside it."""
    ch, name = channel_argument(channel, lam, "detection_probability")
    played: object = attack
    if authenticated and attack is not None and z0 is not None:
        truth = ch if true_channel is None else as_channel(true_channel, "true_channel")
        played = discard_forgeries(attack, channel=truth, design=OnlineDesign(z0, mu))
    general = (
        isinstance(played, (AttackerAutomaton, MimicryAttack))
        or _careful(played)  # the gap laws take min_gap = 1
        or true_channel is not None
    )
    if (
        (general and test != "interval")
        or test == "support"
        or lam_range is not None
        or not is_paper_channel(ch)
    ):
        return belief_probability(
            ch, name, z0, played, n_steps, alpha, test, alternative, mu, beta_bar, true_channel, lam_range
        )
    lam_, design = check_online_channel(ch, name, z0, mu, "detection_probability")
    lam_, design = check_online(lam_, design.z0, design.mu)
    n = as_int("n_steps", required("detection_probability", "n_steps", n_steps), minimum=1, maximum=10**9)
    alpha = as_probability("alpha", required("detection_probability", "alpha", alpha))
    test = check_test(test)
    alternative = check_alternative(alternative)
    lam = lam_
    harm = None if beta_bar is None else harmful_bound(lam, design, n, as_real("beta_bar", beta_bar))
    if general:  # the interval test on the flag process of any attack and true channel
        truth_ch = None if true_channel is None else as_channel(true_channel, "true_channel")
        if truth_ch is not None and beta_bar is not None:
            harmful_count(ch, design, n, beta_bar, true_channel, None)  # refused: belief and truth differ
        general_att: object = played
        if not isinstance(played, (MimicryAttack, AttackerAutomaton)):
            general_att = as_attack(cast("AttackLike", played))
        if alternative != "two-sided":
            raise ValueError(
                f"alternative: the interval test is two-sided by construction, got {alternative!r}"
            )
        test_ = cached_interval_test(lam, design, n, alpha)
        return _interval_probability(test_, general_att, harm, truth_ch)
    built_in = as_attack(cast("AttackLike", played))
    if test == "count":
        return _count_probability(lam, design, n, alpha, alternative, built_in, harm)
    if alternative != "two-sided":
        raise ValueError(f"alternative: the interval test is two-sided by construction, got {alternative!r}")
    return _interval_probability(cached_interval_test(lam, design, n, alpha), built_in, harm)
