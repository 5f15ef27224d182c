"""The structure report (tests/import_graph.py): the repository passes it, and each check catches its case."""

import json
import subprocess
import sys
from pathlib import Path

import import_graph as ig

ROOT = Path(__file__).resolve().parents[2]


def write(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def package(tmp_path: Path, files: dict[str, str]) -> dict:
    base = {"fakeack/__init__.py": "", "fakeack/_fakeack.pyi": "X: int\n"}
    return ig.report(write(tmp_path, {f"python/{k}": v for k, v in (base | files).items()}))


def test_repository_passes():
    out = ig.report(ROOT)
    assert out["problems"] == [], "\n".join(out["problems"])
    assert out["cycles"] == [] and out["modules"] > 50


def test_command_line_json():
    run = subprocess.run(
        [sys.executable, str(ROOT / "tests" / "import_graph.py"), "--json"], capture_output=True, text=True
    )
    out = json.loads(run.stdout)
    assert run.returncode == (1 if out["problems"] else 0)
    assert {"levels", "edges", "cycles", "problems"} <= set(out)
    assert sum(map(len, out["levels"])) == out["modules"]


def test_repository_rust_part_runs():
    """The Rust part reads the crate mid-move without failing; its problems are cycles or sizes only."""
    rust = ig.report(ROOT, rust=True)
    graph = rust["rust"]
    assert graph["modules"] >= 5 and graph["edges"]
    python = set(ig.report(ROOT)["problems"])
    for line in set(rust["problems"]) - python:
        assert line.startswith(("cycle:", "  rust/")) or "lines (limit" in line, line


def test_function_level_cycle_is_caught(tmp_path):
    out = package(
        tmp_path,
        {
            "fakeack/a/__init__.py": "",
            "fakeack/a/x.py": "from .y import g\n",
            "fakeack/a/y.py": "def g():\n    from .x import h\n    return h\n",
        },
    )
    assert out["cycles"] == [["fakeack.a.x", "fakeack.a.y"]]
    assert "  python/fakeack/a/y.py:2: fakeack.a.y -> fakeack.a.x" in out["problems"]


def test_private_names_across_subpackages(tmp_path):
    out = package(
        tmp_path,
        {
            "fakeack/_internal/__init__.py": "",
            "fakeack/_internal/validate.py": "_x = 1\n",
            "fakeack/detection/__init__.py": "",
            "fakeack/detection/count.py": "_law = 1\n",
            "fakeack/detection/_quad.py": "_q = 1\n",
            "fakeack/detection/probability.py": "from .count import _law\n",
            "fakeack/game/__init__.py": "",
            "fakeack/game/payoff.py": (
                "from .. import _fakeack\nfrom .._internal.validate import _x\n"
                "from ..detection._quad import _q\nfrom ..detection.count import _law, __all__\n"
            ),
        },
    )
    assert out["problems"] == [
        "python/fakeack/game/payoff.py:4: private _law imported from fakeack.detection.count"
    ]
    assert out["private_imports"] == 1


def test_library_module_importing_the_cli(tmp_path):
    out = package(
        tmp_path,
        {
            "fakeack/__main__.py": "from .cli import main\n",
            "fakeack/cli/__init__.py": "from ._io import save\n\ndef main(): pass\n",
            "fakeack/cli/_io.py": "def save(): pass\n",
            "fakeack/plots/__init__.py": "",
            "fakeack/plots/grid.py": "def f():\n    from ..cli._io import save\n",
        },
    )
    assert out["problems"] == [
        "python/fakeack/plots/grid.py:2: library module fakeack.plots.grid imports fakeack.cli._io"
    ]


def test_relative_imports_resolve(tmp_path):
    out = package(
        tmp_path,
        {
            "fakeack/__init__.py": "from ._fakeack import X as __version__\nfrom .studies import run\n",
            "fakeack/model/__init__.py": "from .system import compiled\n",
            "fakeack/model/system.py": "def compiled(): pass\n",
            "fakeack/studies/__init__.py": "from .grid.run import run\n",
            "fakeack/studies/report.py": "from ..model import compiled\n",
            "fakeack/studies/grid/__init__.py": "",
            "fakeack/studies/grid/run.py": (
                "from ... import _fakeack\nfrom .. import report\nfrom ...model.system import compiled\n"
                "def run():\n    from ... import __version__\n"
            ),
        },
    )
    edges = {tuple(e) for e in out["edges"]}
    run = "fakeack.studies.grid.run"
    assert {
        (run, "fakeack._fakeack"),
        (run, "fakeack.studies.report"),
        (run, "fakeack.model.system"),
    } <= edges
    assert ("fakeack.studies.report", "fakeack.model.system") in edges  # through the package's re-export
    assert (run, "fakeack") not in edges and out["problems"] == []  # __version__ comes from _fakeack
    assert out["levels"][0] == ["fakeack._fakeack", "fakeack.model.system", "fakeack.studies.grid"]


def test_rust_cycle_and_sizes(tmp_path):
    write(
        tmp_path,
        {
            "python/fakeack/__init__.py": "",
            "rust/src/lib.rs": "pub mod a;\npub mod b;\npub mod c;\npub use c::{Thing, other::Item};\n",
            "rust/src/a.rs": "use crate::b::f;\n/// see [`crate::c`]\n#[cfg(test)]\nmod tests {\n    use crate::c;\n}\n",
            "rust/src/b/mod.rs": "use crate::{Thing, a::{self, g}};\nmod tests;\n",
            "rust/src/b/tests.rs": "use crate::c;\n" + "//\n" * 700,
            "rust/src/c.rs": "pub struct Thing;\n" + "\n" * 600,
            "rust/src/c/tests/deep.rs": "use crate::a;\n",
        },
    )
    out = ig.report(tmp_path, rust=True)["rust"]
    assert out["edges"] == [["a", "b"], ["b", "a"], ["b", "c"]]
    assert out["cycles"] == [["a", "b"]]
    assert out["oversize"] == ["rust/src/c.rs: 601 lines (limit 600)"]


def test_oversize_python_module(tmp_path):
    out = package(tmp_path, {"fakeack/big.py": "x = 1\n" * 501, "fakeack/ok.py": "x = 1\n" * 500})
    assert out["oversize"] == ["python/fakeack/big.py: 501 lines (limit 500)"]
    assert ig.main(["--root", str(tmp_path)]) == 1
