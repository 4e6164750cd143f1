"""The plan: the studies :mod:`benchmarks.studies` declares, found and checked, and the inputs
of each that decide whether its last run can be reused (:mod:`benchmarks.pipeline.manifest`)."""

from __future__ import annotations

import functools
import importlib
import pkgutil
from pathlib import Path

from benchmarks.pipeline import manifest as M
from benchmarks.studies.study import matches

__all__ = ["studies", "declared", "check_plan", "study_named", "list_markdown", "study_inputs"]


@functools.cache
def studies(package: str = "benchmarks.studies") -> tuple:
    """Every study declared in ``package`` (a module's ``STUDY``, or its ``STUDIES``), in their
    declared order; checked by :func:`check_plan`.

    Parameters
    ----------
    package : str
        The package whose modules declare the studies.

    Returns
    -------
    tuple
        The studies, in order.

    Raises
    ------
    ValueError
        From :func:`check_plan`, for a plan that does not hold together.
    """
    pkg = importlib.import_module(package)
    found = []
    for info in pkgutil.iter_modules(pkg.__path__):
        found.extend(declared(importlib.import_module(f"{package}.{info.name}")))
    found.sort(key=lambda s: s.order)
    check_plan(found)
    return tuple(found)


def declared(module) -> tuple:
    """The studies ``module`` declares: its ``STUDIES`` (a tuple: a module that owns the work of
    several) or its ``STUDY``; ``ValueError`` if it has both."""
    one, several = getattr(module, "STUDY", None), getattr(module, "STUDIES", None)
    if one is not None and several is not None:
        raise ValueError(f"{module.__name__} declares both STUDY and STUDIES: put every study "
                         "of the module in STUDIES")
    return tuple(several) if several is not None else () if one is None else (one,)


def check_plan(plan) -> None:
    """``ValueError`` unless the names and orders are unique, no file is declared by two studies
    (a pattern of one matching a pattern of another) and every file a study reads is written by
    an earlier study."""
    for what in ("name", "order"):
        values = [getattr(s, what) for s in plan]
        twice = sorted({v for v in values if values.count(v) > 1})
        if twice:
            raise ValueError(f"studies share a {what}: {twice}")
    for i, one in enumerate(plan):
        for other in plan[i + 1:]:
            both = [p for p in one.writes for q in other.writes if matches(p, q) or matches(q, p)]
            if both:
                raise ValueError(f"studies {one.name} and {other.name} both declare "
                                 f"{', '.join(both)}: a file has one writer")
    for i, study in enumerate(plan):
        for read in study.reads:
            if not any(earlier.declares(read) for earlier in plan[:i]):
                raise ValueError(f"study {study.name} reads {read}, which no earlier study "
                                 "writes")


def study_named(name: str, plan=None):
    """The study called ``name``, or ``ValueError`` naming the known ones.

    Parameters
    ----------
    name : str
        The study's name.
    plan : sequence, optional
        The studies looked in; ``None``: :func:`studies`.

    Returns
    -------
    Study

    Raises
    ------
    ValueError
        For an unknown name.
    """
    plan = studies() if plan is None else plan
    for study in plan:
        if study.name == name:
            return study
    raise ValueError(f"unknown study {name!r}: expected one of "
                     f"{', '.join(s.name for s in plan)}")


def list_markdown(plan=None) -> str:
    """The studies as a Markdown table: name, plan, minutes, settings (``--set``; default and
    limits), reads, writes, title."""
    plan = studies() if plan is None else plan

    def setting(study, key):
        low, high = study.limits.get(key, (None, None))
        return f"{key}={study.settings[key]!r}" + (f" ({low:g}–{high:g})" if low is not None
                                                    else "")
    rows = ["| study | plan | minutes | settings | reads | writes | what |",
            "|---|---|---|---|---|---|---|"]
    rows += [f"| `{s.name}` | {s.plan} | {s.minutes:g} | "
             f"{', '.join(setting(s, k) for k in s.settings) or '–'} | "
             f"{', '.join(s.reads) or '–'} | {', '.join(s.writes)} | {s.title} |" for s in plan]
    return "\n".join(rows) + "\n"


def study_inputs(step, out: Path, **code) -> dict:
    """A study's inputs: its module's code (the whole file: its run, report and helpers) and
    what it imports, the modules it runs as programs, versions, settings, files read."""
    own = step.run.__module__
    project = M.import_graph(code.get("root", M.ROOT), code.get("packages", M.PACKAGES))
    modules = (*step.modules, *([own] if own in project else []))
    return M.step_inputs(step.run, step.settings, out, reads=step.reads, data=step.data,
                         modules=modules, timed=step.timed, **code)
