"""solve_game(..., attack_prior=pi): the attacker is present with probability pi, so each entry is
pi J(policy, attack) + (1 - pi) J(policy, no attack); with pi = 0 the value is J_on, and the
sensor's false alarms cost it on the clean channel."""

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER

LAM, RATIO = 0.5, "1/7"
ATTACKS = [fa.PeriodicBlocking(1, 5), fa.PeriodicBlocking(2, 3), fa.MimicryAttack()]


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


def test_without_an_attacker_the_value_is_j_on(system):
    sol = fa.solve_game(system, LAM, RATIO, 1000, [0.01, 0.05], [2], ATTACKS, attack_prior=0.0)
    assert sol.value == pytest.approx(fa.j_online(system, LAM, 2), rel=1e-9)
    assert sol.policies[int(np.argmax(sol.sensor_strategy))] == fa.SensorPolicy("never")
    assert sol.attack_prior == 0.0


def test_each_entry_is_the_mixture(system):
    full = fa.solve_game(system, LAM, RATIO, 1000, 0.01, [1, 4], ATTACKS)
    for pi in (0.3, 0.7):
        sol = fa.solve_game(system, LAM, RATIO, 1000, 0.01, [1, 4], ATTACKS, attack_prior=pi)
        for i, policy in enumerate(sol.policies):
            clean = fa.game_payoff(system, LAM, RATIO, policy, None, 1000)
            for j in range(len(ATTACKS)):
                expected = pi * full.payoff[i, j] + (1 - pi) * clean.j
                assert sol.payoff[i, j] == pytest.approx(expected, rel=1e-12)
                d = pi * full.detection[i, j] + (1 - pi) * clean.detection
                assert sol.detection[i, j] == pytest.approx(d, abs=1e-12)
    assert full.attack_prior == 1.0


def test_the_value_grows_with_the_prior(system):
    values = [
        fa.solve_game(system, LAM, RATIO, 1000, 0.01, 2, ATTACKS, attack_prior=pi).value
        for pi in (0.0, 0.25, 0.5, 0.75, 1.0)
    ]
    assert np.all(np.diff(values) >= -1e-12)
    assert values[-1] == pytest.approx(fa.j_offline(system, LAM, RATIO), rel=1e-9)


@pytest.mark.parametrize(("prior", "error"), [(-0.1, ValueError), (1.5, ValueError), ("half", TypeError)])
def test_a_bad_prior_is_named(system, prior, error):
    with pytest.raises(error, match="attack_prior"):
        fa.solve_game(system, LAM, RATIO, 1000, 0.01, 2, ATTACKS, attack_prior=prior)


def test_the_game_command_takes_the_prior(tmp_path, capsys):
    import json

    from fakeack.cli import main

    cfg = tmp_path / "game.toml"
    cfg.write_text(
        "[system]\nA = 1.2\nC = 0.7\nQ = 0.8\nR = 0.8\nlam = 0.5\n\n[energy]\nratio = '1/7'\n\n"
        "[game]\nn_steps = 1000\nalphas = [0.01]\nfallbacks = [2]\ntests = ['count']\n"
        "rules = ['any']\nattacks = ['none', '2/3']\nt_max = 4\ngrid = 3\nruns = 0\n"
        "attack_prior = 0.0\n"
    )
    assert main(["game", str(cfg), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["attack_prior"] == 0.0 and doc["value"] == pytest.approx(doc["j_online"], rel=1e-9)
    assert main(["game", str(cfg), "--no-figures"]) == 0
    assert "the attacker present with probability 0" in capsys.readouterr().out
