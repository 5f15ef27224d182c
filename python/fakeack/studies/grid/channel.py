"""A parameter study over bursty channels: the ``mean`` and ``memory`` dimensions of
:func:`fakeack.study_grid` (``channel=dict(kind="gilbert-elliott", mean=[...], memory=[...])``).

Each (mean, memory) is the on/off Gilbert-Elliott channel of
:func:`fakeack.memory_channel`; a cell is computed by
:func:`fakeack.studies.memory.channel_cell` from the single calls (the exact engine's fast
paths under a Markov channel), so it equals them exactly, on any executor and in any block.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from fractions import Fraction
from typing import Any

import numpy as np

from ...model.schedules import OnlineDesign
from ...montecarlo.protocol import simulate
from ..memory import channel_cell, memory_channel
from .cells import Block, ChannelAxes, mc_attack

__all__ = [
    "KINDS",
    "channel_axes",
    "run_channel_block",
]

#: Channel kinds a study takes as dimensions.
KINDS = ("gilbert-elliott",)
_KEYS = ("kind", "mean", "memory")


def channel_axes(channel: Any, values: Any) -> ChannelAxes | None:
    """``channel`` read as the study's channel dimensions (None: none), or a ``ValueError`` /
    ``TypeError`` naming the key. ``values`` reads one axis as :mod:`.spec` does."""
    if channel is None:
        return None
    if not isinstance(channel, Mapping):
        raise TypeError(
            "channel must be None or dict(kind='gilbert-elliott', mean=[...], memory=[...]), "
            f"got {type(channel).__name__}"
        )
    unknown = sorted(set(channel) - set(_KEYS))
    if unknown:
        raise ValueError(f"channel: unknown key {unknown[0]!r} (expected {', '.join(_KEYS)})")
    kind = channel.get("kind")
    if kind not in KINDS:
        raise ValueError(f"channel kind must be 'gilbert-elliott', got {kind!r}")
    for key in ("mean", "memory"):
        if key not in channel:
            raise ValueError(f"channel: missing {key!r}")
    mean_raw = values("channel mean", channel["mean"])
    mem_raw = values("channel memory", channel["memory"])
    mean, memory = [], []
    for i, x in enumerate(mean_raw):
        memory_channel(x, 0.0, (f"channel mean[{i}]", "channel memory"))
        mean.append(float(x))
    for j, m in enumerate(mem_raw):
        for i, x in enumerate(mean):
            memory_channel(x, m, (f"channel mean[{i}]", f"channel memory[{j}]"))
        memory.append(float(m))
    for name, axis, raw in (("mean", mean, mean_raw), ("memory", memory, mem_raw)):
        seen: dict[float, int] = {}
        for i, v in enumerate(axis):
            if v in seen:
                same = f"{raw[seen[v]]!r} and {raw[i]!r} are the same value"
                raise ValueError(f"channel {name}: duplicate coordinate ({same})")
            seen[v] = i
    return ChannelAxes(tuple(mean), tuple(memory))


def _cell_seed(seed: int, system: str, mean: float, memory: float, ratio: Fraction, beta: Fraction) -> int:
    """The Monte Carlo seed of one channel cell and budget: a 62-bit hash of the study seed and
    the cell's coordinates (as :func:`fakeack.studies.grid.cells.cell_seed` for lam)."""
    key = f"fakeack-grid|{seed}|{system}|ge:{mean.hex()}:{memory.hex()}|{ratio}|{beta}".encode()
    return int.from_bytes(hashlib.blake2b(key, digest_size=8).digest(), "little") >> 2


def _mc_analytic(cell: dict[str, Any], block: Block, channel: Any, beta: Fraction) -> float:
    """The stationary J of the attack the Monte Carlo simulates (J_H tends to it)."""
    from ...attacks.chain import j_attack

    if beta == 1 and block.family == "periodic":
        return float(cell["j_max"])
    return j_attack(block.system, channel, cell["z0"], mu=cell["mu"], attack=mc_attack(block.family, beta))


def run_channel_block(block: Block) -> dict[str, Any]:
    """Every variable of a channel block's cells, each an array of shape
    (1, n_mean, n_memory, n_ratio[, n_beta]); see :func:`fakeack.studies.grid.cells.run_block`."""
    assert block.channel is not None
    mean, memory = block.channel.mean, block.channel.memory
    nb = len(block.beta)
    shape = (len(mean), len(memory), len(block.ratio))
    cells: list[dict[str, Any]] = []
    for x in mean:
        for m in memory:
            ch = memory_channel(x, m)
            for r in block.ratio:
                cell = channel_cell(block.system, ch, r, block.beta, block.family, block.t_max)
                mc = block.montecarlo
                if mc is not None and nb:
                    cell["mc_j"], cell["mc_stderr"] = np.full(nb, np.nan), np.full(nb, np.nan)
                    cell["mc_j_analytic"] = np.full(nb, np.nan)
                    if cell["z0"]:
                        for k, b in enumerate(block.beta):
                            seed = _cell_seed(mc.seed, block.system_name, x, m, r, b)
                            try:
                                cell["mc_j_analytic"][k] = _mc_analytic(cell, block, ch, b)
                                res = simulate(
                                    block.system,
                                    ch,
                                    OnlineDesign(int(cell["z0"]), float(cell["mu"])),
                                    horizon=mc.horizon,
                                    runs=mc.runs,
                                    seed=seed,
                                    attack=mc_attack(block.family, b),
                                    mode=mc.mode,
                                    protocol=mc.protocol,
                                    progress=False,
                                )
                            except ValueError as exc:
                                if cell["status"] == "ok":
                                    cell["status"] = f"error: montecarlo at beta={b}: {exc}"
                                continue
                            cell["mc_j"][k], cell["mc_stderr"][k] = res.j, res.stderr
                cells.append(cell)
    data: dict[str, Any] = {}
    for key in cells[0]:
        values = [c[key] for c in cells]
        kind = object if isinstance(values[0], str) or key == "decision" else None
        arr = np.array(values, dtype=kind) if kind is not None else np.asarray(values)
        if key == "z0":
            arr = arr.astype(np.int64)
        elif arr.dtype != object:
            arr = arr.astype(np.float64)
        if key == "j_attack" or key == "decision" or key.startswith("mc_"):
            data[key] = arr.reshape((1, *shape, nb))
        else:
            data[key] = arr.reshape((1, *shape))
    if not nb:
        data.pop("j_attack", None)
        data.pop("decision", None)
    return {"index": block.index, "data": data}
