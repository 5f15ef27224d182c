"""What the sensor believes about the channel against what it is: the count test built for one
channel (or for every lam of a range) and its alarm probability under another.

The sensor's count test is calibrated on the channel it believes in; its alarm probability is the
law of the window's count under the true channel and the attack. :func:`count_probability` gives
it for any pair of channels (the exact count law below 100 expected flag-ACKs, else the normal law
with the window's exact moments; on the paper's channel the renewal moments of
:func:`fakeack.flag_count_moments`), and for a sensor that knows only that lam lies in a range
[lo, hi] and alarms only where the test of every lam of the range alarms, which keeps its
false-alarm rate at most alpha at each of them.
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np
from scipy.special import ndtr

from .._internal.validate import as_int, as_probability, as_real
from ..attacks.automata import AttackerAutomaton, MimicryAttack
from ..attacks.kinds import Attack, FlagInjection, as_attack
from ..model.channels import Channel, as_channel, is_paper_channel
from ..model.schedules import OnlineDesign
from .count import (
    ALTERNATIVES,
    EXACT_BELOW,
    LAM_RANGE_POINTS,
    alarm_bounds,
    check_lam_range,
    exact_alarm_probability,
    exact_count_law,
    harmful_bound,
    process_alarm_bounds,
    uses_exact_law,
)
from .intervals import design_walk
from .process import flag_process

__all__ = [
    "belief_bounds",
    "belief_probability",
    "count_alarm_probability",
    "count_moments",
    "count_probability",
]


def count_moments(lam: float, design: OnlineDesign, n: int, attack: Attack | None) -> tuple[float, float]:
    """(mean, sd) of a stationary window's count under the attack (:func:`flag_count_moments`)."""
    w = design_walk(lam, design, attack)
    if w.endless:
        return 0.0, 0.0
    _, sig = w.time_covariance(np.array([1]))
    return n / w.mean, math.sqrt(max(n * float(sig[0, 0]), 0.0))


def count_alarm_probability(
    bounds: tuple[int, int], n: int, moments: tuple[float, float], harm: int | None
) -> float:
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


def belief_bounds(
    belief: Channel,
    design: OnlineDesign,
    n: int,
    alpha: float,
    alternative: str,
    lam_range: tuple[float, float] | None,
) -> tuple[int, int]:
    """The alarm region of the count test calibrated on ``belief`` or, with ``lam_range``, the
    counts that alarm at every lam of the range (the intersection of the regions)."""
    if lam_range is not None:
        lo, hi = lam_range
        regions = [
            alarm_bounds(float(x), design, n, alpha, alternative)
            for x in np.linspace(lo, hi, LAM_RANGE_POINTS)
        ]
        return min(r[0] for r in regions), max(r[1] for r in regions)
    if is_paper_channel(belief):
        return alarm_bounds(float(belief.low[0]), design, n, alpha, alternative)
    return process_alarm_bounds(flag_process(belief, design), n, alpha, alternative)


def count_probability(
    bounds: tuple[int, int], truth: Channel, design: OnlineDesign, n: int, attack: object
) -> float:
    """P(N <= lo or N >= hi) for the window's count under the true channel and the attack."""
    # The renewal gap laws take the built-in attacks with min_gap = 1.
    renewal = attack is None or (
        isinstance(attack, Attack) and not (isinstance(attack, FlagInjection) and attack.min_gap > 1)
    )
    if is_paper_channel(truth) and renewal:
        built_in = cast("Attack | None", attack)
        lam = float(truth.low[0])
        if uses_exact_law(n, lam, design):
            return exact_alarm_probability(bounds, exact_count_law(n, lam, design, built_in), None)
        return count_alarm_probability(bounds, n, count_moments(lam, design, n, built_in), None)
    process = flag_process(truth, design, attack)
    if n * process.rate < EXACT_BELOW:
        return exact_alarm_probability(bounds, process.count_law(n), None)
    mean, var = process.count_moments(n)
    return count_alarm_probability(bounds, n, (mean, math.sqrt(var)), None)


def belief_probability(
    channel: Channel,
    name: str,
    z0: int | None,
    attack: object,
    n_steps: int | None,
    alpha: float | None,
    test: str,
    alternative: str,
    mu: float,
    beta_bar: float | None,
    true_channel: object,
    lam_range: object,
) -> float:
    """:func:`fakeack.detection_probability` with a Markov channel, ``true_channel`` or ``lam_range``."""
    if z0 is None:
        raise TypeError("detection_probability() missing required argument: 'z0'")
    design = OnlineDesign(z0, mu)  # validates both
    truth = channel if true_channel is None else as_channel(true_channel, "true_channel")
    span = None if lam_range is None else check_lam_range(lam_range)
    att = attack if isinstance(attack, (MimicryAttack, AttackerAutomaton)) else as_attack(attack)  # type: ignore[arg-type]
    if n_steps is None or alpha is None:
        raise TypeError("detection_probability() missing required argument: 'n_steps' and 'alpha'")
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**9)
    alpha_ = as_probability("alpha", alpha)
    if test == "support":
        gap = flag_process(channel, design).min_gap
        process = flag_process(truth, design, att)
        if beta_bar is None:
            return process.short_gap_probability(n, gap)
        # The harmful rule reads the window's count: a short gap counts only with N <= harm.
        harm = harmful_count(channel, design, n, beta_bar, true_channel, span)
        return process.window_alarm_probability(n, gap, (-1, n + 1), harm)
    if test != "count":
        raise ValueError(
            "test: with a Markov channel, true_channel, lam_range, mimicry, an attacker automaton or a "
            "forger with min_gap > 1 only the count and support tests are computed (the interval "
            f"test's gap laws take the paper's channel and the built-in attacks), got {test!r}"
        )
    if alternative not in ALTERNATIVES:
        raise ValueError(f"alternative must be one of {ALTERNATIVES}, got {alternative!r}")
    bounds = belief_bounds(channel, design, n, alpha_, alternative, span)
    if beta_bar is not None:  # the exact joint law of the count and the harmful region
        harm = harmful_count(channel, design, n, beta_bar, true_channel, span)
        return flag_process(truth, design, att).window_alarm_probability(n, 1, bounds, harm)
    return count_probability(bounds, truth, design, n, att)


def harmful_count(
    channel: Channel, design: OnlineDesign, n: int, beta_bar: float, true_channel: object, span: object
) -> int:
    """The harmful rule's count bound: N <= harm means an estimated budget above ``beta_bar``
    (:func:`fakeack.estimate_beta`); computed on the paper's channel, belief equal to the truth."""
    if not is_paper_channel(channel) or true_channel is not None or span is not None:
        raise ValueError(
            "beta_bar: the harmful rule is computed on the paper's channel with no true_channel or lam_range"
        )
    return harmful_bound(float(channel.low[0]), design, n, as_real("beta_bar", beta_bar))
