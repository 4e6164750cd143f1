"""An ensemble's finished chunks on disk: one Parquet file per chunk, written atomically.

A store is a directory holding one ensemble (the code that makes rows, one base problem,
algorithm, wall budget, set of points and chunking: its *identity*, in ``_ensemble.json``;
another ensemble there is refused, or with ``reclaim`` — the harness's own caches — cleared).
Each finished chunk of points is one
file ``c<first point>-<key>.parquet``, written to a temporary file, fsync'd and renamed
(:func:`benchmarks.files.atomic_write`): a killed run leaves whole chunks or none. The key hashes
the identity and the chunk's points, so a rerun with the same arguments finds its finished
chunks and runs only the others.

A chunk file is trusted only if it reads as Parquet (page checksums verified), carries its own
key in its metadata, has one row per point of its chunk with exactly those parameter values, the
expected columns, known classes and retcodes, and finite metrics exactly for the points with a
limit cycle; anything else (truncated, corrupt, copied from another chunk) is reported by name
(:class:`BadChunkWarning`), renamed ``.bad-<name>`` (so no reader sees it) and recomputed.

Two runs on one directory would interleave their chunks: a lock (``.lock``, ``flock``, released
when the process ends, however it ends) makes the second stop with a clear error. Reading a store
back is ``pandas.read_parquet(DIR)``: Parquet readers skip the names that start with ``.`` or
``_``, and the chunks' names sort in the order of the points.
"""

from __future__ import annotations

import fcntl
import functools
import hashlib
import io
import json
import os
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.files import atomic_write, remove_stale_temporaries
from benchmarks.ensemble.rows import METRIC_COLUMNS, columns_of
from benchmarks.metrics import CLASSIFICATIONS, CYCLES
from integrators import ReturnCode

__all__ = ["ChunkStore", "BadChunkWarning", "StoreBusy", "identity_of", "SCHEMA"]

#: the version of the rows' layout: a store written under another is another ensemble
SCHEMA = 1
_RETCODES = {r.value for r in ReturnCode}


class BadChunkWarning(UserWarning):
    """A chunk file that cannot be trusted; it is recomputed (the message names the file)."""


class StoreBusy(RuntimeError):
    """Another run holds the store's lock."""


@functools.cache
def code_version() -> str:
    """A hash of the code that decides a row (``integrators/``, ``problems/``, and of
    ``benchmarks/`` the metrics, the curves and the rows) and of numba's and numpy's versions: a
    store written by other code is another ensemble, so a fixed bug cannot hide in old rows.
    Read once a process: the code a process runs does not change under it."""
    import numba
    import benchmarks
    import integrators
    import problems
    here = Path(benchmarks.__file__).parent
    files = [*sorted(Path(integrators.__file__).parent.rglob("*.py")),
             *sorted(Path(problems.__file__).parent.rglob("*.py")),
             here / "metrics.py", here / "fitting.py", here / "ensemble" / "rows.py"]
    digest = hashlib.sha256(f"numba {numba.__version__} numpy {np.__version__}".encode())
    for f in files:
        digest.update(f.name.encode() + f.read_bytes())
    return digest.hexdigest()[:16]


def identity_of(problem, algorithm, names, values, chunk_size: int, wall_budget,
                curve_dt=None) -> dict:
    """What makes an ensemble the same ensemble: the code (:func:`code_version`), the base
    problem, the algorithm and its options, the wall budget per point, the curves' resolution,
    the parameter names, the points (a hash) and the chunking."""
    return {"schema": SCHEMA, "code": code_version(), "problem": repr(problem),
            "algorithm": repr(algorithm),
            "wall_budget": wall_budget, "curve_dt": curve_dt, "parameters": list(names),
            "n_points": len(values),
            "points_sha256": hashlib.sha256(np.ascontiguousarray(values).tobytes()).hexdigest(),
            "chunk_size": chunk_size}


class ChunkStore:
    """The chunks of one ensemble under ``root`` (module docstring). Use as a context manager:
    it holds the lock from ``__enter__`` to ``__exit__``."""

    def __init__(self, root, identity: dict, reclaim: bool = False) -> None:
        self.root = Path(root)
        self.identity = identity
        self.reclaim = reclaim
        self.bad: list[str] = []
        self._lock = None

    def __enter__(self) -> "ChunkStore":
        if self.root.exists() and not self.root.is_dir():
            raise ValueError(f"the store {self.root} is a file, not a directory")
        self.root.mkdir(parents=True, exist_ok=True)
        self._lock = open(self.root / ".lock", "a+")
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._lock.close()
            self._lock = None
            raise StoreBusy(f"the store {self.root} is in use by another run (its lock "
                            f"{self.root / '.lock'} is held): wait for it, or use another "
                            "directory") from None
        try:
            self._claim()
        except BaseException:
            self.__exit__()
            raise
        remove_stale_temporaries(self.root)
        return self

    def __exit__(self, *exc) -> None:
        if self._lock is not None:
            fcntl.flock(self._lock, fcntl.LOCK_UN)
            self._lock.close()
            self._lock = None

    def _claim(self) -> None:
        """Write the identity in an empty store; refuse a store of another ensemble."""
        path = self.root / "_ensemble.json"
        if path.exists():
            try:
                held = json.loads(path.read_text())
            except (OSError, ValueError):
                held = None
            if held != self.identity:
                what = ("unreadable" if not isinstance(held, dict) else ", ".join(
                    k for k in sorted(set(held) | set(self.identity))
                    if held.get(k) != self.identity.get(k)))
                if not self.reclaim:
                    raise ValueError(f"the store {self.root} holds another ensemble (differing: "
                                     f"{what}): give another directory, or remove it to start "
                                     "over")
                for old in [*self.root.glob("c*.parquet"), *self.root.glob(".bad-*"), path]:
                    old.unlink(missing_ok=True)      # a cache of the harness: start it over
                atomic_write(path, json.dumps(self.identity, indent=2))
        elif any(self.root.glob("*.parquet")):
            raise ValueError(f"the store {self.root} holds Parquet files but no _ensemble.json: "
                             "not an ensemble store of this version; give another directory")
        else:
            atomic_write(path, json.dumps(self.identity, indent=2))

    # --- chunks -----------------------------------------------------------------------------
    def key(self, first: int, values: np.ndarray) -> str:
        text = json.dumps(self.identity, sort_keys=True) + f"|{first}|"
        digest = hashlib.sha256(text.encode() + np.ascontiguousarray(values).tobytes())
        return digest.hexdigest()[:24]

    def path(self, first: int, key: str) -> Path:
        return self.root / f"c{first:09d}-{key}.parquet"

    def load(self, first: int, names, values: np.ndarray) -> pd.DataFrame | None:
        """The stored rows of the chunk of points ``values`` starting at point ``first``, or
        None: not stored, or stored but untrustworthy (then reported, to be recomputed)."""
        key = self.key(first, values)
        path = self.path(first, key)
        if not path.exists():
            return None
        try:
            table = _read(path, key)
            _check(table, names, values, path, bool(self.identity.get("curve_dt")))
        except _Bad as exc:
            self.bad.append(str(exc))
            aside = path.with_name(f".bad-{path.name}")
            os.replace(path, aside)             # readers skip it; the rerun writes a good one
            warnings.warn(f"{exc}: recomputing it (the file is kept as {aside.name})",
                          BadChunkWarning, stacklevel=2)
            return None
        return table

    def save(self, first: int, values: np.ndarray, table: pd.DataFrame) -> Path:
        """Write a finished chunk (atomically); returns its path."""
        import pyarrow as pa
        import pyarrow.parquet as pq
        key = self.key(first, values)
        arrow = pa.Table.from_pandas(table, preserve_index=False)
        arrow = arrow.replace_schema_metadata({**(arrow.schema.metadata or {}),
                                               b"rsfbench_key": key.encode()})
        sink = io.BytesIO()
        pq.write_table(arrow, sink, compression="zstd", write_page_checksum=True)
        path = self.path(first, key)
        atomic_write(path, sink.getvalue())
        return path


class _Bad(Exception):
    pass


def _read(path: Path, key: str) -> pd.DataFrame:
    import pyarrow.parquet as pq
    try:
        arrow = pq.read_table(path, page_checksum_verification=True)
    except Exception as exc:         # truncated, corrupt, not Parquet: pyarrow's own errors
        raise _Bad(f"chunk {path} does not read as Parquet ({type(exc).__name__}: {exc})")
    held = (arrow.schema.metadata or {}).get(b"rsfbench_key", b"").decode()
    if held != key:
        raise _Bad(f"chunk {path} holds the key {held!r}, not {key!r} (a copied file?)")
    return arrow.to_pandas()


def _check(table: pd.DataFrame, names, values: np.ndarray, path: Path, curves: bool) -> None:
    """``_Bad`` unless ``table`` is the whole chunk: one row per point with exactly its
    parameter values, every column, known classes and retcodes, metrics (and curves) for the
    cycles only."""
    expected = columns_of(names, curves)
    if list(table.columns) != expected:
        raise _Bad(f"chunk {path} has the columns {list(table.columns)}, not {expected}")
    if len(table) != len(values):
        raise _Bad(f"chunk {path} has {len(table)} rows, not {len(values)}")
    if not np.array_equal(table[list(names)].to_numpy(dtype=float), values):
        raise _Bad(f"chunk {path} holds other points than its chunk's")
    if not (table.classification.isin(CLASSIFICATIONS).all()
            and table.retcode.isin(_RETCODES).all()):
        raise _Bad(f"chunk {path} holds an unknown classification or retcode")
    cycle = table.classification.isin(CYCLES).to_numpy()
    metrics = table[list(METRIC_COLUMNS)].to_numpy(dtype=float)
    if not (np.isfinite(metrics[cycle]).all() and np.isnan(metrics[~cycle]).all()):
        raise _Bad(f"chunk {path} holds limit-cycle metrics that do not match its classes")
    if curves:
        for is_cycle, slip, mu in zip(cycle, table.curve_slip, table.curve_friction):
            x, y = np.asarray(slip, dtype=float), np.asarray(mu, dtype=float)
            if not (x.shape == y.shape and np.isfinite(x).all() and np.isfinite(y).all()
                    and (x.size >= 2 if is_cycle else x.size == 0)):
                raise _Bad(f"chunk {path} lacks a slip-weakening curve of a limit cycle, or "
                           "holds one of another point")
