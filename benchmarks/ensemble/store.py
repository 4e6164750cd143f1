"""An ensemble's finished chunks on disk, and the one reader that may read them back.

A store is a directory holding one ensemble. Its *identity file* ``_ensemble.json`` records what
makes the ensemble (the code that makes rows, the base problem, algorithm, wall budget, points and
chunking: :func:`identity_of`) and lists every finished chunk with the SHA-256 of its file.
Another ensemble there is refused (or, with ``reclaim`` — the harness's own caches — cleared).
Each finished chunk is one file ``_c<first point>-<key>.parquet``, written to a temporary file,
fsync'd and renamed (:func:`benchmarks.records.files.atomic_write`), then listed; the key hashes the
identity and the chunk's points, so a rerun with the same arguments finds its finished chunks
and runs only the others. A killed run leaves whole listed chunks, and at most one chunk written
but not yet listed (recomputed, like any unlisted file).

**Read a store with** :func:`read_store`, never with ``pandas.read_parquet(DIR)``: a Parquet
reader reads every file of a directory, so a stray copy (``….parquet.orig``, a chunk of another
ensemble dropped in) or a chunk edited in place would come back as rows. So the layout turns raw
readers away: the chunks' names start with ``_``, which Parquet readers skip, and the directory
holds ``README.txt``, which is not Parquet, so ``pandas.read_parquet(DIR)`` fails naming it
instead of returning wrong rows. :func:`read_store` and a resuming run read only the chunks the
identity file lists, and only when the file's hash is the listed one and its rows check out
(one row per point of its chunk, its key, every column, known classes and retcodes, metrics
exactly for the limit cycles). A listed chunk that fails is reported by name
(:class:`BadChunkWarning`), set aside as ``.bad-<name>`` and recomputed by a run; any other file
in the directory is ignored and reported (:class:`StrayFileWarning`), never deleted. A damaged
identity file is set aside and the store starts over (reported); a missing one, in a directory
that holds files, is refused: nothing there can be verified.

Two runs on one directory would interleave their chunks: a lock (``.lock``, a ``filelock``
FileLock: ``flock``, released when the process ends, however it ends) makes the second stop with
a clear error.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import os
import re
import warnings
from pathlib import Path

import numba
import numpy as np
import pandas as pd
from filelock import FileLock, Timeout

import benchmarks
import integrators
import problems
from benchmarks.ensemble.executors import RunStopped
from benchmarks.ensemble.rows import METRIC_COLUMNS, columns_of, gradient_columns
from benchmarks.physics.metrics import CLASSIFICATIONS, CYCLES
from benchmarks.records.files import _PREFIX as _TEMPORARY
from benchmarks.records.files import LEDGER_LOCK, atomic_write, remove_stale_temporaries
from benchmarks.records.interrupts import uninterrupted
from benchmarks.records.optional import require
from integrators import ReturnCode

__all__ = ["ChunkStore", "read_store", "BadChunkWarning", "StrayFileWarning",
           "IncompleteStoreWarning", "StoreBusy", "identity_of", "SCHEMA", "IDENTITY",
           "held_algorithm"]

#: the version of the store's layout: a store written under another is another ensemble
#: (2: chunks named ``_c…``, listed with their hashes in the identity file)
SCHEMA = 2
IDENTITY = "_ensemble.json"
_LOCK, _README, _ASIDE = ".lock", "README.txt", ".bad-"
#: the store's own files besides its identity, chunks and set-aside ones (a ledger's lock, left
#: by a run that wrote a file here, is no stray either)
_OWN = (_LOCK, LEDGER_LOCK, _README)
_CHUNK = re.compile(r"_c(\d{9})-([0-9a-f]{24})\.parquet")
_CHUNK_V1 = re.compile(r"c\d{9}-[0-9a-f]{24}\.parquet")        # layout 1's, cleared on reclaim
_RETCODES = {r.value for r in ReturnCode}
_README_TEXT = """\
This directory is an rsfbench ensemble store, not a Parquet dataset.

Read it with

    from benchmarks.ensemble import read_store
    table = read_store("path/to/this/directory")

which reads only the chunks that _ensemble.json lists, each checked against its SHA-256.
pandas.read_parquet on this directory would read any other file put here as rows too (a copy,
a chunk edited by hand, a chunk of another ensemble); this file is here to make it fail.
See docs/ensembles.md.
"""


class BadChunkWarning(UserWarning):
    """A chunk file (or identity file) that cannot be trusted: set aside and, by a run,
    recomputed (the message names the file)."""


class StrayFileWarning(UserWarning):
    """A file in a store that its identity file does not list: ignored, never read (the message
    names it)."""


class IncompleteStoreWarning(UserWarning):
    """:func:`read_store` found fewer points than the ensemble has (an unfinished run)."""


class StoreBusy(RunStopped):
    """Another run holds the store's lock: the run cannot go on (a command exits with status 1,
    one line)."""


@functools.cache
def code_version() -> str:
    """A hash of the code that decides a row (``integrators/``, ``problems/``, and of
    ``benchmarks/`` the metrics, the curves and the rows) and of numba's and numpy's versions: a
    store written by other code is another ensemble, so a fixed bug cannot hide in old rows.
    Read once a process: the code a process runs does not change under it."""
    here = Path(benchmarks.__file__).parent
    files = [*sorted(Path(integrators.__file__).parent.rglob("*.py")),
             *sorted(Path(problems.__file__).parent.rglob("*.py")),
             here / "physics" / "metrics.py", here / "physics" / "curves.py",
             here / "ensemble" / "rows.py"]
    digest = hashlib.sha256(f"numba {numba.__version__} numpy {np.__version__}".encode())
    for f in files:
        digest.update(f.name.encode() + f.read_bytes())
    return digest.hexdigest()[:16]


def identity_of(problem, algorithm, names, values, chunk_size: int, wall_budget,
                curve_dt=None, curve_chain=None, sensitivity=(),
                sensitivity_error: bool = True, settle: float = 0.0) -> dict:
    """What makes an ensemble the same ensemble: the code (:func:`code_version`), the base
    problem, the algorithm and its options, the wall budget per point, the curves' resolution,
    the parameter names, the points (a hash) and the chunking (and a curves' measurement chain,
    the sensitivities asked for and their error control, a ``settle``)."""
    return {"schema": SCHEMA, "code": code_version(), "problem": repr(problem),
            "algorithm": repr(algorithm),
            "wall_budget": wall_budget, "curve_dt": curve_dt, "parameters": list(names),
            "n_points": len(values),
            "points_sha256": hashlib.sha256(np.ascontiguousarray(values).tobytes()).hexdigest(),
            "chunk_size": chunk_size,
            **({"curve_chain": repr(curve_chain)} if curve_chain is not None else {}),
            **({"sensitivity": list(sensitivity), "sensitivity_error": sensitivity_error}
               if sensitivity else {}),
            **({"settle": settle} if settle else {})}


def _held_asked(held, asked) -> str:
    """`` (held X, asked Y)`` for short values of an identity's key; nothing for long ones
    (a problem's repr, a hash) or the code's version."""
    if any(len(repr(v)) > 60 for v in (held, asked)):
        return ""
    return f" (held {held!r}, asked {asked!r})"


def held_algorithm(root) -> str | None:
    """The ``algorithm`` (its ``repr``) of the ensemble a store at ``root`` holds, or None
    where there is no store or its identity file cannot be read (reading changes nothing)."""
    try:
        held = json.loads((Path(root) / IDENTITY).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return held.get("algorithm") if isinstance(held, dict) else None


class ChunkStore:
    """The chunks of one ensemble under ``root`` (module docstring). Use as a context manager:
    it holds the lock from ``__enter__`` to ``__exit__``. ``bad``: the chunk files found
    untrustworthy (set aside, to be recomputed); ``strays``: the other files ignored.

    Parameters
    ----------
    root : str or pathlib.Path
        The store's directory (made if missing).
    identity : dict
        What the ensemble is (problem, algorithm, points, chunking): a store of another
        identity is refused.
    reclaim : bool
        Clear a store of another ensemble instead of refusing it.

    Raises
    ------
    StoreBusy
        On entry, when another run holds the store's lock.
    ValueError
        On entry, for a root that is a file or cannot be written, or that holds another
        ensemble (without ``reclaim``).
    """

    def __init__(self, root, identity: dict, reclaim: bool = False) -> None:
        require("pyarrow", "ensemble", "a store of an ensemble (Parquet chunks)")
        self.root = Path(root)
        self.identity = identity
        self.reclaim = reclaim
        self.bad: list[str] = []
        self.strays: list[str] = []
        self.listed: dict[str, str] = {}          # chunk file name → SHA-256 of its bytes
        self._seen: set[str] = set()              # chunk names this run has looked for
        self._lock = None

    def __enter__(self) -> "ChunkStore":
        if self.root.exists() and not self.root.is_dir():
            raise ValueError(f"the store {self.root} is a file, not a directory")
        lock = FileLock(self.root / _LOCK, timeout=0)
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            lock.acquire()
        except Timeout:
            raise StoreBusy(f"the store {self.root} is in use by another run (its lock "
                            f"{self.root / _LOCK} is held): wait for it, or use another "
                            "directory") from None
        except OSError as exc:             # a path through a file, a read-only place
            raise ValueError(f"the store {self.root} cannot be written "
                             f"({exc.strerror or exc}): give a directory you can write") from None
        self._lock = lock
        try:
            remove_stale_temporaries(self.root)
            self._claim()
            if not (self.root / _README).is_file():
                atomic_write(self.root / _README, _README_TEXT)
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def _claim(self) -> None:
        """Take the listing of a store of this ensemble; start an empty one; refuse (or, with
        ``reclaim``, clear) another ensemble's; set a damaged identity file aside."""
        path = self.root / IDENTITY
        if not path.exists():
            others = sorted(p.name for p in self.root.iterdir() if not _ours(p.name))
            if others and not self.reclaim:
                raise ValueError(f"the store {self.root} holds files (e.g. {others[0]}) but no "
                                 f"identity file {IDENTITY}: not an ensemble store, or one whose "
                                 "identity was removed, so nothing in it can be verified; give "
                                 "another directory, or remove it to start over")
            self._clear()
            return self._write_identity()
        try:
            held = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(held, dict):
                raise ValueError(f"a JSON {type(held).__name__}, not an object")
        except (OSError, ValueError) as exc:
            # only a hand or a broken disk makes this (the file is written atomically)
            self._set_aside(path, f"the store's identity file {path} is damaged ({exc})")
            self._clear(chunks_only=True)
            return self._write_identity()
        same = {k: v for k, v in held.items() if k != "chunks"} == self.identity
        if not same:
            what = [k for k in sorted(set(held) | set(self.identity)) if k != "chunks"
                    and held.get(k) != self.identity.get(k)]
            if "sensitivity" not in set(held) & set(self.identity):
                # the error control is recorded only with names: not a difference of its own
                what = [k for k in what if k != "sensitivity_error"] or what
            what = ", ".join(k + _held_asked(held.get(k), self.identity.get(k)) for k in what)
            if not self.reclaim:
                raise ValueError(f"the store {self.root} holds another ensemble (differing: "
                                 f"{what}): give another directory, or remove it to start over")
            self._clear()                     # a cache of the harness: start it over
            return self._write_identity()
        listed = held.get("chunks", {})
        if not (isinstance(listed, dict) and all(
                isinstance(k, str) and isinstance(v, str) for k, v in listed.items())):
            self._set_aside(path, f"the store's identity file {path} lists its chunks in a form "
                                  "it never writes")
            self._clear(chunks_only=True)
            return self._write_identity()
        self.listed = dict(listed)

    def _clear(self, chunks_only: bool = False) -> None:
        """Remove what a store of another ensemble left: its chunks (set aside when they may
        be evidence: ``chunks_only``, after a damaged identity file), quarantined files, its
        identity file."""
        for p in self.root.iterdir():
            if _CHUNK.fullmatch(p.name):
                if chunks_only:
                    _aside(p)
                else:
                    p.unlink(missing_ok=True)
            elif not chunks_only and (p.name.startswith(_ASIDE) or p.name == IDENTITY
                                      or _CHUNK_V1.fullmatch(p.name)):
                p.unlink(missing_ok=True)
        self.listed = {}

    def _write_identity(self) -> None:
        atomic_write(self.root / IDENTITY, json.dumps(
            {**self.identity, "chunks": dict(sorted(self.listed.items()))}, indent=1))

    def _set_aside(self, path: Path, why: str) -> None:
        aside = _aside(path)                 # readers skip it; a run writes a good one
        self.bad.append(why)
        warnings.warn(f"{why}: recomputing it (the file is kept as {aside.name})",
                      BadChunkWarning, stacklevel=3)

    # --- chunks -----------------------------------------------------------------------------
    def key(self, first: int, values: np.ndarray) -> str:
        text = json.dumps(self.identity, sort_keys=True) + f"|{first}|"
        digest = hashlib.sha256(text.encode() + np.ascontiguousarray(values).tobytes())
        return digest.hexdigest()[:24]

    def path(self, first: int, key: str) -> Path:
        return self.root / f"_c{first:09d}-{key}.parquet"

    def load(self, first: int, names, values: np.ndarray) -> pd.DataFrame | None:
        """The stored rows of the chunk of points ``values`` starting at point ``first``, or
        None: not stored, or stored but untrustworthy (then reported and set aside, to be
        recomputed)."""
        key = self.key(first, values)
        path = self.path(first, key)
        self._seen.add(path.name)
        digest = self.listed.get(path.name)
        if digest is None:
            if path.exists():               # written by a run killed before it listed it
                self._set_aside(path, f"chunk {path} is not listed in {IDENTITY}")
            return None
        try:
            table = _verified(path, digest, key)
            _check(table, names, values, path, bool(self.identity.get("curve_dt")),
                   tuple(self.identity.get("sensitivity", ())))
        except FileNotFoundError:
            self.bad.append(f"chunk {path} is listed but missing")
            warnings.warn(f"chunk {path} is listed in {IDENTITY} but missing: recomputing it",
                          BadChunkWarning, stacklevel=2)
            self._unlist(path.name)
            return None
        except _Bad as exc:
            self._unlist(path.name)
            self._set_aside(path, str(exc))
            return None
        return table

    def report_strays(self) -> list[str]:
        """Warn of every file that is not this store's (after the run's :meth:`load` calls):
        ignored, never read nor deleted. Returns their names. A listed name that is no chunk
        of this ensemble (only a hand lists one) is unlisted first: its file is a stray too."""
        if set(self.listed) - self._seen:
            self.listed = {k: v for k, v in self.listed.items() if k in self._seen}
            self._write_identity()
        self.strays = _strays(self.root, self._seen)
        for name in self.strays:
            warnings.warn(f"{self.root / name} is not a chunk listed in the store's {IDENTITY}: "
                          "ignored", StrayFileWarning, stacklevel=2)
        return self.strays

    def save(self, first: int, values: np.ndarray, table: pd.DataFrame) -> Path:
        """Write a finished chunk (atomically), then list it with its hash; returns its path."""
        import pyarrow as pa
        import pyarrow.parquet as pq
        key = self.key(first, values)
        arrow = pa.Table.from_pandas(table, preserve_index=False)
        arrow = arrow.replace_schema_metadata({**(arrow.schema.metadata or {}),
                                               b"rsfbench_key": key.encode()})
        sink = io.BytesIO()
        pq.write_table(arrow, sink, compression="zstd", write_page_checksum=True)
        data = sink.getvalue()
        path = self.path(first, key)
        # a Ctrl-C or SIGTERM between the chunk and its listing would leave a finished chunk
        # unlisted (a stray, computed again): it waits until both are written (a kill cannot)
        with uninterrupted():
            atomic_write(path, data)
            self.listed[path.name] = hashlib.sha256(data).hexdigest()
            self._write_identity()
        return path

    def _unlist(self, name: str) -> None:
        if self.listed.pop(name, None) is not None:
            self._write_identity()


def read_store(root) -> pd.DataFrame:
    """The rows of the ensemble stored in ``root``, in the order of its points: only the chunks
    its identity file lists, each checked against its SHA-256 and its rows checked.

    Parameters
    ----------
    root : str or pathlib.Path
        The store's directory.

    Returns
    -------
    pandas.DataFrame
        ``attrs``: n_points, n_stored, complete, bad_chunks, stray_files. A listed chunk that
        fails is left out (:class:`BadChunkWarning`), any other file ignored
        (:class:`StrayFileWarning`), a part store warns (:class:`IncompleteStoreWarning`).

    Raises
    ------
    ValueError
        Naming a directory that is not a store (no identity file, or a damaged one)."""
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"the store {root} is not a directory" if root.exists() else
                         f"the store {root} does not exist")
    path = root / IDENTITY
    try:
        held = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{root} has no identity file {IDENTITY}: not an ensemble store") \
            from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"the store's identity file {path} is damaged ({exc}); run the "
                         "ensemble again to rebuild the store") from None
    if not isinstance(held, dict) or held.get("schema") != SCHEMA:
        raise ValueError(f"{path} is not the identity file of a store of this version (schema "
                         f"{held.get('schema') if isinstance(held, dict) else None!r}, not "
                         f"{SCHEMA}); run the ensemble again to rebuild the store")
    try:
        names, n_points, size = list(held["parameters"]), int(held["n_points"]), \
            int(held["chunk_size"])
        listed = dict(held["chunks"])
        curves, sensitivity = bool(held.get("curve_dt")), tuple(held.get("sensitivity", ()))
        if not (names and n_points > 0 and size > 0
                and all(isinstance(v, str) for v in listed.values())):
            raise ValueError("values out of range")
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"the store's identity file {path} is damaged ({exc!r}); run the "
                         "ensemble again to rebuild the store") from None
    tables, bad = {}, []
    for name in sorted(listed):
        match = _CHUNK.fullmatch(name)
        first = int(match.group(1)) if match else -1
        n = min(size, n_points - first)
        try:
            if not match or first % size or n <= 0 or first in tables:
                raise _Bad(f"{IDENTITY} lists {name!r}, which is no chunk of this ensemble")
            table = _verified(root / name, listed[name], match.group(2))
            if len(table) != n:
                raise _Bad(f"chunk {root / name} has {len(table)} rows, not {n}")
            _check_rows(table, names, root / name, curves, sensitivity)
        except (_Bad, FileNotFoundError) as exc:
            why = str(exc) if isinstance(exc, _Bad) else f"chunk {root / name} is missing"
            bad.append(why)
            warnings.warn(f"{why}: left out (run the ensemble again to recompute it)",
                          BadChunkWarning, stacklevel=2)
            continue
        tables[first] = table
    strays = _strays(root, set(listed))
    for name in strays:
        warnings.warn(f"{root / name} is not a chunk listed in the store's {IDENTITY}: ignored",
                      StrayFileWarning, stacklevel=2)
    table = (pd.concat([tables[k] for k in sorted(tables)], ignore_index=True) if tables
             else pd.DataFrame(columns=columns_of(names, curves, sensitivity)))
    if len(table) < n_points:
        warnings.warn(f"the store {root} holds {len(table)} of its ensemble's {n_points} "
                      "points (an unfinished run, or chunks left out: run it again to complete "
                      "it)", IncompleteStoreWarning, stacklevel=2)
    table.attrs = {"n_points": n_points, "n_stored": len(table),
                   "complete": len(table) == n_points, "bad_chunks": bad, "stray_files": strays}
    return table


def _aside(path: Path) -> Path:
    """Rename ``path`` to ``.bad-<name>`` (Parquet readers and the store skip it); when an
    earlier one of another kind is in the way (a directory, a file), to ``.bad-<name>.<n>``."""
    for n in range(100):
        aside = path.with_name(f"{_ASIDE}{path.name}{f'.{n}' if n else ''}")
        try:
            os.replace(path, aside)
            return aside
        except OSError:
            if not path.exists():
                raise
    raise OSError(f"cannot set {path} aside: 100 earlier .bad- files are in the way")


def _ours(name: str) -> bool:
    """The store's own files other than chunks: locks, README, set-aside and temporary files."""
    return name in _OWN or name.startswith((_ASIDE, _TEMPORARY))


def _strays(root: Path, known: set[str]) -> list[str]:
    """The files of ``root`` a store does not know: not its identity file, locks or README, not
    a set-aside file (reported when it was set aside), not one of ``known``. A temporary file
    of a killed writer is a stray until it is old enough to be removed."""
    return sorted(p.name for p in root.iterdir()
                  if p.name not in known and p.name not in (IDENTITY, *_OWN)
                  and not p.name.startswith(_ASIDE))


class _Bad(Exception):
    pass


def _verified(path: Path, digest: str, key: str) -> pd.DataFrame:
    """The rows of the chunk file ``path`` if its bytes hash to ``digest`` and it reads as the
    Parquet file of the chunk ``key``; else ``_Bad``. ``FileNotFoundError`` if it is gone."""
    import pyarrow.parquet as pq
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise _Bad(f"chunk {path} cannot be read ({exc.strerror or exc})") from None
    if hashlib.sha256(data).hexdigest() != digest:
        raise _Bad(f"chunk {path} is not the file its store wrote (its SHA-256 differs from "
                   f"the one {IDENTITY} lists: edited, truncated or replaced)")
    try:
        arrow = pq.read_table(io.BytesIO(data), page_checksum_verification=True)
    except Exception as exc:         # not Parquet after all: pyarrow's own errors
        raise _Bad(f"chunk {path} does not read as Parquet ({type(exc).__name__}: {exc})")
    held = (arrow.schema.metadata or {}).get(b"rsfbench_key", b"").decode()
    if held != key:
        raise _Bad(f"chunk {path} holds the key {held!r}, not {key!r} (a copied file?)")
    return arrow.to_pandas()


def _check(table: pd.DataFrame, names, values: np.ndarray, path: Path, curves: bool,
           sensitivity=()) -> None:
    """``_Bad`` unless ``table`` is the whole chunk: one row per point with exactly its
    parameter values, and rows that check out (:func:`_check_rows`)."""
    if len(table) != len(values):
        raise _Bad(f"chunk {path} has {len(table)} rows, not {len(values)}")
    _check_rows(table, names, path, curves, sensitivity)
    if not np.array_equal(table[list(names)].to_numpy(dtype=float), values):
        raise _Bad(f"chunk {path} holds other points than its chunk's")


def _check_rows(table: pd.DataFrame, names, path: Path, curves: bool, sensitivity=()) -> None:
    """``_Bad`` unless every column is there, classes and retcodes are known, and metrics (and
    curves, gradients) are there for the limit cycles only."""
    expected = columns_of(names, curves, sensitivity)
    if list(table.columns) != expected:
        raise _Bad(f"chunk {path} has the columns {list(table.columns)}, not {expected}")
    if not (table.classification.isin(CLASSIFICATIONS).all()
            and table.retcode.isin(_RETCODES).all()):
        raise _Bad(f"chunk {path} holds an unknown classification or retcode")
    cycle = table.classification.isin(CYCLES).to_numpy()
    metrics = table[list(METRIC_COLUMNS)].to_numpy(dtype=float)
    if not (np.isfinite(metrics[cycle]).all() and np.isnan(metrics[~cycle]).all()):
        raise _Bad(f"chunk {path} holds limit-cycle metrics that do not match its classes")
    if not np.isnan(table[gradient_columns(sensitivity)].to_numpy(dtype=float)[~cycle]).all():
        raise _Bad(f"chunk {path} holds gradients of points without a limit cycle")
    if curves:
        for is_cycle, slip, mu in zip(cycle, table.curve_slip, table.curve_friction):
            x, y = np.asarray(slip, dtype=float), np.asarray(mu, dtype=float)
            if not (x.shape == y.shape and np.isfinite(x).all() and np.isfinite(y).all()
                    and (x.size >= 2 if is_cycle else x.size == 0)):
                raise _Bad(f"chunk {path} lacks a slip-weakening curve of a limit cycle, or "
                           "holds one of another point")
