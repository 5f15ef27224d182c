"""The strongest Monte Carlo check: 10^6 runs x 10^4 steps of the compiled release kernel against
the exact per-step law of the holding time, each step within 6 standard errors (a 0.5% bias
fails it). About 10^10 simulated steps, so it runs only when ``FAKEACK_BIG_RUN=1`` (CI sets it,
on the release build that ``pip install .`` made).

The expected values are derived here from the protocol, not from the package: the steady-state
a-posteriori covariance from SciPy's Riccati solver, h(X) = A X A' + Q, and the law of tau from
its definition (tau < z0: to 0 with probability lam, else tau + 1; tau = z0: a flag-ACK was
delivered, so the next packet goes at high power and arrives; tau_1 = 0).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

import fakeack as fa

pytestmark = pytest.mark.skipif(
    os.environ.get("FAKEACK_BIG_RUN") != "1", reason="10^10 steps: set FAKEACK_BIG_RUN=1"
)

A, C, Q, R = 1.2, 0.7, 0.8, 0.8
LAM, Z0, HORIZON, RUNS = 0.5, 2, 10_000, 1_000_000


def _traces(depth: int) -> np.ndarray:
    """Tr h^tau(P_bar), tau = 0..depth, with P_bar the local filter's a-posteriori covariance."""
    prior = float(
        solve_discrete_are(np.array([[A]]), np.array([[C]]), np.array([[Q]]), np.array([[R]]))[0, 0]
    )
    p = prior - prior * C * C * prior / (C * prior * C + R)
    out = [p]
    for _ in range(depth):
        out.append(A * out[-1] * A + Q)
    return np.array(out)


def test_ten_billion_steps_match_the_exact_law_of_tau() -> None:
    sys = fa.LinearSystem(A=[[A]], C=[[C]], Q=[[Q]], R=[[R]])
    r = fa.simulate(sys, LAM, fa.OnlineDesign(Z0), horizon=HORIZON, runs=RUNS, seed=3, progress=False)
    tr = _traces(Z0)
    law = np.zeros(Z0 + 1)
    law[0] = 1.0
    means = np.empty(HORIZON)
    sds = np.empty(HORIZON)
    for k in range(HORIZON):
        if k > 0:
            nxt = np.zeros(Z0 + 1)
            nxt[0] = law[Z0] + LAM * law[:Z0].sum()
            nxt[1:] += (1 - LAM) * law[:Z0]
            law = nxt
        means[k] = law @ tr
        sds[k] = np.sqrt(law @ (tr - means[k]) ** 2)
    se = sds / np.sqrt(RUNS)
    tol = 6.0 * se + 1e-12 * means  # rounding of the sums where the law is a point
    worst = int(np.argmax(np.abs(r.mean_trace - means) - tol))
    assert np.all(np.abs(r.mean_trace - means) <= tol), (worst, r.mean_trace[worst], means[worst])
    j_h = means.mean()
    assert abs(r.j - j_h) <= 4.0 * r.stderr + 1e-12 * j_h, (r.j, j_h, r.stderr)
