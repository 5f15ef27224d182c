"""Module paths that the documentation of the previous release named keep working for one release,
with a DeprecationWarning that names the new path."""

import importlib
import sys

import pytest


@pytest.mark.parametrize(
    ("old", "new", "name"),
    [
        ("fakeack.study", "fakeack.studies.report", "analyse"),
        ("fakeack.grid_figures", "fakeack.plots.grid", "plot_beta_bar"),
    ],
)
def test_old_module_path_warns_and_works(old, new, name):
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=new.replace(".", r"\.")):
        mod = importlib.import_module(old)
    assert getattr(mod, name) is getattr(importlib.import_module(new), name)
