import os
import re
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# CI is deterministic (the same examples every run, plus every corner pinned with @example);
# local runs explore new seeds. FAKEACK_FUZZ=N multiplies every hypothesis budget by N with fresh
# random seeds, even under CI (README, development): the long random search.
FUZZ = max(1, int(os.environ.get("FAKEACK_FUZZ", "1")))
settings.register_profile("ci", derandomize=True, database=None, deadline=None)
settings.register_profile("fuzz", derandomize=False, deadline=None, print_blob=True)
if FUZZ > 1:
    settings.load_profile("fuzz")
elif os.environ.get("CI"):
    settings.load_profile("ci")

sys.path.insert(0, str(Path(__file__).parent))

import fakeack as fa  # noqa: E402

PAPER = dict(A=1.2, C=0.7, Q=0.8, R=0.8)
PAPER_LAM = 0.5
PAPER_RATIO = Fraction(1, 7)


@pytest.fixture
def paper():
    return fa.LinearSystem(**PAPER)


def random_system(rng, n, m=None, unstable=True):
    """A random system with (A, C) observable and Q > 0; spectral radius up to 1.3."""
    m = m or max(1, n // 2)
    A = rng.standard_normal((n, n))
    rho = max(abs(np.linalg.eigvals(A)))
    A *= (rng.uniform(0.5, 1.3) if unstable else rng.uniform(0.3, 0.95)) / rho
    C = rng.standard_normal((m, n))
    B = rng.standard_normal((n, n))
    Q = B @ B.T / n + 0.1 * np.eye(n)
    D = rng.standard_normal((m, m))
    R = D @ D.T / m + 0.2 * np.eye(m)
    return A, C, Q, R


def names(argument: str) -> str:
    """A `pytest.raises(match=...)` pattern for an error message naming `argument` as a word of
    its own, case exact: "lam" matches "lam must be ..." but not "XXlamXX", "LAM" or "None"
    (kills a mutated argument name in a message)."""
    return rf"(?<![A-Za-z0-9_]){re.escape(argument)}(?![A-Za-z0-9_])"
