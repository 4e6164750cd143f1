"""Tags on algorithms: each registered class carries the tags of the facts it declares, the
studies and the CLI select families by tag, and the registry is a read-only Mapping."""

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import pytest

from benchmarks.studies.target import groups, target_integrators
from integrators import REGISTRY
from integrators.core.registry import (CODES, KINDS, LIBRARIES, TAGS, Algorithm, Registry,
                                       filter_by_tags)

NAMES = sorted(REGISTRY)


@pytest.mark.parametrize("name", NAMES)
def test_every_algorithm_has_one_library_and_one_kind(name):
    tags = REGISTRY[name].tags
    assert len(tags & set(LIBRARIES)) == 1 and len(tags & set(KINDS)) == 1, sorted(tags)
    assert len(tags & {"adaptive", "fixed-step"}) == 1 and tags <= TAGS
    assert ("adaptive" in tags) == REGISTRY[name].adaptive
    assert ("stiff" in tags) == REGISTRY[name].stiff
    assert ("dense-output" in tags) == REGISTRY[name].saves_at_times
    assert ("sensitivities" in tags) == getattr(REGISTRY[name], "sensitive", False)


# The expected sets below are the selections of the code before tags, evaluated on this registry
# (every library installed): target.groups() picked by library strings and lists of names, the
# CLI's default of `work-precision --problem` by library-string prefixes
# ("rsfbench", "CyRK", "numbalsoda", "SUNDIALS (C").
OWN = ["CashKarp45", "ETD1", "ETD2", "ETDIterated", "Exprb32", "Exprb43", "RadauIIA5",
       "Rodas5P", "Rosenbrock23"]
SUNDIALS = ["assimulo-CVode", "assimulo-IDA", "odes-CVODE-Adams", "odes-CVODE-BDF", "odes-IDA",
            "sundae-CVODE", "sundae-IDA", "sundials-ARKODE-ERK", "sundials-ARKODE-IMEX",
            "sundials-CVODE-Adams", "sundials-CVODE-BDF", "sundials-IDA"]
COMPILED = sorted(OWN + ["CyRK-BDF", "CyRK-DOP853", "CyRK-LSODA", "CyRK-RK45", "CyRK-Radau",
                         "CyRK-Tsit5", "numbalsoda-LSODA", "numbalsoda-LSODA-grid",
                         "sundials-ARKODE-ERK", "sundials-ARKODE-IMEX", "sundials-CVODE-Adams",
                         "sundials-CVODE-BDF", "sundials-IDA"])


def test_the_target_sides_are_the_families_they_were():
    assert groups() == {"own": OWN, "lsoda": ["CyRK-LSODA", "numbalsoda-LSODA",
                                              "numbalsoda-LSODA-grid"],
                        "sundials": SUNDIALS, "cyrk": ["CyRK-BDF", "CyRK-Radau"]}
    assert "CashKarp45" not in target_integrators() and "sundials-CVODE-BDF" in target_integrators()


def test_the_cli_default_of_a_problem_file_is_the_compiled_ones():
    assert REGISTRY.select("compiled") == COMPILED


def test_select_keeps_all_tags_and_drops_the_excluded():
    assert REGISTRY.select("own", "adaptive") == ["CashKarp45", "Exprb32", "Exprb43",
                                                  "RadauIIA5", "Rodas5P", "Rosenbrock23"]
    assert REGISTRY.select("own", exclude=("adaptive",)) == ["ETD1", "ETD2", "ETDIterated"]
    assert REGISTRY.select("dae") == ["assimulo-IDA", "odes-IDA", "sundae-IDA", "sundials-IDA"]
    assert REGISTRY.select("sensitivities") == ["RadauIIA5", "Rodas5P"]
    assert sorted(REGISTRY.select()) == NAMES
    classes = [REGISTRY[n] for n in ("ETD2", "scipy-LSODA", "CyRK-LSODA")]
    assert filter_by_tags(classes, "lsoda", exclude=("scipy",)) == [REGISTRY["CyRK-LSODA"]]
    assert filter_by_tags([REGISTRY["ETD2"]()], "own") != []       # an instance carries them too


@pytest.mark.parametrize("call", [lambda: REGISTRY.select("Own"),
                                  lambda: REGISTRY.select(exclude=("rk45",)),
                                  lambda: filter_by_tags([], "numba")])
def test_an_unknown_tag_is_refused_naming_it_and_the_known_ones(call):
    with pytest.raises(ValueError, match=r"unknown tag\(s\) '\w+'.*known: adaptive, assimulo"):
        call()


def test_tags_follow_from_the_declared_facts():
    @dataclass(frozen=True)
    class Made(Algorithm):
        name: ClassVar[str] = "made"
        package: ClassVar[str] = "own"
        kind: ClassVar[str] = "multistep"
        code: ClassVar[str] = CODES[0]
        dae: ClassVar[bool] = True

    assert Made.tags == {"own", "multistep", CODES[0], "fixed-step", "stiff", "dense-output",
                         "events", "dae"}


def test_registration_refuses_a_class_without_a_library_or_kind():
    registry = Registry()

    @dataclass(frozen=True)
    class NoKind(Algorithm):
        name: ClassVar[str] = "no-kind"
        package: ClassVar[str] = "scipy"

    with pytest.raises(ValueError, match="no-kind: kind must be one of"):
        registry.register(NoKind)
    assert "no-kind" not in registry


def test_the_registry_is_a_read_only_mapping():
    assert isinstance(REGISTRY, Mapping) and not isinstance(REGISTRY, dict)
    with pytest.raises(TypeError):
        REGISTRY["ETD2"] = REGISTRY["ETD1"]
    with pytest.raises(TypeError):
        del REGISTRY["ETD2"]
    assert not hasattr(REGISTRY, "pop") and not hasattr(REGISTRY, "update")
    assert dict(REGISTRY) == {n: REGISTRY[n] for n in NAMES} and len(REGISTRY) == len(NAMES)
    assert REGISTRY.get("no-such-method") is None and "no-such-method" not in REGISTRY
    assert set(REGISTRY.keys()) == set(NAMES) == {c.name for c in REGISTRY.values()}


def test_registration_is_the_one_way_in_and_once():
    registry = Registry()
    registry.declare("not.imported", ["scipy-RK45"])
    assert registry.names() == ["scipy-RK45"]
    registry.register(REGISTRY["scipy-RK45"])      # registered: its module is not imported
    assert registry["scipy-RK45"] is REGISTRY["scipy-RK45"] and len(registry) == 1
    with pytest.raises(ValueError, match="registered twice"):
        registry.register(REGISTRY["scipy-RK45"])
