"""The numpy baseline of benches/compare.py (benches/numpy_protocol.py) simulates the right protocol.

Its J must agree with the analytic costs within 4 standard errors. Runs are few and long, so the
finite-horizon bias (O(1/horizon), from the start at tau = 0) is far below the standard error; the
exact finite-horizon mean (fa.expected_trace_curve) is checked too.
"""

import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER, PAPER_LAM, PAPER_RATIO

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benches"))

import numpy_protocol as npp  # noqa: E402

RUNS, HORIZON = 512, 16_384


def _close(res, expected, curve=None):
    assert np.isfinite(res.stderr) and res.stderr > 0
    assert abs(res.j - expected) <= 4 * res.stderr, (res.j, expected, res.stderr)
    if curve is not None:
        assert abs(res.j - curve.j_k[-1]) <= 4 * res.stderr, (res.j, curve.j_k[-1], res.stderr)


@pytest.fixture(scope="module")
def paper():
    return fa.LinearSystem(**PAPER)


def test_pbar_and_traces_match_fakeack(paper):
    np.testing.assert_allclose(npp.pbar_posterior(**PAPER), paper.pbar, rtol=1e-12)
    np.testing.assert_allclose(npp.h_traces(1.2, 0.8, paper.pbar, 40), paper.h_traces(40), rtol=1e-12)


def test_offline(paper):
    pattern = fa.offline_schedule(PAPER_RATIO)
    horizon = HORIZON - HORIZON % len(pattern)
    res = npp.simulate(**PAPER, lam=PAPER_LAM, pattern=pattern, horizon=horizon, runs=RUNS, seed=3)
    curve = fa.expected_trace_curve(paper, PAPER_LAM, fa.OfflineSchedule(PAPER_RATIO), horizon)
    _close(res, fa.j_offline(paper, PAPER_LAM, PAPER_RATIO), curve)
    assert res.high_power_rate == pytest.approx(float(PAPER_RATIO), abs=1e-12)
    assert res.flags_sent == 0


@pytest.mark.parametrize("ratio", [Fraction(1, 7), Fraction(1, 6)])  # mu = 1 and mu < 1
def test_online(paper, ratio):
    z0, mu = fa.design_online(PAPER_LAM, ratio)
    res = npp.simulate(**PAPER, lam=PAPER_LAM, z0=z0, mu=mu, horizon=HORIZON, runs=RUNS, seed=4)
    curve = fa.expected_trace_curve(paper, PAPER_LAM, fa.OnlineSchedule(z0, mu), HORIZON)
    _close(res, fa.j_online(paper, PAPER_LAM, z0, mu), curve)
    assert abs(res.high_power_rate - float(ratio)) < 0.003
    assert res.flags_blocked == 0


@pytest.mark.parametrize(("z0", "mu", "r", "t"), [(2, 1.0, 1, 5), (2, 1.0, 2, 3), (1, 1 / 7, 2, 5)])
def test_attack(paper, z0, mu, r, t):
    res = npp.simulate(
        **PAPER, lam=PAPER_LAM, z0=z0, mu=mu, mask=[1] * r + [0] * (t - r), horizon=HORIZON, runs=RUNS, seed=5
    )
    curve = fa.expected_trace_curve(paper, PAPER_LAM, fa.OnlineSchedule(z0, mu), HORIZON, attack=(r, t))
    _close(res, fa.j_attack(paper, PAPER_LAM, z0, r, t, mu), curve)
    assert res.flags_blocked == pytest.approx(res.flags_sent * r / t, rel=0.01)


@pytest.mark.parametrize(
    ("beta", "gamma", "mask", "attack"),
    [
        (0.2, 0.0, None, fa.RandomBlocking(0.2)),
        (None, 0.05, None, fa.FlagInjection(0.05)),
        (0.3, 0.1, None, fa.FlagInjection(0.1, fa.RandomBlocking(0.3))),
        (None, 0.1, [1, 0, 0], fa.FlagInjection(0.1, fa.PeriodicBlocking(1, 3))),
    ],
)
def test_other_attacks(paper, beta, gamma, mask, attack):
    res = npp.simulate(
        **PAPER, lam=PAPER_LAM, z0=2, mask=mask, beta=beta, gamma=gamma, horizon=HORIZON, runs=RUNS, seed=8
    )
    # (No exact J_H here: under independent blocking its chain grows with the horizon.)
    _close(res, fa.j_attack(paper, PAPER_LAM, 2, attack=attack))
    rates = fa.flag_rates(PAPER_LAM, 2, attack)
    assert res.high_power_rate == pytest.approx(rates.delivered, rel=0.01)
    assert res.flags_forged == pytest.approx(rates.forged, rel=0.02, abs=1e-12)


def test_state_mode_scalar(paper):
    res = npp.simulate(
        **PAPER, lam=PAPER_LAM, z0=2, mask=[1, 0, 0, 0, 0], horizon=HORIZON, runs=RUNS, seed=6, mode="state"
    )
    curve = fa.expected_trace_curve(paper, PAPER_LAM, fa.OnlineSchedule(2), HORIZON, attack=(1, 5))
    _close(res, fa.j_attack(paper, PAPER_LAM, 2, 1, 5), curve)


def test_state_mode_vector():
    A = np.array([[1.1, 0.3], [0.0, 0.7]])
    C = np.array([[1.0, 0.5]])
    Q = np.array([[0.5, 0.1], [0.1, 0.4]])
    R = np.array([[0.3]])
    s = fa.LinearSystem(A, C, Q, R)
    for mode in ("covariance", "state"):
        res = npp.simulate(
            A, C, Q, R, lam=0.4, z0=2, mask=[1, 0, 0], horizon=4096, runs=1024, seed=7, mode=mode
        )
        curve = fa.expected_trace_curve(s, 0.4, fa.OnlineSchedule(2), 4096, attack=(1, 3))
        _close(res, fa.j_attack(s, 0.4, 2, 1, 3), curve)
