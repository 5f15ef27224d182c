"""Every public function is documented, and its docstring names every parameter
(python-control's docstrings_test, in small)."""

import inspect

import pytest

import fakeack as fa

PUBLIC = [getattr(fa, n) for n in fa.__all__ if inspect.isfunction(getattr(fa, n))]


@pytest.mark.parametrize("fn", PUBLIC, ids=lambda f: f.__name__)
def test_documented(fn):
    doc = inspect.getdoc(fn)
    assert doc and len(doc) > 40, f"{fn.__name__} has no real docstring"
    for name in inspect.signature(fn).parameters:
        assert name in doc, f"{fn.__name__}: parameter {name!r} is not documented"


def test_classes_documented():
    for n in fa.__all__:
        obj = getattr(fa, n)
        if inspect.isclass(obj):
            assert inspect.getdoc(obj), n


DOCTEST_MODULES = [
    "attacks.automata",
    "attacks.jamming",
    "attacks.chain",
    "attacks.kinds",
    "attacks.random",
    "attacks.rates",
    "detection.cusum",
    "detection.flags",
    "detection.interval_test",
    "detection.intervals",
    "detection.likelihood",
    "detection.probability",
    "detection.run_length",
    "game.policies",
    "model.channels",
    "model.schedules",
    "model.offline",
    "model.system",
    "engine.scenario",
    "engine.stability",
    "montecarlo.curves",
    "optimal.policies",
    "optimal.power",
    "optimal.jamming",
    "optimal.attack",
    "optimal.state_policy",
]


@pytest.mark.parametrize("module", DOCTEST_MODULES)
def test_docstring_examples_run(module):
    """Every example in a docstring runs, with the public names of ``fakeack`` in scope."""
    import doctest
    import importlib

    mod = importlib.import_module(f"fakeack.{module}")
    scope = {n: getattr(fa, n) for n in fa.__all__}
    result = doctest.testmod(mod, extraglobs=scope, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and result.attempted > 0
