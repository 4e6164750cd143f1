"""Result files written so that a reader never sees half of one, and read so that a bad one is
never trusted.

* :func:`atomic_write`: a temporary file in the same directory, fsync'd, then renamed over the
  target; a writer killed half-way leaves a temporary ``.rsfbench-tmp-NAME.*.tmp`` file, never a
  half file.
* :func:`remove_stale_temporaries`: such leftovers are removed once they are older than any
  write can take (:data:`STALE_AFTER_S`), so a directory written by killed runs does not fill up.
* :func:`read_json_record` and :func:`read_table` check what they read (it parses, it is the kind
  of object expected, it has the keys or columns expected) and raise :class:`BadResultsFile`,
  which names the file and what is wrong with it. A cache catches it and recomputes; a command
  reports it in one line.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path

import pandas as pd

__all__ = ["BadResultsFile", "atomic_write", "remove_stale_temporaries", "read_json_record",
           "read_table", "STALE_AFTER_S"]

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
    0600)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f"{_PREFIX}{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb" if isinstance(text, bytes) else "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


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
    """A JSON object from ``path`` that has the ``required`` keys, or :class:`BadResultsFile`."""
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
    :class:`BadResultsFile` (``hint`` says how to make a good one)."""
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
