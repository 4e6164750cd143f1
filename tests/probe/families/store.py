"""Probe cases: the store reads back only what it wrote (kind ``store``).

An ensemble store lists its chunks with their SHA-256 in its identity file
(:mod:`benchmarks.ensemble.store`); these cases put every kind of foreign or damaged file in a
store and read it back through every reader: :func:`~benchmarks.ensemble.read_store`, a rerun of
the ensemble (the Python API) and a rerun of ``rsfbench sweep --json`` (whose store is
``OUT/chunks``). A stray file must be ignored and reported by name (``warned``) and left in
place; a listed chunk that is not what the store wrote must be left out by the reader
(``warned``) and recomputed by a run (``recovered``), the table then equal to the undamaged one;
a damaged identity file is set aside by a run (``recovered``) and refused by the reader; a
missing one, or another ensemble in the directory, is refused. A raw ``pandas.read_parquet`` of a
store must fail rather than return extra rows. The slow cases lose the Dask scheduler, or every
worker, of a running sweep: exit status 1, one line saying what is kept, and a rerun resumes.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

from probe.harness import (Case, Observed, Wrong, cli, cli_outcome, dask_cluster, one_json,
                           stop_processes)

__all__ = ["cases"]

KIND = "store"
ROOT = Path(__file__).resolve().parents[3]
_READERS = ("read_store", "ensemble rerun", "sweep --json rerun")


# --- the ensemble, the sweep and their stores ----------------------------------------------------

def _run_ensemble(root, t_end=2.0):
    """4 points of W2 (t_end s each, Rodas5P), 2 chunks of 2; returns (table, warnings)."""
    from benchmarks.ensemble import ensemble, grid
    from integrators import Rodas5P
    from problems import window
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        table = ensemble(window("W2", "slip", t_end=t_end), Rodas5P(rtol=1e-4, atol=1e-4),
                         grid(b=[0.0090, 0.0094], lc=[3e-7, 1e-6]), store=root, chunk_size=2,
                         progress=False)
    return table, [f"{w.category.__name__}: {w.message}" for w in seen]


def _sweep(out, t_end="2", preset="W2"):
    """``rsfbench sweep --json`` of the same 4 points in 2 chunks; returns (CliRun, summary)."""
    run = cli("sweep", "--preset", preset, "--law", "slip", "--b", "0.0090:0.0094:0.0004",
              "--lc", "3e-7:1e-6:2log", "--t-end", t_end, "--integrator", "Rodas5P", "--rtol",
              "1e-4", "--atol", "1e-4", "--workers", "1", "--chunk-size", "2", "--no-progress",
              "--no-plot", "--out", str(out), "--json")
    return run, one_json(run.out)


def _read(root):
    from benchmarks.ensemble import read_store
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        table = read_store(root)
    return table, [f"{w.category.__name__}: {w.message}" for w in seen]


def _rows(table):
    """What must not change when a store is read back or resumed: every column but times."""
    import pandas as pd
    cols = [c for c in table.columns if c not in ("wall_s", "sim_wall_s")]
    return pd.DataFrame(table[cols]).reset_index(drop=True)


def _same(a, b, what: str) -> None:
    import pandas as pd
    try:
        pd.testing.assert_frame_equal(_rows(a), _rows(b))
    except AssertionError as exc:
        raise Wrong(f"{what}: the rows differ from the undamaged store's "
                    f"({' '.join(str(exc).split())[:200]})") from None


def _chunks(root: Path) -> list[Path]:
    return sorted(root.glob("_c*.parquet"))


class _Store:
    """A fresh store made by ``reader``'s own path (the API, or the command line: OUT/chunks),
    the undamaged table, and how to read it back the same way."""

    def __init__(self, tmp: Path, reader: str):
        self.reader = reader
        if reader == "sweep --json rerun":
            self.out = tmp / "out"
            first, self.summary = _sweep(self.out)
            if first.status != 0:
                raise Wrong(f"the first sweep failed: {first.err[-300:]}")
            self.root = self.out / "chunks"
            self.table = _csv(self.out)
        else:
            self.root = tmp / "s"
            self.table, seen = _run_ensemble(self.root)
            if seen:
                raise Wrong(f"a fresh store warned: {seen}")

    def read_back(self):
        """(table, warnings, what it did): the store read back by this reader."""
        if self.reader == "read_store":
            table, seen = _read(self.root)
            return table, seen, table.attrs
        if self.reader == "ensemble rerun":
            table, seen = _run_ensemble(self.root)
            return table, seen, table.attrs
        run, summary = _sweep(self.out)
        outcome = cli_outcome(run, json_mode=True)
        if outcome.outcome != "ok":
            raise Wrong(f"the rerun's outcome was {outcome.outcome}: {outcome.detail}")
        seen = [x for x in run.err.splitlines() if "warning:" in x]
        return _csv(self.out), seen, summary


def _csv(out: Path):
    import pandas as pd
    return pd.read_csv(out / "sweep.csv")


def _named(seen, category: str, name: str) -> bool:
    """Did a warning of ``category`` (a warning line of a command) name ``name``?"""
    return any(name in s and (s.startswith(category) or "warning:" in s) for s in seen)


def _other_chunk(tmp: Path) -> Path:
    """A chunk file of another ensemble (other t_end), under its own name."""
    _run_ensemble(tmp / "other", t_end=1.0)
    return _chunks(tmp / "other")[0]


# --- stray files × readers: ignored, named, never deleted ----------------------------------------

def _stray_makers():
    """Kinds of stray file: (name, make(root, tmp) → the stray's name)."""
    def orig(root, tmp):
        c = _chunks(root)[0]
        shutil.copyfile(c, root / f"{c.name}.orig")
        return f"{c.name}.orig"

    def visible(root, tmp):
        shutil.copyfile(_chunks(root)[1], root / "c000000002.parquet")
        return "c000000002.parquet"

    def other(root, tmp):
        c = _other_chunk(tmp)
        shutil.copy(c, root)
        return c.name

    def temporary(root, tmp):
        name = ".rsfbench-tmp-_c000000000-x.parquet.k3j2.tmp"     # a writer killed just now
        (root / name).write_bytes(b"PAR1")
        return name

    def notes(root, tmp):
        (root / "notes.txt").write_text("b = 0.0094 looked odd")
        return "notes.txt"

    def directory(root, tmp):
        (root / "old run").mkdir()
        shutil.copyfile(_chunks(root)[0], root / "old run" / "part.parquet")
        return "old run"

    return {"a copy of a chunk (.orig)": orig, "a visible copy of a chunk": visible,
            "a chunk of another ensemble": other, "a killed writer's temporary file": temporary,
            "a user's notes": notes, "a directory of old parts": directory}


def _stray_case(kind: str, make, reader: str) -> Case:
    def run(tmp):
        store = _Store(tmp, reader)
        stray = make(store.root, tmp)
        table, seen, did = store.read_back()
        if not _named(seen, "StrayFileWarning", stray):
            raise Wrong(f"the stray {stray!r} was not reported: {seen}")
        _same(table, store.table, f"with {stray!r} in the store")
        if not (store.root / stray).exists():
            raise Wrong(f"the stray {stray!r} was deleted")
        if reader != "read_store" and did.get("n_resumed") != 4:
            raise Wrong(f"the rerun did not resume the 4 stored points: {did}")
        return Observed("warned", next(s for s in seen if stray in s)[:200])
    return Case(KIND, f"{reader}: {kind} is ignored and reported", run, "warned", timeout=180)


# --- a listed chunk that is not what the store wrote × readers -----------------------------------

def _rewrite(path: Path, change) -> None:
    """The chunk's table changed by ``change``, its metadata (so its key) kept."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    arrow = pq.read_table(path)
    out = pa.Table.from_pandas(change(arrow.to_pandas()), preserve_index=False)
    pq.write_table(out.replace_schema_metadata(arrow.schema.metadata), path)


def _edit_hash(root: Path, target: Path) -> None:
    path = root / "_ensemble.json"
    held = json.loads(path.read_text())
    held["chunks"][target.name] = "0" * 64
    path.write_text(json.dumps(held))


_DAMAGE = {
    "edited in place, its key kept": lambda t, root, tmp: _rewrite(
        t, lambda d: d.assign(recurrence_s=d.recurrence_s * 1.01)),
    "truncated": lambda t, root, tmp: t.write_bytes(t.read_bytes()[:-100]),
    "replaced by its neighbour": lambda t, root, tmp: t.write_bytes(_chunks(root)[1].read_bytes()),
    "replaced by a chunk of another ensemble":
        lambda t, root, tmp: t.write_bytes(_other_chunk(tmp).read_bytes()),
    "its hash edited in the identity file": lambda t, root, tmp: _edit_hash(root, t),
    "removed": lambda t, root, tmp: t.unlink(),
    # an OSError on reading it, as a chunk without read permission gives (not testable as root)
    "a directory under its name": lambda t, root, tmp: (t.unlink(), t.mkdir()),
}


def _damage_case(kind: str, damage, reader: str) -> Case:
    expect = "warned" if reader == "read_store" else "recovered"

    def run(tmp):
        store = _Store(tmp, reader)
        target = _chunks(store.root)[0]
        damage(target, store.root, tmp)
        table, seen, did = store.read_back()
        if not _named(seen, "BadChunkWarning", target.name):
            raise Wrong(f"the damaged chunk {target.name} was not reported: {seen}")
        if reader == "read_store":
            if did.get("complete") or len(table) != 2:
                raise Wrong(f"the reader did not leave the chunk out: {len(table)} rows, {did}")
            _same(table, store.table.iloc[2:], "the chunks left")
            return Observed("warned", next(s for s in seen if target.name in s)[:200])
        if did.get("n_run") != 2 or did.get("n_resumed") != 2:
            raise Wrong(f"not exactly the damaged chunk recomputed: {did}")
        _same(table, store.table, "after recomputing")
        again, after = _read(store.root)
        if after or len(again) != 4:
            raise Wrong(f"the store does not read back whole after the recovery: {after}")
        return Observed("recovered", next(s for s in seen if target.name in s)[:200])
    return Case(KIND, f"{reader}: a chunk {kind}", run, expect, timeout=180)


# --- the identity file, another ensemble, a store that cannot be one -----------------------------

_IDENTITY_DAMAGE = {
    "truncated": '{"schema": 2, "code": "',
    "a JSON list": "[1, 2]",
    "binary garbage": "\x00\x01\x02garbage",
}


def _identity_case(kind: str, text: str, reader: str) -> Case:
    expect = "refused" if reader == "read_store" else "recovered"

    def run(tmp):
        store = _Store(tmp, reader)
        (store.root / "_ensemble.json").write_text(text)
        table, seen, did = store.read_back()          # read_store: a ValueError, refused
        if not _named(seen, "BadChunkWarning", "_ensemble.json"):
            raise Wrong(f"the damaged identity file was not reported: {seen}")
        _same(table, store.table, "after starting over")
        if not (store.root / ".bad-_ensemble.json").exists():
            raise Wrong("the damaged identity file was not kept aside")
        if did.get("n_run") != 4:
            raise Wrong(f"unverifiable chunks were trusted: {did}")
        return Observed("recovered", next(s for s in seen if "_ensemble.json" in s)[:200])
    return Case(KIND, f"{reader}: the identity file {kind}", run, expect,
                names="_ensemble.json" if expect == "refused" else "", timeout=180)


def _missing_identity_case(reader: str) -> Case:
    def run(tmp):
        store = _Store(tmp, reader)
        (store.root / "_ensemble.json").unlink()
        try:
            if reader == "sweep --json rerun":
                got = cli_outcome(_sweep(store.out)[0], json_mode=True)
            else:
                store.read_back()                   # a ValueError: refused
                got = Observed("ok")
        finally:
            if len(_chunks(store.root)) != 2:
                raise Wrong("the refusal removed chunk files")
        if got.outcome == "ok":
            raise Wrong("a store without its identity file was read")
        return got
    return Case(KIND, f"{reader}: the identity file removed", run, "refused",
                names="_ensemble.json", timeout=180)


def _another_ensemble_api(tmp):
    _run_ensemble(tmp / "s")
    _run_ensemble(tmp / "s", t_end=1.0)              # ValueError: refused
    raise Wrong("a second ensemble was written into the store of another")


def _another_problem_cli(tmp):
    first, _ = _sweep(tmp / "out")
    run, _ = _sweep(tmp / "out", preset="W3")
    got = cli_outcome(run, json_mode=True)
    if got.outcome == "refused" and len(_chunks(tmp / "out" / "chunks")) != 2:
        raise Wrong("the refusal touched the first sweep's chunks")
    return got


def _edited_identity_api(tmp):
    _run_ensemble(tmp / "s")
    path = tmp / "s" / "_ensemble.json"
    held = json.loads(path.read_text())
    path.write_text(json.dumps({**held, "problem": held["problem"] + " (edited)"}))
    _run_ensemble(tmp / "s")                          # ValueError: another ensemble
    raise Wrong("an identity file edited to another problem was taken as this ensemble's")


def _listed_by_hand(reader: str) -> Case:
    """A copy listed in the identity file with its right hash is still no chunk: read_store
    names it and leaves it out, a run unlists it and reports it as a stray."""
    def run(tmp):
        import hashlib
        store = _Store(tmp, reader)
        copy = store.root / "c_copy.parquet"
        shutil.copyfile(_chunks(store.root)[0], copy)
        path = store.root / "_ensemble.json"
        held = json.loads(path.read_text())
        held["chunks"][copy.name] = hashlib.sha256(copy.read_bytes()).hexdigest()
        path.write_text(json.dumps(held))
        table, seen, _ = store.read_back()
        if not any(copy.name in w for w in seen):
            raise Wrong(f"the copy listed by hand was not reported: {seen}")
        _same(table, store.table, "with a copy listed by hand")
        return Observed("warned", next(w for w in seen if copy.name in w)[:200])
    return Case(KIND, f"{reader}: a copy listed by hand in the identity file", run, "warned",
                timeout=180)


def _store_in_sys_api(tmp):
    _run_ensemble(Path("/sys") / f"rsfbench-probe-{os.getpid()}")
    raise Wrong("a store in /sys was accepted")


def _identity_is_a_directory(tmp):
    table, _ = _run_ensemble(tmp / "s")
    (tmp / "s" / "_ensemble.json").unlink()
    (tmp / "s" / "_ensemble.json").mkdir()
    again, seen = _run_ensemble(tmp / "s")
    if not any("BadChunkWarning" in w and "_ensemble.json" in w for w in seen):
        raise Wrong(f"an identity file that cannot be read was not reported: {seen}")
    _same(again, table, "after starting over")
    if again.attrs["n_run"] != 4:
        raise Wrong(f"unverifiable chunks were trusted: {again.attrs}")
    return Observed("recovered", next(w for w in seen if "_ensemble.json" in w)[:200])


def _store_is_a_file_api(tmp):
    (tmp / "s").write_text("x")
    _run_ensemble(tmp / "s" / "deeper")
    raise Wrong("a store below a file was accepted")


def _chunks_is_a_file_cli(tmp):
    (tmp / "out").mkdir()
    (tmp / "out" / "chunks").write_text("x")
    run, _ = _sweep(tmp / "out")
    return cli_outcome(run, json_mode=True)


def _raw_read(tmp):
    """The issue's case: a stray copy beside the chunks made pandas.read_parquet(DIR) return
    more rows than points. It must fail now, naming the file that says how to read a store."""
    import pandas as pd
    table, _ = _run_ensemble(tmp / "s")
    c = _chunks(tmp / "s")[0]
    shutil.copyfile(c, tmp / "s" / f"{c.name}.orig")
    try:
        raw = pd.read_parquet(tmp / "s")
    except Exception as exc:
        if "README.txt" not in str(exc):
            raise Wrong(f"a raw read failed without naming README.txt: {exc}") from None
        read, _ = _read(tmp / "s")
        _same(read, table, "read_store beside the stray")
        return Observed("refused", "pandas.read_parquet(DIR) fails on README.txt; read_store "
                        "reads the 4 listed rows")
    raise Wrong(f"pandas.read_parquet(DIR) returned {len(raw)} rows of a 4-point store")


def _read_store_no_store(what, names):
    def run(tmp):
        from benchmarks.ensemble import read_store
        root = tmp / "s"
        if what == "a file":
            root.write_text("x")
        elif what == "an empty directory":
            root.mkdir()
        elif what == "a directory of Parquet files":
            root.mkdir()
            _run_ensemble(tmp / "t")
            shutil.copyfile(_chunks(tmp / "t")[0], root / "part-0.parquet")
        read_store(root)
        raise Wrong(f"read_store read {what}")
    return Case(KIND, f"read_store: {what} is no store", run, "refused", names=names)


# --- the Dask cluster lost mid-sweep (slow) -------------------------------------------------------

def _dask_sweep(out, address, *extra):
    # 32 points of W4, 10 s each, ETD2 point by point: one point a chunk (auto_chunk_size), a
    # few seconds of work, long enough to lose the cluster half-way
    return [sys.executable, "-m", "benchmarks.cli", "sweep", "--preset", "W4", "--law", "slip",
            "--b", "0.0095:0.0110:0.0001", "--lc", "1e-7:3e-7:2log", "--t-end", "10",
            "--integrator", "ETD2", "--scheduler", address, "--connect-timeout", "30",
            "--worker-timeout", "5", "--out", str(out), "--no-progress", "--no-plot", *extra]


def _main_stack(err: str) -> str:
    """The main thread's stack from a faulthandler dump in ``err``: its four innermost calls and
    every call in the project's own code."""
    frames = [x.strip() for x in err.rsplit("Current thread", 1)[-1].splitlines()[1:]]
    ours = [x for x in frames[4:] if "/benchmarks/" in x]
    return " | ".join(frames[:4] + ours) or repr(err[-400:])


def _lost(what: str, json_mode: bool):
    def run(tmp):
        out = tmp / "s"
        address, scheduler, worker = dask_cluster()
        try:
            # PYTHONFAULTHANDLER: a hung sweep is stopped with SIGABRT, which then prints where
            # each of its threads was (the message below carries the main thread's stack)
            proc = subprocess.Popen(_dask_sweep(out, address, *(["--json"] if json_mode else [])),
                                    cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True, env={**os.environ, "PYTHONFAULTHANDLER": "1"})
            deadline = time.time() + 180
            while time.time() < deadline and not _chunks(out / "chunks") \
                    and proc.poll() is None:
                time.sleep(0.05)
            stop_processes(scheduler if what == "scheduler" else worker)
            try:
                stdout, err = proc.communicate(timeout=120)
            except subprocess.TimeoutExpired:
                proc.send_signal(signal.SIGABRT)
                try:
                    _, err = proc.communicate(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    _, err = proc.communicate()
                raise Wrong(f"the sweep hung for 120 s after losing its {what}: "
                            f"{_main_stack(err)}") from None
        finally:
            stop_processes(scheduler, worker)
        if "Traceback" in err or proc.returncode != 1:
            raise Wrong(f"exit status {proc.returncode}: {err[-300:]!r}")
        lines = [x for x in err.splitlines() if x.startswith("rsfbench: error")]
        if len(lines) != 1 or "kept in" not in lines[0]:
            raise Wrong(f"not one line saying what is kept: {err[-400:]!r}")
        if json_mode and "error" not in one_json(stdout):
            raise Wrong(f"--json printed no error document: {stdout[:200]!r}")
        kept = int(lines[0].rsplit("; ", 1)[1].split(" of ")[0])
        if kept < 1 or len(_chunks(out / "chunks")) != kept:
            raise Wrong(f"{kept} points said kept, {len(_chunks(out / 'chunks'))} chunks stored")
        address, scheduler, worker = dask_cluster()      # a new cluster: the rerun resumes
        try:
            again = subprocess.run(_dask_sweep(out, address, "--json"), cwd=ROOT,
                                   capture_output=True, text=True, timeout=300)
        finally:
            stop_processes(scheduler, worker)
        summary = one_json(again.stdout)
        if again.returncode != 0 or summary.get("n_resumed", 0) < kept:
            raise Wrong(f"the rerun did not resume the {kept} kept points: {again.stderr[-300:]}")
        return Observed("retcode", lines[0][:200])
    name = "the Dask scheduler" if what == "scheduler" else "every Dask worker"
    return Case(KIND, f"sweep{' --json' if json_mode else ''}: {name} lost mid-sweep", run,
                "retcode", slow=True, timeout=600)


def cases() -> list[Case]:
    out = []
    for kind, make in _stray_makers().items():
        out += [_stray_case(kind, make, reader) for reader in _READERS]
    for kind, damage in _DAMAGE.items():
        out += [_damage_case(kind, damage, reader) for reader in _READERS]
    for kind, text in _IDENTITY_DAMAGE.items():
        out += [_identity_case(kind, text, reader) for reader in _READERS]
    out += [_missing_identity_case(reader) for reader in _READERS]
    out += [_listed_by_hand(reader) for reader in _READERS]
    out += [Case(KIND, "ensemble: another ensemble in the store's directory",
                 _another_ensemble_api, "refused", names="holds another ensemble"),
            Case(KIND, "sweep --json: another problem in the same --out", _another_problem_cli,
                 "refused", names="holds another ensemble", timeout=180),
            Case(KIND, "ensemble: an identity file edited to another problem",
                 _edited_identity_api, "refused", names="differing: problem"),
            Case(KIND, "ensemble: a store below a file", _store_is_a_file_api, "refused",
                 names="cannot be written"),
            Case(KIND, "ensemble: a store where nothing can be written (/sys)",
                 _store_in_sys_api, "refused", names="cannot be written"),
            Case(KIND, "ensemble rerun: the identity file a directory (cannot be read)",
                 _identity_is_a_directory, "recovered"),
            Case(KIND, "sweep --json: OUT/chunks is a file", _chunks_is_a_file_cli, "refused",
                 names="not a directory"),
            Case(KIND, "pandas.read_parquet(DIR) beside a stray copy", _raw_read, "refused")]
    out += [_read_store_no_store("a file", "not a directory"),
            _read_store_no_store("an empty directory", "no identity file"),
            _read_store_no_store("a directory of Parquet files", "no identity file")]
    out += [_lost("scheduler", False), _lost("scheduler", True), _lost("workers", True)]
    return out
