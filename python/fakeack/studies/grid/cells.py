"""One block of a parameter study: every quantity of its cells, as arrays (runs on any worker).

A block is one system over a tile of (lam, ratio) cells. Each (lam, ratio) gets the online design
of :func:`fakeack.design_online` (computed bit for bit by the compiled core); the
compiled core evaluates the whole tile at once (:func:`fakeack._fakeack.grid_cells`, cells in
parallel, traces shared per lam); the optional Monte Carlo runs :func:`fakeack.simulate` once per
cell and budget with a seed derived from the study seed and the cell's coordinates. Nothing here
depends on which worker runs the block or on what else it holds, so a study's results do not
depend on the executor or the block size.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from ... import _fakeack
from ...attacks.kinds import MaskBlocking, PeriodicBlocking, RandomBlocking
from ...model.schedules import OnlineSchedule, design_online
from ...model.system import LinearSystem
from ...montecarlo.protocol import simulate
from .design import lam_fractions

__all__ = [
    "MonteCarlo",
    "ChannelAxes",
    "Block",
    "cell_seed",
    "mc_attack",
    "run_block",
]


@dataclass(frozen=True)
class MonteCarlo:
    """Settings of the Monte Carlo check of every cell (arguments of :func:`fakeack.simulate`)."""

    runs: int
    horizon: int
    seed: int
    mode: str = "covariance"
    protocol: str = "B"


@dataclass(frozen=True)
class ChannelAxes:
    """The ``mean`` and ``memory`` dimensions of a study over on/off Gilbert-Elliott channels
    (read by :func:`fakeack.studies.grid.channel.channel_axes`)."""

    mean: tuple[float, ...]
    memory: tuple[float, ...]
    kind: str = "gilbert-elliott"


@dataclass(frozen=True)
class Block:
    """One task: ``system`` over the tile ``lam`` x ``ratio`` (C order), at every budget; with
    ``channel``, over the tile (mean x memory) x ``ratio`` instead (``lam`` empty)."""

    index: int
    system_name: str
    system: LinearSystem
    lam: tuple[float, ...]
    ratio: tuple[Fraction, ...]
    beta: tuple[Fraction, ...]
    family: str
    t_max: int
    montecarlo: MonteCarlo | None
    channel: ChannelAxes | None = None


def cell_seed(seed: int, system: str, lam: float, ratio: Fraction, beta: Fraction) -> int:
    """The Monte Carlo seed of one cell and budget: a 62-bit hash of the study seed and the
    cell's coordinates (not its position, so adding grid points leaves other cells' seeds alone).
    """
    key = f"fakeack-grid|{seed}|{system}|{lam.hex()}|{ratio}|{beta}".encode()
    # 62 bits: the largest integer argument fakeack accepts is 2**62.
    return int.from_bytes(hashlib.blake2b(key, digest_size=8).digest(), "little") >> 2


def mc_attack(family: str, beta: Fraction) -> Any:
    """The attack the Monte Carlo simulates at budget ``beta``: "first r of every t" with r/t = beta
    in lowest terms (every flag-ACK blocked at beta = 1), or independent blocking.
    """
    if family == "random":
        return RandomBlocking(beta)
    if beta == 1:
        return MaskBlocking([1])
    return PeriodicBlocking(beta.numerator, beta.denominator)


def _core_attack(beta: Fraction) -> Any:
    if beta == 1:
        return _fakeack.Attack.mask([True])
    return _fakeack.Attack.periodic(beta.numerator, beta.denominator)


def _j_max_note(family: str) -> str:
    note = "J_max is infinite: (1 - lam) rho(A)^2 >= 1 (Model note 5)"
    if family == "periodic":
        note += "; J_attack is inf for every beta > 0 and beta_bar_limit is 0"
    return note


def run_block(block: Block) -> dict[str, Any]:
    """Every variable of the block's cells, each an array of shape (1, n_lam, n_ratio[, n_beta]).

    Parameters
    ----------
    block : Block
        The task.

    Returns
    -------
    dict
        ``{"index": block.index, "data": {name: array}}``.
    """
    nl, nr, nb = len(block.lam), len(block.ratio), len(block.beta)
    n = nl * nr
    lam = np.repeat(np.asarray(block.lam, dtype=np.float64), nr)
    ratios = list(block.ratio) * nl
    status = np.full(n, "ok", dtype=object)
    p = np.array([r.numerator for r in ratios], dtype=np.uint64)
    q = np.array([r.denominator for r in ratios], dtype=np.uint64)
    # The exact design in the compiled core (the same bits as fakeack.design_online, λ read as
    # fakeack reads a float); the cells it leaves take design_online itself, and its errors.
    num, den = lam_fractions(block.lam)
    z0, mu = _fakeack.grid_designs(lam, np.repeat(num, nr), np.repeat(den, nr), p, q)
    for i in np.flatnonzero(z0 == 0).tolist():
        try:
            z0[i], mu[i] = design_online(float(lam[i]), Fraction(int(p[i]), int(q[i])))
        except ValueError as exc:
            status[i] = f"no online design: {exc}"
    listed = [_core_attack(b) for b in block.beta] if block.montecarlo and block.family == "periodic" else []
    out = _fakeack.grid_cells(
        [block.system._core],
        np.zeros(n, dtype=np.uint64),
        lam,
        p,
        q,
        z0,
        np.where(np.isnan(mu), 1.0, mu),
        [float(b) for b in block.beta],
        block.family,
        block.t_max,
        listed,
    )
    ok = status == "ok"
    for i in np.flatnonzero(ok & (np.array(out["error"], dtype=object) != "")):
        status[i] = f"error: {out['error'][i]}"
    status[(status == "ok") & np.isinf(out["j_max"])] = _j_max_note(block.family)
    data: dict[str, Any] = {
        "j_offline": out["j_offline"],
        "j_online": out["j_online"],
        "j_max": out["j_max"],
        "z0": z0.astype(np.int64),
        "mu": mu,
        "beta_bar_limit": out["beta_bar_limit"],
        "beta_bar_finite": _finite(out["finite_r"], out["finite_t"]),
        "beta_bar_finite_rt": np.array(
            [f"{r}/{t}" if t else "" for r, t in zip(out["finite_r"], out["finite_t"], strict=True)],
            dtype=object,
        ),
        "status": status,
    }
    if block.family == "random":
        data["beta_bar_random"] = out["beta_bar_random"]
    if nb:
        j_att = out["j_attack"]
        j_off = out["j_offline"][:, None]
        known = ~(np.isnan(j_att) | np.isnan(j_off))
        data["j_attack"] = j_att
        data["decision"] = np.where(known, np.where(j_att < j_off, "online", "offline"), "n/a").astype(object)
    if block.montecarlo is not None and nb:
        mc = _monte_carlo(block, lam, ratios, z0, mu, status)
        data.update(mc)
        data["mc_j_analytic"] = out["j_listed"] if block.family == "periodic" else out["j_attack"]
    shaped = {k: v.reshape((1, nl, nr) + v.shape[1:]) for k, v in data.items()}
    return {"index": block.index, "data": shaped}


def _finite(r: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = np.full(len(r), np.nan)
    has = t > 0
    out[has] = r[has] / t[has]
    return out


def _monte_carlo(
    block: Block, lam: np.ndarray, ratios: list[Fraction], z0: np.ndarray, mu: np.ndarray, status: np.ndarray
) -> dict[str, np.ndarray]:
    """:func:`fakeack.simulate` of the online schedule at every budget of every designed cell."""
    mc = block.montecarlo
    assert mc is not None
    n, nb = len(lam), len(block.beta)
    j = np.full((n, nb), np.nan)
    se = np.full((n, nb), np.nan)
    attacks = [mc_attack(block.family, b) for b in block.beta]
    for i in range(n):
        if z0[i] == 0:
            continue
        sched = OnlineSchedule(int(z0[i]), float(mu[i]))
        for k, beta in enumerate(block.beta):
            seed = cell_seed(mc.seed, block.system_name, float(lam[i]), ratios[i], beta)
            try:
                res = simulate(
                    block.system,
                    float(lam[i]),
                    sched,
                    horizon=mc.horizon,
                    runs=mc.runs,
                    seed=seed,
                    attack=attacks[k],
                    mode=mc.mode,
                    protocol=mc.protocol,
                    progress=False,
                )
            except ValueError as exc:
                if status[i] == "ok":
                    status[i] = f"error: montecarlo at beta={beta}: {exc}"
                continue
            j[i, k], se[i, k] = res.j, res.stderr
    return {"mc_j": j, "mc_stderr": se}
