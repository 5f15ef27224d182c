"""Detection probability against the window length, per test and attack (:func:`detection_curves`),
for the figure of :func:`fakeack.plots.plot_detection_curves`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._internal.types import FloatArray, IntArray
from .._internal.validate import as_int, as_probability
from ..attacks.automata import AttackerAutomaton, MimicryAttack
from ..attacks.kinds import AttackLike
from ..model.channels import ChannelLike
from ..model.schedules import OnlineDesign
from .interval_test import MIN_EXPECTED_FLAGS
from .probability import detection_probability
from .process import flag_process

__all__ = [
    "DetectionCurves",
    "detection_curves",
]

#: The tests a curve may show: the two flag-timing tests, the support check alone and the
#: likelihood-ratio test.
CURVE_TESTS = ("count", "interval", "support", "lr")
#: The tests drawn unless told.
DEFAULT_TESTS = ("count", "interval", "support")


@dataclass(frozen=True)
class DetectionCurves:
    """The result of :func:`detection_curves`."""

    n_steps: IntArray
    """Window lengths (steps)."""
    tests: tuple[str, ...]
    attacks: tuple[object, ...]
    probability: FloatArray
    """``probability[i, j, k]``: test i, attack j, window k. NaN where the test is not computed:
    the interval test on a window with fewer than 100 expected flag-ACKs (it refuses them)."""
    alpha: float
    support: bool
    """Whether the count and interval tests ran with the support check beside them."""


def detection_curves(
    channel: ChannelLike,
    z0: int,
    attacks: Sequence[AttackLike | MimicryAttack | AttackerAutomaton],
    n_steps: Sequence[int],
    alpha: float = 0.01,
    tests: Sequence[str] = DEFAULT_TESTS,
    mu: float = 1.0,
    *,
    support: bool = True,
    lr_alternative: object = None,
) -> DetectionCurves:
    r"""The detection probability per window (:func:`fakeack.detection_probability`) of each test
    and attack over a range of window lengths.

    Parameters
    ----------
    channel : Channel or float
        The channel (a float: the paper's, of that low-power arrival probability).
    z0 : int
        Memory length of the event detector.
    attacks : sequence
        ``None`` (the false-alarm rate) or any attack, :class:`fakeack.MimicryAttack` or
        :class:`fakeack.AttackerAutomaton`.
    n_steps : sequence of int
        Window lengths, each >= 1.
    alpha : float, optional
        False-alarm level of the count and interval tests (default 0.01).
    tests : sequence of {"count", "interval", "support", "lr"}, optional
        The tests (default the first three; ``"support"`` is the support check alone, ``"lr"``
        the likelihood-ratio test of :func:`fakeack.likelihood_ratio_test`).
    mu : float, optional
        Probability of the z0-bit memory at each step (default 1).
    support : bool, optional
        Whether the count and interval tests run with the support check beside them (default
        True; the ``"lr"`` test holds it in its statistic).
    lr_alternative : optional
        The attack the ``"lr"`` test is tuned to (default ``RandomBlocking(0.2)``).

    Returns
    -------
    DetectionCurves
    """
    tests_ = tuple(tests)
    for t in tests_:
        if t not in CURVE_TESTS:
            raise ValueError(f"tests: each must be one of {CURVE_TESTS}, got {t!r}")
    if not tests_:
        raise ValueError("tests must not be empty")
    windows = np.array([as_int("n_steps", n, minimum=1, maximum=10**7) for n in n_steps], dtype=np.int64)
    if windows.size == 0:
        raise ValueError("n_steps must not be empty")
    attacks_ = tuple(attacks)
    if not attacks_:
        raise ValueError("attacks must not be empty")
    level = as_probability("alpha", alpha)
    if not isinstance(support, bool):
        raise TypeError(f"support must be True or False, got {support!r}")
    rate = flag_process(channel, OnlineDesign(z0, mu)).rate
    out = np.full((len(tests_), len(attacks_), len(windows)), np.nan)
    for i, test in enumerate(tests_):
        for k, n in enumerate(windows):
            if test == "interval" and n * rate < MIN_EXPECTED_FLAGS:
                continue  # the interval test refuses such windows
            for j, a in enumerate(attacks_):
                extra = {"lr_alternative": lr_alternative} if test == "lr" else {"support": support}
                out[i, j, k] = detection_probability(channel, z0, a, int(n), level, test, mu=mu, **extra)
    return DetectionCurves(windows, tests_, attacks_, out, level, support)
