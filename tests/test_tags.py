"""The registry is a read-only Mapping: classes enter through :meth:`Registry.register` only."""

from collections.abc import Mapping

import pytest

from integrators import REGISTRY
from integrators.core.registry import Registry

NAMES = sorted(REGISTRY)


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
