r"""What the memory of a bursty channel does at a fixed mean: the on/off Gilbert-Elliott channel
of mean arrival ``mean`` and memory :math:`m = 1 - p - q`, and one study cell under it.

With :math:`\lambda_{\mathrm{good}} = 1`, :math:`\lambda_{\mathrm{bad}} = 0` the mean low-power
arrival probability is :math:`\pi_{\mathrm{good}} = q/(p+q)`, so the channel of mean
:math:`\bar\lambda` and memory :math:`m` has

.. math:: p = (1 - m)(1 - \bar\lambda), \qquad q = (1 - m)\,\bar\lambda,

and :math:`m` is the correlation of successive channel states: :math:`m = 0` is the i.i.d.
channel of :math:`\lambda = \bar\lambda` (then :math:`p + q = 1`), :math:`m \to 1` ever longer
bursts, :math:`m < 0` alternation. :func:`channel_cell` computes one cell of
:func:`fakeack.study_grid` under such a channel from the public functions, so a cell equals the
single calls exactly; :func:`memory_sweep` runs it along the memory at a fixed mean and
:func:`fakeack.plots.plot_memory` draws the result.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .._internal.types import FloatArray, RatioLike
from .._internal.validate import as_fraction, as_int, as_ratio
from ..attacks.chain import j_attack
from ..attacks.kinds import RandomBlocking
from ..attacks.random import beta_bar_random
from ..attacks.threshold import beta_bar, j_attack_limit
from ..model.channels import GilbertElliott
from ..model.schedules import design_online, j_max, j_offline, j_online
from ..model.system import LinearSystem

__all__ = [
    "FAMILIES",
    "MemorySweep",
    "channel_cell",
    "memory_channel",
    "memory_sweep",
]

#: Attack families of a study cell (as in :func:`fakeack.study_grid`).
FAMILIES = ("periodic", "random")


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating, Fraction)):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x


def memory_channel(mean: float, memory: float, names: tuple[str, str] = ("mean", "memory")) -> GilbertElliott:
    r"""The on/off Gilbert-Elliott channel of mean arrival ``mean`` and memory ``memory``.

    ``GilbertElliott((1 - memory) * (1 - mean), (1 - memory) * mean, 1, 0)``, computed in that
    order in floating point (a study's cell is this channel exactly).

    Parameters
    ----------
    mean : float
        The stationary low-power arrival probability :math:`\pi_{\mathrm{good}}`, in (0, 1).
    memory : float
        :math:`1 - p - q`, below 1; at least :math:`1 - 1/\max(\bar\lambda, 1 - \bar\lambda)` so
        that p and q are probabilities.
    names : (str, str)
        The argument names used in error messages.

    Returns
    -------
    GilbertElliott

    Raises
    ------
    ValueError
        For a mean outside (0, 1) or a memory that gives no channel (naming the argument).
    """
    m_name, k_name = names
    mean_ = _number(m_name, mean)
    mem = _number(k_name, memory)
    if not 0.0 < mean_ < 1.0:
        raise ValueError(f"{m_name} must lie in (0, 1), got {mean!r}")
    if not mem < 1.0:
        raise ValueError(f"{k_name} must be below 1 (memory 1 never changes state), got {memory!r}")
    p, q = (1.0 - mem) * (1.0 - mean_), (1.0 - mem) * mean_
    if p > 1.0 or q > 1.0:
        low = 1.0 - 1.0 / max(mean_, 1.0 - mean_)
        raise ValueError(
            f"{k_name} = {memory!r} at {m_name} = {mean!r} gives p = {p:.6g}, q = {q:.6g}: a memory "
            f"below {low:.6g} has no channel of this mean"
        )
    return GilbertElliott(p, q, 1.0, 0.0)


def _design_or_reason(channel: GilbertElliott, ratio: Fraction) -> tuple[Any, str]:
    try:
        return design_online(channel, ratio), "ok"
    except ValueError as exc:
        return None, f"no online design: {exc}"


def channel_cell(
    system: LinearSystem,
    channel: GilbertElliott,
    ratio: Fraction,
    beta: Sequence[Fraction],
    family: str,
    t_max: int,
) -> dict[str, Any]:
    r"""One cell of a study under ``channel``: the values of the single calls.

    :func:`fakeack.design_online` (z0, mu), :func:`fakeack.j_offline` (the best offline pattern
    of :func:`fakeack.offline_search`), :func:`fakeack.j_online`, :func:`fakeack.j_max`,
    :func:`fakeack.beta_bar` (``beta_bar_limit``, ``beta_bar_finite``), with ``family="random"``
    :func:`fakeack.beta_bar_random`, and at each budget the attacked cost
    (:func:`fakeack.j_attack_limit`, or :func:`fakeack.j_attack` of ``RandomBlocking(beta)``) and
    the decision (online iff it is below J_offline).

    Returns
    -------
    dict
        Scalars by variable name (``j_attack`` and ``decision`` arrays over ``beta``); NaN, z0 = 0
        and the reason in ``status`` where a value cannot be computed.
    """
    nb = len(beta)
    out: dict[str, Any] = {
        "j_offline": math.nan,
        "j_online": math.nan,
        "j_max": math.nan,
        "z0": 0,
        "mu": math.nan,
        "beta_bar_limit": math.nan,
        "beta_bar_finite": math.nan,
        "beta_bar_finite_rt": "",
        "status": "ok",
    }
    if family == "random":
        out["beta_bar_random"] = math.nan
    j_att = np.full(nb, math.nan)
    try:
        out["j_offline"] = j_offline(system, channel, ratio)
        out["j_max"] = j_max(system, channel)
        design, out["status"] = _design_or_reason(channel, ratio)
        if design is not None:
            z0, mu = design
            out["z0"], out["mu"] = z0, mu
            out["j_online"] = j_online(system, channel, z0, mu)
            bar = beta_bar(system, channel, ratio, t_max)
            out["beta_bar_limit"] = bar.limit
            if bar.finite is not None:
                out["beta_bar_finite"] = float(bar.finite)
                out["beta_bar_finite_rt"] = f"{bar.finite.numerator}/{bar.finite.denominator}"
            if family == "random":
                out["beta_bar_random"] = beta_bar_random(system, channel, ratio)
            for k, b in enumerate(beta):
                if family == "periodic":
                    j_att[k] = j_attack_limit(system, channel, z0, b, mu)
                else:
                    j_att[k] = j_attack(system, channel, z0, mu=mu, attack=RandomBlocking(b))
    except ValueError as exc:
        out["status"] = f"error: {exc}"
    if out["status"] == "ok" and math.isinf(out["j_max"]):
        out["status"] = "J_max is infinite: the always-low sensor is unstable on this channel"
    known = ~(np.isnan(j_att) | math.isnan(out["j_offline"]))
    out["j_attack"] = j_att
    out["decision"] = np.where(known, np.where(j_att < out["j_offline"], "online", "offline"), "n/a").astype(
        object
    )
    return out


@dataclass(frozen=True)
class MemorySweep:
    """The study along the memory at one mean (see :func:`memory_sweep`); arrays over ``memory``."""

    mean: float
    ratio: Fraction
    beta: Fraction | None
    """The budget of ``j_attack`` (None: no attack)."""
    family: str
    t_max: int
    memory: FloatArray
    """Memory 1 - p - q, increasing (:func:`memory_sweep` always includes 0, the i.i.d. channel)."""
    p: FloatArray
    q: FloatArray
    j_online: FloatArray
    j_offline: FloatArray
    j_max: FloatArray
    j_attack: FloatArray | None
    beta_bar_limit: FloatArray
    beta_bar_finite: FloatArray
    status: tuple[str, ...]

    @property
    def iid(self) -> int | None:
        """Index of memory 0, the i.i.d. channel of the same mean (None if absent)."""
        at = np.flatnonzero(self.memory == 0.0)
        return int(at[0]) if at.size else None

    @classmethod
    def from_dataset(
        cls, ds: Any, system: str, mean: float, ratio: Fraction | str, beta: Fraction | str | None = None
    ) -> MemorySweep:
        """The sweep along ``memory`` held in a study of :func:`fakeack.study_grid` with
        ``channel=dict(kind="gilbert-elliott", ...)``, at one system, mean, ratio (and budget)."""
        if "memory" not in ds.dims:
            raise ValueError("ds: not a study over channel memories (no 'memory' dimension)")
        cell = ds.sel(system=system, mean=mean, ratio=str(as_ratio("ratio", ratio)))
        order = np.argsort(np.asarray(cell["memory"].values, dtype=float))
        cell = cell.isel(memory=order)
        j_att = None
        if beta is not None:
            b = as_fraction("beta", beta)
            j_att = np.asarray(cell["j_attack"].sel(beta=float(b)).values, dtype=float)
        return cls(
            mean=float(mean),
            ratio=as_ratio("ratio", ratio),
            beta=None if beta is None else as_fraction("beta", beta),
            family=str(ds.attrs["family"]),
            t_max=int(ds.attrs["t_max"]),
            memory=np.asarray(cell["memory"].values, dtype=float),
            p=np.asarray(cell["p"].values, dtype=float),
            q=np.asarray(cell["q"].values, dtype=float),
            j_online=np.asarray(cell["j_online"].values, dtype=float),
            j_offline=np.asarray(cell["j_offline"].values, dtype=float),
            j_max=np.asarray(cell["j_max"].values, dtype=float),
            j_attack=j_att,
            beta_bar_limit=np.asarray(cell["beta_bar_limit"].values, dtype=float),
            beta_bar_finite=np.asarray(cell["beta_bar_finite"].values, dtype=float),
            status=tuple(str(x) for x in cell["status"].values),
        )


def memory_sweep(
    system: LinearSystem,
    mean: float,
    ratio: RatioLike,
    memory: Sequence[float] | FloatArray,
    beta: float | Fraction | str | None = None,
    family: str = "periodic",
    t_max: int = 60,
) -> MemorySweep:
    r"""J_online, J_offline, J under an attack and :math:`\bar\beta` against the channel's memory.

    Each point is the on/off Gilbert-Elliott channel of the given mean and memory
    :math:`m = 1 - p - q` (:math:`p = (1-m)(1-\bar\lambda)`, :math:`q = (1-m)\bar\lambda`); the
    online schedule is designed for it (:func:`fakeack.design_online`) and the offline one is
    its best pattern (:func:`fakeack.offline_search`), so every curve compares schedules that
    spend the same budget on the same channel. Memory 0, the i.i.d. channel of
    :math:`\lambda = \bar\lambda`, is added when absent. Each point equals the single calls (and
    the cell of :func:`fakeack.study_grid` with ``channel=dict(kind="gilbert-elliott", ...)``).

    Parameters
    ----------
    system : LinearSystem
        The process and sensor.
    mean : float
        The mean low-power arrival probability, in (0, 1).
    ratio : Fraction or str
        The energy ratio p/q in (0, 1).
    memory : sequence of float
        Memories 1 - p - q below 1 (see :func:`fakeack.memory_channel`).
    beta : float, Fraction or str, optional
        An attacker budget in [0, 1] (read exactly): J of the large-period worst case
        :func:`fakeack.j_attack_limit` (``family="periodic"``) or of independent blocking.
    family : {"periodic", "random"}
        The attack at ``beta``.
    t_max : int
        Largest attack period of the finite threshold.

    Returns
    -------
    MemorySweep

    Raises
    ------
    ValueError, TypeError
        For a bad argument, naming it.

    Examples
    --------
    >>> import fakeack as fa
    >>> s = fa.LinearSystem(1.2, 0.7, 0.8, 0.8)
    >>> sw = fa.memory_sweep(s, 0.5, "1/7", [0.0, 0.5], beta="1/5")
    >>> bool(sw.j_online[sw.iid] < sw.j_offline[sw.iid])
    True
    """
    if not isinstance(system, LinearSystem):
        raise TypeError(f"system must be a fakeack.LinearSystem, got {type(system).__name__}")
    ratio_ = as_ratio("ratio", ratio)
    if family not in FAMILIES:
        raise ValueError(f"family must be 'periodic' or 'random', got {family!r}")
    t_max_ = as_int("t_max", t_max, minimum=2, maximum=2**32 - 1)
    beta_: Fraction | None = None
    if beta is not None:
        beta_ = as_fraction("beta", beta)
        if not 0 <= beta_ <= 1:
            raise ValueError(f"beta must lie in [0, 1], got {beta!r}")
    raw = np.atleast_1d(np.asarray(memory, dtype=object))
    if raw.ndim != 1 or raw.size == 0:
        raise ValueError("memory: give a non-empty sequence of numbers")
    mems = sorted({_number(f"memory[{i}]", x) for i, x in enumerate(raw.tolist())} | {0.0})
    channels = [memory_channel(mean, m, ("mean", "memory")) for m in mems]
    cells = [
        channel_cell(system, ch, ratio_, () if beta_ is None else (beta_,), family, t_max_) for ch in channels
    ]

    def col(key: str) -> FloatArray:
        return np.array([c[key] for c in cells], dtype=np.float64)

    return MemorySweep(
        mean=float(mean),
        ratio=ratio_,
        beta=beta_,
        family=family,
        t_max=t_max_,
        memory=np.array(mems),
        p=np.array([ch.p for ch in channels]),
        q=np.array([ch.q for ch in channels]),
        j_online=col("j_online"),
        j_offline=col("j_offline"),
        j_max=col("j_max"),
        j_attack=None if beta_ is None else np.array([c["j_attack"][0] for c in cells]),
        beta_bar_limit=col("beta_bar_limit"),
        beta_bar_finite=col("beta_bar_finite"),
        status=tuple(str(c["status"]) for c in cells),
    )
