"""The layers of the code are a contract: each room of ``benchmarks/`` imports only its own
modules and the rooms below it, ``problems`` and ``integrators`` never import the harness, and
no import goes round in a circle. The graph counts imports inside functions too
(:func:`benchmarks.pipeline.manifest.import_graph`). import-linter checks the same contracts,
stated in pyproject.toml, and chains through other modules besides."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.pipeline.manifest import find_cycles, import_graph

#: bottom to top: a room may import the rooms before it, never those after
ROOMS = ("records", "physics", "devtools", "ensemble", "inversion", "lab", "studies", "pipeline",
         "cli")
#: modules of ``benchmarks`` outside the rooms: the lazy-API helper, importable from any room;
#: the pytest-benchmark suite, which imports anything and which nothing imports
BASE = {"benchmarks", "benchmarks._api"}
OUTSIDE = ("benchmarks.test_speed",)
GRAPH = import_graph()


def _room(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "benchmarks" or module in BASE:
        return None
    if module.startswith(OUTSIDE):
        return "outside"
    assert len(parts) > 1 and parts[1] in ROOMS, f"{module} is in no room"
    return parts[1]


def test_every_module_is_in_a_room():
    for module in GRAPH:
        _room(module)


def climbing(graph, room: str) -> dict[str, list[str]]:
    """The modules of ``room`` that import a room above it, with what they import."""
    allowed = set(ROOMS[:ROOMS.index(room) + 1]) | {None}
    wrong = {m: sorted(d for d in deps if _room(d) not in allowed)
             for m, deps in graph.items() if _room(m) == room}
    return {m: d for m, d in wrong.items() if d}


@pytest.mark.parametrize("room", ROOMS)
def test_a_room_imports_only_the_rooms_below_it(room):
    assert climbing(GRAPH, room) == {}


def test_the_contract_sees_a_climb_and_a_circle():
    graph = {"benchmarks.physics.a": {"benchmarks.studies.b", "benchmarks.records.c"},
             "benchmarks.studies.b": {"benchmarks.physics.a"}, "benchmarks.records.c": set()}
    assert climbing(graph, "physics") == {"benchmarks.physics.a": ["benchmarks.studies.b"]}
    assert climbing(graph, "studies") == {}
    assert find_cycles(graph) == [["benchmarks.physics.a", "benchmarks.studies.b"]]


@pytest.mark.parametrize("package", ["problems", "integrators"])
def test_the_model_and_the_methods_never_import_the_harness(package):
    wrong = {m: sorted(d for d in deps if d.startswith("benchmarks"))
             for m, deps in GRAPH.items() if m.split(".")[0] == package}
    assert not {m: d for m, d in wrong.items() if d}


def test_problems_never_import_the_integrators():
    wrong = {m: sorted(d for d in deps if d.startswith("integrators"))
             for m, deps in GRAPH.items() if m.split(".")[0] == "problems"}
    assert not {m: d for m, d in wrong.items() if d}


def test_no_import_goes_round_in_a_circle():
    assert find_cycles(GRAPH) == []


ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("problems", "integrators", "benchmarks")


def lint_imports(root: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` of this environment on the packages and pyproject.toml under ``root``
    (no cache: nothing written into the checkout)."""
    return subprocess.run([str(Path(sys.executable).parent / "lint-imports"), "--no-cache"],
                          cwd=root, env={**os.environ, "PYTHONPATH": str(root)},
                          capture_output=True, text=True, timeout=60)


def test_import_linter_finds_every_contract_kept():
    run = lint_imports(ROOT)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "4 kept, 0 broken" in run.stdout


def test_import_linter_sees_the_methods_core_reach_up_through_the_package(tmp_path):
    """``from integrators import ...`` in a function of ``integrators.core`` reaches the own
    methods through the package's ``__init__``: a broken contract."""
    for package in PACKAGES:
        shutil.copytree(ROOT / package, tmp_path / package,
                        ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    with open(tmp_path / "integrators" / "core" / "solution.py", "a") as f:
        f.write("\n\ndef _reaching_up():\n    from integrators import REGISTRY\n")
    run = lint_imports(tmp_path)
    assert run.returncode == 1
    assert "integrators.core never imports the package above it BROKEN" in run.stdout
