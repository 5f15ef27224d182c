"""``fakeack optimal``: its numbers are the library's (and, where a closed form exists, the closed
form's), its ``[optimal]`` errors name their keys, ``--json`` round-trips and ``--example`` reads
back through standard input."""

import io
import json
import math
import sys
from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER
from fakeack import cli
from fakeack.config import loads, parse_config
from fakeack.config.optimal import example_text, parse_optimal

BASE = """
[system]
A = 1.2
C = 0.7
Q = 0.8
R = 0.8
lam = 0.5

[energy]
ratio = "1/7"
"""
#: A small [optimal] section that keeps the run short: the budget of the paper's ratio 1/7.
SMALL = """
[optimal]
budgets = ["9/7", "6/5"]
betas = [0.5, "1/5"]
jam_rates = [0.1]
horizon = 8
n_jams = [1, 3]
"""


def run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def run_config(capsys, tmp_path, text, *flags):
    path = tmp_path / "optimal.toml"
    path.write_text(text, encoding="utf-8")
    return run(capsys, "optimal", path, *flags)


def traces(system, n):
    """tr_i = Tr h^i(Pbar), i = 0..n, by iterating h(X) = AXA' + Q."""
    X, out = np.array(system.pbar), []
    for _ in range(n + 1):
        out.append(float(np.trace(X)))
        X = system.A @ X @ system.A.T + system.Q
    return out


def j_online_fixed(system, lam, z0):
    """Theorem 4.5 with mu = 1 (Model note 2): lam / (1 - a^(z0+1)) sum_{i<=z0} a^i tr_i."""
    a, tr = 1.0 - lam, traces(system, z0)
    return lam / (1.0 - a ** (z0 + 1)) * sum(a**i * tr[i] for i in range(z0 + 1))


def jam_cost(system, lam, jammed, T):
    """(1/T) sum_k Tr E[P_k] from tau_0 = 0, by carrying the law of tau step by step."""
    tr = traces(system, T)
    law = np.zeros(T + 1)
    law[0] = 1.0
    total = 0.0
    for k in range(1, T + 1):
        q = 0.0 if k in jammed else lam
        new = np.zeros(T + 1)
        new[0] = q * law.sum()
        new[1:] = (1.0 - q) * law[:-1]
        law = new
        total += float(law @ np.array(tr))
    return total / T


@pytest.fixture
def small(capsys, tmp_path):
    rc, out, err = run_config(capsys, tmp_path, BASE + SMALL, "--json")
    assert rc == 0, err
    return json.loads(out)


# ------------------------------------------------------------------------------ the numbers


def test_power_rows_are_the_librarys(small):
    s = fa.LinearSystem(**PAPER)
    for row, budget in zip(small["power"], (Fraction(9, 7), Fraction(6, 5)), strict=True):
        res = fa.optimal_power_policy(s, 0.5, [(1.0, 0.5), (3.0, 1.0)], float(budget))
        assert row["budget"] == str(budget) and row["share"] == str((budget - 1) / 2)
        assert row["j"] == res.j and row["j_lp"] == res.j_lp and row["policy"] == str(res.policy)
        design = fa.design_online(0.5, (budget - 1) / 2)
        assert row["online"] == {"z0": design.z0, "mu": design.mu}
        assert row["j_online"] == fa.j_online(s, 0.5, design.z0, design.mu)
    # Independently: at p/q = 1/7 the LP's policy is the online schedule z0 = 2, mu = 1, whose J
    # is Theorem 4.5's closed form.
    assert small["power"][0]["online"] == {"z0": 2, "mu": 1.0}
    assert small["power"][0]["j"] == pytest.approx(j_online_fixed(s, 0.5, 2), rel=1e-10)
    assert small["power"][0]["j_online"] == pytest.approx(j_online_fixed(s, 0.5, 2), rel=1e-12)


def test_attack_rows_are_the_librarys(small):
    s = fa.LinearSystem(**PAPER)
    for row, beta in zip(small["attack"], (0.5, 0.2), strict=True):
        w = fa.worst_attack(s, 0.5, fa.OnlineDesign(2), beta)
        assert row["beta"] == beta
        assert (row["j"], row["j_lp"], row["blocked_fraction"]) == (w.j, w.j_lp, w.blocked_fraction)
        assert row["policy"] == str(w.policy)
        assert row["j_limit"] == fa.j_attack_limit(s, 0.5, 2, beta)
        # A second derivation: on this example consecutive blocking's limit is the worst attack.
        assert row["j"] == pytest.approx(row["j_limit"], rel=1e-9)
        assert row["blocked_fraction"] == pytest.approx(beta, abs=1e-9)


def test_jamming_rows_are_the_librarys(small):
    s = fa.LinearSystem(**PAPER)
    jam = small["jamming"]
    assert jam["horizon"] == 8
    for row, n in zip(jam["finite"], (1, 3), strict=True):
        r = fa.optimal_jamming(s, 0.5, n_jams=n, horizon=8)
        assert (row["n_jams"], row["j"], row["method"]) == (n, r.j, r.method)
        assert tuple(row["jammed_steps"]) == r.jammed_steps
    # Independently: the best single jam of 8 steps, by the law of tau written out here.
    best = max(jam_cost(s, 0.5, {m}, 8) for m in range(1, 9))
    assert jam["finite"][0]["j"] == pytest.approx(best, rel=1e-12)
    (lr,) = jam["long_run"]
    r = fa.optimal_jamming(s, 0.5, rate=0.1)
    assert lr["rate"] == 0.1 and lr["method"] == r.method == "unbounded" and lr["j"] is None  # inf


def test_text_prints_the_json_numbers(capsys, tmp_path, small):
    rc, out, _ = run_config(capsys, tmp_path, BASE + SMALL)
    assert rc == 0
    for row in small["power"]:
        assert f"{row['j']:.6f}" in out and row["policy"] in out
    for row in small["attack"]:
        assert f"{row['j']:.6f}" in out and f"{row['j_limit']:.6f}" in out
    assert f"{small['jamming']['finite'][1]['j']:.6f}" in out and "unbounded" in out


def test_gap_law_without_forging_is_the_attack_free_cost(capsys, tmp_path):
    """On an i.i.d. channel the gap law without forging leaves only the attack-free policy."""
    text = BASE + SMALL.replace('betas = [0.5, "1/5"]', 'betas = [0.5]\nstealth = "gap-law"')
    rc, out, err = run_config(capsys, tmp_path, text, "--json")
    assert rc == 0, err
    (row,) = json.loads(out)["attack"]
    s = fa.LinearSystem(**PAPER)
    assert row["j"] == pytest.approx(j_online_fixed(s, 0.5, 2), rel=1e-10)
    assert row["blocked_fraction"] == 0.0


def test_a_channel_the_attack_refuses_leaves_its_table_out(capsys, tmp_path):
    """lam = 0.2: g rho(A)^2 = 0.8 * 1.44 >= 1, which fakeack.worst_attack refuses."""
    text = BASE.replace("lam = 0.5", "lam = 0.2") + SMALL
    rc, out, err = run_config(capsys, tmp_path, text, "--json")
    assert rc == 0, err
    doc = json.loads(out)
    assert doc["attack"] == [] and doc["refused"]["attack"].startswith("channel:")
    assert len(doc["power"]) == 2 and len(doc["jamming"]["finite"]) == 2


# ------------------------------------------------------------------------------ config errors


@pytest.mark.parametrize(
    ("section", "key"),
    [
        ("betas = [1.5]", "betas[0]"),
        ('betas = "1/5"', "betas"),
        ("levels = [[1]]", "levels[0]"),
        ("levels = [[1, 1.5], [3, 1]]", "levels[0] arrival"),
        ("levels = [[1, [0.5, 0.5]], [3, 1]]", "levels[0] arrival"),
        ('levels = [["x", 0.5], [3, 1]]', "levels[0] energy"),
        ("budgets = [0.5]", "budgets[0]"),
        ("budgets = []", "budgets"),
        ('stealth = "loud"', "stealth"),
        ("tau_max = 0", "tau_max"),
        ("tau_max = 5000", "tau_max"),
        ("forge_budget = 2", "forge_budget"),
        ("csi = 1", "csi"),
        ("horizon = 4\nn_jams = [5]", "n_jams[0]"),
        ("n_jams = [-1]", "n_jams[0]"),
        ("jam_rates = [1.1]", "jam_rates[0]"),
        ("betaz = [0.2]", "betaz"),
    ],
)
def test_config_errors_name_the_key(capsys, tmp_path, section, key):
    rc, out, err = run_config(capsys, tmp_path, BASE + "\n[optimal]\n" + section + "\n")
    assert rc == 2 and out == ""
    assert err.startswith(f"fakeack: error: config: [optimal] {key}:"), err


def test_long_run_jamming_on_a_channel_with_memory_is_refused_by_key():
    text = BASE.replace("lam = 0.5", "") + (
        '[channel]\nkind = "gilbert-elliott"\np = 0.1\nq = 0.3\nlam_good = 0.9\nlam_bad = 0.4\n'
    )
    cfg = parse_config(loads(text + "[optimal]\njam_rates = [0.1]\n"))
    with pytest.raises(ValueError, match=r"^config: \[optimal\] jam_rates:"):
        parse_optimal(cfg.raw, cfg.channel_arg, cfg.ratio)
    # Without the key, the long run is left out and the default levels follow the channel.
    cfg = parse_config(loads(text))
    opt = parse_optimal(cfg.raw, cfg.channel_arg, cfg.ratio)
    assert opt.jam_rates == () and opt.levels == ((1, (0.9, 0.4)), (3, (1.0,)))


def test_a_function_refusal_names_the_key(capsys, tmp_path):
    """A horizon too long to evaluate is refused by fakeack.optimal_jamming, named here."""
    rc, _, err = run_config(capsys, tmp_path, BASE + "[optimal]\nhorizon = 3000\nn_jams = [1000]\n")
    assert rc == 2 and err.startswith(
        "fakeack: error: config: [optimal] n_jams[0]: optimal_jamming: horizon = 3000"
    )


# ------------------------------------------------------------------------------ JSON, example, stdin


def test_json_round_trips(capsys, tmp_path, small):
    rc, out, _ = run_config(capsys, tmp_path, BASE + SMALL, "--json")
    assert rc == 0
    doc = json.loads(out)
    assert json.loads(json.dumps(doc)) == doc
    assert doc["command"] == "optimal" and doc["ratio"] == "1/7"
    assert {k: v for k, v in doc.items() if k != "seconds"} == {
        k: v for k, v in small.items() if k != "seconds"
    }
    assert doc["levels"] == [{"energy": "1", "arrival": [0.5]}, {"energy": "3", "arrival": [1.0]}]


def test_example_states_the_defaults_and_reads_back_from_stdin(capsys, monkeypatch):
    rc, example, _ = run(capsys, "optimal", "--example")
    assert rc == 0 and example == example_text()
    cfg = parse_config(loads(example))
    bare = parse_config(loads(BASE))
    assert parse_optimal(cfg.raw, cfg.channel_arg, cfg.ratio) == parse_optimal(
        bare.raw, bare.channel_arg, bare.ratio
    )
    monkeypatch.setattr(sys, "stdin", io.StringIO(example))
    rc, out, err = run(capsys, "optimal", "-", "--json")
    assert rc == 0, err
    doc = json.loads(out)
    assert doc["config"] == "<stdin>"
    assert [r["budget"] for r in doc["power"]] == ["6/5", "9/7", "7/5", "5/3"]
    assert [r["beta"] for r in doc["attack"]] == [0.1, 0.2, 0.25, 0.5, 2 / 3, 0.9]
    assert [r["n_jams"] for r in doc["jamming"]["finite"]] == [1, 2, 3, 5, 8, 10]
    assert all(math.isclose(r["j"], r["j_online"], rel_tol=1e-9) for r in doc["power"])


def test_example_and_config_together_are_refused(capsys, tmp_path):
    rc, _, err = run_config(capsys, tmp_path, BASE, "--example")
    assert rc == 2 and "--example" in err


def test_channel_flag_replaces_the_configs(capsys, tmp_path):
    rc, out, err = run_config(capsys, tmp_path, BASE + SMALL, "--json", "--channel", "bernoulli:0.7")
    assert rc == 0, err
    doc = json.loads(out)
    s = fa.LinearSystem(**PAPER)
    assert doc["lam"] == 0.7 and doc["levels"][0]["arrival"] == [0.7]
    res = fa.optimal_power_policy(s, 0.7, [(1.0, 0.7), (3.0, 1.0)], 9 / 7)
    assert doc["power"][0]["j"] == res.j
