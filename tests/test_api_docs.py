"""docs/api.md states the public API once: autosummary writes a page per package from its
``__all__`` at each build (docs/conf.py), and api.md names every package that has one.
tests/test_docs.py checks the built pages hold every name; here, that the page lists every
package."""

import re
import runpy
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.fixture(scope="module")
def public_api() -> dict[str, list[str]]:
    return runpy.run_path(str(DOCS / "conf.py"))["public_api"]()


@pytest.mark.needs("sphinx")
def test_the_api_page_names_every_package_with_an_all(public_api):
    text = (DOCS / "api.md").read_text(encoding="utf-8")
    block = text.split(".. autosummary::", 1)[1].split("```", 1)[0]
    listed = re.findall(r"^   ([\w.]+)$", block, re.M)
    assert sorted(listed) == sorted(public_api)
    assert {"problems", "integrators", "benchmarks.lab"} <= set(public_api)


@pytest.mark.needs("sphinx")
def test_every_public_name_exists(public_api):
    import importlib
    for package, names in public_api.items():
        module = importlib.import_module(package)
        for name in names:
            assert getattr(module, name) is not None, f"{package}.{name}"
