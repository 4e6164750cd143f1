"""A room's exported name is the exported object, whatever was imported before: no room
exports a name that is also one of its modules' (importing the module would bind the room's
attribute to the module, even for a first ``from room import name``)."""

import importlib
import pkgutil
import types

import pytest

from benchmarks._api import lazy_api

import benchmarks

ROOMS = [f"benchmarks.{m.name}" for m in pkgutil.iter_modules(benchmarks.__path__) if m.ispkg]


@pytest.mark.parametrize("room", ROOMS)
def test_every_exported_name_is_the_exported_object(room):
    package = importlib.import_module(room)
    modules = {m.name for m in pkgutil.iter_modules(package.__path__)}
    for name in getattr(package, "__all__", ()):
        if name in modules:
            importlib.import_module(f"{room}.{name}")      # what any other import may do first
        exported = getattr(__import__(room, fromlist=[name]), name)   # `from room import name`
        assert not isinstance(exported, types.ModuleType), f"{room}.{name} is a module"


def test_an_export_named_as_its_module_is_refused():
    with pytest.raises(ValueError, match=r"exports \['errors'\], the names of its own modules"):
        lazy_api("benchmarks.devtools", {"errors": ("errors", "ERROR_COLUMNS")})
