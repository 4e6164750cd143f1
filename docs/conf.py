"""Sphinx configuration of the documentation site: `make docs` builds it into docs/_build/html,
and tests/test_docs.py fails on any warning (a broken link or reference, a docstring Sphinx
cannot read)."""

import importlib
import pkgutil
import sys
from pathlib import Path

from sphinx.pycode import ModuleAnalyzer

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def public_api() -> dict[str, list[str]]:
    """Each package's ``__all__``, by package: ``problems``, ``integrators`` and every room of
    ``benchmarks`` that has one. api.md's autosummary pages list these names, so the reference
    cannot drift from the code."""
    import benchmarks
    rooms = [f"benchmarks.{m.name}" for m in pkgutil.iter_modules(benchmarks.__path__)
             if m.ispkg]
    modules = [importlib.import_module(name) for name in ["problems", "integrators", *rooms]]
    for m in modules:
        for name in getattr(m, "__all__", ()):
            getattr(m, name)        # a room imports the module that holds the name
    return {m.__name__: list(m.__all__) for m in modules if hasattr(m, "__all__")}


project = "rsfbench"
author = "the rsfbench developers"
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.autosummary",
              "sphinx.ext.napoleon", "sphinx.ext.mathjax"]
# .rst for the pages autosummary writes into api/ at each build (git-ignored)
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
templates_path = ["_templates"]
root_doc = "index"
exclude_patterns = ["_build", "examples"]
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
html_theme = "furo"
html_title = "rsfbench"
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autosummary_generate = True
autosummary_context = {"public_api": public_api()}
napoleon_google_docstring = False
napoleon_numpy_docstring = True


def constant_doc(app, what, name, obj, options, lines):
    """A constant a package re-exports (``problems.LAWS``) is documented by the ``#:`` comment
    of the module that defines it, not by the docstring of its type (dict's, tuple's)."""
    if what != "data" or type(obj).__module__ != "builtins":
        return
    package, attr = name.rsplit(".", 1)
    root = package.split(".")[0]
    for modname in sorted(m for m in sys.modules if m == root or m.startswith(root + ".")):
        if getattr(sys.modules[modname], attr, None) is obj:
            comment = ModuleAnalyzer.for_module(modname).find_attr_docs().get(("", attr))
            if comment:
                lines[:] = list(comment)
                return
    lines[:] = []


def clear_stubs(app):
    """Delete the pages an earlier build's autosummary wrote into ``api/``: a name no longer in
    an ``__all__`` would leave its page in no toctree (a warning, so a failed build). Runs
    before autosummary writes them afresh (priority 100 < its 500)."""
    for page in (Path(app.srcdir) / "api").glob("*.rst"):
        page.unlink()


def setup(app):
    app.connect("builder-inited", clear_stubs, priority=100)
    app.connect("autodoc-process-docstring", constant_doc)
