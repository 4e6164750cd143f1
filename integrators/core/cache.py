"""Stale numba caches, removed before any kernel loads one.

numba keys a compiled function's cache on its own source file alone, but the compiled code here
inlines functions from other files: every own kernel inlines the engine, the friction laws and
the events, the batch kernels and the lab-fit models those kernels. After a change to one of
those files, a kernel whose own file did not change would load its old build and run it
silently (the problem vector's layout one slot off, say). So, as ``make numba-cache`` does, every
cache file (``__pycache__/*.nbi``, ``*.nbc``) of a package older than the newest source it may
inline is removed when ``integrators`` (and ``benchmarks``) is imported: a few hundred ``stat``
calls, a millisecond. Caches numba keeps elsewhere (``NUMBA_CACHE_DIR``, the user-wide cache of
a read-only install) are left to ``make numba-cache``.

A kernel compiled for the first time costs from seconds to a minute; :func:`announce_compile`
says so on the standard error, once, before the wait, so that a first run does not look hung.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["drop_stale_caches", "announce_compile", "ROOT", "FIRST_COMPILE", "SENSITIVE_COMPILE"]

#: what compiling one method's kernels costs on this project's 2-core machines (the warm-up
#: module, :mod:`integrators.warm`, reports each)
FIRST_COMPILE = "about 10 to 60 s"
#: the same for a kernel carrying forward sensitivities (the step's derivative is compiled in)
SENSITIVE_COMPILE = "about 2 to 5 min"
#: the dispatchers announced, by id (held, so that an id is never reused)
_ANNOUNCED: dict = {}

#: the directory holding the packages ``integrators``, ``problems`` and ``benchmarks``
ROOT = Path(__file__).resolve().parents[2]


def drop_stale_caches(packages, sources, root: Path = ROOT) -> int:
    """Remove the numba cache files under the ``packages`` (names of directories in ``root``)
    older than the newest ``.py`` under the ``sources``; how many."""
    root = Path(root)
    try:
        newest = max(p.stat().st_mtime for name in sources for p in (root / name).rglob("*.py"))
    except (OSError, ValueError):
        return 0
    dropped = 0
    for name in packages:
        for cache in (root / name).rglob("__pycache__/*.nb[ic]"):
            try:
                if cache.stat().st_mtime < newest:
                    cache.unlink()
                    dropped += 1
            except OSError:         # gone already (another process), or not ours to remove
                pass
    return dropped


def announce_compile(dispatcher, what: str, expected: str = FIRST_COMPILE,
                     cached: bool = True) -> bool:
    """Say on the standard error, once a process, that ``dispatcher`` (a numba function) is
    about to be compiled for ``what``, when it will be: it has no build in this process and,
    if ``cached``, no cache index on disk (a cached build only loads). Returns whether it said
    so. Never raises: a numba whose internals differ makes it silent."""
    try:
        if id(dispatcher) in _ANNOUNCED or dispatcher.signatures:
            return False
        _ANNOUNCED[id(dispatcher)] = dispatcher
        if cached and os.path.exists(dispatcher._cache._cache_file._index_path):
            return False
    except Exception:           # noqa: BLE001 - a message must never break a solve
        return False
    later = ("numba caches it for the next runs; `make warm` compiles every kernel ahead"
             if cached else "once in every process: it cannot be cached")
    print(f"rsfbench: compiling {what} for its first use ({expected}; {later})",
          file=sys.stderr, flush=True)
    return True
