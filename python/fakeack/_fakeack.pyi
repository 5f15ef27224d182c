"""Type stubs for the compiled core ``fakeack._fakeack`` (PyO3). Use the public API in ``fakeack``."""

from collections.abc import Callable
from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "Attack",
    "ConvergenceError",
    "DEFAULT_MAX_ITER",
    "DEFAULT_TOL",
    "Engine",
    "MAX_BUILD_STATES",
    "MAX_VECTOR_STATES",
    "LinearSystem",
    "attack_chain",
    "balance_residual",
    "flag_rates",
    "general_attack_chain",
    "grid_cells",
    "grid_designs",
    "high_power_rate",
    "num_states",
    "offline_schedule",
    "markov_beta_sweep",
    "markov_mask_j",
    "markov_worst_mask",
    "raise_core_error",
    "simulate",
    "simulate_automaton",
    "simulate_game",
    "stationary_gth",
    "stationary_structured",
    "__version__",
]

MAX_BUILD_STATES: int
MAX_VECTOR_STATES: int
DEFAULT_TOL: float
DEFAULT_MAX_ITER: int
__version__: str

class ConvergenceError(ValueError): ...

@final
class Attack:
    @staticmethod
    def periodic(r: int, t: int) -> Attack: ...
    @staticmethod
    def mask(mask: list[bool]) -> Attack: ...
    @staticmethod
    def random(beta: float) -> Attack: ...
    @staticmethod
    def injection(gamma: float, block: Attack | None) -> Attack: ...

_CsrArrays = tuple[
    npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.float64]
]

@final
class LinearSystem:
    def __new__(
        cls,
        a: npt.NDArray[np.float64],
        c: npt.NDArray[np.float64],
        q: npt.NDArray[np.float64],
        r: npt.NDArray[np.float64],
        tol: float = ...,
        max_iter: int = ...,
    ) -> LinearSystem: ...
    def pbar(self) -> npt.NDArray[np.float64]: ...
    @property
    def residual(self) -> float: ...
    @property
    def iterations(self) -> int: ...
    @property
    def spectral_radius(self) -> float: ...
    def weighted_traces(self, weight: float, n: int) -> npt.NDArray[np.float64]: ...
    def j_offline(self, lam: float, p: int, q: int) -> float: ...
    def j_online(self, lam: float, z0: int, mu: float) -> float: ...
    def j_max(self, lam: float) -> float: ...
    def j_attack(self, lam: float, z0: int, mu: float, attack: Attack) -> float: ...
    def j_attack_limit(self, lam: float, z0: int, mu: float, beta: float) -> float: ...
    def beta_sweep(
        self, lam: float, z0: int, mu: float, t_max: int
    ) -> tuple[
        npt.NDArray[np.uint32], npt.NDArray[np.uint32], npt.NDArray[np.float64], npt.NDArray[np.float64]
    ]: ...
    def beta_bar(
        self, lam: float, p: int, q: int, z0: int, mu: float, t_max: int
    ) -> tuple[tuple[int, int] | None, float, float, float, float]: ...
    def choose_schedule(
        self, lam: float, p: int, q: int, z0: int, mu: float, beta: float
    ) -> tuple[bool, float, float, float, float]: ...
    def curve_offline(self, lam: float, p: int, q: int, horizon: int) -> npt.NDArray[np.float64]: ...
    def curve_online(
        self, lam: float, z0: int, mu: float, attack: Attack | None, horizon: int
    ) -> npt.NDArray[np.float64]: ...
    def j_random_sweep(
        self, lam: float, z0: int, mu: float, gamma: float, betas: list[float]
    ) -> npt.NDArray[np.float64]: ...
    def beta_bar_random(self, lam: float, p: int, q: int, z0: int, mu: float) -> float: ...
    def worst_mask(
        self, lam: float, z0: int, mu: float, t: int, blocked: int
    ) -> tuple[list[bool], float, float]: ...

_Coo = tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.float64]]
_Moves = list[list[tuple[float, bool, int]]]

@final
class Engine:
    def __new__(
        cls,
        P: list[list[float]],
        low: list[float],
        high: list[float],
        z0: int,
        mu: float,
        offline: list[bool] | None,
        attack: Attack | None,
        min_gap: int,
        mimicry: tuple[list[list[float]], list[float], list[float], int, float] | None,
        automaton: tuple[_Moves, _Moves, int] | None,
        max_states: int,
    ) -> Engine: ...
    @staticmethod
    def from_automaton(
        n: int,
        k0: _Coo,
        k1: _Coo,
        init: npt.NDArray[np.float64] | None,
        labels: list[str] | None,
        max_states: int,
    ) -> Engine: ...
    @property
    def n_states(self) -> int: ...
    def cost(self, system: LinearSystem) -> float: ...
    def stability_index(self, system: LinearSystem) -> float: ...
    def high_power_rate(self) -> float: ...
    def flag_rates(self) -> tuple[float, float, float]: ...
    def holding_time_law(self, n: int) -> npt.NDArray[np.float64]: ...
    def cost_curve(
        self, system: LinearSystem, horizon: int
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    def automaton(self) -> tuple[list[str], _Coo, _Coo]: ...

def offline_schedule(p: int, q: int) -> npt.NDArray[np.int64]: ...

_ChannelParts = tuple[list[list[float]], list[float], list[float]]

def markov_beta_sweep(
    system: LinearSystem, channel: _ChannelParts, z0: int, mu: float, t_max: int
) -> tuple[
    npt.NDArray[np.uint32], npt.NDArray[np.uint32], npt.NDArray[np.float64], npt.NDArray[np.float64]
]: ...
def markov_mask_j(
    system: LinearSystem, channel: _ChannelParts, z0: int, mu: float, mask: list[bool]
) -> float: ...
def markov_worst_mask(
    system: LinearSystem, channel: _ChannelParts, z0: int, mu: float, t: int, blocked: int
) -> tuple[list[bool], float, float]: ...
def high_power_rate(lam: float, z0: int, mu: float) -> float: ...
def flag_rates(lam: float, z0: int, mu: float, attack: Attack | None) -> tuple[float, float, float]: ...
def num_states(z0: int, r: int, t: int) -> int: ...
def attack_chain(lam: float, z0: int, r: int, t: int) -> _CsrArrays: ...
def stationary_structured(lam: float, z0: int, r: int, t: int) -> npt.NDArray[np.float64]: ...
def stationary_gth(
    indptr: npt.NDArray[np.int64], indices: npt.NDArray[np.int64], data: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]: ...
def balance_residual(lam: float, z0: int, r: int, t: int, pi: npt.NDArray[np.float64]) -> float: ...
def general_attack_chain(lam: float, z0: int, mu: float, attack: Attack) -> _CsrArrays: ...
def simulate(
    system: LinearSystem,
    lam: float,
    kind: str,
    p: int,
    q: int,
    z0: int,
    mu: float,
    attack: Attack | None,
    mode: str,
    protocol: str,
    horizon: int,
    runs: int,
    seed: int,
    progress: Callable[[int], object],
    record_runs: bool,
    channel: tuple[float, float, float, float] | None = None,
) -> dict[str, Any] | None: ...
def simulate_automaton(
    system: LinearSystem,
    P: list[list[float]],
    low: list[float],
    high: list[float],
    z0: int,
    mu: float,
    offline: list[bool] | None,
    flag: list[list[tuple[float, bool, int]]],
    quiet: list[list[tuple[float, bool, int]]],
    start: int,
    horizon: int,
    runs: int,
    seed: int,
    progress: Callable[[int], object],
    record_runs: bool = False,
    mode: str = "covariance",
) -> dict[str, Any]: ...
def raise_core_error(kind: str) -> None: ...
def grid_cells(
    systems: list[LinearSystem],
    system: npt.NDArray[np.uint64],
    lam: npt.NDArray[np.float64],
    p: npt.NDArray[np.uint64],
    q: npt.NDArray[np.uint64],
    z0: npt.NDArray[np.uint64],
    mu: npt.NDArray[np.float64],
    betas: list[float],
    family: str,
    t_max: int,
    attacks: list[Attack],
) -> dict[str, Any]: ...
def grid_designs(
    lam: npt.NDArray[np.float64],
    lam_num: npt.NDArray[np.uint64],
    lam_den: npt.NDArray[np.uint64],
    p: npt.NDArray[np.uint64],
    q: npt.NDArray[np.uint64],
) -> tuple[npt.NDArray[np.uint64], npt.NDArray[np.float64]]: ...
def simulate_game(
    system: LinearSystem,
    lam: float,
    p: int,
    q: int,
    z0: int,
    mu: float,
    attack: Attack | None,
    kind: str,
    lo: int,
    hi: int,
    edges: list[int],
    expected: list[float],
    critical: float,
    harmful_at_most: int | None,
    fallback: int,
    window: int,
    horizon: int,
    burn_in: int,
    runs: int,
    seed: int,
    progress: Callable[[int], object],
    channel_p: list[list[float]] | None = None,
    channel_low: list[float] | None = None,
    channel_high: list[float] | None = None,
    offline_pattern: list[bool] | None = None,
    min_gap: int = 0,
    automaton: tuple[list[list[tuple[float, bool, int]]], list[list[tuple[float, bool, int]]], int]
    | None = None,
    cusum: tuple[list[float], list[float], float] | None = None,
    lr: tuple[list[float], list[float], list[float]] | None = None,
) -> dict[str, Any]: ...
