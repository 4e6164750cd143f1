"""The ensemble store reads back only what it wrote (issue 29): the chunks its identity file
lists, each with the SHA-256 listed there. Stray files of every kind are ignored and reported by
both readers (:func:`read_store` and a resuming run) and never deleted; an edited, truncated or
replaced chunk is left out by the reader and recomputed by a run; a damaged identity file is set
aside (a run) or refused (the reader); a missing one, or another ensemble, is refused; a raw
``pandas.read_parquet`` of the directory fails instead of returning extra rows. The slow test
loses the Dask scheduler of a running ensemble."""

import json
import shutil
import time
import warnings

import numpy as np
import pandas as pd
import pytest

from benchmarks.ensemble import (BadChunkWarning, IncompleteStoreWarning, StrayFileWarning,
                                 ensemble, grid, read_store)
from integrators import Rodas5P
from probe.harness import dask_cluster, stop_processes
from problems import variant, window

# 4 points in 2 chunks of 2, 2 s of W2 each: what is stored matters here, not the physics
POINTS = grid(b=[0.0090, 0.0094], lc=[3e-7, 1e-6])
ALGORITHM = Rodas5P(rtol=1e-4, atol=1e-4)


def _base():
    return window("W2", "slip", t_end=2.0)


def _run(store, base=None, **kw):
    """The ensemble on ``store``, with the warnings it gave."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        table = ensemble(base or _base(), ALGORITHM, POINTS, store=store, chunk_size=2,
                         progress=False, **kw)
    return table, seen


def _read(store):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        table = read_store(store)
    return table, seen


def _named(seen, category, name) -> bool:
    return any(issubclass(w.category, category) and name in str(w.message) for w in seen)


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    """The same rows, wall time aside (a recomputed chunk has its own)."""
    cols = [c for c in a.columns if c != "wall_s"]
    pd.testing.assert_frame_equal(a[cols].reset_index(drop=True), b[cols].reset_index(drop=True))


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    root = tmp_path_factory.mktemp("pristine") / "s"
    table, seen = _run(root)
    assert not seen and table.attrs["n_run"] == 4
    return root, table


@pytest.fixture
def store(pristine, tmp_path):
    root, table = pristine
    copy = tmp_path / "s"
    shutil.copytree(root, copy, ignore=shutil.ignore_patterns(".lock"))
    return copy, table


def _chunks(root):
    return sorted(root.glob("_c*.parquet"))


def _other_ensemble_chunk(tmp_path):
    """A chunk file of another ensemble (another t_end), under its own name."""
    other = tmp_path / "other"
    _run(other, base=variant(_base(), t_end=1.0))
    return _chunks(other)[0]


# --- the layout ----------------------------------------------------------------------------

def test_the_store_lists_every_chunk_with_its_hash(store):
    import hashlib
    root, table = store
    listed = json.loads((root / "_ensemble.json").read_text())["chunks"]
    assert sorted(listed) == [p.name for p in _chunks(root)] and len(listed) == 2
    for name, digest in listed.items():
        assert hashlib.sha256((root / name).read_bytes()).hexdigest() == digest
    again, seen = _read(root)
    assert not seen and again.attrs["complete"]
    _same(again, table)


def test_a_raw_read_of_the_directory_fails_instead_of_reading_strays(store):
    """The issue's case: a stray copy of a chunk beside it. pandas.read_parquet(DIR) read 243
    rows of a 225-point ensemble; now it fails, naming the file that says how to read it."""
    root, table = store
    shutil.copyfile(_chunks(root)[0], root / (_chunks(root)[0].name + ".orig"))
    with pytest.raises(Exception, match="README.txt"):
        pd.read_parquet(root)
    again, seen = _read(root)
    assert len(again) == len(table) == 4
    assert "read_store" in (root / "README.txt").read_text()


# --- stray files: ignored and reported by both readers, never deleted ------------------------

def _strays(root, tmp_path):
    chunk = _chunks(root)[0]
    return {
        "a copy of a chunk (.orig)": lambda: shutil.copyfile(chunk, root / (chunk.name + ".orig")),
        "a visible copy of a chunk": lambda: shutil.copyfile(chunk, root / "c1.parquet"),
        "a chunk of another ensemble": lambda: shutil.copy(_other_ensemble_chunk(tmp_path), root),
        "a killed writer's temporary file":
            lambda: (root / ".rsfbench-tmp-_c1.parquet.ab12.tmp").write_bytes(b"PAR1"),
        "a user's notes": lambda: (root / "notes.txt").write_text("b = 0.0094 looked odd"),
        "a directory": lambda: (root / "old").mkdir(),
    }


@pytest.mark.parametrize("kind", ["a copy of a chunk (.orig)", "a visible copy of a chunk",
                                  "a chunk of another ensemble",
                                  "a killed writer's temporary file", "a user's notes",
                                  "a directory"])
def test_a_stray_file_is_ignored_and_reported(store, tmp_path, kind):
    root, table = store
    before = set(p.name for p in root.iterdir())
    _strays(root, tmp_path)[kind]()
    (stray,) = set(p.name for p in root.iterdir()) - before
    read, seen = _read(root)
    assert _named(seen, StrayFileWarning, stray), [str(w.message) for w in seen]
    _same(read, table)
    assert read.attrs["stray_files"] == [stray]
    again, seen = _run(root)
    assert _named(seen, StrayFileWarning, stray)
    assert again.attrs["n_resumed"] == 4 and again.attrs["stray_files"] == [stray]
    _same(again, table)
    assert (root / stray).exists()                       # reported, never deleted


def test_locks_left_by_a_killed_run_are_no_strays(store):
    """The store's lock and a ledger's (a run that wrote a file here) are the store's own."""
    from benchmarks.records.files import LEDGER_LOCK
    root, table = store
    for name in (".lock", LEDGER_LOCK):
        (root / name).touch()
    read, seen = _read(root)
    assert not seen and read.attrs["stray_files"] == []
    again, seen = _run(root)
    assert not seen and again.attrs["n_resumed"] == 4 and again.attrs["stray_files"] == []


# --- a listed chunk that is not what the store wrote -------------------------------------------

def _rewrite(path, change):
    """The chunk's table changed by ``change``, its metadata (and so its key) kept."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    arrow = pq.read_table(path)
    out = pa.Table.from_pandas(change(arrow.to_pandas()), preserve_index=False)
    pq.write_table(out.replace_schema_metadata(arrow.schema.metadata), path)


DAMAGE = {
    "edited in place, its key kept": lambda p, root, tmp: _rewrite(
        p, lambda t: t.assign(recurrence_s=t.recurrence_s * 1.01)),
    "truncated": lambda p, root, tmp: p.write_bytes(p.read_bytes()[:-100]),
    "replaced by its neighbour": lambda p, root, tmp: p.write_bytes(_chunks(root)[1].read_bytes()),
    "replaced by a chunk of another ensemble":
        lambda p, root, tmp: p.write_bytes(_other_ensemble_chunk(tmp).read_bytes()),
    "removed": lambda p, root, tmp: p.unlink(),
    # an OSError on reading it, as a chunk without read permission gives (not testable as root)
    "a directory under its name": lambda p, root, tmp: (p.unlink(), p.mkdir()),
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_chunk_is_left_out_by_the_reader_and_recomputed_by_a_run(store, tmp_path,
                                                                           damage):
    root, table = store
    target = _chunks(root)[0]
    DAMAGE[damage](target, root, tmp_path)
    read, seen = _read(root)
    assert _named(seen, BadChunkWarning, target.name), [str(w.message) for w in seen]
    assert _named(seen, IncompleteStoreWarning, "2 of its ensemble's 4 points")
    assert not read.attrs["complete"] and len(read) == 2
    _same(read, table.iloc[2:])                          # the other chunk only
    again, seen = _run(root)
    assert _named(seen, BadChunkWarning, target.name)
    assert again.attrs["n_run"] == 2 and again.attrs["n_resumed"] == 2
    _same(again, table)
    read, seen = _read(root)
    assert not seen and read.attrs["complete"]
    _same(read, table)


def test_a_hash_edited_in_the_identity_file_recomputes_its_chunk(store):
    root, table = store
    path = root / "_ensemble.json"
    held = json.loads(path.read_text())
    name = sorted(held["chunks"])[1]
    held["chunks"][name] = "0" * 64
    path.write_text(json.dumps(held))
    again, seen = _run(root)
    assert _named(seen, BadChunkWarning, name) and again.attrs["n_run"] == 2
    _same(again, table)


def test_a_chunk_written_but_not_listed_is_recomputed(store):
    """A run killed between writing a chunk and listing it: the file is not trusted."""
    root, table = store
    path = root / "_ensemble.json"
    held = json.loads(path.read_text())
    name = sorted(held["chunks"])[0]
    del held["chunks"][name]
    path.write_text(json.dumps(held))
    read, seen = _read(root)
    assert _named(seen, StrayFileWarning, name) and len(read) == 2
    again, seen = _run(root)
    assert _named(seen, BadChunkWarning, name) and again.attrs["n_run"] == 2
    _same(again, table)


def test_a_stray_listed_by_hand_is_still_a_stray(store):
    """Listing a copy (with its right hash) in the identity file does not make it a chunk: the
    run reads only its own chunks' names, unlists the copy and reports it."""
    import hashlib
    root, table = store
    copy = root / "c_copy.parquet"
    shutil.copyfile(_chunks(root)[0], copy)
    path = root / "_ensemble.json"
    held = json.loads(path.read_text())
    held["chunks"][copy.name] = hashlib.sha256(copy.read_bytes()).hexdigest()
    path.write_text(json.dumps(held))
    read, seen = _read(root)
    assert _named(seen, BadChunkWarning, copy.name) and len(read) == 4
    _same(read, table)
    again, seen = _run(root)
    assert _named(seen, StrayFileWarning, copy.name) and again.attrs["n_resumed"] == 4
    assert copy.name not in json.loads(path.read_text())["chunks"]
    _same(again, table)


# --- the identity file ----------------------------------------------------------------------

@pytest.mark.parametrize("text", ["{\"schema\": 2, \"code\"", "[1, 2]", "\x00\x01garbage"])
def test_a_damaged_identity_file_is_set_aside_and_the_store_starts_over(store, text):
    root, table = store
    (root / "_ensemble.json").write_text(text)
    with pytest.raises(ValueError, match="_ensemble.json"):
        read_store(root)
    again, seen = _run(root)
    assert _named(seen, BadChunkWarning, "_ensemble.json")
    assert again.attrs["n_run"] == 4
    _same(again, table)
    assert (root / ".bad-_ensemble.json").read_text() == text
    _same(_read(root)[0], table)


def test_chunks_listed_in_a_form_never_written_start_the_store_over(store):
    root, table = store
    path = root / "_ensemble.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), "chunks": ["x"]}))
    again, seen = _run(root)
    assert _named(seen, BadChunkWarning, "_ensemble.json") and again.attrs["n_run"] == 4
    _same(again, table)


def test_a_missing_identity_file_is_refused_by_both_readers(store):
    root, _ = store
    (root / "_ensemble.json").unlink()
    with pytest.raises(ValueError, match="no identity file _ensemble.json"):
        read_store(root)
    with pytest.raises(ValueError, match="no identity file _ensemble.json"):
        _run(root)
    assert len(_chunks(root)) == 2                       # nothing removed


def test_another_ensemble_in_the_directory_is_refused(store):
    root, _ = store
    with pytest.raises(ValueError, match="holds another ensemble .*problem"):
        _run(root, base=variant(_base(), t_end=1.0))
    assert len(_chunks(root)) == 2


@pytest.mark.parametrize("where", ["a file", "a path through a file"])
def test_a_store_that_cannot_be_a_directory_is_refused_before_any_work(tmp_path, where):
    (tmp_path / "f").write_text("x")
    root = tmp_path / "f" if where == "a file" else tmp_path / "f" / "s"
    with pytest.raises(ValueError, match="the store .*f"):
        _run(root)


@pytest.mark.parametrize("where", ["missing", "a file", "an empty directory"])
def test_read_store_refuses_what_is_no_store(tmp_path, where):
    root = tmp_path / "s"
    if where == "a file":
        root.write_text("x")
    elif where == "an empty directory":
        root.mkdir()
    with pytest.raises(ValueError, match=str(root)):
        read_store(root)


def test_an_unfinished_store_reads_as_what_it_holds_with_a_warning(store):
    root, table = store
    path = root / "_ensemble.json"
    held = json.loads(path.read_text())
    last = sorted(held["chunks"])[1]
    del held["chunks"][last]
    (root / last).unlink()
    path.write_text(json.dumps(held))
    read, seen = _read(root)
    assert _named(seen, IncompleteStoreWarning, "2 of its ensemble's 4 points")
    assert read.attrs == {**read.attrs, "n_stored": 2, "complete": False}
    _same(read, table.iloc[:2])


# --- a lost Dask scheduler (slow: a scheduler and a worker in their own processes) ----------

@pytest.mark.slow
def test_a_result_lost_with_its_worker_is_not_waited_for(tmp_path):
    """Tasks that finished on a worker killed before their results were fetched: the fetch
    would wait for ever (Future.result has no timeout; CI once hung there). The run must end
    with ClusterGone once the cluster has had no worker for worker_timeout."""
    import threading

    from benchmarks.ensemble.executors import ClusterGone, connect, execute
    address, s, w = dask_cluster()
    ended = []
    try:
        client = connect(address, 30)
        while not client.scheduler_info().get("workers"):
            time.sleep(0.1)

        def consume():
            # abs: tasks done at once. After the first row, a pause lets all the others finish
            # on the worker, so that the next wait finds them all done; the worker is killed
            # as the first of those is taken, before the others' results are fetched
            try:
                rows = execute(abs, abs, None, list(range(200)), 1, "dask", client, 3.0)
                for n, _ in enumerate(rows):
                    if n == 0:
                        time.sleep(2.0)
                    elif n == 1:
                        stop_processes(w)
                        time.sleep(1.0)             # the scheduler has seen the worker go
            except ClusterGone as exc:
                ended.append(exc)
        thread = threading.Thread(target=consume, daemon=True)
        thread.start()
        thread.join(90)
        hung = thread.is_alive()
        client.close()
    finally:
        stop_processes(s, w)
    assert not hung, "the run waited for a result lost with its worker"
    assert ended and "no worker for 3 s" in str(ended[0])


@pytest.mark.slow
def test_losing_the_dask_scheduler_stops_the_run_keeping_its_chunks(tmp_path):
    """The scheduler is SIGKILLed once a chunk is stored: the run stops with SchedulerLost (a
    RunStopped: one line, exit status 1 in a command) saying what is kept; a rerun on a new
    cluster resumes the stored chunks and gives the table a local run gives."""
    import os
    import signal
    import threading

    from benchmarks.ensemble.executors import SchedulerLost
    from integrators import ETD2
    # 16 points of W4, 10 s each, ETD2 point by point: a few seconds of work, one point a chunk
    base = window("W4", "slip", t_end=10.0)
    points = grid(b=np.arange(0.0095, 0.0103, 0.0001), lc=[1e-7, 3e-7])
    store = tmp_path / "s"
    address, s, w = dask_cluster()
    try:
        def kill_when_stored():
            deadline = time.time() + 180
            while time.time() < deadline and not list(store.glob("_c*.parquet")):
                time.sleep(0.05)
            os.killpg(s.pid, signal.SIGKILL)
        threading.Thread(target=kill_when_stored, daemon=True).start()
        with pytest.raises(SchedulerLost) as caught:
            ensemble(base, ETD2(), points, store=store, scheduler=address, progress=False,
                     connect_timeout=30)
    finally:
        stop_processes(s, w)
    message = str(caught.value)
    assert "\n" not in message and "was lost" in message and str(store) in message
    kept = int(message.split("; ")[-1].split(" of ")[0])
    assert kept >= 1 and len(_chunks(store)) == kept      # one point a chunk
    address, s, w = dask_cluster()
    try:
        again = ensemble(base, ETD2(), points, store=store, scheduler=address, progress=False,
                         connect_timeout=30)
    finally:
        stop_processes(s, w)
    assert again.attrs["n_resumed"] == kept
    local = ensemble(base, ETD2(), points, workers=1, progress=False)
    _same(again, local)


def test_the_setting_a_store_holds_is_read_without_touching_it(store, tmp_path):
    from benchmarks.ensemble.store import IDENTITY, held_algorithm
    root, _ = store
    before = (root / IDENTITY).read_bytes()
    assert held_algorithm(root) == json.loads(before)["algorithm"]
    assert "Rodas5P" in held_algorithm(root)
    assert (root / IDENTITY).read_bytes() == before
    assert held_algorithm(tmp_path / "none") is None
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / IDENTITY).write_text("[1, 2")
    assert held_algorithm(tmp_path / "bad") is None
