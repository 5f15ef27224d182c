"""plot_stability_region follows the figures' rule (tests/plots/test_plots.py): it draws on the Axes
it is given (one per region) or on a new Figure with an Agg canvas, returns the Figure and never
touches pyplot. The paper's system under the online schedule with and without PeriodicBlocking(1, 5)
and under the offline schedule makes the three-panel figure."""

import numpy as np
import pytest

import fakeack as fa
from conftest import PAPER, PAPER_RATIO
from fakeack.engine.stability import stability_region
from fakeack.plots.stability import plot_stability_region

mpl = pytest.importorskip("matplotlib")

from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.layout_engine import ConstrainedLayoutEngine  # noqa: E402

GRID = np.linspace(0.05, 1.0, 12)
#: A bad state where low power is always lost and high power arrives one time in five.
RATES = dict(lam_good=0.5, lam_bad=0.0, high_good=1.0, high_bad=0.2)


def pyplot_figures():
    import matplotlib.pyplot as plt

    return plt.get_fignums()


@pytest.fixture(scope="module")
def regions():
    s = fa.LinearSystem(**PAPER)
    return [
        stability_region(s, fa.OnlineDesign(2), None, p=GRID, q=GRID, **RATES),
        stability_region(s, fa.OnlineDesign(2), fa.PeriodicBlocking(1, 5), p=GRID, q=GRID, **RATES),
        stability_region(s, fa.OfflineSchedule(PAPER_RATIO), p=GRID, q=GRID, **RATES),
    ]


def panels(fig):
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]


def test_the_three_regions_differ_and_the_attack_shrinks_the_online_one(regions):
    online, attacked, offline = (int(r.stable.sum()) for r in regions)
    assert 0 < offline < attacked < online < GRID.size**2
    assert (regions[1].stable <= regions[0].stable).all()


def test_without_axes_a_new_figure_on_an_agg_canvas(regions):
    fig = plot_stability_region(regions)
    assert isinstance(fig, Figure) and isinstance(fig.canvas, FigureCanvasAgg)
    assert isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)
    drawn = panels(fig)
    assert len(drawn) == 3 and all(ax.has_data() for ax in drawn)
    assert len(fig.axes) == 4  # one colour bar for the three panels
    for ax, reg in zip(drawn, regions, strict=True):
        assert ax.collections, "no colour map"
        iid = [line for line in ax.get_lines() if line.get_label().startswith("i.i.d.")]
        assert (
            len(iid) == 1
            and list(iid[0].get_xdata()) == [0.0, 1.0]
            and list(iid[0].get_ydata()) == [1.0, 0.0]
        )
        assert f"{int(reg.stable.sum())} of {GRID.size**2}" in ax.get_title()
    assert "1/5" in drawn[1].get_title() and "offline" in drawn[2].get_title()
    fig.canvas.draw()  # lays out and renders without a GUI
    assert pyplot_figures() == []


def test_draws_on_the_given_axes(regions):
    fig = Figure()
    axes = fig.subplots(1, 3)
    assert plot_stability_region(regions, axes) is fig
    assert all(ax.has_data() for ax in axes)
    one = Figure()
    ax = one.subplots()
    assert plot_stability_region(regions[0], ax, titles=["mine"]) is one
    assert ax.get_title().startswith("mine")
    assert pyplot_figures() == []


def test_a_region_stable_everywhere_and_a_masked_point_draw_without_warnings():
    """No level 1 to draw (every point stable): no contour, and no matplotlib warning (warnings are
    errors here); the point p = q = 0 is grey."""
    s = fa.LinearSystem(**PAPER)
    everywhere = stability_region(s, fa.OnlineDesign(2), p=[0.0, 0.5, 1.0], q=[0.0, 0.5, 1.0])
    assert everywhere.stable.sum() == 8 and not everywhere.evaluated[0, 0]
    fig = plot_stability_region(everywhere)
    fig.canvas.draw()
    single = stability_region(s, fa.OfflineSchedule(pattern="0"), p=[0.3], q=[0.5])
    plot_stability_region(single).canvas.draw()


def test_one_axes_and_one_title_per_region_or_a_clear_error(regions):
    with pytest.raises(ValueError, match="ax must be 3 Axes"):
        plot_stability_region(regions, list(Figure().subplots(1, 2)))
    with pytest.raises(ValueError, match="titles"):
        plot_stability_region(regions, titles=["a"])
    with pytest.raises(TypeError, match="region"):
        plot_stability_region([])
    with pytest.raises(TypeError, match="region"):
        plot_stability_region([regions[0], "x"])
