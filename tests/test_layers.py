"""The layers of the code are a contract: each room of ``benchmarks/`` imports only its own
modules and the rooms below it, ``problems`` and ``integrators`` never import the harness, and
no import goes round in a circle. The graph counts imports inside functions too
(:func:`benchmarks.pipeline.manifest.import_graph`)."""

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
