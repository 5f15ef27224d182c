"""Sphinx configuration of the fakeack documentation.

Build: ``python -m sphinx -W --keep-going -b html docs docs/_build/html`` (after
``pip install ".[docs]"``). The API page is written here from ``fakeack.__all__`` at every build,
so a new public name appears on it without editing the docs; ``tests/package/test_api_docs.py`` checks the
built pages against ``__all__``.
"""

from __future__ import annotations

import inspect
import re
import shutil
from pathlib import Path

import fakeack

HERE = Path(__file__).parent
ROOT = HERE.parent

project = "fakeack"
author = "the fakeack developers"
copyright = "2026, the fakeack developers"
version = release = fakeack.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_nb",
    "sphinxarg.ext",
    "sphinx_design",
    "sphinx-mathjax-offline",  # MathJax 3 copied into the site: formulas render with no network
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "jupyter_execute", "**.ipynb_checkpoints", ".gitignore"]
templates_path = ["_templates"]

# --- cross-references: every name of the package must resolve; external ones are listed here ----
# (no intersphinx: the build machines cannot download inventories)
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|scipy|fractions|matplotlib|control|concurrent|collections)(\..*)?"),
    (r"py:.*", r"(Fraction|Any|Sequence|Iterable|Callable|Path|NamedTuple|array_like|optional)"),
    (r"py:.*", r"(int|float|str|bool|tuple|list|dict|object|None|ValueError|TypeError)"),
]

# --- API pages ------------------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_typehints = "none"  # the numpydoc sections carry the types
autodoc_default_options = {"member-order": "bysource"}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# Sections of the API page, by the subpackage a name is defined in; a subpackage not listed here gets
# a section of its own, titled by its name.
API_SECTIONS = {
    "fakeack.model": "The system, the channels and the schedules",
    "fakeack.engine": "The exact engine",
    "fakeack.attacks": "Attacks: the chain, costs, thresholds and the decision",
    "fakeack.montecarlo": "Monte Carlo and exact finite-horizon curves",
    "fakeack.detection": "Detecting an attack",
    "fakeack.game": "The game with an attacker who must not be seen",
    "fakeack.optimal": "Optimal attacks and schedules",
    "fakeack.studies": "Parameter studies",
    "fakeack.plots": "Figures",
    "constants": "Limits and exceptions",
}


def _section_of(name: str) -> str:
    obj = getattr(fakeack, name)
    module = getattr(obj, "__module__", None) if (inspect.isclass(obj) or callable(obj)) else None
    if not module or not module.startswith("fakeack.") or module.startswith("fakeack._"):
        return "constants"
    return ".".join(module.split(".")[:2])


def api_names() -> dict[str, list[str]]:
    """``fakeack.__all__`` grouped by section, in the order of :data:`API_SECTIONS`."""
    groups: dict[str, list[str]] = {}
    for name in fakeack.__all__:
        groups.setdefault(_section_of(name), []).append(name)
    order = list(API_SECTIONS) + sorted(set(groups) - set(API_SECTIONS))
    return {key: sorted(groups[key], key=str.lower) for key in order if key in groups}


def write_api_page() -> None:
    """Write ``api.rst``: one autosummary table per section, stubs under ``generated/``."""
    lines = [
        ".. This page is written by conf.py from fakeack.__all__; edit conf.py, not this file.",
        "",
        "API reference",
        "=============",
        "",
        ".. currentmodule:: fakeack",
        "",
        "Everything below is importable as ``fakeack.NAME`` (``import fakeack as fa``). Every",
        "function validates its arguments and raises :class:`ValueError` or :class:`TypeError` naming",
        "the bad one; :class:`fakeack.ConvergenceError` is a :class:`ValueError`.",
        "",
        f"The numerical core is a Rust crate with an API of its own: its `reference <{RUST_DOCS}>`__",
        "(rustdoc) is part of this site when the site is built after ``cargo doc --no-deps``, and",
        "``cargo doc --open`` shows it locally.",
        "",
    ]
    for key, names in api_names().items():
        title = API_SECTIONS.get(key, key)
        lines += [title, "-" * len(title), ""]
        if key != "constants":
            lines += [f"Defined in ``{key}``.", ""]
        lines += [".. autosummary::", "   :toctree: generated", "   :nosignatures:", ""]
        lines += [f"   {name}" for name in names]
        lines.append("")
    text = "\n".join(lines)
    page = HERE / "api.rst"
    if not page.exists() or page.read_text() != text:  # unchanged text keeps incremental builds
        page.write_text(text)


# The rustdoc of the crate is copied into the site (as rust/) when `cargo doc --no-deps` has run.
RUST_DOCS = "rust/fakeack/index.html"


# Constants carry no docstring of their own (autodoc would show int's); their descriptions live here.
DATA_DOCS = {
    "MAX_BUILD_STATES": "Largest attack chain :func:`fakeack.attack_chain` and "
    ":func:`fakeack.general_attack_chain` build as a sparse matrix (about 0.5 GB as CSR); larger "
    "requests raise :class:`ValueError` before allocating.",
    "MAX_VECTOR_STATES": "Largest stationary vector :func:`fakeack.stationary_distribution` "
    "allocates (0.8 GB of float64); larger requests raise :class:`ValueError` before allocating.",
}


def _data_docstring(app, what, name, obj, options, lines) -> None:
    if what == "data" and lines and "\n".join(lines).strip() == (type(obj).__doc__ or "").strip():
        lines[:] = [DATA_DOCS.get(name.rpartition(".")[2], "A constant of the compiled core."), ""]


# autosummary ends a summary at the first ". ", which cuts "(paper, Sec. II-A, ...)" short; a word
# joiner (invisible, not a space) after the abbreviation's period keeps the sentence whole.
_ABBREVIATION = re.compile(r"\b(Sec|Secs|Eq|Eqs|eq|eqs|Fig|Figs|Prop|Thm|cf|ref)\.( |$)")


def _keep_abbreviations(app, what, name, obj, options, lines) -> None:
    lines[:] = [_ABBREVIATION.sub("\\1.\u2060\\2", line) for line in lines]


def _copy_rustdoc(app, exception) -> None:
    built = ROOT / "target" / "doc"
    if exception is None and app.builder.format == "html" and (built / "fakeack").is_dir():
        shutil.copytree(built, Path(app.outdir) / "rust", dirs_exist_ok=True)


write_api_page()

# --- notebooks and MyST ---------------------------------------------------------------------------
nb_execution_mode = "force"  # every build runs every notebook: a broken example fails the build
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_execution_timeout = 600
nb_merge_streams = True
nb_render_markdown_format = "myst"  # Markdown outputs of the notebooks may hold tables
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# --- HTML -----------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"fakeack {release}"
html_static_path = ["_static"]
html_css_files = ["fakeack.css"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 5,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
    "secondary_sidebar_items": ["page-toc"],
    "navbar_persistent": ["search-button"],
}
# A flat site: the left column only where there is something to navigate (the API pages).
html_sidebars = {"*": [], "api": ["sidebar-nav-bs"], "generated/*": ["sidebar-nav-bs"]}
html_show_sourcelink = False


def setup(app) -> None:
    app.connect("autodoc-process-docstring", _data_docstring)
    app.connect("autodoc-process-docstring", _keep_abbreviations)
    app.connect("build-finished", _copy_rustdoc)
