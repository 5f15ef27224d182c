"""fa.attack_effort: which attack raises J most per unit of attacker energy.

Expected values come from derivations independent of the code: the consecutive-blocking limit's
mixture of the attack-free and the all-blocked regimes (J and the flag rates linear in the time
share), the renewal rate of flag-ACKs with every packet at low power, Theorem 4.5's J_on,
Proposition 3.1's J_off, the all-blocked J_max, and the law of the holding time carried through
an offline period step by step.
"""

from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER, PAPER_LAM, PAPER_RATIO
from fakeack.optimal.effort import KINDS, attack_effort, jam_high_channel
from fakeack.plots.effort import plot_attack_effort

S = fa.LinearSystem(**PAPER)
A_LOSS = 1 - PAPER_LAM
Z0 = 2  # design_online(0.5, 1/7) = (2, 1)
#: Flag-ACKs per step with every packet at low power: a flag after z0 losses in a row, the
#: detector's count restarting at every arrival and every flag (renewal: mean gap
#: (1 - a^z0) / ((1 - a) a^z0)).
FULL_RATE = (1 - A_LOSS) * A_LOSS**Z0 / (1 - A_LOSS**Z0)
FREE_RATE = 1 / 7  # attack-free: the flag rate is the high-power rate, the energy ratio
J_ON = fa.j_online(S, PAPER_LAM, Z0, 1.0)
J_MAX = fa.j_max(S, PAPER_LAM)
J_OFF = fa.j_offline(S, PAPER_LAM, PAPER_RATIO)
EFFORTS = [0.0, 0.02, 0.5 * FULL_RATE, 0.12]


@pytest.fixture(scope="module")
def res():
    return attack_effort(S, PAPER_LAM, PAPER_RATIO, EFFORTS, block_cost=0.8)


def test_zero_effort_gives_the_attack_free_cost_for_every_kind(res):
    assert res.kinds == KINDS
    assert res.j[:, 0] == pytest.approx(np.full(len(KINDS), J_ON), rel=1e-10)
    assert res.j_online == pytest.approx(J_ON, rel=1e-12)
    assert res.j_offline == pytest.approx(J_OFF, rel=1e-12)
    assert res.best[0] == "none" and res.best_fallback[0] == "none"


def test_j_grows_with_effort_and_the_energy_is_the_effort(res):
    assert np.all(np.diff(res.j, axis=1) >= -1e-12)
    for row in res.options:
        for o in row:
            assert o.spent <= o.effort * (1 + 1e-9) + 1e-15
            saturated = o.budget == 1.0 or o.kind == "forge"
            if not saturated:
                assert o.spent == pytest.approx(o.effort, rel=1e-9, abs=1e-15)


def test_every_point_is_its_attack_evaluated_by_the_scenario(res):
    for row in res.options:
        for o in row:
            assert fa.Scenario(S, o.channel, res.design, o.attack).cost() == pytest.approx(o.j, rel=1e-10)


def test_blocking_follows_the_mixture_of_the_free_and_the_all_blocked_regimes(res):
    # The worst blocking on the paper's example is the consecutive-blocking limit: a share w of
    # the time with every flag blocked (rate FULL_RATE, cost J_max), the rest attack-free. So
    # blocked flags per step w FULL_RATE = effort / block_cost, J = J_on + w (J_max - J_on).
    i = res.kinds.index("block")
    for o in res.options[i]:
        w = min(1.0, o.effort / 0.8 / FULL_RATE)
        assert o.j == pytest.approx(J_ON + w * (J_MAX - J_ON), rel=1e-9)
        sent = w * FULL_RATE + (1 - w) * FREE_RATE
        assert o.budget == pytest.approx(w * FULL_RATE / sent, rel=1e-9, abs=1e-12)  # beta
        rates = fa.Scenario(S, PAPER_LAM, res.design, o.attack).flag_rates()
        assert rates.sent == pytest.approx(sent, rel=1e-9)
        assert 0.8 * rates.blocked == pytest.approx(o.spent, rel=1e-12, abs=1e-15)


def test_reactive_jamming_at_p_equal_to_the_loss_probability_gives_j_max(res):
    # Jamming each high-power step with probability 1 - lam makes high power arrive as often as
    # low: the sensor's power no longer matters, J = J_max and high power runs at the all-low
    # flag rate, so the energy is (1 - lam) FULL_RATE = EFFORTS[2].
    o = res.options[res.kinds.index("jam-high")][2]
    assert o.budget == pytest.approx(A_LOSS, rel=1e-9)
    assert o.j == pytest.approx(J_MAX, rel=1e-9)
    assert res.best[2] == "jam-high"


def test_blind_jamming_is_the_channel_with_every_arrival_scaled():
    r = 0.05
    res = attack_effort(S, PAPER_LAM, PAPER_RATIO, [r * 2.0], jam_cost=2.0, kinds=("jam",))
    o = res.options[0][0]
    assert o.budget == pytest.approx(r) and o.spent == pytest.approx(2 * r)
    scaled = fa.MarkovChannel([[1.0]], [(1 - r) * PAPER_LAM], [1 - r])
    assert o.j == pytest.approx(fa.Scenario(S, scaled, res.design).cost(), rel=1e-10)
    # The offline schedule under the same jamming: the law of tau carried through the period.
    assert o.j_offline == pytest.approx(_offline_jammed(r), rel=1e-9)
    assert o.j_fallback == min(o.j, o.j_offline)


def _offline_jammed(r, periods=200, depth=400):
    pattern = fa.offline_schedule(PAPER_RATIO)
    tr = S.h_traces(depth)
    law = np.zeros(depth + 1)
    law[0] = 1.0
    total = 0.0
    for p in range(periods):
        for level in pattern:
            arrive = (1 - r) * (1.0 if level else PAPER_LAM)
            new = np.zeros_like(law)
            new[0] = arrive * law.sum()
            new[1:] = (1 - arrive) * law[:-1]
            new[-1] += (1 - arrive) * law[-1]
            law = new
            if p == periods - 1:
                total += float(law @ tr)
    return total / len(pattern)


def test_forging_alone_never_raises_j(res):
    for o in res.options[res.kinds.index("forge")]:
        assert o.j == pytest.approx(J_ON, rel=1e-10) and o.spent == 0.0


def test_fall_back_caps_flag_ack_attacks_at_j_off(res):
    i = res.kinds.index("block")
    assert res.j_fallback[i] == pytest.approx(np.minimum(res.j[i], J_OFF), rel=1e-12)
    # 0.12 blocks enough for J above J_off: the fall-back then holds J_off, reactive jamming
    # still rises above it.
    assert res.j[i, 3] > J_OFF and res.j_fallback[i, 3] == pytest.approx(J_OFF)
    assert res.best_fallback[3] == "jam-high" and res.j_best_fallback[3] > J_OFF


def test_default_efforts_run_to_the_energy_of_blocking_every_flag():
    res = attack_effort(S, PAPER_LAM, Fraction(1, 7), kinds=("block",))
    assert res.effort[-1] == pytest.approx(FULL_RATE, rel=1e-9) and res.effort.size == 11
    assert res.j[0, -1] == pytest.approx(J_MAX, rel=1e-9)


def test_jam_high_channel_scales_only_high_power():
    ch = jam_high_channel(fa.GilbertElliott(0.1, 0.3, 0.9, 0.2), 0.25)
    assert ch.low.tolist() == [0.9, 0.2] and ch.high.tolist() == [0.75, 0.75]
    with pytest.raises(ValueError, match="^p "):
        jam_high_channel(0.5, 1.5)


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        (dict(efforts=[-0.1]), ValueError, "^efforts"),
        (dict(efforts=[]), ValueError, "^efforts"),
        (dict(efforts=[float("nan")]), ValueError, "^efforts"),
        (dict(efforts=["a"]), TypeError, "^efforts"),
        (dict(jam_cost=0.0), ValueError, "^jam_cost"),
        (dict(block_cost=-1.0), ValueError, "^block_cost"),
        (dict(forge_cost="1"), TypeError, "^forge_cost"),
        (dict(kinds=("jam", "bribe")), ValueError, "^kinds"),
        (dict(kinds="jam"), TypeError, "^kinds"),
        (dict(kinds=()), ValueError, "^kinds"),
    ],
)
def test_bad_arguments_are_named(kwargs, exc, match):
    kwargs.setdefault("efforts", [0.0])
    with pytest.raises(exc, match=match):
        attack_effort(S, PAPER_LAM, PAPER_RATIO, **kwargs)


def test_bad_ratio_is_named():
    with pytest.raises(ValueError, match="^ratio"):
        attack_effort(S, PAPER_LAM, 1.5, [0.0])


def test_plot_draws_one_curve_per_kind_and_the_references(res):
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    fig = plot_attack_effort(res)
    (ax,) = fig.axes
    assert len(ax.lines) == len(res.kinds) + 2
    fig2 = Figure()
    ax2 = fig2.add_subplot()
    assert plot_attack_effort(res, ax2, fallback=True) is fig2
    np.testing.assert_allclose(ax2.lines[2].get_ydata(), res.j_fallback[2])
    with pytest.raises(TypeError, match="^result"):
        plot_attack_effort(object())  # type: ignore[arg-type]


def test_saturated_jamming():
    from fakeack.attacks import Jamming

    res = attack_effort(S, PAPER_LAM, PAPER_RATIO, [2.0], kinds=("jam", "jam-high"))
    jam, high = (row[0] for row in res.options)
    assert jam.budget == 1.0 and jam.spent == 1.0 and jam.j == jam.j_offline == np.inf  # rho(A) > 1
    # Every high-power step jammed: the offline schedule loses its high-power step each period,
    # the periodic jamming pattern of the same phase.
    assert high.budget == 1.0 and high.spent < 2.0
    off = fa.OfflineSchedule(pattern="1000000")
    assert high.j_offline == pytest.approx(
        fa.Scenario(S, PAPER_LAM, off, Jamming("1000000")).cost(), rel=1e-10
    )
    stable = fa.LinearSystem(A=0.9, C=0.7, Q=0.8, R=0.8)
    jam = attack_effort(stable, PAPER_LAM, PAPER_RATIO, [2.0], jam_cost=2.0, kinds=("jam",)).options[0][0]
    assert jam.j == pytest.approx(0.8 / (1 - 0.81), rel=1e-12)  # Tr X_inf, X = A X A' + Q
