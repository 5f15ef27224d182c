"""The repeated game between the sensor and an attacker who must not be seen: sensor policies, the
payoff, the Stackelberg solution, its closed-loop simulation, and the stealthy frontier."""

from .frontier import FAMILIES, StealthyFrontier, stealthy_frontier
from .payoff import Payoff, game_payoff
from .policies import SensorPolicy
from .simulate import GameSimulation, simulate_game
from .solve import GameSolution, Stackelberg, solve_game

__all__ = [
    "SensorPolicy",
    "Payoff",
    "game_payoff",
    "Stackelberg",
    "GameSolution",
    "solve_game",
    "GameSimulation",
    "simulate_game",
    "FAMILIES",
    "StealthyFrontier",
    "stealthy_frontier",
]
