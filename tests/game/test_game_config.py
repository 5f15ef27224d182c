"""The ``[game]`` section of a config: the attack spellings, the support check and the frontiers'
grid, and clear errors for bad values."""

import pytest

import fakeack as fa
from fakeack.config.game import DEFAULT_ATTACKS, GameConfig, parse_game
from fakeack.config.values import ConfigError


def test_the_careful_forger_and_mimicry_are_spelled():
    game = parse_game({"game": {"attacks": ["careful:0.2", "match:0.2", "mimicry", "none"]}})
    careful, naive, mimic, none = game.attack_objects(0.5, 2, 1.0)
    assert careful == fa.rate_matching_attack(0.5, 2, 0.2, min_gap=3)
    assert naive == fa.rate_matching_attack(0.5, 2, 0.2)
    assert isinstance(mimic, fa.MimicryAttack) and none is None
    assert {"careful:0.2", "mimicry"} <= set(DEFAULT_ATTACKS)


def test_the_lr_test_is_spelled():
    assert parse_game({"game": {"tests": ["lr", "count"]}}).tests == ("lr", "count")
    with pytest.raises(ConfigError, match="tests"):
        parse_game({"game": {"tests": ["cusum"]}})


def test_support_grid_and_prior():
    assert (GameConfig().support, GameConfig().grid, GameConfig().attack_prior) == (True, 41, 1.0)
    game = parse_game({"game": {"support": False, "grid": 5, "attack_prior": 0.25}})
    assert (game.support, game.grid, game.attack_prior) == (False, 5, 0.25)


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ({"support": 1}, "support: must be true or false"),
        ({"grid": 1}, "grid"),
        ({"attack_prior": 1.5}, "attack_prior: must lie in"),
        ({"attacks": ["careful:x"]}, r"attacks\[0\]: cannot read 'careful:x'"),
        ({"attacks": ["careful:1.5"]}, r"attacks\[0\]"),
    ],
)
def test_bad_values_name_their_key(table, match):
    with pytest.raises(ConfigError, match=match):
        parse_game({"game": table}).attack_objects(0.5, 2, 1.0)
