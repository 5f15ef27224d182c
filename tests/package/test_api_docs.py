"""The API reference documents every public name: each name in ``fakeack.__all__`` has a generated
page of the built documentation with the object on it (python-control's test of its docs, against
the built site rather than a hand-kept list).

Runs against ``docs/_build/html`` (or ``$FAKEACK_DOCS_HTML``) when the site has been built; CI
builds it first and sets ``FAKEACK_DOCS_BUILT=1``, which turns a missing site into a failure.
"""

import os
from pathlib import Path

import pytest

import fakeack as fa

HTML = Path(
    os.environ.get("FAKEACK_DOCS_HTML", Path(__file__).resolve().parents[2] / "docs" / "_build" / "html")
)


@pytest.fixture(scope="module")
def site() -> Path:
    if not (HTML / "api.html").is_file():
        if os.environ.get("FAKEACK_DOCS_BUILT"):
            pytest.fail(f"FAKEACK_DOCS_BUILT is set but {HTML}/api.html does not exist")
        pytest.skip("the documentation is not built (python -m sphinx -b html docs docs/_build/html)")
    return HTML


@pytest.mark.parametrize("name", sorted(fa.__all__))
def test_public_name_has_an_api_page(site, name):
    page = site / "generated" / f"fakeack.{name}.html"
    assert page.is_file(), f"fakeack.{name} is in __all__ but has no page in the API reference"
    html = page.read_text(encoding="utf-8")
    assert f'id="fakeack.{name}"' in html, f"the page of fakeack.{name} does not document it"
    api = (site / "api.html").read_text(encoding="utf-8")
    assert f'href="generated/fakeack.{name}.html' in api, f"fakeack.{name} is not listed on the API page"


def test_command_line_reference_lists_every_command(site):
    html = (site / "cli.html").read_text(encoding="utf-8")
    for command in ("reproduce", "analyze", "sweep", "simulate"):
        assert f"fakeack {command}" in html or f">{command}<" in html, command
