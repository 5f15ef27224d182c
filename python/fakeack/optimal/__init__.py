"""Optimal attacks and schedules: the attacker's and the sensor's best choices, computed exactly."""

from .jamming import JammingResult, optimal_jamming

__all__ = [
    "JammingResult",
    "optimal_jamming",
]
