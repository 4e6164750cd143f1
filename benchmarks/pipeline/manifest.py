"""What ``make reproduce`` may reuse: the inputs of a step, hashed, and the manifest of the steps
that ran.

The inputs of a step (:func:`step_inputs`):

* ``code``: its function's source, and the source of every project module it imports, directly
  or through other modules (imports inside functions count; a module of ``integrators`` or
  ``problems`` stands for its whole package). Source is hashed as what runs (:func:`code_hash`:
  its syntax tree without docstrings, comments and layout), so editing documentation reuses;
* ``versions``: Python's and those of the packages ``pyproject.toml`` declares, as installed:
  every package of ``dependencies``, and a package of an extra (the inversions' emcee, a peer
  library, pyarrow) only for a step whose code imports it, so that adding a leaf package for
  new steps leaves the others' results reusable;
* ``settings``: its keyword arguments;
* ``machine``: platform, CPU model and count, for a step whose numbers are timings;
* ``reads``: the results files it reads (another step's output) and the project's data files.

``results/manifest.json`` records for each step that ran the hash of its inputs, the inputs
themselves (so that a rerun can say what changed) and the files it wrote, with their hashes. A
step whose inputs hash the same and whose files are all there, unchanged, is reused. The
manifest is a JSON array of one object per step: ``pd.read_json("results/manifest.json")``.
"""

from __future__ import annotations

import ast
import datetime
import functools
import hashlib
import importlib.metadata
import inspect
import json
import os
import platform
import re
import sys
import textwrap
import tomllib
from pathlib import Path

from benchmarks.records.files import RESULTS_MANIFEST, BadResultsFile, atomic_write
from benchmarks.records.provenance import cpu_model, git_commit

__all__ = ["ROOT", "PACKAGES", "WHOLE_PACKAGES", "MANIFEST", "import_graph", "find_cycles",
           "step_inputs", "inputs_hash", "what_changed", "versions", "machine", "file_hash",
           "code_hash", "read_manifest", "write_manifest", "snapshot", "written_since", "reusable",
           "make_record"]

ROOT = Path(__file__).resolve().parents[2]
#: the project's packages: imports of these are followed
PACKAGES = ("benchmarks", "integrators", "problems")
#: packages that count as a whole: any module of theirs stands for all their files
WHOLE_PACKAGES = ("integrators", "problems")
#: the manifest's name in a results directory
MANIFEST = RESULTS_MANIFEST      # one name, kept by records.files (a study file is its own)
_RECORD_KEYS = ("step", "inputs_hash", "inputs", "outputs")


# --- the project's import graph ------------------------------------------------------------

def _modules(root: Path, packages) -> dict[str, Path]:
    """Module name → file, for every ``.py`` file of ``packages`` under ``root``."""
    found = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _imported(tree: ast.AST, module: str, is_package: bool, known) -> set[str]:
    """The modules of ``known`` that the imports anywhere in ``tree`` name (relative imports
    resolved against ``module``)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                base = base[:len(base) - node.level + (1 if is_package else 0)]
                full = ".".join(base + ([node.module] if node.module else []))
            else:
                full = node.module
            names.add(full)
            names.update(f"{full}.{a.name}" for a in node.names)
    hits = set()
    for name in names:               # ``import a.b.c`` imports a, a.b and a.b.c
        parts = name.split(".")
        hits.update(".".join(parts[:i]) for i in range(1, len(parts) + 1))
    return hits & set(known)


_GRAPHS: dict[tuple, dict[str, set[str]]] = {}     # by the files' paths, sizes and times


def import_graph(root: Path = ROOT, packages=PACKAGES) -> dict[str, set[str]]:
    """Module → the project modules it imports, at module level or inside functions (not
    counting its own packages, which Python imports before any of their modules)."""
    modules = _modules(root, packages)
    stamp = tuple((p, p.stat().st_mtime_ns, p.stat().st_size) for p in modules.values())
    if stamp not in _GRAPHS:
        _GRAPHS.clear()
        _GRAPHS[stamp] = _import_graph(modules)
    return {m: set(deps) for m, deps in _GRAPHS[stamp].items()}


def _import_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    graph = {}
    for m, p in modules.items():
        parts = m.split(".")
        own = {".".join(parts[:i]) for i in range(1, len(parts) + 1)}
        graph[m] = _imported(ast.parse(p.read_text(encoding="utf-8")), m,
                             p.name == "__init__.py", modules) - own
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of ``graph``: its strongly connected components of more than one
    module, each sorted (Tarjan)."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph) + 100))
    try:
        for v in sorted(graph):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return sorted(cycles)


def _function_modules(fn, known) -> set[str]:
    """The project modules ``fn`` uses: those it imports, and those its module imported the
    global names it reads from."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    used = _imported(tree, fn.__module__, False, known)
    module_file = inspect.getsourcefile(fn)
    top = ast.parse(Path(module_file).read_text(encoding="utf-8"))
    origin = {}                       # global name → the module it was imported from
    for node in top.body:
        if isinstance(node, ast.ImportFrom) and not node.level and node.module:
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                origin[a.asname or a.name] = sub if sub in known else node.module
        elif isinstance(node, ast.Import):
            for a in node.names:
                origin[a.asname or a.name.split(".")[0]] = a.name
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    return used | ({origin[n] for n in names if n in origin} & set(known))


def _closure(start, graph) -> set[str]:
    seen, todo = set(), list(start)
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(graph.get(m, ()))
    return seen


def file_hash(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _without_docstrings(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                    and isinstance(body[0].value.value, str)):
                node.body = body[1:] or [ast.Pass()]
    return tree


@functools.lru_cache(maxsize=4096)
def code_hash(source: str) -> str:
    """The hash of Python source as what runs: its syntax tree without docstrings (comments and
    layout are not in the tree), so that a documentation edit does not make results stale.
    Source that does not parse is hashed as text. (Cached by the source text.)"""
    try:
        tree = _without_docstrings(ast.parse(source))
    except SyntaxError:
        return hashlib.sha256(source.encode()).hexdigest()
    return hashlib.sha256(ast.dump(tree, include_attributes=False).encode()).hexdigest()


def _code(fn, root: Path, packages, whole, extra=()) -> dict[str, str]:
    """Relative path → hash of every source file ``fn`` (and the modules ``extra``) depends on,
    and of ``fn``'s own source."""
    modules = _modules(root, packages)
    unknown = set(extra) - set(modules)
    if unknown:
        raise ValueError(f"not modules of the project: {sorted(unknown)}")
    graph = import_graph(root, packages)
    used = _closure(_function_modules(fn, modules) | set(extra), graph)
    wholes = {m.split(".")[0] for m in used} & set(whole)
    files = {modules[m] for m in used} | {p for n, p in modules.items()
                                          if n.split(".")[0] in wholes}
    code = {p.relative_to(root).as_posix(): code_hash(p.read_text(encoding="utf-8"))
            for p in sorted(files)}
    own, base = Path(inspect.getsourcefile(fn)).resolve(), root.resolve()
    where = own.relative_to(base).as_posix() if own.is_relative_to(base) else own.name
    code[f"{where}::{fn.__qualname__}"] = code_hash(textwrap.dedent(inspect.getsource(fn)))
    return code


# --- versions and machine --------------------------------------------------------------------

def _pinned(root: Path, optional: bool = False) -> list[str]:
    """The names of the packages ``pyproject.toml`` declares (their versions are pinned in
    ``requirements.lock``): its ``dependencies``, or with ``optional`` those of every extra
    (the project's own extras that name other extras left out)."""
    path = root / "pyproject.toml"
    if not path.exists():
        return []
    project = tomllib.loads(path.read_text(encoding="utf-8")).get("project", {})
    deps = ([d for group in project.get("optional-dependencies", {}).values() for d in group]
            if optional else project.get("dependencies", []))
    own = _normal(project.get("name", ""))
    return sorted({m.group(1) for d in deps if (m := re.match(r"\s*([A-Za-z0-9_.\-]+)", d))
                   and _normal(m.group(1)) != own})


def _top_imports(sources) -> set[str]:
    """The top-level names of the modules that the Python ``sources`` import (absolute imports,
    at module level or inside functions; a source that does not parse imports nothing)."""
    return set().union(*map(_imports_of, sources))


@functools.lru_cache(maxsize=4096)
def _imports_of(text: str) -> frozenset[str]:
    try:
        tree = ast.parse(text)
    except SyntaxError:
        return frozenset()
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module.split(".")[0])
    return frozenset(names)


def versions(root: Path = ROOT, sources=None) -> dict[str, str]:
    """Python's version and the installed version of every pinned package: those of
    ``dependencies``, and those of ``optional-dependencies`` that ``sources`` (the step's code,
    as texts) import; all of them when ``sources`` is None."""
    def version(name):
        try:
            return importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            return "missing"
    optional = _pinned(root, optional=True)
    if sources is not None:
        imported = _top_imports(sources)
        optional = [n for n in optional if _import_names(n) & imported]
    return {"python": platform.python_version(),
            **{n: version(n) for n in _pinned(root) + optional}}


def _normal(name: str) -> str:
    """A distribution's name as PEP 503 compares them."""
    return re.sub(r"[-_.]+", "-", name).lower()


@functools.lru_cache(maxsize=None)
def _import_names(distribution: str) -> frozenset[str]:
    """Every top-level module the installed ``distribution`` provides, and the name it would
    import as (``-`` → ``_``) in case it is not installed or keeps no record of its modules."""
    wanted = _normal(distribution)
    found = {module for module, names in importlib.metadata.packages_distributions().items()
             if any(_normal(n) == wanted for n in names)}
    return frozenset(found | {distribution.replace("-", "_").lower()})


def machine() -> dict:
    """What a timing depends on besides the code: platform, CPU model, number of CPUs."""
    return {"system": platform.system(), "machine": platform.machine(), "cpu": cpu_model(),
            "n_cpus": os.cpu_count()}


# --- a step's inputs -------------------------------------------------------------------------

def step_inputs(fn, settings: dict, out: Path, reads=(), data=(), modules=(),
                timed: bool = False, root: Path = ROOT, packages=PACKAGES,
                whole=WHOLE_PACKAGES) -> dict:
    """The inputs of a step that runs ``fn(out, **settings)`` (see the module docstring):
    ``reads`` are paths relative to ``out``, ``data`` relative to ``root`` (a missing file
    hashes as ``"missing"``); ``modules``: project modules it runs without importing them."""
    def hashed(base, paths):
        return {p: file_hash(base / p) if (base / p).is_file() else "missing" for p in paths}
    code = _code(fn, Path(root), packages, whole, modules)
    sources = [textwrap.dedent(inspect.getsource(fn))] + [
        (Path(root) / p).read_text(encoding="utf-8") for p in code if "::" not in p]
    return {"code": code,
            "versions": versions(Path(root), sources),
            "settings": json.loads(json.dumps(settings, sort_keys=True, default=str)),
            "machine": machine() if timed else None,
            "reads": {**hashed(Path(out), reads), **hashed(Path(root), data)}}


def inputs_hash(inputs: dict) -> str:
    text = json.dumps(inputs, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _keys(old: dict, new: dict) -> list[str]:
    return sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))


def _some(names: list[str], n: int = 3) -> str:
    return ", ".join(names[:n]) + (f" and {len(names) - n} more" if len(names) > n else "")


def what_changed(old: dict, new: dict) -> str:
    """One line: which inputs differ between two :func:`step_inputs`."""
    parts = []
    for kind in ("code", "versions", "settings", "reads"):
        a, b = old.get(kind) or {}, new.get(kind) or {}
        if kind == "versions":
            # a package absent on one side: not imported by the step's code then, or now
            keys = [f"{k} {a.get(k, 'not imported')} → {b.get(k, 'not imported')}"
                    for k in _keys(a, b)]
        else:
            keys = _keys(a, b)
        if keys:
            parts.append(f"{kind} ({_some(keys)})")
    if old.get("machine") != new.get("machine"):
        parts.append("machine")
    return ", ".join(parts) or "the inputs' form"


# --- the manifest ----------------------------------------------------------------------------

def read_manifest(out: Path) -> dict[str, dict]:
    """Step name → its record in ``out/manifest.json`` (none if there is no manifest), or
    :class:`BadResultsFile`."""
    path = Path(out) / MANIFEST
    if not path.exists():
        return {}
    try:
        records = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BadResultsFile(f"manifest {path} cannot be read ({type(exc).__name__})") from None
    if not isinstance(records, list) or not all(
            isinstance(r, dict) and all(k in r for k in _RECORD_KEYS) for r in records):
        raise BadResultsFile(f"manifest {path} is not an array of step records with the keys "
                             f"{list(_RECORD_KEYS)}")
    return {r["step"]: r for r in records}


def read_manifest_or_none(out: Path) -> dict[str, dict] | None:
    """:func:`read_manifest`, or None where there is none or it cannot be read."""
    try:
        return read_manifest(out) or None
    except BadResultsFile:
        return None


def write_manifest(out: Path, records: dict[str, dict], order=()) -> None:
    """``out/manifest.json``, atomically: the records in ``order``, then any others."""
    rank = {name: i for i, name in enumerate(order)}
    rows = sorted(records.values(), key=lambda r: (rank.get(r["step"], len(rank)), r["step"]))
    atomic_write(Path(out) / MANIFEST, json.dumps(rows, indent=1, sort_keys=True) + "\n")


def make_record(step: str, plan: str, inputs: dict, outputs: dict[str, str],
                wall_s: float) -> dict:
    return {"step": step, "plan": plan, "inputs_hash": inputs_hash(inputs),
            "outputs": dict(sorted(outputs.items())), "inputs": inputs, "wall_s": round(wall_s, 1),
            "finished": datetime.datetime.now().isoformat(timespec="seconds"),
            "git_commit": git_commit()}


def _ignored(rel: Path) -> bool:
    """Not a step's output: the manifest, the report, caches, hidden files and temporaries."""
    return (rel.as_posix() in (MANIFEST, "REPORT.md") or rel.parts[0] == "cache"
            or any(part.startswith(".") for part in rel.parts))


def snapshot(out: Path) -> dict[str, tuple[int, int]]:
    """Relative path → (mtime in ns, size) of every file in ``out`` a step may write."""
    out = Path(out)
    if not out.is_dir():
        return {}
    found = {}
    for path in out.rglob("*"):
        rel = path.relative_to(out)
        if path.is_file() and not _ignored(rel):
            st = path.stat()
            found[rel.as_posix()] = (st.st_mtime_ns, st.st_size)
    return found


def written_since(before: dict, out: Path) -> dict[str, str]:
    """Relative path → hash of every file of ``out`` written (new or touched) since
    ``before`` (a :func:`snapshot`)."""
    after = snapshot(out)
    return {p: file_hash(Path(out) / p) for p, stamp in sorted(after.items())
            if before.get(p) != stamp}


def reusable(record: dict | None, inputs: dict, out: Path) -> tuple[bool, str]:
    """``(True, "")`` if ``record`` ran on these inputs and its files are there unchanged; else
    ``(False, why)``."""
    if record is None:
        return False, "not in the manifest"
    if record["inputs_hash"] != inputs_hash(inputs):
        return False, f"inputs changed: {what_changed(record['inputs'], inputs)}"
    missing = [p for p in record["outputs"] if not (Path(out) / p).is_file()]
    if missing:
        return False, f"outputs missing: {_some(sorted(missing))}"
    changed = [p for p, h in record["outputs"].items() if file_hash(Path(out) / p) != h]
    if changed:
        return False, f"outputs changed since: {_some(sorted(changed))}"
    return True, ""
