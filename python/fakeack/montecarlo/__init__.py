"""Monte Carlo of the real protocol, and the exact finite-horizon curves it is checked against."""

from .curves import TraceCurve, expected_trace_curve
from .protocol import SimulationResult, simulate

__all__ = [
    "TraceCurve",
    "expected_trace_curve",
    "SimulationResult",
    "simulate",
]
