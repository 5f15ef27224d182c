"""``fakeack analyze``, ``sweep``, ``simulate`` and ``game`` under a channel that is not the paper's.

Two independent checks. The i.i.d. reduction: a Gilbert-Elliott channel with p + q = 1 and
high_good = high_bad = 1 draws its state afresh at every step, so it is the paper's channel with
lam = pi_good lam_good + pi_bad lam_bad (pi_good = q/(p+q)); every number the commands print for it
must equal the i.i.d. ones to 1e-12, although they come from other code (the engine, the Markov
renewal, the automaton Monte Carlo) than the i.i.d. formulas. And under a bursty channel, the values
against the exact engine (``fa.Scenario``) and the closed-form stability condition.
"""

import json
import math
from fractions import Fraction

import pytest

import fakeack as fa
from conftest import PAPER
from fakeack import cli

HAS_SIMULATE = hasattr(fa._fakeack, "simulate")
needs_simulate = pytest.mark.skipif(not HAS_SIMULATE, reason="compiled core has no simulate yet")

SYSTEM = """
[system]
A = 1.2
C = 0.7
Q = 0.8
R = 0.8
"""
REST = """
[energy]
ratio = "1/7"

[attack]
betas = ["1/5", "2/3"]
random = [0.2]
inject = [0.05]

[attack.sweep]
t_max = 12
"""
# p + q = 1: memory 0. pi_good = 0.7, so lam = 0.7 * 0.8 + 0.3 * 0.1 = 0.59.
MEMORYLESS = "ge:0.3,0.7,0.8,0.1"
MEMORYLESS_LAM = 0.7 * 0.8 + 0.3 * 0.1
MEMORYLESS_SECTION = """
[channel]
kind = "gilbert-elliott"
p = 0.3
q = 0.7
lam_good = 0.8
lam_bad = 0.1
"""
BURSTY = fa.GilbertElliott(0.1, 0.1, 1.0, 0.0)
BURSTY_SECTION = """
[channel]
kind = "gilbert-elliott"
p = 0.1
q = 0.1
lam_good = 1.0
lam_bad = 0.0
"""


def run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def run_json(capsys, *argv):
    rc, out, err = run(capsys, *argv, "--json")
    assert rc == 0, err
    return json.loads(out)


def close(a, b, rel=1e-12):
    if a is None or b is None or math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= rel * max(1.0, abs(b))


@pytest.fixture
def configs(tmp_path):
    paths = {}
    for name, head in (
        ("memoryless", SYSTEM + MEMORYLESS_SECTION),
        ("iid", SYSTEM + f"lam = {MEMORYLESS_LAM!r}\n"),
        ("bursty", SYSTEM + BURSTY_SECTION),
        ("paper", SYSTEM + "lam = 0.5\n"),
    ):
        paths[name] = tmp_path / f"{name}.toml"
        paths[name].write_text(head + REST)
    return paths


# ------------------------------------------------------------------------------ analyze


def test_analyze_memoryless_channel_is_the_iid_one(capsys, configs):
    ge = run_json(capsys, "analyze", configs["memoryless"])
    iid = run_json(capsys, "analyze", configs["iid"])
    assert ge["lam"] is None and ge["channel"]["kind"] == "gilbert-elliott" and ge["channel"]["memory"] == 0
    assert ge["iid"]["lam"] == pytest.approx(MEMORYLESS_LAM, abs=1e-15)
    assert (iid["channel"]["kind"], iid["channel"]["paper"]) == ("bernoulli", True)
    # The channel's own column (engine, renewal) against the i.i.d. analysis of the same mean.
    assert ge["online"]["z0"] == iid["online"]["z0"] and close(ge["online"]["mu"], iid["online"]["mu"])
    assert close(ge["online"]["high_power_rate"], 1 / 7)
    for mine, theirs in zip(ge["rows"], iid["rows"], strict=True):
        assert mine["key"] == theirs["key"]
        assert close(mine["analytic"], theirs["analytic"]), mine["key"]
        assert close(mine["exact_h"], theirs["exact_h"]), mine["key"]
    assert ge["beta_bar"]["finite"] == iid["beta_bar"]["finite"]
    assert close(ge["beta_bar"]["limit"], iid["beta_bar"]["limit"])
    for mine, theirs in zip(ge["decisions"], iid["decisions"], strict=True):
        assert close(mine["j_attack_limit"], theirs["j_attack_limit"])
    for row in ge["other_attacks"]["rows"]:
        assert close(row["j"], row["j_iid"]), row["attack"]
    assert close(ge["other_attacks"]["beta_bar_random"], ge["other_attacks"]["beta_bar_random_iid"])
    # ... and the twin column is the i.i.d. analysis itself.
    assert [r["analytic"] for r in ge["iid"]["rows"]] == [r["analytic"] for r in iid["rows"]]
    assert ge["iid"]["beta_bar"] == iid["beta_bar"]


def test_analyze_bursty_channel(capsys, configs, tmp_path):
    """GE(0.1, 0.1, 1, 0) on the paper's system: J_max is infinite because the bad state alone
    loses every low-power packet and lasts 1/q steps, (1 - q) rho(A)^2 = 0.9 * 1.44 >= 1 (docs
    page "Bursty channels"), so the large-period threshold is 0. Costs against the engine."""
    s = fa.LinearSystem(**PAPER)
    text = configs["bursty"].read_text() + "\n[montecarlo]\nruns = 400\nhorizon = 30\nseed = 2\n"
    configs["bursty"].write_text(text)
    d = run_json(capsys, "analyze", configs["bursty"])
    design = fa.OnlineDesign(d["online"]["z0"], d["online"]["mu"])
    rows = {r["key"]: r for r in d["rows"]}
    assert close(fa.Scenario(s, BURSTY, design).high_power_rate(), 1 / 7)
    assert close(rows["j_online"]["analytic"], fa.Scenario(s, BURSTY, design).cost(), 1e-9)
    blocked = fa.Scenario(s, BURSTY, design, fa.PeriodicBlocking(1, 5)).cost()
    assert close(rows["j_attack_1/5"]["analytic"], blocked, 1e-9)
    assert d["offline_schedule"] == [1, 0, 0, 0, 0, 0, 0]
    offline = fa.Scenario(s, BURSTY, fa.OfflineSchedule(pattern="1000000")).cost()
    assert close(rows["j_offline"]["analytic"], offline, 1e-9)
    assert 0.9 * 1.2**2 >= 1 and d["j_max"] is None and rows["j_max"]["analytic"] is None  # inf in JSON
    assert d["beta_bar"]["limit"] == 0.0 and rows["j_max"]["exact_h"] > 0
    assert d["montecarlo"]["runs"] == 400 and d["flagged"] == []
    assert all(rows[k]["mc"] is not None for k in ("j_offline", "j_online", "j_attack_1/5"))
    # The i.i.d. column is the analysis of the paper's lam = 0.5, and the i.i.d. design overspends.
    paper = run_json(capsys, "analyze", configs["paper"])
    assert [r["analytic"] for r in d["iid"]["rows"]] == [r["analytic"] for r in paper["rows"]]
    assert (d["iid"]["online"]["z0"], d["iid"]["online"]["mu"]) == (
        paper["online"]["z0"],
        paper["online"]["mu"],
    )
    iid_design = fa.OnlineDesign(paper["online"]["z0"], paper["online"]["mu"])
    over = fa.Scenario(s, BURSTY, iid_design).high_power_rate()
    assert close(d["iid"]["design_under_channel"]["high_power_rate"], over, 1e-9) and over > 1 / 7

    rc, out, err = run(capsys, "analyze", configs["bursty"], "--out", tmp_path / "res", "--no-figures")
    assert rc == 0, err
    lines = out.splitlines()
    assert lines[2].startswith(
        "  channel Gilbert-Elliott p=0.1, q=0.1, lam_good=1, lam_bad=0 (memory 1-p-q = 0.8"
    )
    head = next(line for line in lines if line.startswith("quantity"))
    assert head.endswith("i.i.d. lam=0.5") and "MC J_H" in head
    jmax = next(line for line in lines if line.startswith("J_max"))
    assert jmax.split()[3] == "inf" and jmax.split()[-1] == f"{paper['j_max']:.6f}"
    assert "J_max = inf" in out and "J (i.i.d.)" in out
    saved = json.loads((tmp_path / "res" / "analysis.json").read_text())
    assert saved["iid"] == d["iid"] and saved["channel"] == d["channel"]


def test_analyze_given_schedule_and_one_state_twin(capsys, tmp_path):
    """With high_bad < 1 the twin is one state with high = pi . high, not the paper's channel; a
    given (z0, mu) is kept for both columns."""
    path = tmp_path / "c.toml"
    path.write_text(
        SYSTEM
        + BURSTY_SECTION.replace("q = 0.1", "q = 0.4")
        + "high_bad = 0.5\n"
        + '[energy]\nratio = "1/5"\n'
        "[online]\nz0 = 2\nmu = 0.5\n"
    )
    d = run_json(capsys, "analyze", path)
    twin = d["iid"]["channel"]
    # pi_good = q/(p+q) = 0.8: mean low 0.8, mean high 0.8 + 0.2 * 0.5 = 0.9.
    assert twin["kind"] == "markov" and twin["paper"] is False
    assert twin["low"] == pytest.approx([0.8], abs=1e-15) and twin["high"] == pytest.approx([0.9], abs=1e-15)
    assert (d["online"]["z0"], d["online"]["mu"], d["online"]["designed"]) == (2, 0.5, False)
    assert (d["iid"]["online"]["z0"], d["iid"]["online"]["mu"]) == (2, 0.5)
    one_state = fa.MarkovChannel([[1.0]], [0.8], [0.9])
    expected = fa.Scenario(fa.LinearSystem(**PAPER), one_state, fa.OnlineDesign(2, 0.5)).cost()
    assert close(d["iid"]["j_online"], expected, 1e-9)


# ------------------------------------------------------------------------------ sweep and simulate


def test_sweep_channel(capsys, configs):
    ge = run_json(capsys, "sweep", "--t-max", 6, "--channel", MEMORYLESS)
    iid = run_json(capsys, "sweep", "--t-max", 6, "--lam", MEMORYLESS_LAM)
    assert ge["lam"] is None and ge["channel"]["kind"] == "gilbert-elliott" and iid["channel"]["paper"]
    assert ge["z0"] == iid["z0"] and close(ge["mu"], iid["mu"]) and ge["count"] == iid["count"] == 11
    for mine, theirs in zip(ge["points"], iid["points"], strict=True):
        assert (mine["r"], mine["t"], mine["better"]) == (theirs["r"], theirs["t"], theirs["better"])
        assert close(mine["j_attack"], theirs["j_attack"]) and close(
            mine["j_attack_limit"], theirs["j_attack_limit"]
        )
    assert close(ge["beta_bar"]["limit"], iid["beta_bar"]["limit"])
    # --channel with --config replaces the config's channel (and designs for it).
    from_config = run_json(
        capsys, "sweep", "--t-max", 6, "--config", configs["paper"], "--channel", MEMORYLESS
    )
    assert from_config["points"] == ge["points"]
    rc, out, _ = run(capsys, "sweep", "--t-max", 6, "--channel", "ge:0.1,0.1,1,0")
    assert rc == 0 and "channel Gilbert-Elliott p=0.1" in out and "J_max = inf" in out
    rc, _, err = run(capsys, "sweep", "--channel", MEMORYLESS, "--lam", 0.5)
    assert rc == 2 and "give either --channel or --lam" in err
    rc, _, err = run(capsys, "sweep", "--channel", "ge:0.1,0.1,1")
    assert (
        rc == 2 and err.startswith("fakeack: error: --channel: ge takes 4 values") and "Traceback" not in err
    )


@needs_simulate
def test_simulate_channel(capsys):
    args = ("simulate", "--attack", "1/5", "--runs", 2000, "--horizon", 40, "--seed", 4)
    ge = run_json(capsys, *args, "--channel", MEMORYLESS)
    iid = run_json(capsys, *args, "--lam", MEMORYLESS_LAM)
    assert ge["lam"] is None and ge["channel"]["p"] == 0.3 and iid["lam"] == MEMORYLESS_LAM
    assert close(ge["stationary_j"], iid["stationary_j"]) and close(ge["exact_j_h"], iid["exact_j_h"])
    assert abs(ge["j"] - ge["exact_j_h"]) <= 4 * ge["stderr"]
    off = run_json(
        capsys,
        "simulate",
        "--schedule",
        "offline",
        "--runs",
        500,
        "--horizon",
        30,
        "--channel",
        "ge:0.1,0.1,1,0",
    )
    s = fa.LinearSystem(**PAPER)
    assert off["schedule"] == "offline pattern: 1000000"
    assert close(
        off["stationary_j"], fa.Scenario(s, BURSTY, fa.OfflineSchedule(pattern="1000000")).cost(), 1e-9
    )
    assert abs(off["j"] - off["exact_j_h"]) <= 4 * off["stderr"]


# ------------------------------------------------------------------------------ game

GAME = """
[game]
n_steps = 200
alphas = [0.01]
fallbacks = [2]
tests = ["count"]
rules = ["any"]
attacks = ["none", "1/5"]
t_max = 4
grid = 5
runs = 0
"""


def test_game_takes_iid_channels_only(capsys, configs, tmp_path):
    rc, out, err = run(capsys, "game", "--channel", "ge:0.1,0.1,1,0")
    assert rc == 2 and out == "" and "fakeack game takes the paper's i.i.d. channel only" in err
    bursty = tmp_path / "bursty_game.toml"
    bursty.write_text(configs["bursty"].read_text() + GAME)
    rc, out, err = run(capsys, "game", bursty)
    assert rc == 2 and err.startswith("fakeack: error: config: [channel]: fakeack game takes") and out == ""
    d = run_json(capsys, "game", bursty, "--channel", "bernoulli:0.6")
    assert d["lam"] == 0.6 and d["config"].endswith("with --channel bernoulli:0.6")
    z0, mu = fa.design_online(0.6, Fraction(1, 7))
    assert close(d["j_online"], fa.j_online(fa.LinearSystem(**PAPER), 0.6, z0, mu), 1e-9)
