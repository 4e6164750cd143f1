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
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["drop_stale_caches", "ROOT"]

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
