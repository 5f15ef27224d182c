"""The command line, the TOML config and the figures (fast: small runs, figures drawn once)."""

import csv
import io
import json
import math
import os
import re
import stat
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import fakeack as fa
import reference as ref
from conftest import PAPER, PAPER_LAM, PAPER_RATIO
from fakeack import cli, config, plots
from fakeack.attacks import as_attack

HAS_SIMULATE = hasattr(fa._fakeack, "simulate")
needs_simulate = pytest.mark.skipif(not HAS_SIMULATE, reason="compiled core has no simulate yet")
needs_mpl = pytest.mark.skipif(not plots.have_matplotlib(), reason="matplotlib not installed")

FIGURES = {
    f"{stem}.{ext}"
    for stem in ("fig3_jk", "fig4_beta", "fig_stationary", "fig_attack_families")
    for ext in ("png", "svg")
}
ROW_KEYS = [
    "j_offline",
    "j_online",
    "j_attack_1/5",
    "j_attack_2/3",
    "j_max",
    "beta_bar_limit",
    "beta_bar_finite",
]

# A valid config to break one key at a time.
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


def run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def no_temp_files(d: Path) -> bool:
    return not [p for p in d.iterdir() if p.name.startswith(".") or p.name.endswith(".tmp")]


@pytest.fixture
def fake_simulate(monkeypatch):
    """A stand-in for the compiled Monte Carlo whose answer (J = 5 +- 0.01) is far from every exact J_H."""

    def fake(core, lam, kind, p, q, z0, mu, attack, mode, protocol, horizon, runs, seed, bar, *rest):
        j = np.full(horizon, 5.0)
        return dict(
            j_k=j,
            mean_trace=j,
            j=5.0,
            stderr=0.01,
            high_power_rate=0.1,
            flags_sent=0.1,
            flags_blocked=0.0,
            flags_forged=0.0,
        )

    monkeypatch.setattr(fa._fakeack, "simulate", fake, raising=False)


# ------------------------------------------------------------------------------ entry points


def test_python_m_help_subprocess():
    p = subprocess.run(
        [sys.executable, "-m", "fakeack", "--help"], capture_output=True, text=True, timeout=60
    )
    assert p.returncode == 0, p.stderr
    for cmd in ("reproduce", "analyze", "sweep", "simulate"):
        assert cmd in p.stdout


def test_help_states_defaults(capsys):
    rc, out, _ = run(capsys, "reproduce", "--help")
    assert rc == 0
    out = " ".join(out.split())
    assert f"default: {cli.DEFAULT_RUNS}" in out and f"default: {cli.DEFAULT_HORIZON}" in out
    rc, _, err = run(capsys, "reproduce", "--runs", "1")
    assert rc == 2 and "--runs" in err
    rc, _, err = run(capsys, "nonsense")
    assert rc == 2


# ------------------------------------------------------------------------------ reproduce


def test_reproduce_table_without_mc(capsys):
    rc, out, err = run(capsys, "reproduce", "--runs", 0, "--no-figures")
    assert rc == 0, err
    s = fa.LinearSystem(**PAPER)
    for text in ("J_offline", "J_online", "J_attack beta=1/5", "J_attack beta=2/3", "J_max", "beta-bar"):
        assert text in out
    assert f"{fa.j_offline(s, PAPER_LAM, PAPER_RATIO):.6f}" in out
    assert f"{fa.j_attack(s, PAPER_LAM, 2, 2, 3):.6f}" in out
    assert "2.0953" in out and "1.6399" in out and "~0.28" in out
    bar = fa.beta_bar(s, PAPER_LAM, PAPER_RATIO, 60)
    assert f"{bar.limit:.6f}" in out and "20/59" in out
    # The finite-horizon exact value sits beside the stationary one.
    exact = fa.expected_trace_curve(s, PAPER_LAM, fa.OnlineSchedule(2), cli.DEFAULT_HORIZON).j_k[-1]
    assert f"{exact:.6f}" in out
    flat = " ".join(out.split())
    assert "not with the stationary value" not in flat  # that footnote is for runs with MC
    assert (
        "note: the paper prints J_online = 1.6399" in flat
        and "Model note 2" in flat
        and "Model note 7" in flat
    )


def test_reproduce_json(capsys):
    rc, out, _ = run(capsys, "reproduce", "--runs", 0, "--no-figures", "--json", "--horizon", 50)
    assert rc == 0
    d = json.loads(out)
    assert [r["key"] for r in d["rows"]] == ROW_KEYS
    assert {"analytic", "exact_h", "mc", "mc_stderr", "flagged", "paper"} <= set(d["rows"][0])
    rows = {r["key"]: r for r in d["rows"]}
    s = fa.LinearSystem(**PAPER)
    assert rows["j_online"]["analytic"] == pytest.approx(fa.j_online(s, 0.5, 2))
    assert rows["j_online"]["paper"] == "1.6399"
    assert rows["j_max"]["analytic"] == pytest.approx(fa.j_max(s, 0.5))
    # Exact finite-horizon J_max, from the series, against a direct evaluation.
    tr, a, H = s.h_traces(50), 0.5, 50
    e = [(0.5 * sum(a**i * tr[i] for i in range(k - 1)) + a ** (k - 1) * tr[k - 1]) for k in range(1, H + 1)]
    assert rows["j_max"]["exact_h"] == pytest.approx(np.mean(e), rel=1e-12)
    assert d["beta_bar"]["finite"] == "20/59"
    assert d["horizon"] == 50 and d["montecarlo"] is None
    assert d["online"] == {"z0": 2, "mu": 1.0, "designed": True, "high_power_rate": pytest.approx(1 / 7)}


@needs_simulate
def test_reproduce_monte_carlo_agrees(capsys):
    """Every Monte Carlo row within 4 standard errors of the exact J_H, with standard errors
    below 0.1% of J (4 SE < 0.4%: a 1% error in a row shows; the former 3000 runs gave 4 SE =
    2.2%). The exact J_H of each row is checked against the reference's propagation of the
    holding-time law.

    Kills: a row simulated with the wrong schedule or attack (1/5 for 2/3, online for offline),
    a 1% error in the exact J_H column, the standard error column not the one simulated."""
    runs, horizon = 200_000, 60
    rc, out, _ = run(capsys, "reproduce", "--runs", runs, "--horizon", horizon, "--no-figures", "--json")
    assert rc == 0
    d = json.loads(out)
    rows = {r["key"]: r for r in d["rows"]}
    for key in ROW_KEYS[:4]:
        r = rows[key]
        assert r["mc"] is not None and 0 < r["mc_stderr"] < 1e-3 * r["exact_h"], r
        assert abs(r["mc"] - r["exact_h"]) <= 4 * r["mc_stderr"], r
        assert not r["flagged"]
    s = fa.LinearSystem(**PAPER)
    tr = ref.traces(1.2, 0.8, s.pbar, horizon)
    masks = {"j_online": [0], "j_attack_1/5": [1, 0, 0, 0, 0], "j_attack_2/3": [1, 1, 0]}
    for key, mask in masks.items():
        states, T = ref.explore_mask_chain(PAPER_LAM, 2, mask)
        law = np.zeros(len(states))
        law[0] = 1.0  # high power at k = 1: tau = 0, counter 0
        taus = np.array([st[0] for st in states])
        e = []
        for _ in range(horizon):
            e.append(law @ tr[np.minimum(taus, horizon)])
            law = law @ T
        assert rows[key]["exact_h"] == pytest.approx(np.mean(e), rel=1e-11), key
    law, e = np.zeros(horizon + 1), []
    for k in range(horizon):  # offline 1/7: high power at k = 1, 8, 15, ...
        law = (
            np.eye(horizon + 1)[0]
            if k % 7 == 0
            else np.concatenate(([PAPER_LAM * law.sum()], 0.5 * law[:-1]))
        )
        e.append(law @ tr)
    assert rows["j_offline"]["exact_h"] == pytest.approx(np.mean(e), rel=1e-11)
    assert rows["j_max"]["mc"] is None and rows["beta_bar_limit"]["mc"] is None
    assert d["montecarlo"]["runs"] == runs


def test_reproduce_flags_disagreement(capsys, fake_simulate):
    rc, out, _ = run(capsys, "reproduce", "--runs", 100, "--horizon", 20, "--no-figures")
    assert rc == 0
    flagged = [ln for ln in out.splitlines() if ln.rstrip().endswith("!") or " ! " in ln]
    assert len(flagged) == 4  # offline, online and the two attacks; J_max and beta-bar have no MC
    assert "5.000000 +- 0.010000 !" in out
    flat = " ".join(out.split())
    assert "FLAGGED" in flat and "compared with exact J_H, not with the stationary value" in flat


@needs_mpl
def test_reproduce_writes_figures_atomically(capsys, tmp_path):
    out_dir = tmp_path / "figs"
    rc, out, err = run(capsys, "reproduce", "--runs", 0, "--horizon", 40, "--out", out_dir)
    assert rc == 0, err
    assert {p.name for p in out_dir.iterdir()} == FIGURES
    for name in FIGURES:
        data = (out_dir / name).read_bytes()
        assert data.startswith(b"\x89PNG") if name.endswith(".png") else b"<svg" in data[:2000]
    assert "fig4_beta.png" in out


def test_figures_skipped_without_matplotlib(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(plots, "have_matplotlib", lambda: False)
    rc, _, err = run(capsys, "reproduce", "--runs", 0, "--out", tmp_path / "f")
    assert rc == 0
    assert "matplotlib is not installed" in err
    assert not (tmp_path / "f").exists()


def test_keyboard_interrupt_exits_130(capsys, monkeypatch):
    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli.reproduce, "analyse", boom)
    rc, out, err = run(capsys, "reproduce", "--runs", 0, "--no-figures")
    assert rc == 130 and err.strip() == "fakeack: interrupted"


# ------------------------------------------------------------------------------ atomic files


def test_atomic_write_replaces_and_cleans_up(tmp_path, monkeypatch):
    target = tmp_path / "out.txt"
    cli.atomic_write(target, "old\n")
    os.chmod(target, 0o640)
    cli.atomic_write(target, "new\n")
    assert target.read_text() == "new\n"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640

    def interrupted(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        cli.atomic_write(target, "half-written\n")
    assert target.read_text() == "new\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


# ------------------------------------------------------------------------------ sweep


def test_sweep_table_csv_json(capsys, tmp_path):
    rc, out, _ = run(capsys, "sweep", "--t-max", 6)
    assert rc == 0
    assert "beta-bar" in out and "J_attack" in out
    n = sum(1 for t in range(2, 7) for r in range(1, t) if math.gcd(r, t) == 1)  # 11 fractions

    rc, out, _ = run(capsys, "sweep", "--t-max", 6, "--csv")
    rows = list(csv.reader(io.StringIO(out)))
    assert rows[0] == ["r", "t", "beta", "j_attack", "j_attack_limit", "better"]
    assert len(rows) == n + 1
    s = fa.LinearSystem(**PAPER)
    r15 = next(r for r in rows[1:] if r[:2] == ["1", "5"])
    assert float(r15[3]) == pytest.approx(fa.j_attack(s, 0.5, 2, 1, 5), rel=1e-12)

    dest = tmp_path / "sub" / "sweep.json"
    rc, out, err = run(capsys, "sweep", "--t-max", 6, "--json", "--out", dest, "--lam", 0.5, "--ratio", "1/7")
    assert rc == 0 and out == ""
    d = json.loads(dest.read_text())
    assert d["count"] == n == len(d["points"])
    assert {"r", "t", "beta", "j_attack", "j_attack_limit", "better"} == set(d["points"][0])
    assert d["beta_bar"]["limit"] == pytest.approx(fa.beta_bar(s, 0.5, "1/7", 6).limit)
    assert no_temp_files(dest.parent)


def test_sweep_bad_arguments(capsys, tmp_path):
    rc, _, err = run(capsys, "sweep", "--ratio", "2/1")
    assert rc == 2 and err.startswith("fakeack: error:") and "ratio" in err
    rc, _, err = run(capsys, "sweep", "--lam", 1.5)
    assert rc == 2 and "--lam" in err
    cfg = tmp_path / "c.toml"
    cfg.write_text(BASE)
    rc, _, err = run(capsys, "sweep", "--config", cfg, "--A", 2)
    assert rc == 2 and "--config" in err
    assert "Traceback" not in err


# ------------------------------------------------------------------------------ simulate


def test_simulate_without_core_or_bad_args(capsys):
    rc, _, err = run(capsys, "simulate", "--schedule", "offline", "--attack", "1/5")
    assert rc == 2 and "offline" in err
    rc, _, err = run(capsys, "simulate", "--attack", "3/3")
    assert rc == 2 and "--attack" in err
    rc, _, err = run(capsys, "simulate", "--mu", 0.5)
    assert rc == 2 and "--z0" in err
    if not HAS_SIMULATE:
        rc, _, err = run(capsys, "simulate", "--runs", 10)
        assert rc == 1 and "simulate" in err


def test_simulate_formats_with_fake_core(capsys, tmp_path, fake_simulate):
    rc, out, _ = run(capsys, "simulate", "--attack", "1/5", "--runs", 10, "--horizon", 7)
    assert rc == 0 and "J_H exact" in out and "check!" in out
    rc, out, _ = run(capsys, "simulate", "--runs", 10, "--horizon", 7, "--csv")
    rows = list(csv.reader(io.StringIO(out)))
    assert rows[0] == ["k", "mc_trace", "mc_j_k", "exact_trace", "exact_j_k"] and len(rows) == 8
    dest = tmp_path / "sim.json"
    rc, out, _ = run(
        capsys, "simulate", "--schedule", "offline", "--runs", 10, "--horizon", 7, "--json", "--out", dest
    )
    d = json.loads(dest.read_text())
    assert {"j", "stderr", "exact_j_h", "stationary_j", "j_k", "exact_j_k", "flagged"} <= set(d)
    assert d["flagged"] and len(d["j_k"]) == 7
    assert d["stationary_j"] == pytest.approx(fa.j_offline(fa.LinearSystem(**PAPER), 0.5, "1/7"))
    assert no_temp_files(tmp_path)


@needs_simulate
def test_simulate_real(capsys):
    rc, out, _ = run(
        capsys, "simulate", "--attack", "2/3", "--runs", 2000, "--horizon", 40, "--seed", 3, "--json"
    )
    assert rc == 0
    d = json.loads(out)
    assert abs(d["j"] - d["exact_j_h"]) <= 4 * d["stderr"]
    assert d["attack"] == "2/3" and d["runs"] == 2000 and len(d["mean_trace"]) == 40


@needs_simulate
@pytest.mark.parametrize(
    "spelling, forged", [("random:0.3", False), ("inject:0.1", True), ("inject:0.1+random:0.3", True)]
)
def test_simulate_other_attacks(capsys, spelling, forged):
    rc, out, _ = run(capsys, "simulate", "--attack", spelling, "--runs", 2000, "--horizon", 60, "--seed", 5)
    assert rc == 0
    attack = fa.attacks.as_attack(spelling)
    assert f"attack {spelling} ({attack})" in out.splitlines()[0]
    assert ("forged" in out) == forged
    rc, out, _ = run(
        capsys, "simulate", "--attack", spelling, "--runs", 2000, "--horizon", 60, "--seed", 5, "--json"
    )
    d = json.loads(out)
    assert d["attack"] == spelling and abs(d["j"] - d["exact_j_h"]) <= 4 * d["stderr"]
    assert (d["flags_forged"] > 0) == forged
    assert d["stationary_j"] == pytest.approx(fa.j_attack(fa.LinearSystem(**PAPER), 0.5, 2, attack=attack))


# ------------------------------------------------------------------------------ config and analyze


def test_example_round_trips(capsys, tmp_path):
    rc, text, _ = run(capsys, "analyze", "--example")
    assert rc == 0 and text == config.example_text()
    cfg = config.parse_config(config.loads(text))
    assert (cfg.lam, cfg.ratio, tuple(cfg.online), cfg.designed) == (0.5, Fraction(1, 7), (2, 1.0), True)
    assert [a.label for a in cfg.attacks] == ["1/5", "2/3"] and cfg.sweep_t_max == 60
    assert float(cfg.system.A[0, 0]) == PAPER["A"] and float(cfg.system.R[0, 0]) == PAPER["R"]
    path = tmp_path / "paper.toml"
    # Keep the round trip fast: fewer runs, same everything else.
    path.write_text(text.replace("runs = 20000", "runs = 500").replace("horizon = 200", "horizon = 30"))
    rc, out, err = run(capsys, "analyze", path, "--json")
    assert rc == 0, err
    d = json.loads(out)
    assert [r["key"] for r in d["rows"]] == ROW_KEYS
    assert d["beta_bar"]["finite"] == "20/59"
    assert (d["montecarlo"] is not None) == HAS_SIMULATE


def test_analyze_reads_stdin(capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdin", io.StringIO(BASE + '[attack]\nbetas = ["1/3"]\n'))
    rc, out, err = run(capsys, "analyze", "-", "--json")
    assert rc == 0, err
    d = json.loads(out)
    assert d["config"] == "<stdin>" and [r["key"] for r in d["rows"]][2] == "j_attack_1/3"


def test_analyze_matrix_config_and_out_dir(capsys, tmp_path):
    path = tmp_path / "two.toml"
    path.write_text(
        """
[system]
A = [[1.1, 0.2], [0.0, 0.9]]
C = [[1.0, 0.0]]
Q = [[0.5, 0.0], [0.0, 0.5]]
R = [[1.0]]
lam = 0.6
[energy]
Psi = 4
Delta = 10
delta = "3"
[online]
z0 = 2
mu = 0.5
[attack]
betas = ["1/4", 0.5, "2/6"]
sweep = { t_max = 8 }
"""
    )
    rc, out, err = run(capsys, "analyze", path, "--out", tmp_path / "res", "--no-figures")
    assert rc == 0, err
    assert "n_x=2" in out and "J_attack beta=2/6" in out and "given" in out
    d = json.loads((tmp_path / "res" / "analysis.json").read_text())
    s = fa.LinearSystem([[1.1, 0.2], [0, 0.9]], [[1.0, 0]], 0.5 * np.eye(2), [[1.0]])
    rows = {r["key"]: r for r in d["rows"]}
    assert rows["j_attack_2/6"]["analytic"] == pytest.approx(fa.j_attack(s, 0.6, 2, 2, 6, 0.5))
    assert rows["j_attack_1/2"]["analytic"] == pytest.approx(fa.j_attack(s, 0.6, 2, 1, 2, 0.5))
    assert d["ratio"] == "1/7" and d["online"]["designed"] is False
    assert no_temp_files(tmp_path / "res")


@pytest.mark.parametrize(
    "edit, expected",
    [
        (lambda t: t.replace("lam = 0.5\n", ""), "config: [system] lam: missing"),
        (lambda t: t.replace("lam = 0.5", 'lam = "half"'), "config: [system] lam: must be a number"),
        (lambda t: t.replace("lam = 0.5", "lamda = 0.5"), "config: [system] lamda: unknown key"),
        (lambda t: t.replace("A = 1.2", "A = [[1, 2, 3], [4, 5, 6]]"), "config: [system] A: must be square"),
        (lambda t: t.replace("Q = 0.8", "Q = -0.8"), "config: [system] Q: must be positive semi-definite"),
        (lambda t: t.replace('ratio = "1/7"', 'ratio = "1/x"'), "config: [energy] ratio: cannot read"),
        (lambda t: t + '[montecarlo]\nruns = "100"\n', "config: [montecarlo] runs: must be an integer"),
        (lambda t: t + '[attack]\nbetas = ["1/5", "5/3"]\n', "config: [attack] betas[1]: must lie in [0, 1)"),
        (lambda t: t + "[attack.sweep]\ntmax = 9\n", "config: [attack.sweep] tmax: unknown key"),
        (lambda t: t + "[montecarl]\nruns = 9\n", "config: [montecarl]: unknown section"),
        (lambda t: t + "[online]\nmu = 0.5\n", "config: [online] z0: missing"),
        (lambda t: t + "x = = 1\n", "invalid TOML"),
    ],
)
def test_config_errors_name_the_key(capsys, tmp_path, edit, expected):
    path = tmp_path / "bad.toml"
    path.write_text(edit(BASE))
    rc, out, err = run(capsys, "analyze", path)
    assert rc == 2
    assert err.startswith("fakeack: error: " + expected.split("config: ")[-1]) or expected in err, err
    assert "Traceback" not in err and out == ""


def test_config_unknown_key_suggests(capsys, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(BASE.replace("lam = 0.5", "lamda = 0.5"))
    rc, _, err = run(capsys, "analyze", path)
    assert rc == 2 and "did you mean 'lam'?" in err
    rc, _, err = run(capsys, "analyze", tmp_path / "missing.toml")
    assert rc == 2 and "cannot read" in err
    rc, _, err = run(capsys, "analyze")
    assert rc == 2 and "--example" in err


def test_attack_spellings():
    assert as_attack("2/6") == fa.PeriodicBlocking(2, 6)  # kept as written
    assert as_attack(0.2) == fa.PeriodicBlocking(1, 5)
    assert as_attack("0.25").label == "1/4"
    assert as_attack(0).label == "0/1"
    for bad in ("1/1", "3/2", "a/b", -0.5):
        with pytest.raises(ValueError):
            as_attack(bad)
    with pytest.raises(TypeError):
        as_attack(True)


def test_config_attacks_are_periodic_blocking():
    cfg = config.parse_config(config.loads(BASE + '[attack]\nbetas = ["2/6", 0.2, "0.25"]\n'))
    assert cfg.attacks == (fa.PeriodicBlocking(2, 6), fa.PeriodicBlocking(1, 5), fa.PeriodicBlocking(1, 4))
    assert [a.label for a in cfg.attacks] == ["2/6", "1/5", "1/4"]


def test_online_z0_without_mu_means_mu_1():
    cfg = config.parse_config(config.loads(BASE + "[online]\nz0 = 2\n"))
    assert cfg.online == (2, 1.0) and cfg.online.mu == 1.0 and not cfg.designed
    s = fa.LinearSystem(**PAPER)
    assert fa.j_online(s, 0.5, 2, cfg.online.mu) == pytest.approx(fa.j_online(s, 0.5, 2, 1.0), rel=1e-15)
    assert fa.j_online(s, 0.5, 2, 0.0) != pytest.approx(
        fa.j_online(s, 0.5, 2, 1.0)
    )  # so a default of 0 would show


# ------------------------------------------------------------------------------ plots


@needs_mpl
def test_plot_functions_draw_on_given_axes():
    from matplotlib.figure import Figure

    fig = Figure()
    axes = fig.subplots(1, 3)
    s = fa.LinearSystem(**PAPER)
    curve = fa.expected_trace_curve(s, 0.5, fa.OnlineSchedule(2), 20)
    assert plots.plot_jk([plots.JkCurve("online", curve.k, None, curve.j_k, 1.69)], ax=axes[0]) is fig
    sw, bar = fa.beta_sweep(s, 0.5, "1/7", 10), fa.beta_bar(s, 0.5, "1/7", 10)
    assert plots.plot_beta_sweep(sw, bar, ax=axes[1]) is fig
    states, _ = fa.attack_chain(0.5, 2, 1, 3)
    pi = fa.stationary_distribution(0.5, 2, 1, 3)
    assert plots.plot_stationary(states, pi, ax=axes[2], r=1) is fig
    assert axes[2].get_xlabel().startswith("holding time")


def test_reproduce_reports_the_other_attacks(capsys):
    rc, out, _ = run(capsys, "reproduce", "--runs", 0, "--no-figures")
    assert rc == 0
    assert "other attacks (beyond the paper" in out
    for label in (
        "random blocking beta=1/5",
        "random blocking beta=2/3",
        "injection gamma=0.1",
        "rate matching beta=1/5",
        "beta-bar against random blocking",
    ):
        assert label in out
    rc, out, _ = run(capsys, "reproduce", "--runs", 0, "--no-figures", "--json")
    doc = json.loads(out)["other_attacks"]
    assert len(doc["rows"]) == 4 and 0 < doc["beta_bar_random"] < 1
    paper = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    assert doc["rows"][0]["j"] == fa.j_attack(paper, 0.5, 2, attack=fa.RandomBlocking(0.2))
    # The rate-matching attack spends exactly the budget.
    assert abs(doc["rows"][3]["energy_per_step"] - 9 / 7) < 1e-12


def test_analyze_config_with_random_and_injection(capsys, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        fa.config.example_text()
        .replace("# random = [0.2, 0.5]", "random = [0.2, 0.5]")
        .replace("# inject = [0.05]", "inject = [0.05]")
        .replace("[montecarlo]", "[x]")
        .split("[x]")[0]
    )
    rc, out, _ = run(capsys, "analyze", str(cfg))
    assert rc == 0, out
    assert (
        "block each flag-ACK with probability 0.5" in out and "forge a flag-ACK with probability 0.05" in out
    )
    parsed = fa.config.load_config(cfg)
    assert parsed.other_attacks == (fa.RandomBlocking(0.2), fa.RandomBlocking(0.5), fa.FlagInjection(0.05))


@pytest.mark.parametrize(
    "line, message",
    [
        ("random = [1.5]", "random[0]: must lie in [0, 1]"),
        ("inject = ['x']", "inject[0]: must be a number"),
        ("random = 0.2", "random: must be an array"),
        ("random = [0.2, 0.2]", "listed twice"),
    ],
)
def test_bad_other_attack_keys(tmp_path, line, message):
    text = fa.config.example_text().replace("# random = [0.2, 0.5]", line)
    with pytest.raises(fa.config.ConfigError, match=re.escape(message)):
        fa.config.parse_config(fa.config.loads(text))
