"""The dataset of a parameter study: its variables, coordinates and attributes, as an
:class:`xarray.Dataset` (or the arrays that make one)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from ..memory import memory_channel
from .cells import ChannelAxes
from .spec import Spec
from .store import Variable

_EXTRA = (
    "fakeack.study_grid needs the optional 'grid' extra: pip install \"fakeack[grid]\" "
    "(xarray, zarr 3, dask[distributed], h5netcdf)"
)

_LAM_CELL = ("system", "lam", "ratio")
_CHANNEL_CELL = ("system", "mean", "memory", "ratio")


def _variables(sp: Spec) -> list[Variable]:
    """The study's data variables, in dataset order."""
    nb = (len(sp.beta),)
    _CELL = _LAM_CELL if sp.channel is None else _CHANNEL_CELL
    _CELL_BETA = (*_CELL, "beta")
    j_max_note = (
        "J with every flag-ACK blocked; inf when (1 - lam) rho(A)^2 >= 1 (Model note 5)"
        if sp.channel is None
        else "J with every flag-ACK blocked (the always-low sensor); inf when it is unstable"
    )
    j_off_note = (
        "J of the optimal offline schedule (Theorem 3.1, Model note 1)"
        if sp.channel is None
        else "J of the best offline pattern under the channel (fakeack.offline_search)"
    )
    v = [
        Variable(
            "j_offline",
            _CELL,
            "f",
            {"long_name": j_off_note},
        ),
        Variable(
            "j_online", _CELL, "f", {"long_name": "J of the online schedule without attack (Model note 2)"}
        ),
        Variable(
            "j_max",
            _CELL,
            "f",
            {"long_name": j_max_note},
        ),
        Variable(
            "z0", _CELL, "i", {"long_name": "memory length of fakeack.design_online; 0: no online design"}
        ),
        Variable(
            "mu", _CELL, "f", {"long_name": "probability of the z0-step memory (fakeack.design_online)"}
        ),
        Variable(
            "beta_bar_limit",
            _CELL,
            "f",
            {"long_name": "threshold beta-bar of the large-period limit, J_inf(beta) = J_offline"},
        ),
        Variable(
            "beta_bar_finite",
            _CELL,
            "f",
            {"long_name": "smallest r/t (t <= t_max, lowest terms) with J(r, t) >= J_offline; NaN if none"},
        ),
        Variable("beta_bar_finite_rt", _CELL, "U", {"long_name": "beta_bar_finite as 'r/t' ('' if none)"}),
    ]
    if sp.family == "random":
        v.append(
            Variable(
                "beta_bar_random",
                _CELL,
                "f",
                {"long_name": "beta at which independent blocking costs J_offline"},
            )
        )
    v.append(Variable("status", _CELL, "U", {"long_name": "'ok', or why the cell is NaN or special"}))
    if sp.beta:
        what = (
            "J_inf(beta), the large-period worst case of blocking a fraction beta"
            if sp.family == "periodic"
            else "J under independent blocking with probability beta"
        )
        v += [
            Variable("j_attack", _CELL_BETA, "f", {"long_name": what}, nb),
            Variable(
                "decision",
                _CELL_BETA,
                "U",
                {"long_name": "the sensor's schedule against budget beta: online if j_attack < j_offline"},
                nb,
            ),
        ]
    if sp.montecarlo is not None:
        sim = "r/t = beta in lowest terms" if sp.family == "periodic" else "independent blocking"
        v += [
            Variable(
                "mc_j",
                _CELL_BETA,
                "f",
                {"long_name": f"Monte Carlo J_H of the online schedule, attack {sim}"},
                nb,
            ),
            Variable("mc_stderr", _CELL_BETA, "f", {"long_name": "standard error of mc_j"}, nb),
            Variable(
                "mc_j_analytic",
                _CELL_BETA,
                "f",
                {"long_name": "stationary J of the attack the Monte Carlo simulates (J_H tends to it)"},
                nb,
            ),
        ]
    return v


def _coords(sp: Spec) -> dict[str, tuple[tuple[str, ...], np.ndarray, dict[str, Any]]]:
    c: dict[str, tuple[tuple[str, ...], np.ndarray, dict[str, Any]]] = {
        "system": (("system",), np.array(sp.names, dtype=str), {"long_name": "system name"}),
    }
    if sp.channel is None:
        c["lam"] = (
            ("lam",),
            np.array(sp.lam, dtype=np.float64),
            {"long_name": "arrival probability at low power"},
        )
    else:
        c.update(_channel_coords(sp.channel))
    c.update(
        {
            "ratio": (
                ("ratio",),
                np.array([str(r) for r in sp.ratio], dtype=str),
                {"long_name": "energy ratio p/q"},
            ),
            "ratio_value": (
                ("ratio",),
                np.array([float(r) for r in sp.ratio]),
                {"long_name": "energy ratio as a float"},
            ),
            "n_x": (
                ("system",),
                np.array([s.n_x for s in sp.systems], dtype=np.int64),
                {"long_name": "state dimension"},
            ),
        }
    )
    if sp.beta:
        c["beta"] = (("beta",), np.array([float(b) for b in sp.beta]), {"long_name": "attacker budget"})
        c["beta_fraction"] = (
            ("beta",),
            np.array([str(b) for b in sp.beta], dtype=str),
            {"long_name": "beta as r/t"},
        )
    return c


def _channel_coords(axes: ChannelAxes) -> dict[str, tuple[tuple[str, ...], np.ndarray, dict[str, Any]]]:
    """``mean`` and ``memory``, and each cell's channel parameters p and q over both."""
    grid = [[memory_channel(x, m) for m in axes.memory] for x in axes.mean]
    dims = ("mean", "memory")
    return {
        "mean": (
            ("mean",),
            np.array(axes.mean, dtype=np.float64),
            {"long_name": "mean low-power arrival probability q/(p+q)"},
        ),
        "memory": (("memory",), np.array(axes.memory, dtype=np.float64), {"long_name": "memory 1 - p - q"}),
        "p": (
            dims,
            np.array([[ch.p for ch in row] for row in grid]),
            {"long_name": "good-to-bad probability"},
        ),
        "q": (
            dims,
            np.array([[ch.q for ch in row] for row in grid]),
            {"long_name": "bad-to-good probability"},
        ),
    }


def _attrs(sp: Spec) -> dict[str, Any]:
    from ... import __version__

    mc = sp.montecarlo
    channel = {} if sp.channel is None else {"channel": "GilbertElliott(p, q, lam_good=1, lam_bad=0)"}
    return {
        **channel,
        "title": "fakeack parameter study",
        "fakeack_version": __version__,
        "fakeack_study": sp.fingerprint(),
        "family": sp.family,
        "t_max": sp.t_max,
        "seed": "none" if mc is None else mc.seed,
        "montecarlo": "none"
        if mc is None
        else f"runs={mc.runs} horizon={mc.horizon} mode={mc.mode} protocol={mc.protocol}",
        "systems": json.dumps(
            {
                n: {k: m.tolist() for k, m in zip("ACQR", s._matrices(), strict=True)}
                for n, s in zip(sp.names, sp.systems, strict=True)
            }
        ),
    }


def _dataset(sp: Spec, values: dict[str, np.ndarray], attrs: dict[str, Any]) -> Any:
    import xarray as xr

    data = {}
    for var in _variables(sp):
        arr = values[var.name]
        data[var.name] = (var.dims, arr.astype(str) if var.kind == "U" else arr, dict(var.attrs))
    coords = {name: (dims, vals, a) for name, (dims, vals, a) in _coords(sp).items()}
    return xr.Dataset(data, coords=coords, attrs=attrs)
