"""The sensor's two tests for a fake-ACK attacker and their detection probability per window.

* The **count test** (:func:`fakeack.detect_attack`) compares how many flag-ACKs reached the sensor
  in a window of n steps with the attack-free count (renewal central limit theorem).
* The **interval test** (:func:`detect_intervals`) also looks at *when* they came: Pearson's
  goodness-of-fit statistic over bins of the exact attack-free gap law.

:func:`detection_probability` gives the probability that either test raises an alarm in one window
under any attack (``None``: the false-alarm rate), from the exact laws of
``fakeack.detection.intervals`` and the stated normal approximations. :func:`flag_process` gives
the delivered flag-ACKs on any channel as a Markov arrival process over the exact engine's
automaton: their rate, variance rate and the exact count law of a window. :class:`CusumTest` is
the sequential test for an attack's onset, with its run lengths from :func:`cusum_run_length`;
:func:`likelihood_ratio_test` the window's likelihood-ratio test against an alternative, with the
exact law of its statistic from :func:`likelihood_ratio_law`.

The interval statistic's law under an attack lives in ``interval_power`` (from the gap walk of
``intervals`` or the flag process's bin moments of ``gap_bins``); the support check's joint laws
with the count in ``process``.
"""

from .count import ALTERNATIVES, Detection, count_alarm_bounds, detect_attack, harmful_count_bound
from .curves import DetectionCurves, detection_curves
from .cusum import CusumIncrements, CusumTest
from .cusum_filter import SimulatedRunLength
from .flags import FlagRates, delivered_flag_rate, estimate_beta, flag_interval_moments, flag_rates
from .interval_test import IntervalDetection, IntervalTest, detect_intervals, interval_test
from .intervals import FlagCount, IntervalLaw, flag_count_moments, flag_interval_law
from .likelihood import LikelihoodRatioTest, likelihood_ratio_law, likelihood_ratio_test
from .likelihood_law import LikelihoodRatioLaw
from .probability import TESTS, detection_probability
from .process import FlagProcess, flag_process
from .rates import DetectionRates, detection_rates
from .run_length import CusumRunLength, cusum_run_length, cusum_threshold

__all__ = [
    "flag_interval_moments",
    "FlagRates",
    "flag_rates",
    "delivered_flag_rate",
    "estimate_beta",
    "ALTERNATIVES",
    "count_alarm_bounds",
    "harmful_count_bound",
    "Detection",
    "detect_attack",
    "IntervalTest",
    "interval_test",
    "IntervalDetection",
    "detect_intervals",
    "IntervalLaw",
    "flag_interval_law",
    "FlagCount",
    "flag_count_moments",
    "TESTS",
    "detection_probability",
    "DetectionCurves",
    "detection_curves",
    "DetectionRates",
    "detection_rates",
    "FlagProcess",
    "flag_process",
    "CusumTest",
    "CusumIncrements",
    "CusumRunLength",
    "SimulatedRunLength",
    "cusum_run_length",
    "cusum_threshold",
    "LikelihoodRatioTest",
    "likelihood_ratio_test",
    "LikelihoodRatioLaw",
    "likelihood_ratio_law",
]
