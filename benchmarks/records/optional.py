"""Optional libraries: a feature that needs one says which and how to install it, before any
work, instead of failing half-way with Python's own ``ModuleNotFoundError``.

Call :func:`require` first, then import the library with an ``import`` statement as usual: the
pipeline finds a study's libraries by its import statements (their versions are inputs of its
reuse), not by calls."""

from __future__ import annotations

import importlib

__all__ = ["MissingExtra", "require"]


class MissingExtra(ModuleNotFoundError):
    """An optional library a feature needs is not installed (``name``: the module); the message
    says which extra of the package installs it."""


def require(module: str, extra: str, what: str):
    """Import ``module`` and return it, or :class:`MissingExtra` saying that ``what`` needs it
    and ``pip install 'rsfbench[extra]'`` installs it. An installed library that fails to import
    (a missing shared library, a module of its own missing) raises its own error."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        top = module.split(".")[0]
        if exc.name not in (module, top):       # installed, but broken: say so, with the cause
            raise
        raise MissingExtra(f"{what} needs {module}, which is not installed: pip install "
                           f"'rsfbench[{extra}]'", name=module) from None
