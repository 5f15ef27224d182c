r"""The likelihood-ratio test of a window of the flag-ACK stream (:func:`likelihood_ratio_test`).

In a window of n steps the sensor sums the per-step log-likelihood ratio :math:`\Lambda_n` of what
reached it between an alternative with i.i.d. gaps and the attack-free law (the increments of
:class:`fakeack.CusumTest`, without the CUSUM's reflection at 0), opened by the log-likelihood
ratio of the gap :math:`y_0` already running at the window's start under the two stationary age
laws, :math:`\log(P_a(y_0)/P_0(y_0))`, :math:`P(y_0 = y) = S(y)/m` (S the survival of the gap
law, m its mean). On the paper's channel the gaps are i.i.d. under both laws, so this is the exact
log-likelihood ratio of everything the sensor saw in a stationary window; it alarms when
:math:`\Lambda_n \ge c_\alpha`, the :math:`1-\alpha` quantile of its attack-free law. By the lemma of
Neyman and Pearson no test of level alpha has a higher detection probability against the
alternative itself; against other attacks it is one more detector, whose detection probability
is computed exactly (:func:`likelihood_ratio_law`). A flag-ACK sooner than any can come without
attack makes :math:`\Lambda_n = +\infty`: the support check is part of the test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from .._internal.validate import as_int, as_probability, as_real
from ..attacks.automata import AttackerAutomaton, MimicryAttack
from ..attacks.kinds import RandomBlocking, as_attack
from ..model.channels import Channel, ChannelLike, as_channel
from ..model.schedules import OnlineDesign
from .cusum import CusumIncrements, CusumTest
from .likelihood_law import LikelihoodRatioLaw, law_of, opening
from .process import flag_process

__all__ = [
    "DEFAULT_ALTERNATIVE",
    "LikelihoodRatioTest",
    "likelihood_ratio_law",
    "likelihood_ratio_test",
]

#: The alternative the test is tuned to unless told: each flag-ACK blocked with probability 0.2,
#: a blocker that silences the sensor's fallback a fifth of the time.
DEFAULT_ALTERNATIVE = RandomBlocking(0.2)
#: Grid steps per standard deviation of one step's increment.
RESOLUTION = 8.0

_TESTS: dict[tuple[Any, ...], LikelihoodRatioTest] = {}
_LAWS: dict[tuple[Any, ...], LikelihoodRatioLaw] = {}


def _design(z0: object, mu: object) -> OnlineDesign:
    return OnlineDesign(as_int("z0", z0, minimum=1), as_real("mu", mu))


def _played(attack: object) -> object:
    if attack is None or isinstance(attack, (MimicryAttack, AttackerAutomaton)):
        return attack
    return as_attack(attack)  # type: ignore[arg-type]


def likelihood_ratio_law(
    channel: ChannelLike,
    z0: int,
    n_steps: int,
    attack: object = None,
    mu: float = 1.0,
    *,
    alternative: object = DEFAULT_ALTERNATIVE,
    true_channel: ChannelLike | None = None,
    resolution: float = RESOLUTION,
) -> LikelihoodRatioLaw:
    r"""The law of the window's log-likelihood ratio :math:`\Lambda_n` under an attack.

    A forward recursion over (automaton state, gap since the last flag-ACK, :math:`\Lambda` on a
    grid) of the exact engine's flag process (``fakeack.detection.likelihood_law`` explains it),
    from the long-run regime of the attack, so any attack :class:`fakeack.Scenario` takes is
    covered. The grid's spacing is the standard deviation of one step's increment divided by
    ``resolution``; its split rounding keeps the mean exactly.

    Parameters
    ----------
    channel : Channel or float
        The channel the statistic is built on (a float: the paper's channel).
    z0 : int
        Memory length of the event detector.
    n_steps : int
        The window, >= 1.
    attack : optional
        The attack played (None: the attack-free law).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    alternative : RandomBlocking, FlagInjection or array_like, optional
        The attack the statistic is tuned to, as in :class:`fakeack.CusumTest` (default
        ``RandomBlocking(0.2)``).
    true_channel : Channel or float, optional
        The channel the window is played on (default ``channel``).
    resolution : float, optional
        Grid steps per standard deviation of one step's increment (default 8), > 0.

    Returns
    -------
    LikelihoodRatioLaw

    Raises
    ------
    ValueError, TypeError
        For a bad argument (naming it), or a law past about 6e10 operations (naming ``n_steps``).

    Examples
    --------
    >>> from fakeack.detection import likelihood_ratio_law
    >>> law = likelihood_ratio_law(0.5, 2, 1000)
    >>> round(law.mean, 2)   # the opening's mean, then minus the Kullback-Leibler rate per step
    -5.03
    """
    ch = as_channel(channel, "channel")
    design = _design(z0, mu)
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**7)
    res = as_real("resolution", resolution)
    if not res > 0.0:
        raise ValueError(f"resolution must be > 0, got {res}")
    truth = ch if true_channel is None else as_channel(true_channel, "true_channel")
    inc = CusumTest(alternative, 1.0).increments(ch, design)
    return law_of(flag_process(truth, design, _played(attack)), inc, n, res)


@dataclass(frozen=True)
class LikelihoodRatioTest:
    r"""The likelihood-ratio test for windows of ``n_steps`` steps at level ``alpha`` (see
    :func:`likelihood_ratio_test`)."""

    alternative: object
    """The attack the statistic is tuned to."""
    channel: Channel
    design: OnlineDesign
    n_steps: int
    alpha: float
    critical: float
    r"""Alarm when :math:`\Lambda_n \ge` this value."""
    alpha_reached: float
    """The attack-free P(alarm) at ``critical`` on the law as read (equal to ``alpha`` to rounding).
    The hat kernels act as a randomisation at the scale of the grid: the statistic's own atoms
    lie much closer together than the grid's spacing where its increments are many and
    unrelated, and the level then holds up to the grid's error."""
    error: float
    """How far ``critical`` moves on a grid twice as coarse: its stated accuracy."""
    increments: CusumIncrements = field(repr=False)
    null: LikelihoodRatioLaw = field(repr=False)
    """The attack-free law of the statistic."""

    def statistic(self, delivered: npt.ArrayLike, gap: int) -> float:
        r""":math:`\Lambda_n` of a window: the opening of ``gap`` plus the window's increments.

        Parameters
        ----------
        delivered : numpy.ndarray of bool
            ``delivered[k]``: whether a flag-ACK reached the sensor at the window's step k.
        gap : int
            The gap y of the window's first step: 1 if a flag-ACK reached the sensor on the step
            just before the window, one more for each silent step since.

        Returns
        -------
        float
            ``+inf`` where a step's outcome is impossible without attack.
        """
        x = np.asarray(delivered)
        if x.ndim != 1 or x.dtype != bool:
            raise TypeError("delivered must be a 1-D boolean array")
        if x.size != self.n_steps:
            raise ValueError(f"delivered: the test is for windows of {self.n_steps} steps, got {x.size}")
        y = as_int("gap", gap, minimum=1)
        Y = self.increments.length
        total = float(opening(self.increments, np.array([y]))[0])
        if total == math.inf:
            return math.inf
        for flag in x:
            step = self.increments.flag[min(y, Y) - 1] if flag else self.increments.quiet[min(y, Y) - 1]
            if step == math.inf:
                return math.inf
            total += float(step)
            y = 1 if flag else y + 1
        return total

    def detection_probability(self, attack: object = None, true_channel: ChannelLike | None = None) -> float:
        r"""P(alarm) in a stationary window under an attack, from the exact law of the statistic
        (:func:`likelihood_ratio_law`).

        Parameters
        ----------
        attack : optional
            Any attack :class:`fakeack.Scenario` takes (None: the false-alarm rate,
            ``alpha_reached``).
        true_channel : Channel or float, optional
            The channel the window is played on (default the test's channel).

        Returns
        -------
        float
            P(:math:`\Lambda_n \ge` ``critical``).
        """
        if attack is None and true_channel is None:
            return self.alpha_reached
        truth = self.channel if true_channel is None else as_channel(true_channel, "true_channel")
        key = (self.channel, self.design, _alternative_key(self.alternative), self.n_steps, truth)
        law = _cached_law(key, _played(attack), self.increments, RESOLUTION)
        return law.tail(self.critical)


def _alternative_key(alt: object) -> object:
    return tuple(alt.tolist()) if isinstance(alt, np.ndarray) else alt


def _cached_law(
    key: tuple[Any, ...], attack: object, inc: CusumIncrements, resolution: float
) -> LikelihoodRatioLaw:
    """The statistic's law under ``attack`` on the window, channel and design of ``key`` (its
    last entry the true channel), kept for the tests of other levels on the same window: the law
    does not depend on alpha, and a game asks for it at every alpha."""
    full = (*key, resolution, attack)
    try:
        law = _LAWS.get(full)
    except TypeError:  # an attack that cannot be hashed is computed each time
        return law_of(flag_process(key[-1], key[1], attack), inc, key[3], resolution)
    if law is None:
        law = law_of(flag_process(key[-1], key[1], attack), inc, key[3], resolution)
        if len(_LAWS) > 256:
            _LAWS.clear()
        _LAWS[full] = law
    return law


def lr_tables(test: LikelihoodRatioTest) -> tuple[list[float], list[float], list[float]]:
    """The closed-loop kernel's form of the statistic: the increments at a flag-ACK and at a
    silent step and the opening, per gap y = 1..Y (the kernel continues the opening past Y by
    the last silent increment per step, as :func:`opening` does)."""
    inc = test.increments
    start = opening(inc, np.arange(1, inc.length + 1))
    return [float(v) for v in inc.flag], [float(v) for v in inc.quiet], [float(v) for v in start]


def _critical(law: LikelihoodRatioLaw, alpha: float) -> tuple[float, float]:
    """The critical value at level alpha and the tail the law gives there."""
    c = law.quantile(alpha)
    return c, law.tail(c)


def likelihood_ratio_test(
    channel: ChannelLike,
    z0: int,
    n_steps: int,
    alpha: float = 0.01,
    mu: float = 1.0,
    *,
    alternative: object = DEFAULT_ALTERNATIVE,
) -> LikelihoodRatioTest:
    r"""The likelihood-ratio test of a window against ``alternative``: its critical value.

    The statistic :math:`\Lambda_n` (module docstring) has an exact attack-free law
    (:func:`likelihood_ratio_law`); the critical value c solves :math:`P(\Lambda_n \ge c)` =
    ``alpha`` on it, read through hat kernels (:meth:`fakeack.LikelihoodRatioLaw.tail`),
    which act as a randomisation at the scale of the grid; ``error`` is how far c moves on a grid
    twice as coarse. By Neyman and Pearson, no test of the same level detects ``alternative``
    more often. An alternative with the attack-free gap law (every finite increment 0) is refused.

    Parameters
    ----------
    channel : Channel or float
        The channel (a float: the paper's channel of that low-power arrival probability).
    z0 : int
        Memory length of the event detector.
    n_steps : int
        Window length in steps.
    alpha : float, optional
        False-alarm probability per window, in (0, 1) (default 0.01).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    alternative : RandomBlocking, FlagInjection or array_like, optional
        The attack the test is tuned to, with i.i.d. gaps (as :class:`fakeack.CusumTest` takes;
        default ``RandomBlocking(0.2)``).

    Returns
    -------
    LikelihoodRatioTest

    Raises
    ------
    ValueError, TypeError
        For a bad argument, naming it.

    Examples
    --------
    >>> import fakeack as fa
    >>> from fakeack.detection import likelihood_ratio_test
    >>> test = likelihood_ratio_test(0.5, 2, 1000, 0.01)
    >>> test.alpha_reached <= 0.01
    True
    >>> 0.7 < test.detection_probability(fa.RandomBlocking(0.2)) < 0.9
    True
    """
    ch = as_channel(channel, "channel")
    design = _design(z0, mu)
    n = as_int("n_steps", n_steps, minimum=1, maximum=10**7)
    level = as_probability("alpha", alpha)
    cusum = CusumTest(alternative, 1.0)
    alt = cusum.alternative
    key = (ch, design, n, level, _alternative_key(alt))
    if key in _TESTS:
        return _TESTS[key]
    inc = cusum.increments(ch, design)
    steps = np.concatenate((inc.flag, inc.quiet))
    if not np.any((steps == -math.inf) | (np.isfinite(steps) & (np.abs(steps) > 1e-12))):
        raise ValueError(
            f"alternative: {alt} has the attack-free gap law; the statistic is the support check "
            "alone (test='support')"
        )
    laws = (ch, design, _alternative_key(alt), n, ch)
    null = _cached_law(laws, None, inc, RESOLUTION)
    critical, reached = _critical(null, level)
    coarse, _ = _critical(_cached_law(laws, None, inc, RESOLUTION / 2), level)
    test = LikelihoodRatioTest(
        alt, ch, design, n, level, critical, reached, abs(coarse - critical), inc, null
    )
    if len(_TESTS) > 64:
        _TESTS.clear()
    _TESTS[key] = test
    return test
