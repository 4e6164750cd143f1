"""A room's public API, imported on first use: ``from benchmarks.physics import summarize``
imports :mod:`benchmarks.physics.metrics` then, and nothing else of the room."""

from __future__ import annotations

import importlib


def lazy_api(package: str, exports: dict[str, tuple[str, ...]]):
    """``(__getattr__, __dir__, __all__)`` for ``package``, whose public names live in its
    modules: ``exports`` maps a module (relative to ``package``) to the names it gives.

    A name may not be a module's: importing ``package.errors`` binds ``package.errors`` to the
    module, so an exported function ``errors`` could never be reached as ``from package import
    errors`` (import it from its module, ``from package.errors import errors``)."""
    where = {name: module for module, names in exports.items() for name in names}
    shadowed = sorted(set(where) & set(exports))
    if shadowed:
        raise ValueError(f"{package} exports {shadowed}, the names of its own modules: the "
                         "module would shadow the name once imported")

    def __getattr__(name: str):
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{where[name]}"), name)

    def __dir__():
        return sorted(where)

    return __getattr__, __dir__, sorted(where)
