"""Detecting the attacker from the flag-ACKs the sensor receives: flag rates and gap laws, the count
and interval tests, and their detection probability per window."""

from .count import ALTERNATIVES, Detection, count_alarm_bounds, detect_attack, harmful_count_bound
from .flags import FlagRates, delivered_flag_rate, estimate_beta, flag_interval_moments, flag_rates
from .interval_test import IntervalDetection, IntervalTest, detect_intervals, interval_test
from .intervals import FlagCount, IntervalLaw, flag_count_moments, flag_interval_law
from .probability import TESTS, DetectionRates, detection_probability, detection_rates

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
    "DetectionRates",
    "detection_rates",
]
