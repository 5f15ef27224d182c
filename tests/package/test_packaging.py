"""Packaging and interoperability: the version has one source, TOML configs can be read on every
supported Python, state-space models from python-control convert, and results render in Jupyter."""

import importlib.metadata
import re
import sys
import types
from fractions import Fraction
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.signal

import fakeack as fa
from fakeack import config

ROOT = Path(__file__).resolve().parents[2]


def _cargo_version() -> str:
    text = (ROOT / "Cargo.toml").read_text(encoding="utf-8")
    return re.search(r'^version = "([^"]+)"', text, re.M).group(1)


def test_version_comes_from_cargo_toml():
    assert fa.__version__ == _cargo_version()
    assert (
        "version"
        in (ROOT / "pyproject.toml").read_text(encoding="utf-8").split("dynamic = ")[1].split("\n")[0]
    )


def test_installed_metadata_reports_the_same_version():
    try:
        dist = importlib.metadata.distribution("fakeack")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("fakeack is imported from the source tree, not installed")
    if Path(dist.locate_file("fakeack/__init__.py")).resolve() != Path(fa.__file__).resolve():
        pytest.skip("the installed fakeack is not the one imported")
    assert dist.version == fa.__version__


def test_toml_reader_on_every_supported_python():
    # On Python 3.10 this needs the tomli backport, a declared dependency there.
    assert config.analyze._toml is not None, f"no TOML parser on Python {sys.version_info[:2]}"
    cfg = config.parse_config(config.loads(config.example_text()), "<example>")
    assert cfg.ratio == Fraction(1, 7)


def test_tomli_is_declared_for_python_310():
    # On 3.10 pytest itself pulls in tomli, so the reader test above cannot see a missing
    # declaration; the installed package's metadata (or pyproject.toml) can.
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert re.search(r"tomli>=[\d.]+; python_version < '3.11'", pyproject)
    try:
        dist = importlib.metadata.distribution("fakeack")
    except importlib.metadata.PackageNotFoundError:
        return
    if Path(dist.locate_file("fakeack/__init__.py")).resolve() == Path(fa.__file__).resolve():
        assert any(r.startswith("tomli") and "3.11" in r for r in dist.requires or []), dist.requires


# --- LinearSystem.from_statespace --------------------------------------------------------------


def test_from_control_statespace_discrete():
    A = np.array([[1.1, 0.2], [0.0, 0.9]])
    C = np.array([[1.0, 0.0]])
    sys_d = control.ss(A, np.eye(2), C, np.zeros((1, 2)), dt=0.1)
    s = fa.LinearSystem.from_statespace(sys_d, Q=np.eye(2), R=[[0.5]])
    ref = fa.LinearSystem(A, C, np.eye(2), [[0.5]])
    np.testing.assert_array_equal(s.A, A)
    np.testing.assert_array_equal(s.C, C)
    np.testing.assert_allclose(s.pbar, ref.pbar, rtol=1e-14)


def test_from_control_statespace_dt_true_and_sampled():
    sys_c = control.ss([[0.1]], [[1.0]], [[1.0]], [[0.0]])
    s = fa.LinearSystem.from_statespace(sys_c.sample(0.5), Q=1.0, R=1.0)
    assert s.A[0, 0] == pytest.approx(np.exp(0.05))
    fa.LinearSystem.from_statespace(control.ss(1.2, 1, 0.7, 0, dt=True), Q=0.8, R=0.8)


def test_from_control_statespace_continuous_is_refused():
    sys_c = control.ss([[0.1]], [[1.0]], [[1.0]], [[0.0]])
    with pytest.raises(ValueError, match=r"continuous-time.*sample"):
        fa.LinearSystem.from_statespace(sys_c, Q=1.0, R=1.0)


def test_from_scipy_signal():
    fa.LinearSystem.from_statespace(scipy.signal.dlti([[1.2]], [[1]], [[0.7]], [[0]]).to_ss(), Q=0.8, R=0.8)
    with pytest.raises(ValueError, match="continuous-time"):
        fa.LinearSystem.from_statespace(scipy.signal.StateSpace([[1.2]], [[1]], [[0.7]], [[0]]), Q=0.8, R=0.8)


def test_from_any_object_with_a_and_c():
    model = types.SimpleNamespace(A=1.2, C=0.7)
    s = fa.LinearSystem.from_statespace(model, 0.8, 0.8)
    assert s.pbar[0, 0] == pytest.approx(0.924458, abs=1e-6)
    with pytest.raises(TypeError, match="has no C"):
        fa.LinearSystem.from_statespace(types.SimpleNamespace(A=1.2), 0.8, 0.8)
    with pytest.raises(ValueError, match="Q"):
        fa.LinearSystem.from_statespace(model, Q=[[1.0, 0.0], [0.0, 1.0]], R=0.8)


# --- Jupyter -------------------------------------------------------------------------------------


def test_result_objects_render_as_html(paper):
    sweep = fa.beta_sweep(paper, 0.5, Fraction(1, 7), 20)
    html = sweep._repr_html_()
    assert "<table" in html and f"{sweep.j_offline:.6f}" in html
    assert repr(sweep).startswith("BetaSweep(") and len(repr(sweep)) < 200
    bar = fa.beta_bar(paper, 0.5, Fraction(1, 7), 60)
    assert "20/59" in bar._repr_html_() and f"{bar.limit:.6f}" in bar._repr_html_()
    res = fa.simulate(paper, 0.5, fa.OnlineSchedule(2), horizon=50, runs=100, seed=1)
    assert f"{res.j:.6f}" in res._repr_html_()


def test_study_result_renders_as_html(paper):
    from fakeack.studies.report import PAPER_ATTACKS, analyse

    study = analyse(
        paper, 0.5, Fraction(1, 7), fa.OnlineDesign(2, 1.0), True, PAPER_ATTACKS, 20, None, horizon=50
    )
    html = study._repr_html_()
    assert html.count("<table") == 2 and "offline" in html
    assert repr(study).startswith("Analysis(") and "\n" not in repr(study)
