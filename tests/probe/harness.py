"""The reliability probe: the harness used as a new user and a hostile one would use it.

A :class:`Case` does one thing — builds a problem with a bad parameter, runs a command line,
corrupts a results file, stops a run by its budget, kills a sweep — and says what it observed:

* ``refused``: a clear error before any work (one line; for the command line exit status 2,
  and with ``--json`` exactly one JSON document on the standard output);
* ``retcode``: the run failed or stopped, and said so (a failure retcode, exit status 1, a
  classification that is not physics, with its reason);
* ``warned``: it ran, and a warning named the doubtful value;
* ``recovered``: a bad results file was reported by name and recomputed;
* ``ok``: it worked, and the answer checked out.

What must never be observed: ``traceback`` (an exception other than the library's clear errors,
or a command line that printed one), ``hang`` (no answer within the case's time limit) and
``wrong`` (an answer that the case's own check found silently wrong: physics from a failed run,
a bad file trusted, a budget overrun, output that is not one JSON document).

The catalogue is :mod:`probe.cases` and :mod:`probe.families`; ``test_reliability.py`` runs
every case, and with ``--probe-report DIR`` writes the table of kinds and outcomes
(:func:`write_probe`; ``rsfbench study probe`` writes ``results/reliability.md``).

The probe runs the command line as a user does: the installed program ``rsfbench``, in this
process by its entry point (:func:`cli`) or as a subprocess; it imports no part of it.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.metadata
import json
import os
import signal
import tempfile
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pandas as pd

__all__ = ["Case", "Observed", "CliRun", "run_case", "cli", "write_probe", "OUTCOMES",
           "dask_cluster", "stop_processes",
           "BAD_OUTCOMES", "Wrong"]

OUTCOMES = ("refused", "retcode", "warned", "recovered", "ok")
BAD_OUTCOMES = ("traceback", "hang", "wrong")


class Wrong(AssertionError):
    """Raised by a case's check: the answer is silently wrong (the message says how)."""


@dataclass(frozen=True)
class Observed:
    outcome: str
    detail: str = ""


@dataclass(frozen=True)
class Case:
    """One probe: ``run(tmp)`` in a fresh temporary directory returns what it observed (an
    :class:`Observed`, or an outcome name); ``expect`` is the outcome it must have."""

    kind: str
    name: str
    run: Callable[[Path], "Observed | str"] = field(compare=False, repr=False)
    expect: str = "refused"
    slow: bool = False
    timeout: float = 120.0
    names: str = ""            # what a refusal must name (the parameter, flag or value)

    @property
    def id(self) -> str:
        return f"{self.kind}/{self.name}"


class _Timeout(BaseException):
    """Raised in the case by the alarm (a BaseException: no ``except Exception`` swallows it)."""


@contextlib.contextmanager
def _time_limit(seconds: float):
    def alarm(signum, frame):
        raise _Timeout()
    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def run_case(case: Case) -> Observed:
    """Run ``case`` under its time limit and name what happened. A refusal that does not name
    what the case says it must (``Case.names``) is not clear: ``wrong``."""
    got = _run(case)
    if got.outcome == "refused" and case.names and case.names not in got.detail:
        return Observed("wrong", f"the refusal does not name {case.names!r}: {got.detail}")
    return got


def _run(case: Case) -> Observed:
    with tempfile.TemporaryDirectory(prefix="rsfbench-probe-") as tmp:
        try:
            with _time_limit(case.timeout):
                got = case.run(Path(tmp))
        except _Timeout:
            return Observed("hang", f"no answer within {case.timeout:g} s")
        except Wrong as exc:
            return Observed("wrong", str(exc))
        except ValueError as exc:               # the library's clear error
            text = str(exc)
            if not text or "\n" in text:
                return Observed("traceback", f"unclear error: {text!r}")
            return Observed("refused", text)
        except Exception as exc:
            return Observed("traceback", "".join(traceback.format_exception_only(exc)).strip())
    return got if isinstance(got, Observed) else Observed(got)


# --- the command line, run in this process -------------------------------------------------

@dataclass(frozen=True)
class CliRun:
    status: int
    out: str
    err: str


@functools.cache
def program():
    """The ``rsfbench`` program's entry point, loaded as its installed script loads it."""
    found = importlib.metadata.entry_points(group="console_scripts", name="rsfbench")
    if not found:
        raise RuntimeError("the rsfbench program is not installed (pip install -e .)")
    return next(iter(found)).load()


def cli(*args: str) -> CliRun:
    """``rsfbench ARGS`` in this process, its standard output and error captured at the file
    descriptors (so what a library writes there is seen too)."""
    import sys
    main = program()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = os.dup(1), os.dup(2)
        old = sys.stdout, sys.stderr
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        sys.stdout = os.fdopen(os.dup(1), "w", buffering=1)
        sys.stderr = os.fdopen(os.dup(2), "w", buffering=1)
        try:
            status = main([str(a) for a in args])
        finally:
            sys.stdout.close()
            sys.stderr.close()
            sys.stdout, sys.stderr = old
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
        out.seek(0)
        err.seek(0)
        return CliRun(status, out.read(), err.read())


def one_json(text: str) -> dict | list:
    """The one JSON document ``text`` must be (whitespace around it allowed), or :class:`Wrong`."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise Wrong(f"standard output is not exactly one JSON document ({exc}): "
                    f"{text[:200]!r}") from None


def cli_outcome(run: CliRun, json_mode: bool = False) -> Observed:
    """Name a command line's outcome: exit status 2 with one line is ``refused``, 1 ``retcode``,
    0 ``ok``; anything with a traceback, or (``--json``) an output that is not one JSON
    document, is not."""
    if "Traceback (most recent call last)" in run.err or run.status == 3:
        return Observed("traceback", run.err.strip()[-300:])
    if json_mode:
        doc = one_json(run.out)
        if run.status == 2 and not (isinstance(doc, dict) and "error" in doc):
            raise Wrong(f"--json error without an 'error' document: {run.out[:200]!r}")
    lines = [x for x in run.err.splitlines() if x.strip() and "warning:" not in x
             and not x.lstrip().startswith(("THE PROBLEM", "sweep", "windows", "probe"))]
    if run.status == 2:
        errors = [x for x in lines if "error" in x or x.startswith("rsfbench")]
        if len(errors) != 1:
            raise Wrong(f"a refusal must be one line, got {len(errors)}: {run.err[-300:]!r}")
        return Observed("refused", errors[0])
    if run.status == 1:
        return Observed("retcode", (run.out.strip().splitlines() or [""])[-1][:200])
    if run.status == 0:
        return Observed("ok")
    return Observed("traceback", f"exit status {run.status}: {run.err[-300:]}")


# --- the report ------------------------------------------------------------------------------

KIND_TITLES = {
    "api-input": "bad values and types through the Python API",
    "cli-input": "bad values on the command line",
    "paths": "paths and files a command cannot use",
    "budgets": "wall-time and step budgets, kills, lost workers",
    "physics": "runs that must not be read as physics",
    "idioms": "one problem however it is built",
    "corrupt-results": "results files that must not be trusted",
    "machine-output": "--json: exactly one JSON document on stdout",
    "misfit": "J2 sees the friction it fits",
    "problem-files": "a user's own apparatus through every command",
    "lab": "laboratory-test measures from the dense output",
    "units": "dimensional inputs in an implausible unit",
    "classification": "classifying runs at and near the edges of stability",
    "integrators": "the own integrators where their peers succeed",
    "load-histories": "load histories, no mass, damping, Nagata: every backend",
    "store": "the store reads back only what it wrote",
    "inversion": "inversions, their intervals and their commands",
    "observe": "a laboratory recording in, and the observations file out",
}


def write_probe(table: pd.DataFrame, out: Path) -> str:
    """``reliability.csv`` (every case) and ``reliability.md`` (kinds × outcomes) in ``out``;
    returns the Markdown."""
    from benchmarks.records.report import markdown_table
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "reliability.csv", index=False)
    columns = list(OUTCOMES) + list(BAD_OUTCOMES)
    counts = (table.groupby(["kind", "observed"]).size().unstack(fill_value=0)
              .reindex(columns=columns, fill_value=0))
    counts = counts.reindex([k for k in KIND_TITLES if k in counts.index])
    md = counts.reset_index()
    md.insert(1, "what", [KIND_TITLES[k] for k in md.kind])
    md["cases"] = counts.sum(axis=1).to_numpy()
    total = {"kind": "all", "what": "", **{c: int(counts[c].sum()) for c in columns},
             "cases": int(counts.to_numpy().sum())}
    md = pd.concat([md, pd.DataFrame([total])], ignore_index=True)
    unexpected = table[~table.as_expected]
    n_bad = int(table.observed.isin(BAD_OUTCOMES).sum())
    text = (f"{len(table)} cases ({int(table.slow.sum())} slow), "
            f"{int(table.as_expected.sum())} as expected; {n_bad} tracebacks, hangs or silently "
            "wrong results.\n\n" + markdown_table(md))
    if len(unexpected):
        text += "\nNot as expected:\n\n" + markdown_table(
            unexpected[["kind", "case", "expected", "observed", "detail"]])
    (out / "reliability.md").write_text(text)
    return text


def dask_cluster():
    """A Dask scheduler and one worker on this machine, each a process in its own process
    group (so that :func:`stop_processes` kills a nanny with its worker): (address, scheduler,
    worker)."""
    import socket
    import subprocess
    import sys
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    address = f"tcp://127.0.0.1:{port}"
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                                  "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                                 **quiet)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                               "--nthreads", "1", "--no-dashboard"], **quiet)
    return address, scheduler, worker


def stop_processes(*procs) -> None:
    """SIGKILL each process's group and reap it."""
    for p in procs:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        p.wait()
