"""Stability regions over the (p, q) plane of a Gilbert-Elliott channel: the engine's index against
closed forms derived here, the i.i.d. line against today's structured routes, the points that are
not evaluated, the result object and the bad inputs."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fakeack as fa
from conftest import names
from fakeack.engine import stability
from fakeack.engine.stability import DEFAULT_GRID, StabilityRegion, stability_region
from reference import pbar_scipy, traces

S = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
RHO2 = 1.44
GRID = np.array([0.05, 0.2, 0.3, 0.5, 0.8, 1.0])
TR = traces(S.A, S.Q, pbar_scipy(S.A, S.C, S.Q, S.R), 400)


def test_always_low_sensor_boundary_is_one_minus_q_times_rho_a_squared():
    """OfflineSchedule(pattern="0") on GilbertElliott(p, q, 1, 0): a packet arrives exactly at a
    good step, so K0 = diag(0, 1) P = [[0, 0], [q, 1 - q]], rho(K0) = 1 - q whatever p, and J is
    finite iff (1 - q) rho(A)^2 < 1 (q > 0.3056 here). The holding time is the time since the last
    good step: P(tau = 0) = pi_good = q/(p+q), P(tau = t) = pi_good p (1 - q)^(t-1) for t >= 1."""
    reg = stability_region(S, fa.OfflineSchedule(pattern="0"), p=GRID, q=GRID)
    want = np.broadcast_to((1 - GRID) * RHO2, (len(GRID), len(GRID)))
    assert_allclose(reg.index, want, rtol=1e-12, atol=1e-15)
    assert (reg.stable == ((1 - GRID) * RHO2 < 1)[None, :]).all()
    for i, p in enumerate(GRID):
        for j, q in enumerate(GRID):
            if not reg.stable[i, j]:
                assert reg.cost[i, j] == math.inf
                continue
            t = np.arange(1, len(TR))
            j_want = q / (p + q) * (TR[0] + p * np.sum((1 - q) ** (t - 1) * TR[1:]))
            assert_allclose(reg.cost[i, j], j_want, rtol=1e-11)


@pytest.mark.parametrize(
    "design, rates",
    [
        (fa.OnlineDesign(1), (1.0, 0.0)),
        (fa.OnlineDesign(2), (1.0, 0.0)),
        (fa.OnlineDesign(3, 0.5), (0.7, 0.2)),
    ],
    ids=str,
)
def test_unattacked_online_sensor_with_high_power_arriving_is_stable_everywhere(design, rates):
    """Without attack every z0 (z0 + 1 when mu < 1) losses in a row bring a flag-ACK and a
    high-power packet that arrives: tau <= z0 + 1, K0 is nilpotent, the index is 0 at every
    (p, q), whatever the low-power rates."""
    reg = stability_region(S, design, p=GRID, q=GRID, lam_good=rates[0], lam_bad=rates[1])
    assert_allclose(reg.index, 0.0, atol=1e-15)
    assert reg.stable.all() and np.isfinite(reg.cost).all()


def test_online_z0_one_closed_form():
    """z0 = 1, GilbertElliott(p, q, 1, 0), high power always arriving: a low-power step in the bad
    state is lost and brings a flag-ACK, the next step is at high power and arrives; every other
    step arrives. So tau is 0 or 1 and J = tr_0 + y (tr_1 - tr_0), y the stationary probability of
    (low power, bad). With x, u, v those of (low, good), (high, good), (high, bad):
    u = q y, v = (1 - q) y, and y + v = pi_bad = p/(p+q) give y = p / ((p + q)(2 - q))."""
    reg = stability_region(S, fa.OnlineDesign(1), p=GRID, q=GRID)
    p, q = np.meshgrid(GRID, GRID, indexing="ij")
    y = p / ((p + q) * (2 - q))
    assert_allclose(reg.cost, TR[0] + y * (TR[1] - TR[0]), rtol=1e-12)


@pytest.mark.parametrize(
    "sched, attack",
    [
        (fa.OnlineDesign(2), None),
        (fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5)),
        (fa.OnlineDesign(2, 0.6), fa.RandomBlocking(0.4)),
        (fa.OfflineSchedule("1/7"), None),
    ],
    ids=str,
)
def test_iid_line_gives_todays_values(sched, attack):
    """On p + q = 1 with high_good = high_bad = 1 the channel is the paper's with lam = q lam_good +
    p lam_bad: the region's J there is today's structured J (j_online, j_attack, j_offline) to
    1e-12, and its index the one-state engine's."""
    grid = np.array([0.25, 0.5, 0.75])  # p + q = 1 exactly in binary floating point
    reg = stability_region(S, sched, attack, p=grid, q=grid, lam_good=0.6, lam_bad=0.1)
    for i, p in enumerate(grid):
        j = len(grid) - 1 - i
        lam = (1 - p) * 0.6 + p * 0.1
        if isinstance(sched, fa.OfflineSchedule):
            want = fa.j_offline(S, lam, sched.ratio)
        else:
            want = fa.j_attack(S, lam, sched.z0, mu=sched.mu, attack=attack or fa.PeriodicBlocking(0, 1))
        assert_allclose(reg.cost[i, j], want, rtol=1e-12)
        assert_allclose(
            reg.index[i, j], fa.Scenario(S, lam, sched, attack).stability_index(), rtol=1e-12, atol=1e-15
        )


def test_iid_line_with_lossy_high_power_has_the_bernoulli_index():
    """high_good = high_bad = 0.5 and the always-low-in-the-bad-state rates: on p + q = 1 the
    index is that of the one-state channel with low = lam, high = 0.5."""
    grid = np.array([0.25, 0.5, 0.75])
    reg = stability_region(
        S, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 3), p=grid, q=grid, high_good=0.5, high_bad=0.5
    )
    for i, p in enumerate(grid):
        one = fa.MarkovChannel([[1.0]], [1 - p], [0.5])
        sc = fa.Scenario(S, one, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 3))
        assert_allclose(reg.index[i, len(grid) - 1 - i], sc.stability_index(), rtol=1e-12)
        assert_allclose(reg.cost[i, len(grid) - 1 - i], sc.cost(), rtol=1e-12)


def test_the_point_without_a_channel_is_masked_and_nothing_is_nan():
    """p = q = 0 is no channel (two closed classes): masked, not evaluated, not stable. p = 0 makes
    the good state absorbing (every packet arrives: J = tr_0); q = 0 the bad one (nothing arrives:
    rho(K0) = 1, the engine refuses it, the index is rho(A)^2 and J is infinite)."""
    reg = stability_region(S, fa.OfflineSchedule(pattern="0"), p=[0.0, 0.5], q=[0.0, 0.4])
    assert reg.evaluated.tolist() == [[False, True], [True, True]]
    assert np.ma.getmaskarray(reg.index).tolist() == [[True, False], [False, False]]
    assert not reg.stable[0, 0]
    assert_allclose(reg.index[0, 1], 0.0, atol=1e-15)
    assert_allclose(reg.cost[0, 1], TR[0], rtol=1e-12)
    assert reg.index[1, 0] == RHO2 and reg.cost[1, 0] == math.inf and not reg.stable[1, 0]
    for field in (reg.index, reg.cost):
        assert not np.isnan(np.ma.getdata(field)).any()


def test_no_arrival_with_a_stable_system_leaves_the_cost_masked():
    """rho(A) < 1 with rho(K0) = 1: J is the limit of an ever-growing holding time, which the
    engine does not compute; the index rho(A)^2 < 1 says it is finite."""
    stable = fa.LinearSystem(0.9, 1.0, 1.0, 1.0)
    reg = stability_region(stable, fa.OfflineSchedule(pattern="0"), p=[0.5], q=[0.0, 0.5])
    assert_allclose(reg.index[0, 0], 0.81, rtol=1e-12)
    assert reg.stable.all() and np.ma.getmaskarray(reg.cost).tolist() == [[True, False]]
    assert reg.evaluated.all()


def test_the_result_object():
    reg = stability_region(S, fa.OnlineDesign(2), "1/5", p=[0.1, 0.5], q=[0.3])
    assert isinstance(reg, StabilityRegion) and reg.shape == (2, 1)
    assert reg.attack == fa.PeriodicBlocking(1, 5) and reg.schedule == fa.OnlineDesign(2)
    assert reg.channel(1, 0) == fa.GilbertElliott(0.5, 0.3, 1.0, 0.0)
    assert reg.rho_a2 == pytest.approx(RHO2, rel=1e-14)
    with pytest.raises(dataclasses.FrozenInstanceError):
        reg.p = GRID
    with pytest.raises(ValueError):
        reg.p[0] = 0.2  # read-only arrays
    html = reg._repr_html_()
    assert "StabilityRegion" in html and "block 1 of every 5" in html and "2 of 2" in html
    assert_allclose(DEFAULT_GRID, np.arange(1, 51) / 50, rtol=1e-15)
    full = stability_region(S, fa.OnlineDesign(1))
    assert full.shape == (50, 50) and full.evaluated.all()


def test_ctrl_c_stops_the_grid(monkeypatch):
    """Each point is a few engine calls; a KeyboardInterrupt raised between two of them ends the
    region at once (the progress bar is closed)."""
    calls = []
    real = stability.Scenario

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 4:  # the argument check, then three points
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    closed = []
    monkeypatch.setattr(stability, "Scenario", interrupted)
    monkeypatch.setattr(stability._Bar, "close", lambda self: closed.append(True))
    with pytest.raises(KeyboardInterrupt):
        stability_region(S, fa.OnlineDesign(2), p=GRID, q=GRID, progress=True)
    assert len(calls) == 4 and closed == [True]


def test_progress_bar_over_the_points(monkeypatch, capsys):
    pytest.importorskip("tqdm")
    clock = iter(range(0, 10_000, 5))
    monkeypatch.setattr(stability.time, "monotonic", lambda: float(next(clock)))
    stability_region(S, fa.OnlineDesign(2), p=[0.2, 0.4], q=[0.3, 0.6], progress=True)
    assert "fakeack stability_region" in capsys.readouterr().err
    stability_region(S, fa.OnlineDesign(2), p=[0.2, 0.4], q=[0.3, 0.6], progress=False)
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(
    "kwargs, exc, arg",
    [
        (dict(p="0.5"), TypeError, "p"),
        (dict(q=[True, False]), TypeError, "q"),
        (dict(p=[[0.1, 0.2]]), ValueError, "p"),
        (dict(p=[]), ValueError, "p"),
        (dict(q=[0.2, 1.5]), ValueError, "q"),
        (dict(q=[-0.1, 0.5]), ValueError, "q"),
        (dict(p=[0.5, np.nan]), ValueError, "p"),
        (dict(p=[0.5, 0.2]), ValueError, "p"),
        (dict(p=[0.2, 0.2]), ValueError, "p"),
        (dict(p=[[0.1], [0.2, 0.3]]), ValueError, "p"),
        (dict(lam_good=1.5), ValueError, "lam_good"),
        (dict(lam_bad="x"), TypeError, "lam_bad"),
        (dict(high_good=-1.0), ValueError, "high_good"),
        (dict(high_bad=None), TypeError, "high_bad"),
        (dict(max_states=0), ValueError, "max_states"),
        (dict(schedule="1/7"), TypeError, "schedule"),
        (dict(attack=[1, 0]), TypeError, "attack"),
        (dict(schedule=fa.OfflineSchedule("1/7"), attack="1/5"), ValueError, "attack"),
        (dict(system="S"), TypeError, "system"),
    ],
)
def test_bad_input_names_the_argument(kwargs, exc, arg):
    args = dict(system=S, schedule=fa.OnlineDesign(2), attack=None, p=GRID, q=GRID) | kwargs
    with pytest.raises(exc, match=names(arg)):
        stability_region(**args)
