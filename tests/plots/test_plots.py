"""The figures' one rule: every plot function draws on the Axes it is given (one per panel) or on a
new Figure with an Agg canvas, returns the Figure drawn on, and never touches pyplot; no library
module imports pyplot or the command line. Small inputs from the public API keep each test fast."""

import ast
from pathlib import Path

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER, PAPER_LAM, PAPER_RATIO
from fakeack import plots

mpl = pytest.importorskip("matplotlib")

from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.layout_engine import ConstrainedLayoutEngine  # noqa: E402

PACKAGE = Path(fa.__file__).resolve().parent


def pyplot_figures() -> list[int]:
    """pyplot's registry of open figures (importing pyplot itself opens none)."""
    import matplotlib.pyplot as plt

    return plt.get_fignums()


# ---------------------------------------------------------------------------------------------
# Small real inputs, built once per module.


@pytest.fixture(scope="module")
def paper():
    return fa.LinearSystem(**PAPER)


@pytest.fixture(scope="module")
def chain_inputs(paper):
    curve = fa.expected_trace_curve(paper, PAPER_LAM, fa.OnlineSchedule(2), 20)
    sweep, bar = (
        fa.beta_sweep(paper, PAPER_LAM, PAPER_RATIO, 10),
        fa.beta_bar(paper, PAPER_LAM, PAPER_RATIO, 10),
    )
    states, _ = fa.attack_chain(PAPER_LAM, 2, 1, 3)
    pi = fa.stationary_distribution(PAPER_LAM, 2, 1, 3)
    return {
        "curves": [plots.JkCurve("online", curve.k, None, curve.j_k, 1.69)],
        "sweep": sweep,
        "bar": bar,
        "states": states,
        "pi": pi,
    }


@pytest.fixture(scope="module")
def game_inputs(paper):
    from fakeack.attacks.families import attack_families

    attacks = [None, fa.PeriodicBlocking(1, 5), fa.PeriodicBlocking(2, 3), fa.FlagInjection(0.05)]
    solution = fa.solve_game(paper, PAPER_LAM, PAPER_RATIO, 1000, [0.01], [2], attacks)
    frontiers = [
        fa.stealthy_frontier(paper, PAPER_LAM, 2, 1000, 0.01, test, family, 0.05, t_max=6, grid=11)
        for test in ("count", "interval")
        for family in ("periodic", "random")
    ]
    families = attack_families(paper, PAPER_LAM, PAPER_RATIO, 3.0, 1.0, betas=np.linspace(0.0, 1.0, 11))
    curves = fa.detection.detection_curves(
        PAPER_LAM, 2, [None, fa.PeriodicBlocking(1, 5), fa.FlagInjection(0.2)], [500, 1000]
    )
    return {
        "solution": solution,
        "curves": curves,
        "frontiers": frontiers,
        "j_offline": solution.j_offline,
        "families": families,
    }


@pytest.fixture(scope="module")
def grid_inputs(paper):
    # The small study of tests/studies/test_grid.py's command-line test: 3 lam x 2 ratios x 2 budgets.
    pytest.importorskip("xarray")
    return {"ds": fa.study_grid({"paper": paper}, [0.4, 0.5, 0.6], ["1/7", "1/5"], ["1/5", "2/3"], t_max=30)}


# name: (inputs fixture, number of panels, how to draw with a given ``ax``).
CASES = {
    "plot_jk": ("chain_inputs", 1, lambda d, ax: plots.plot_jk(d["curves"], ax, title="J_k", mc_runs=10)),
    "plot_beta_sweep": (
        "chain_inputs",
        1,
        lambda d, ax: plots.plot_beta_sweep(d["sweep"], d["bar"], ax=ax, paper_beta_bar=0.28),
    ),
    "plot_stationary": (
        "chain_inputs",
        1,
        lambda d, ax: plots.plot_stationary(d["states"], d["pi"], ax, r=1),
    ),
    "plot_game": ("game_inputs", 1, lambda d, ax: fa.plot_game(d["solution"], ax)),
    "plot_detection_curves": (
        "game_inputs",
        3,
        lambda d, ax: plots.plot_detection_curves(d["curves"], ax=ax),
    ),
    "plot_frontiers": ("game_inputs", 2, lambda d, ax: fa.plot_frontiers(d["frontiers"], d["j_offline"], ax)),
    "plot_attack_families": ("game_inputs", 2, lambda d, ax: plots.plot_attack_families(d["families"], ax)),
    "plot_beta_bar": ("grid_inputs", 1, lambda d, ax: plots.plot_beta_bar(d["ds"], "paper", ax)),
    "plot_decision": ("grid_inputs", 2, lambda d, ax: plots.plot_decision(d["ds"], "paper", ax)),
    "plot_stability_region": ("stability_inputs", 2, lambda d, ax: plots.plot_stability_region(d, ax)),
    "plot_memory": ("memory_inputs", 2, lambda d, ax: plots.plot_memory(d, ax)),
    "plot_delay_frontier": ("delay_inputs", 1, lambda d, ax: fa.plot_delay_frontier(d, ax)),
    "plot_attack_effort": ("effort_inputs", 1, lambda d, ax: plots.plot_attack_effort(d, ax)),
}


@pytest.fixture(scope="module")
def delay_inputs(paper):
    return [
        fa.delay_frontier(paper, 0.5, "1/7", 2e4, fam, window=200, grid=2) for fam in ("random", "mimicry")
    ]


@pytest.fixture(scope="module")
def effort_inputs(paper):
    from fakeack.optimal import attack_effort

    return attack_effort(paper, 0.5, "1/7", [0.0, 0.04], kinds=("jam", "block"))


@pytest.fixture(scope="module")
def memory_inputs(paper):
    return fa.memory_sweep(paper, 0.5, "1/7", [-0.2, 0.3], beta="1/5", t_max=20)


@pytest.fixture(scope="module")
def stability_inputs(paper):
    grid = np.linspace(0.1, 1.0, 4)
    design = fa.OnlineDesign(2)
    return [
        fa.stability_region(paper, design, p=grid, q=grid, lam_good=0.5),
        fa.stability_region(paper, fa.OfflineSchedule("1/7"), p=grid, q=grid, lam_good=0.5),
    ]


def test_every_public_plot_function_is_covered():
    assert {n for n in plots.__all__ if n.startswith("plot_")} == set(CASES)


@pytest.mark.parametrize("name", CASES)
def test_draws_on_the_given_axes(name, request):
    inputs, panels, draw = CASES[name]
    data = request.getfixturevalue(inputs)
    fig = Figure()
    axes = list(np.ravel(fig.subplots(panels, 1)))
    given = axes[0] if panels == 1 else axes
    assert draw(data, given) is fig
    assert all(ax.has_data() for ax in axes), "a panel was left empty"
    assert pyplot_figures() == []


@pytest.mark.parametrize("name", CASES)
def test_without_axes_a_new_figure_on_an_agg_canvas(name, request):
    inputs, panels, draw = CASES[name]
    data = request.getfixturevalue(inputs)
    fig = draw(data, None)
    assert isinstance(fig, Figure)
    assert isinstance(fig.canvas, FigureCanvasAgg)
    assert isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)
    drawn = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert len(drawn) == panels and all(ax.has_data() for ax in drawn)
    fig.canvas.draw()  # lays out and renders without a GUI
    assert pyplot_figures() == []


@pytest.mark.parametrize("name", [n for n, (_, panels, _) in CASES.items() if panels > 1])
def test_one_axes_per_panel_or_a_clear_error(name, request):
    inputs, panels, draw = CASES[name]
    data = request.getfixturevalue(inputs)
    fig = Figure()
    with pytest.raises(ValueError, match=rf"ax must be {panels} Axes"):
        draw(data, list(fig.subplots(1, panels + 1)))
    # A 2-d array of Axes, as Figure.subplots returns it, is one Axes per panel too.
    assert draw(data, Figure().subplots(panels, 1, squeeze=False)) is not None


def test_decision_key_stays_beside_the_callers_panels(grid_inputs):
    fig = Figure()
    axes = fig.subplots(1, 2)
    plots.plot_decision(grid_inputs["ds"], ax=axes)
    assert not fig.legends and axes[-1].get_legend() is not None
    assert plots.plot_decision(grid_inputs["ds"]).legends  # its own figure: one key for all panels


def test_frontier_title_only_on_its_own_figure(game_inputs):
    fig = Figure()
    fa.plot_frontiers(game_inputs["frontiers"], ax=fig.subplots(1, 2))
    assert fig.get_suptitle() == ""
    assert "Stealthy frontiers" in fa.plot_frontiers(game_inputs["frontiers"]).get_suptitle()


def test_leaves_the_callers_pyplot_figure_alone(chain_inputs):
    import matplotlib.pyplot as plt

    mine = plt.figure()
    try:
        plots.plot_stationary(chain_inputs["states"], chain_inputs["pi"])
        assert plt.get_fignums() == [mine.number] and plt.gcf() is mine and not mine.axes
    finally:
        plt.close(mine)


# ---------------------------------------------------------------------------------------------
# Writing figures.


def test_save_figure_writes_png_and_svg_atomically_and_reproducibly(tmp_path, chain_inputs):
    out = tmp_path / "new" / "dir"

    def draw():
        return plots.plot_stationary(chain_inputs["states"], chain_inputs["pi"], r=1)

    written = plots.save_figure(draw(), out, "fig")
    assert written == [out / "fig.png", out / "fig.svg"]
    png, svg = (p.read_bytes() for p in written)
    assert png.startswith(b"\x89PNG") and b"<svg" in svg[:2000]
    assert b"Software" not in png and b"<dc:date>" not in svg
    assert {p.name for p in out.iterdir()} == {"fig.png", "fig.svg"}  # no temporary file left
    again = plots.save_figure(draw(), out, "fig")
    assert [p.read_bytes() for p in again] == [png, svg]


def test_save_figure_leaves_the_target_on_a_failed_write(tmp_path, chain_inputs, monkeypatch):
    import os

    fig = plots.plot_stationary(chain_inputs["states"], chain_inputs["pi"])
    (tmp_path / "fig.png").write_bytes(b"old")

    def interrupted(*args):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        plots.save_figure(fig, tmp_path, "fig")
    assert (tmp_path / "fig.png").read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["fig.png"]


def test_write_heat_maps(tmp_path, grid_inputs):
    written = plots.write_heat_maps(grid_inputs["ds"], tmp_path)
    names = {f"{stem}_paper.{ext}" for stem in ("beta_bar", "decision") for ext in ("png", "svg")}
    assert {p.name for p in written} == names == {p.name for p in tmp_path.iterdir()}
    assert pyplot_figures() == []


# ---------------------------------------------------------------------------------------------
# The source: no pyplot anywhere in the library, and the library never imports the command line.


def _imports(path: Path) -> list[str]:
    """Absolute names of every module ``path`` imports (relative imports resolved)."""
    # The package a relative import starts from: the module's own for both x.py and __init__.py.
    package = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)[:-1]
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package[: len(package) - (node.level - 1)]
                base = ".".join([*parent, *([base] if base else [])])
            names += [base, *(f"{base}.{a.name}" for a in node.names)]
    return names


SOURCES = sorted(PACKAGE.rglob("*.py"))


def test_sources_found():
    assert PACKAGE / "plots" / "_figure.py" in SOURCES and len(SOURCES) > 30


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_imports_pyplot(path):
    bad = [n for n in _imports(path) if n == "matplotlib.pyplot" or n.startswith("matplotlib.pyplot.")]
    assert not bad, f"{path.relative_to(PACKAGE)} imports {bad}"


@pytest.mark.parametrize(
    "path",
    [p for p in SOURCES if p.relative_to(PACKAGE).parts[0] not in ("cli", "__main__.py")],
    ids=lambda p: str(p.relative_to(PACKAGE)),
)
def test_library_modules_never_import_the_command_line(path):
    bad = [n for n in _imports(path) if n == "fakeack.cli" or n.startswith("fakeack.cli.")]
    assert not bad, f"{path.relative_to(PACKAGE)} imports {bad}"


def test_import_resolution_sees_relative_imports():
    # ``from ._figure import save_figure`` in fakeack/plots/grid.py, and two levels up from
    # fakeack/plots/game.py: the checks above would see ``from ..cli import x`` the same way.
    assert "fakeack.plots._figure.save_figure" in _imports(PACKAGE / "plots" / "grid.py")
    assert "fakeack.attacks.kinds.FlagInjection" in _imports(PACKAGE / "plots" / "game.py")
    assert "numpy" in _imports(PACKAGE / "plots" / "grid.py")
