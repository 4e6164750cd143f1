"""Stale numba caches are dropped at import (integrators/core/cache.py): numba keys a cache on
the function's own file, while the kernels inline other files."""

import os

from integrators.core.cache import drop_stale_caches


def test_caches_older_than_the_newest_source_go_newer_ones_stay(tmp_path):
    (tmp_path / "a" / "__pycache__").mkdir(parents=True)
    (tmp_path / "b").mkdir()
    old = tmp_path / "a" / "__pycache__" / "m.kernel-1.py311.nbi"
    new = tmp_path / "a" / "__pycache__" / "m.kernel-1.py311.nbc"
    source, other = tmp_path / "a" / "m.py", tmp_path / "b" / "engine.py"
    for path in (old, source, new, other):
        path.write_text("")
    os.utime(old, (1000, 1000))
    os.utime(source, (2000, 2000))
    os.utime(new, (4000, 4000))
    os.utime(other, (3000, 3000))          # an inlined file edited after the old cache
    assert drop_stale_caches(["a"], ["a", "b"], root=tmp_path) == 1
    assert not old.exists() and new.exists()
    os.utime(other, (5000, 5000))          # ... and after the new one too
    assert drop_stale_caches(["a"], ["a", "b"], root=tmp_path) == 1 and not new.exists()
    assert drop_stale_caches(["a"], ["nowhere"], root=tmp_path) == 0
