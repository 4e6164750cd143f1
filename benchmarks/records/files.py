"""Result files written so that a reader never sees half of one, and read so that a bad one is
never trusted.

* :func:`atomic_write`: a temporary file in the same directory, fsync'd, then renamed over the
  target; a writer killed half-way leaves a temporary ``.rsfbench-tmp-NAME.*.tmp`` file, never a
  half file.
* :func:`remove_stale_temporaries`: such leftovers are removed once they are older than any
  write can take (:data:`STALE_AFTER_S`), so a directory written by killed runs does not fill up.
* :func:`writing`, :func:`write_output` and :func:`claim_outputs`: the files a command writes
  for its user, which never replace a file of the user's (below).
* :func:`read_json_record` and :func:`read_table` check what they read (it parses, it is the kind
  of object expected, it has the keys or columns expected) and raise :class:`BadResultsFile`,
  which names the file and what is wrong with it. A cache catches it and recomputes; a command
  reports it in one line.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import time
from pathlib import Path

import pandas as pd
from filelock import FileLock

from benchmarks.records.interrupts import uninterrupted

__all__ = ["BadResultsFile", "OutputExists", "atomic_write", "writing", "write_output",
           "write_table", "write_figure", "claim_outputs", "adopt", "remove_own", "note_input",
           "allow_overwrite", "begin_run", "written", "is_own", "overwriting", "permit", "remove_stale_temporaries",
           "read_json_record", "read_table", "STALE_AFTER_S", "LEDGER", "LEDGER_LOCK"]

#: a temporary file older than this (s) belongs to a writer that was killed: any write here
#: (one small JSON or CSV file) takes milliseconds
STALE_AFTER_S = 60.0
#: the name prefix of :func:`atomic_write`'s temporary files: no other file is ever removed
_PREFIX = ".rsfbench-tmp-"


class BadResultsFile(ValueError):
    """A results file that cannot be trusted; the message names the file and the reason."""


def atomic_write(path: Path, text: str | bytes) -> None:
    """Write ``text`` (or bytes) to ``path`` so that readers see the old file or the new one,
    never half. The file gets the permissions a plain ``open`` would give it (``mkstemp``'s are
    0600). No ownership check: for the files of a store or cache rsfbench owns (a user's
    output goes through :func:`write_output`).

    Parameters
    ----------
    path : pathlib.Path
        The file written.
    text : str or bytes
        Its new content.
    """
    path = Path(path)
    with _temporary(path) as tmp:
        with open(tmp, "wb" if isinstance(text, bytes) else "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())


@contextlib.contextmanager
def _temporary(path: Path, then=None):
    """A temporary path beside ``path``, renamed to it when the block ends without an error and
    removed otherwise (``then()`` right after the rename, a Ctrl-C or SIGTERM held back between
    them); an OSError names ``path``."""
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f"{_PREFIX}{path.name}.",
                                   suffix=".tmp")
    except OSError as exc:
        raise OSError(exc.errno, f"cannot write {path}: {exc.strerror}", str(path)) from None
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        os.close(fd)
        yield Path(tmp)
        with uninterrupted():
            os.replace(tmp, path)
            if then is not None:
                then()
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OSError(exc.errno, f"cannot write {path}: {exc.strerror or exc}",
                      str(path)) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# --- a user's files ---------------------------------------------------------------------------

#: the ledger of the files rsfbench wrote in a directory (module docstring)
LEDGER = ".rsfbench-files.json"
#: the lock held while the ledger is changed: hidden, never an output (removed on release by
#: filelock 4; left, empty, by earlier versions and by a killed run)
LEDGER_LOCK = ".rsfbench-files.lock"


class OutputExists(ValueError):
    """A command would replace a file that is not rsfbench's own, unchanged; the message names
    the file and how to proceed."""


class _Run:
    """What this process's run may write over (module docstring)."""

    def __init__(self) -> None:
        self.overwrite = False
        self.inputs: set[Path] = set()
        self.written: list[Path] = []


_RUN = _Run()


def begin_run() -> None:
    """Start a new run (``rsfbench``'s main, once a command): nothing written, no inputs, no
    overwriting."""
    global _RUN
    _RUN = _Run()


def allow_overwrite(allow: bool = True) -> None:
    """Let this run replace files that are not rsfbench's (``--overwrite``); never an input."""
    _RUN.overwrite = bool(allow)


def overwriting() -> bool:
    """Does this run replace files that are not rsfbench's (``--overwrite``)?"""
    return _RUN.overwrite


def permit(paths) -> None:
    """Let this run write ``paths`` (a pipeline's own records, listed in its manifest)."""
    for path in paths:
        resolved = Path(path).resolve()
        if resolved not in _RUN.written:
            _RUN.written.append(resolved)


def note_input(path) -> None:
    """``path`` is read by this run: it is never written over, not even with ``--overwrite``."""
    with contextlib.suppress(OSError):
        _RUN.inputs.add(Path(path).resolve())


def written() -> list[str]:
    """The files this run wrote, in order (for a run's provenance)."""
    return [str(p) for p in _RUN.written]


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _ledger(directory: Path) -> dict:
    try:
        data = json.loads((directory / LEDGER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


#: the results manifest of a study directory (:mod:`benchmarks.pipeline.manifest`), whose
#: records list each study's files with their sha256: those files are rsfbench's too
RESULTS_MANIFEST = "manifest.json"


def is_own(path) -> bool:
    """Did rsfbench write ``path``, and is it unchanged since? Its directory's ledger says so,
    or a results manifest in it or up to two levels above (a study's file)."""
    path = Path(path)
    try:
        digest = _sha256(path)
    except OSError:
        return False
    entry = _ledger(path.parent).get(path.name)
    if isinstance(entry, dict) and entry.get("sha256") == digest:
        return True
    for root in list(path.parents)[:3]:
        try:
            records = json.loads((root / RESULTS_MANIFEST).read_text(encoding="utf-8"))
            relative = path.resolve().relative_to(root.resolve()).as_posix()
        except (OSError, ValueError):
            continue
        if isinstance(records, list) and any(
                isinstance(r, dict) and isinstance(r.get("outputs"), dict)
                and r["outputs"].get(relative) == digest for r in records):
            return True
    return False


def _refusal(path: Path) -> str | None:
    """Why this run may not write ``path``, or None."""
    resolved = path.resolve()
    if resolved in _RUN.inputs:
        return f"{path} is an input of this run: refusing to write over it (choose another place)"
    if not path.exists() and not path.is_symlink():
        return None
    if path.is_dir():
        return f"{path} is a directory, not a file"
    if resolved in _RUN.written or _RUN.overwrite or is_own(path):
        return None
    return (f"{path} exists and is not a file rsfbench wrote (or it was changed since): "
            "refusing to replace it; choose another place, move it, or give --overwrite")


def claim_outputs(paths) -> None:
    """Refuse, before any work, to go on when one of ``paths`` could not be written
    (:class:`OutputExists` naming the first)."""
    for path in paths:
        why = _refusal(Path(path))
        if why:
            raise OutputExists(why)


@contextlib.contextmanager
def writing(path):
    """``with writing(path) as tmp: df.to_csv(tmp)``: the block writes a temporary file beside
    ``path``, which becomes ``path`` when the block ends (none, and the old file kept, if it
    fails); refused with :class:`OutputExists` when ``path`` holds a file that is not
    rsfbench's (module docstring). The file joins the directory's ledger and :func:`written`."""
    path = Path(path)
    claim_outputs([path])
    path.parent.mkdir(parents=True, exist_ok=True)
    with _temporary(path, then=lambda: _record(path)) as tmp:
        yield tmp


def write_output(path, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` as :func:`writing` does; returns the path."""
    with writing(path) as tmp:
        if isinstance(data, bytes):
            tmp.write_bytes(data)
        else:
            tmp.write_text(data, encoding="utf-8")
    return Path(path)


def write_table(table, path, **to_csv) -> Path:
    """Write the DataFrame ``table`` to ``path`` as CSV (no index unless asked) as
    :func:`writing` does; returns the path."""
    with writing(path) as tmp:
        table.to_csv(tmp, **{"index": False, **to_csv})
    return Path(path)


def write_figure(fig, path, **savefig) -> Path:
    """Save the matplotlib ``fig`` to ``path`` (its format from the suffix) as :func:`writing`
    does; returns the path."""
    path = Path(path)
    with writing(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".").lower() or "png", **savefig)
    return path


def _ledger_lock(directory: Path) -> FileLock:
    """The directory's ledger locked (:data:`LEDGER_LOCK`) while it is read, changed and
    written: runs writing into one directory at once keep each other's entries."""
    return FileLock(directory / LEDGER_LOCK)


def _record(path: Path) -> None:
    resolved = path.resolve()
    if resolved not in _RUN.written:
        _RUN.written.append(resolved)
    digest = _sha256(path)
    with _ledger_lock(path.parent):
        ledger = _ledger(path.parent)
        ledger[path.name] = {"sha256": digest, "written": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        atomic_write(path.parent / LEDGER, json.dumps(ledger, indent=1, sort_keys=True) + "\n")


def adopt(paths) -> None:
    """Record ``paths``, which this run has just written by other means (a study's own
    writers), as this run's and rsfbench's (the ledger)."""
    for path in paths:
        _record(Path(path))


def remove_own(path) -> bool:
    """Delete ``path`` if rsfbench wrote it and it is unchanged since (an earlier run's file
    this run does not make again); a file of anyone else's is kept. Returns whether it went."""
    path = Path(path)
    if not path.is_file() or path.resolve() in _RUN.inputs or not is_own(path):
        return False
    path.unlink()
    with _ledger_lock(path.parent):
        ledger = _ledger(path.parent)
        if ledger.pop(path.name, None) is not None:
            atomic_write(path.parent / LEDGER,
                         json.dumps(ledger, indent=1, sort_keys=True) + "\n")
    return True


def _umask() -> int:
    mask = os.umask(0)          # the only way to read it: set it back at once (at import)
    os.umask(mask)
    return mask


_UMASK = _umask()


def remove_stale_temporaries(directory: Path, older_than: float = STALE_AFTER_S) -> list[Path]:
    """Delete the temporary files :func:`atomic_write` left in ``directory`` when its writer was
    killed (its own prefix, older than ``older_than`` seconds); return them."""
    now, removed = time.time(), []
    for tmp in Path(directory).glob(f"{_PREFIX}*.tmp"):
        try:
            if now - tmp.stat().st_mtime > older_than:
                tmp.unlink()
                removed.append(tmp)
        except FileNotFoundError:       # its writer renamed it meanwhile
            pass
    return removed


def read_json_record(path: Path, required: tuple[str, ...] = (), what: str = "file") -> dict:
    """A JSON object from ``path`` that has the ``required`` keys, or :class:`BadResultsFile`.

    Parameters
    ----------
    path : pathlib.Path
        The JSON file.
    required : tuple of str
        The keys it must have.
    what : str
        What the file is, for messages.

    Returns
    -------
    dict

    Raises
    ------
    BadResultsFile
        For a missing or unreadable file, or one without a required key.
    """
    path = Path(path)
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BadResultsFile(f"{what} {path} is not valid JSON ({exc.__class__.__name__}: "
                             f"{exc})") from None
    except OSError as exc:
        raise BadResultsFile(f"{what} {path} cannot be read: {exc.strerror or exc}") from None
    if not isinstance(record, dict):
        raise BadResultsFile(f"{what} {path} holds a JSON {type(record).__name__}, not an object")
    missing = [k for k in required if k not in record]
    if missing:
        raise BadResultsFile(f"{what} {path} lacks the keys {missing}")
    return record


def read_table(path: Path, required: tuple[str, ...] = (), what: str = "table",
               hint: str = "") -> pd.DataFrame:
    """A CSV table from ``path`` with the ``required`` columns and at least one row, or
    :class:`BadResultsFile` (``hint`` says how to make a good one).

    Parameters
    ----------
    path : pathlib.Path
        The CSV file.
    required : tuple of str
        The columns it must have.
    what : str
        What the table is, for messages.
    hint : str
        How to make a good one, for messages.

    Returns
    -------
    pandas.DataFrame

    Raises
    ------
    BadResultsFile
        For a missing, unreadable or empty table, or one without a required column.
    """
    path = Path(path)
    tail = f"; {hint}" if hint else ""
    if not path.is_file():
        raise BadResultsFile(f"{what} {path} does not exist{tail}" if not path.exists()
                             else f"{what} {path} is not a file{tail}")
    try:
        df = pd.read_csv(path)
    except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise BadResultsFile(f"{what} {path} is not a readable CSV table "
                             f"({exc.__class__.__name__}){tail}") from None
    except OSError as exc:
        raise BadResultsFile(f"{what} {path} cannot be read: {exc.strerror or exc}{tail}") from None
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise BadResultsFile(f"{what} {path} lacks the columns {missing}{tail}")
    if df.empty:
        raise BadResultsFile(f"{what} {path} has no rows{tail}")
    return df
