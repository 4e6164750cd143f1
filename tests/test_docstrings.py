"""Every public callable the reference documents (docs/conf.py's ``public_api``: each
package's ``__all__``) has numpydoc sections, read as the site reads them (napoleon): a
``Parameters`` section naming each parameter of its signature (a class: its constructor's, in
``Parameters`` or, for a dataclass's fields, ``Attributes``), and ``Returns`` (or ``Yields``)
when a function returns something."""

import ast
import dataclasses
import enum
import importlib
import inspect
import re
import runpy
import textwrap
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _public_callables():
    api = runpy.run_path(str(DOCS / "conf.py"))["public_api"]()
    found = []
    for package, names in api.items():
        module = importlib.import_module(package)
        for name in names:
            obj = getattr(module, name)
            if callable(obj) and (inspect.isclass(obj) or inspect.isfunction(obj)
                                  or hasattr(obj, "__wrapped__")):
                found.append((f"{package}.{name}", obj))
    return found


def _sections(doc: str) -> set[str]:
    return set(re.findall(r"^(\w[\w ]*)\n-{3,}$", doc, re.M))


def _described(doc: str, what: str) -> set[str]:
    """The names the Parameters (and Attributes, Other Parameters) sections describe, as
    napoleon splits them (``b, lc : float`` is two)."""
    from sphinx.ext.napoleon import Config
    from sphinx.ext.napoleon.docstring import NumpyDocstring
    fields = str(NumpyDocstring(doc, Config(napoleon_use_param=True), what=what))
    names = re.findall(r"^:param ([^:]+):", fields, re.M)
    names += re.findall(r"^\.\. attribute:: (\S+)", fields, re.M)
    return {n.replace("\\", "").lstrip("*") for n in names}


def _parameters(obj) -> set[str]:
    if inspect.isclass(obj) and (issubclass(obj, (BaseException, enum.Enum))
                                 and "__init__" not in vars(obj)):
        return set()        # an exception's message, an enum's value: nothing to describe
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):
        return set()
    return set(signature.parameters) - {"self", "cls"}


def _returns_something(function) -> bool:
    """By the return annotation where there is one, else by the source (a ``return`` with a
    value, or a ``yield``, in the function's own body)."""
    annotation = inspect.signature(function).return_annotation
    if annotation is not inspect.Signature.empty:
        return annotation not in (None, "None", type(None))
    tree = ast.parse(textwrap.dedent(inspect.getsource(inspect.unwrap(function))))
    body = tree.body[0]
    nested = {id(n) for f in ast.walk(body) if f is not body
              and isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
              for n in ast.walk(f)}
    return any(isinstance(n, (ast.Yield, ast.YieldFrom))
               or (isinstance(n, ast.Return) and n.value is not None)
               for n in ast.walk(body) if id(n) not in nested)


def _missing(name: str, obj) -> list[str]:
    """What the docstring of ``obj`` lacks, in words; empty when nothing."""
    doc = inspect.getdoc(obj) if vars(obj).get("__doc__") or not inspect.isclass(obj) else None
    if not doc:
        return [f"{name}: no docstring"]
    problems = []
    sections = _sections(doc)
    wanted = _parameters(obj)
    is_class = inspect.isclass(obj)
    if wanted:
        if not sections & ({"Parameters", "Attributes"} if is_class else {"Parameters"}):
            problems.append(f"{name}: no Parameters section ({', '.join(sorted(wanted))})")
        else:
            undescribed = wanted - _described(doc, "class" if is_class else "function")
            if undescribed:
                problems.append(f"{name}: Parameters lack {', '.join(sorted(undescribed))}")
    if (not is_class and _returns_something(obj)
            and not sections & {"Returns", "Yields"}):
        problems.append(f"{name}: no Returns section")
    return problems


@pytest.mark.needs("sphinx")
def test_every_public_callable_has_its_numpydoc_sections():
    problems = [p for name, obj in _public_callables() for p in _missing(name, obj)]
    assert problems == [], "\n".join(problems)


@pytest.mark.needs("sphinx")
def test_a_docstring_without_its_sections_fails():
    # the check itself can fail: solve's docstring with its Parameters and Returns cut off
    import integrators

    def solve(problem, algorithm):
        return problem, algorithm
    solve.__doc__ = integrators.solve.__doc__.split("Parameters", 1)[0]
    assert _missing("solve", solve) == ["solve: no Parameters section (algorithm, problem)",
                                        "solve: no Returns section"]

    @dataclasses.dataclass(frozen=True)
    class Options:
        """Options.

        Attributes
        ----------
        rtol : float
            Relative tolerance.
        """
        rtol: float
        atol: float
    assert _missing("Options", Options) == ["Options: Parameters lack atol"]
