"""fakeack.study_grid over bursty channels (the mean and memory dimensions), fakeack.memory_sweep
and the memory figure: every cell against the single calls, the i.i.d. point against the paper's
channel, blocks, executors, an interrupted store resumed, the config and the command line."""

import concurrent.futures as cf
import math
from fractions import Fraction

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER
from fakeack import cli
from fakeack.config import loads
from fakeack.config.grid import ConfigError, parse_grid_config
from fakeack.studies.grid import run_study

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

MEANS = [0.4, 0.5]
# -0.25: alternating states; 0: the i.i.d. channel; 0.6: J_max infinite at mean 0.5 for A = 1.2.
MEMORIES = [-0.25, 0.0, 0.6]
RATIOS = ["1/7", "1/5"]
BETAS = ["1/5", 1]
CHANNEL = dict(kind="gilbert-elliott", mean=MEANS, memory=MEMORIES)


@pytest.fixture(scope="module")
def system():
    return fa.LinearSystem(**PAPER)


@pytest.fixture(scope="module")
def study(system):
    return fa.study_grid({"paper": system}, ratio=RATIOS, beta=BETAS, t_max=30, channel=CHANNEL)


def same(a, b):
    """Equal bit for bit (NaN equal to NaN)."""
    return np.asarray(a, dtype=np.float64).tobytes() == np.asarray(b, dtype=np.float64).tobytes()


def test_dimensions_coordinates_and_the_channel_of_each_cell(study):
    assert dict(study.sizes) == {"system": 1, "mean": 2, "memory": 3, "ratio": 2, "beta": 2}
    assert study["j_online"].dims == ("system", "mean", "memory", "ratio")
    assert study["j_attack"].dims == ("system", "mean", "memory", "ratio", "beta")
    for i, mean in enumerate(MEANS):
        for j, m in enumerate(MEMORIES):
            p, q = float(study.p[i, j]), float(study.q[i, j])
            # The definition: p = (1 - m)(1 - mean), q = (1 - m) mean, so q/(p+q) = mean, 1-p-q = m.
            assert p == (1 - m) * (1 - mean) and q == (1 - m) * mean
            assert math.isclose(q / (p + q), mean, rel_tol=1e-14)
            assert math.isclose(1 - p - q, m, abs_tol=1e-14)


def test_every_cell_equals_the_single_calls(study, system):
    for i in range(len(MEANS)):
        for j in range(len(MEMORIES)):
            ch = fa.GilbertElliott(float(study.p[i, j]), float(study.q[i, j]), 1.0, 0.0)
            for k, r in enumerate(RATIOS):
                cell = study.isel(system=0, mean=i, memory=j, ratio=k)
                assert same(cell.j_offline, fa.j_offline(system, ch, r))
                assert same(cell.j_max, fa.j_max(system, ch))
                z0, mu = fa.design_online(ch, r)
                assert (int(cell.z0), float(cell.mu)) == (z0, mu)
                assert same(cell.j_online, fa.j_online(system, ch, z0, mu))
                bar = fa.beta_bar(system, ch, r, 30)
                assert same(cell.beta_bar_limit, bar.limit)
                finite = math.nan if bar.finite is None else float(bar.finite)
                assert same(cell.beta_bar_finite, finite)
                for b, beta in enumerate(BETAS):
                    j_att = fa.j_attack_limit(system, ch, z0, Fraction(beta), mu)
                    assert same(cell.j_attack[b], j_att)
                    expect = "online" if j_att < fa.j_offline(system, ch, r) else "offline"
                    assert str(cell.decision[b].values) == expect
                stable = math.isfinite(fa.j_max(system, ch))
                assert (str(cell.status.values) == "ok") == stable


def test_memory_zero_is_the_iid_channel_of_the_same_mean(study, system):
    """At memory 0 (p + q = 1) the channel is i.i.d.: the cell equals the paper's channel's
    closed forms (Theorems 3.1, 4.5, Model note 5) to rounding."""
    j = MEMORIES.index(0.0)
    for i, mean in enumerate(MEANS):
        for k, r in enumerate(RATIOS):
            cell = study.isel(system=0, mean=i, memory=j, ratio=k)
            z0, mu = fa.design_online(mean, r)
            assert int(cell.z0) == z0 and math.isclose(float(cell.mu), mu, rel_tol=1e-9)
            for name, value in (
                ("j_online", fa.j_online(system, mean, z0, mu)),
                ("j_offline", fa.j_offline(system, mean, r)),
                ("j_max", fa.j_max(system, mean)),
            ):
                assert math.isclose(float(cell[name]), value, rel_tol=1e-9), name


def test_results_do_not_depend_on_block_or_executor(study, system):
    one = fa.study_grid({"paper": system}, ratio=RATIOS, beta=BETAS, t_max=30, channel=CHANNEL, block=1)
    with cf.ThreadPoolExecutor(3) as pool:
        pooled = fa.study_grid(
            {"paper": system}, ratio=RATIOS, beta=BETAS, t_max=30, channel=CHANNEL, executor=pool, block=5
        )
    for other in (one, pooled):
        for name in [*study.data_vars, *study.coords]:
            a, b = study[name].values, other[name].values
            if a.dtype.kind == "f":
                assert same(a, b), name
            else:
                assert np.array_equal(a, b), name


class _FailAfter(cf.ThreadPoolExecutor):
    """An executor whose blocks after the first ``n`` fail: a run killed part-way."""

    def __init__(self, n):
        super().__init__(1)
        self.n, self.count = n, 0

    def submit(self, fn, *args, **kwargs):
        self.count += 1
        if self.count > self.n:

            def killed(*_a, **_k):
                raise RuntimeError("killed")

            return super().submit(killed)
        return super().submit(fn, *args, **kwargs)


def test_an_interrupted_store_resumes_to_the_same_dataset(tmp_path, study, system):
    store = tmp_path / "channel.zarr"
    args = dict(ratio=RATIOS, beta=BETAS, t_max=30, channel=CHANNEL, block=2)
    with _FailAfter(3) as pool, pytest.raises(RuntimeError, match="killed"):
        fa.study_grid({"paper": system}, **args, executor=pool, store=store)
    resumed, info = run_study({"paper": system}, **args, store=store, resume=True)
    assert info.resumed >= 1 and info.computed >= 1 and info.resumed + info.computed == info.blocks
    for name in study.data_vars:
        a, b = study[name].values, resumed[name].values
        assert same(a, b) if a.dtype.kind == "f" else np.array_equal(a, b), name
    # Another channel grid is another study: refused.
    other = dict(args, channel=dict(CHANNEL, memory=[0.0, 0.5]))
    with pytest.raises(fa.studies.grid.StoreError, match="another study"):
        fa.study_grid({"paper": system}, **other, store=store, resume=True)


def test_monte_carlo_cells_are_single_simulate_calls(system):
    mc = dict(runs=200, horizon=300, seed=5)
    ch = dict(kind="gilbert-elliott", mean=[0.5], memory=[0.5])
    ds = fa.study_grid(system, ratio=["1/7"], beta=["1/5"], channel=ch, montecarlo=mc, t_max=20)
    ge = fa.GilbertElliott(float(ds.p[0, 0]), float(ds.q[0, 0]), 1.0, 0.0)
    design = fa.design_online(ge, "1/7")
    from fakeack.studies.grid.channel import _cell_seed

    seed = _cell_seed(5, "system", 0.5, 0.5, Fraction(1, 7), Fraction(1, 5))
    res = fa.simulate(
        system, ge, design, horizon=300, runs=200, seed=seed, attack=fa.PeriodicBlocking(1, 5), progress=False
    )
    cell = ds.isel(system=0, mean=0, memory=0, ratio=0, beta=0)
    assert same(cell.mc_j, res.j) and same(cell.mc_stderr, res.stderr)
    exact = fa.j_attack(system, ge, design.z0, mu=design.mu, attack=fa.PeriodicBlocking(1, 5))
    assert same(cell.mc_j_analytic, exact)
    assert abs(res.j - exact) < 0.2 * exact  # J_H of 300 steps near the stationary J


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(lam=[0.5], channel=CHANNEL), "lam: give either"),
        (dict(), "lam: missing"),
        (dict(channel=dict(CHANNEL, memory=[0.0], extra=1)), "unknown key 'extra'"),
        (dict(channel=dict(CHANNEL, kind="markov")), "kind must be 'gilbert-elliott'"),
        (dict(channel=dict(kind="gilbert-elliott", mean=[0.5])), "missing 'memory'"),
        (dict(channel=dict(CHANNEL, mean=[0.5, 1.0])), r"channel mean\[1\] must lie in \(0, 1\)"),
        (dict(channel=dict(CHANNEL, memory=[0.0, 1.0])), r"channel memory\[1\] must be below 1"),
        (dict(channel=dict(CHANNEL, memory=[-0.9])), r"channel memory\[0\] = -0.9 at channel mean\[0\]"),
        (dict(channel=dict(CHANNEL, memory=[0.5, 0.5])), "channel memory: duplicate coordinate"),
        (dict(channel=dict(CHANNEL, memory=[])), "channel memory: empty axis"),
    ],
)
def test_bad_channel_grids_are_refused_before_any_work(system, kwargs, message):
    with pytest.raises(ValueError, match=message):
        fa.study_grid(system, ratio=RATIOS, **kwargs)


def test_a_channel_that_is_not_a_dict_is_a_type_error(system):
    with pytest.raises(TypeError, match="channel must be None or dict"):
        fa.study_grid(system, ratio=RATIOS, channel=fa.GilbertElliott(0.1, 0.1, 1, 0))


def test_memory_sweep_equals_the_grid_and_adds_the_iid_point(study, system):
    sw = fa.memory_sweep(system, 0.5, "1/7", [0.6, -0.25], beta="1/5", t_max=30)
    assert sw.memory.tolist() == [-0.25, 0.0, 0.6] and sw.iid == 1
    col = study.sel(system="paper", mean=0.5, ratio="1/7")
    assert same(sw.j_online, col.j_online) and same(sw.j_offline, col.j_offline)
    assert same(sw.j_attack, col.j_attack.sel(beta=0.2)) and same(sw.beta_bar_limit, col.beta_bar_limit)
    from_ds = fa.MemorySweep.from_dataset(study, "paper", 0.5, "1/7", "1/5")
    assert same(from_ds.j_attack, sw.j_attack) and from_ds.iid == 1
    # Alone it also omits the attack; bad arguments name themselves.
    assert fa.memory_sweep(system, 0.5, "1/7", [0.3]).j_attack is None
    with pytest.raises(ValueError, match="mean must lie in"):
        fa.memory_sweep(system, 1.5, "1/7", [0.3])
    with pytest.raises(TypeError, match=r"memory\[0\] must be a number"):
        fa.memory_sweep(system, 0.5, "1/7", ["x"])
    with pytest.raises(ValueError, match="beta must lie in"):
        fa.memory_sweep(system, 0.5, "1/7", [0.3], beta=2)
    with pytest.raises(ValueError, match="family must be"):
        fa.memory_sweep(system, 0.5, "1/7", [0.3], family="jam")


def test_memory_figure_marks_the_iid_point_and_skips_infinite_costs(system):
    pytest.importorskip("matplotlib")
    from fakeack.plots import plot_memory

    sw = fa.memory_sweep(system, 0.5, "1/7", [-0.25, 0.6], beta="1/5", t_max=30)
    fig = plot_memory(sw)
    left, right = fig.axes[:2]
    # J_attack is infinite at memory 0.6: two of its three points are drawn, and the title says so.
    drawn = {
        line.get_label(): line.get_xdata().tolist()
        for line in left.lines
        if not line.get_label().startswith("_")
    }
    assert drawn["$J_{on}$"] == [-0.25, 0.0, 0.6]
    assert [v for k, v in drawn.items() if k.startswith("$J$, attack")] == [[-0.25, 0.0]]
    assert "J_attack at 1 points" in left.get_title()
    # An open circle at memory 0 on every curve of both panels.
    marks = [line for axis in (left, right) for line in axis.lines if line.get_marker() == "o"]
    assert len(marks) == 5 and all(line.get_xdata().tolist() == [0.0] for line in marks)
    with pytest.raises(TypeError, match="sweep must be"):
        plot_memory(object())


GRID_TOML = """
[grid]
ratio = ["1/7"]
beta = ["1/5"]
t_max = 20
[grid.channel]
kind = "gilbert-elliott"
mean = [0.5]
memory = {start = 0, stop = "1/2", num = 2}
[system]
A = 1.2
C = 0.7
Q = 0.8
R = 0.8
"""


def test_config_reads_the_channel_table_and_names_bad_keys():
    cfg = parse_grid_config(loads(GRID_TOML))
    assert cfg.lam is None and cfg.channel == dict(kind="gilbert-elliott", mean=[0.5], memory=[0.0, 0.5])
    for old, new, message in [
        ("[grid.channel]", "[grid.channel]\nextra = 1", r"\[grid.channel\] extra"),
        ('kind = "gilbert-elliott"', 'kind = "markov"', r"\[grid.channel\] kind"),
        ("mean = [0.5]", "mean = [1.5]", r"\[grid.channel\] mean\[0\] must lie in"),
        ("[grid]\n", "[grid]\nlam = [0.5]\n", r"\[grid\] channel: give either lam"),
        ("mean = [0.5]\n", "", r"\[grid.channel\] mean: missing"),
    ]:
        with pytest.raises(ConfigError, match=message):
            parse_grid_config(loads(GRID_TOML.replace(old, new, 1)))


def test_cli_grid_over_channels_writes_the_memory_figures(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    pytest.importorskip("h5netcdf")
    cfg = tmp_path / "study.toml"
    cfg.write_text(GRID_TOML)
    out = tmp_path / "out"
    assert cli.main(["grid", str(cfg), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "1 mean x 2 memory" in text
    ds = xr.open_dataset(out / "study.nc", engine="h5netcdf")
    assert float(ds.j_online.sel(memory=0.0)[0, 0, 0]) == pytest.approx(
        fa.j_online(fa.LinearSystem(**PAPER), 0.5, *fa.design_online(0.5, "1/7")), rel=1e-9
    )
    assert sorted(p.name for p in out.glob("memory_*")) == [
        "memory_system_mean0.5_ratio1-7.png",
        "memory_system_mean0.5_ratio1-7.svg",
    ]
