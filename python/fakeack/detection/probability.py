"""The detection probability of each test per window under an attack (normal approximations of the
count and of X², with exact gap laws), and simulated detection rates that check them."""

from __future__ import annotations

from typing import Any, TypeAlias, cast

from .._internal.validate import as_int, as_probability, as_real
from ..attacks._args import required
from ..attacks.automata import AttackerAutomaton, MimicryAttack, discard_forgeries
from ..attacks.kinds import Attack, AttackLike, FlagInjection, as_attack
from ..model.channels import ChannelLike, as_channel, channel_argument, is_paper_channel
from ..model.schedules import OnlineDesign, check_online, check_online_channel
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
from .interval_power import _careful, _interval_probability, interval_support_probability
from .interval_test import cached_interval_test
from .likelihood import DEFAULT_ALTERNATIVE, likelihood_ratio_test
from .process import flag_process

__all__ = [
    "TESTS",
    "detection_probability",
]


#: The sensor's tests.
TESTS = ("count", "interval")

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
    lr_alternative: object = None,
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
    test : {"count", "interval", "support", "lr"}
        The sensor's test. ``"lr"`` is the likelihood-ratio test of the window against
        ``lr_alternative`` (:func:`fakeack.likelihood_ratio_test`): exact on any channel and under
        any attack, up to the grid of its statistic's law; the support check is part of it.
        ``"support"`` is the support check: an alarm at any gap between
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
        normal as the test's own. ``support=False`` gives the test alone (not for ``"lr"``,
        whose statistic holds the support check).
    lr_alternative : RandomBlocking, FlagInjection or array_like, optional
        The attack the ``"lr"`` test is tuned to (default ``RandomBlocking(0.2)``); only with
        ``test="lr"``.

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
    if test == "lr":
        return _lr_probability(
            channel, z0, attack, n_steps, alpha, alternative, mu, lr_alternative,
            beta_bar=beta_bar, true_channel=true_channel, lam_range=lam_range, lam=lam,
            authenticated=authenticated, support=support,
        )  # fmt: skip
    if lr_alternative is not None:
        raise ValueError(f"lr_alternative: only with test='lr', got test={test!r}")
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


def _lr_probability(
    channel: ChannelLike | None,
    z0: int | None,
    attack: object,
    n_steps: int | None,
    alpha: float | None,
    alternative: str,
    mu: float,
    lr_alternative: object,
    **kw: Any,
) -> float:
    """:func:`detection_probability` of the likelihood-ratio test."""
    ch, _ = channel_argument(channel, kw["lam"], "detection_probability")
    for name in ("beta_bar", "lam_range"):
        if kw[name] is not None:
            raise ValueError(f"{name}: not computed for the likelihood-ratio test")
    if alternative != "two-sided":
        raise ValueError(
            "alternative: the likelihood-ratio test alarms on large values of its statistic by "
            f"construction, got {alternative!r}; lr_alternative names the attack it is tuned to"
        )
    if not kw["support"]:
        raise ValueError("support: the likelihood-ratio test's statistic holds the support check")
    n = as_int("n_steps", required("detection_probability", "n_steps", n_steps), minimum=1)
    level = as_probability("alpha", required("detection_probability", "alpha", alpha))
    design = OnlineDesign(as_int("z0", required("detection_probability", "z0", z0), minimum=1), mu)
    alt = DEFAULT_ALTERNATIVE if lr_alternative is None else lr_alternative
    test = likelihood_ratio_test(ch, design.z0, n, level, design.mu, alternative=alt)
    truth = ch if kw["true_channel"] is None else as_channel(kw["true_channel"], "true_channel")
    played = attack
    if kw["authenticated"] and attack is not None:
        played = discard_forgeries(attack, channel=truth, design=design)
    return test.detection_probability(played, None if kw["true_channel"] is None else truth)


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
