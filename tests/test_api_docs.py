"""docs/api.md states the public API once: autosummary writes a page per package from its
``__all__`` at each build (docs/conf.py), and api.md names every package that has one.
tests/test_docs.py checks the built pages hold every name; here, that the page lists every
package, and that what a user calls first has its numpydoc sections."""

import inspect
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


def _first_calls():
    import integrators
    import problems
    from integrators.core.solution import Solution
    return [integrators.solve, problems.load_problem, problems.paper_example, problems.preset,
            problems.window, problems.variant, Solution.__call__, Solution.resolved,
            Solution.repeats, Solution.plot]


@pytest.mark.needs("sphinx")
@pytest.mark.parametrize("function", _first_calls(), ids=lambda f: f.__qualname__)
def test_what_a_user_calls_first_has_numpydoc_sections(function):
    # napoleon reads the docstring as the site does: every parameter described, and the
    # Returns section (and Raises where the function refuses anything)
    from sphinx.ext.napoleon import Config
    from sphinx.ext.napoleon.docstring import NumpyDocstring
    doc = inspect.getdoc(function)
    assert re.search(r"^Parameters\n-{10}$", doc, re.M)
    assert re.search(r"^Returns\n-{7}$", doc, re.M)
    fields = str(NumpyDocstring(doc, Config(napoleon_use_param=True), what="function"))
    params = re.findall(r"^:param ([^:]+):", fields, re.M)
    described = {n.replace("\\", "").lstrip("*") for n in params}
    wanted = set(inspect.signature(function).parameters) - {"self"}
    assert described == wanted
    assert ":rtype:" in fields or ":returns:" in fields
    if function.__name__ != "repeats":
        assert ":raises" in fields
