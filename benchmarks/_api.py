"""A room's public API, imported on first use: ``from benchmarks.physics import summarize``
imports :mod:`benchmarks.physics.metrics` then, and nothing else of the room."""

from __future__ import annotations

import importlib


def lazy_api(package: str, exports: dict[str, tuple[str, ...]]):
    """``(__getattr__, __dir__, __all__)`` for ``package``, whose public names live in its
    modules: ``exports`` maps a module (relative to ``package``) to the names it gives."""
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{where[name]}"), name)

    def __dir__():
        return sorted(where)

    return __getattr__, __dir__, sorted(where)
