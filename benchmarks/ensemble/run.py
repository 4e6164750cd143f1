"""``ensemble``: one problem, one algorithm, many points; one table.

The points are cut into chunks (``chunk_size`` points, default :data:`CHUNK_SIZE`), the unit of
work, of storage and of scheduling:

* the own compiled methods (:func:`benchmarks.ensemble.rows.compiled`) on one machine: each
  chunk is one numba call whose ``prange`` spreads its points over ``workers`` threads (the
  default; the GIL is released for the whole chunk);
* any other backend, or ``backend="processes"``: chunks go to a pool of processes (or threads),
  each chunk solved point by point (:func:`integrators.solve`) or, for an own method, as one
  single-threaded batch;
* ``scheduler=ADDRESS``: chunks are Dask tasks on that cluster (a task per chunk, never per
  point), with the guarantees of :mod:`benchmarks.ensemble.executors`.

With ``store=DIR`` every finished chunk is written at once (:mod:`benchmarks.ensemble.store`),
and a rerun with the same arguments reads the finished chunks back instead of running them
(:func:`benchmarks.ensemble.read_store` reads a store back; a raw Parquet read of DIR does not).
A cluster lost mid-run (its scheduler, or every worker) ends the run with a
:class:`~benchmarks.ensemble.executors.RunStopped` whose one line says how many points are kept.
Every argument and every point's problem is checked before the first solve.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field

import numba
import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from benchmarks.ensemble.executors import (
    CONNECT_TIMEOUT_S,
    WORKER_TIMEOUT_S,
    RunStopped,
    connect,
    execute,
    quiet_distributed,
)
from benchmarks.ensemble.points import MAX_POINTS, check_points, point_problems
from benchmarks.ensemble.rows import batch_rows, compiled, failed_rows, point_rows
from benchmarks.ensemble.store import ChunkStore, identity_of
from integrators import Algorithm, Output
from integrators.core.solve import check_settle, settle_refusal, short_piece
from problems._validate import check_count, check_positive, units_checked_already

__all__ = ["ensemble", "Chunk", "run_chunk", "batched", "auto_chunk_size", "CHUNK_SIZE",
           "BACKENDS"]

#: points per chunk: a few hundred keeps a Dask task (~1 ms to schedule) and a Parquet file
#: (~10 ms to write) small beside the chunk's solves, and Ctrl-C is seen between chunks
CHUNK_SIZE = 256
BACKENDS = ("threads", "processes")


@dataclass(frozen=True, eq=False)
class Chunk:
    """Consecutive points ``first``… of an ensemble, and how to solve them; ``threads``: numba
    threads for an own method's batch (None: numba's setting).

    Parameters
    ----------
    problem : SpringSlider
        The ensemble's base problem.
    algorithm : Algorithm
        The method and its options.
    names : tuple of str
        The parameters that vary (fields of :func:`~problems.variant`).
    values : numpy.ndarray
        The chunk's points, one row each, one column per name (SI units).
    first : int
        The index of the chunk's first point in the ensemble.
    wall_budget : float, optional
        Each point's wall-time budget (s).
    threads : int, optional
        numba threads for an own method's batch.
    curve_dt : float, optional
        With it, each point's slip-weakening curve too (s; :func:`ensemble`).
    curve_chain : benchmarks.physics.chain.Chain, optional
        The measurement chain the curves are passed through (:func:`ensemble`).
    problems : tuple of SpringSlider, optional
        The points' problems, built and checked already in this process.
    sensitivity : tuple of str
        Parameters to differentiate each limit cycle's metrics by (:func:`ensemble`).
    sensitivity_error : bool
        The sensitivities in the step control.
    settle : float
        Stop each point on its settled cycle (:func:`integrators.solve`'s ``settle``; 0: run
        to t_end).
    """

    problem: object
    algorithm: Algorithm
    names: tuple
    values: np.ndarray = field(repr=False)
    first: int
    wall_budget: float | None = None
    threads: int | None = None
    curve_dt: float | None = None
    curve_chain: object = None
    #: the points' problems, when they were built and checked already in this process (a
    #: chunk sent to another process carries its values only)
    problems: tuple | None = field(default=None, repr=False)
    sensitivity: tuple = ()
    sensitivity_error: bool = True
    settle: float = 0.0


def batched(algorithm) -> bool:
    """Does an ensemble of ``algorithm`` run compiled batches? The own methods on the compiled
    engine do, slip-weakening curves or not (a batch makes them from a second solve of each
    point: :func:`benchmarks.ensemble.rows.batch_rows`)."""
    return compiled(algorithm)


def auto_chunk_size(n: int, algorithm) -> int:
    """The default chunk size: :data:`CHUNK_SIZE` for compiled batches; for point-by-point
    solves (seconds each, for some backends) about 64 chunks, at most :data:`CHUNK_SIZE` points
    each, so that a stopped run keeps most of its work. It depends on the points only, never on
    the workers: a rerun on other workers finds the same chunks."""
    if batched(algorithm):
        return CHUNK_SIZE
    return int(min(CHUNK_SIZE, max(1, -(-n // 64))))


def run_chunk(chunk: Chunk) -> pd.DataFrame:
    """The rows of a chunk (never raises for a failing point: it is a row).

    Parameters
    ----------
    chunk : Chunk
        The points and how to solve them.

    Returns
    -------
    pandas.DataFrame
        One row per point: its parameters, then :data:`RESULT_COLUMNS`.
    """
    problems = (list(chunk.problems) if chunk.problems is not None
                else point_problems(chunk.problem, chunk.names, chunk.values, chunk.first))
    if not batched(chunk.algorithm):
        return point_rows(problems, chunk.algorithm, chunk.names, chunk.values,
                          chunk.wall_budget, chunk.curve_dt, chunk.curve_chain,
                          chunk.settle or None)
    how = dict(curves=bool(chunk.curve_dt), chain=chunk.curve_chain,
               sensitivity=chunk.sensitivity, sensitivity_error=chunk.sensitivity_error,
               settle=chunk.settle)
    if chunk.threads == 1:               # a pool's process, a Dask worker: no OpenMP at all
        return batch_rows(problems, chunk.algorithm, chunk.names, chunk.values,
                          chunk.wall_budget, parallel=False, **how)
    with _numba_threads(chunk.threads):
        return batch_rows(problems, chunk.algorithm, chunk.names, chunk.values,
                          chunk.wall_budget, **how)


@contextlib.contextmanager
def _numba_threads(n: int | None):
    if n is None:
        yield
        return
    before = numba.get_num_threads()
    numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
    try:
        yield
    finally:
        numba.set_num_threads(before)


def warm_chunk(chunk: Chunk) -> None:
    """Compile (or load from numba's cache) what the chunk needs: its first point, briefly."""
    try:
        with units_checked_already():
            first = short_piece(point_problems(chunk.problem, chunk.names, chunk.values[:1])[0])
        run_chunk(Chunk(first, chunk.algorithm, (), np.empty((1, 0)), 0, threads=chunk.threads,
                        curve_dt=chunk.curve_dt, curve_chain=chunk.curve_chain,
                        sensitivity=chunk.sensitivity,
                        sensitivity_error=chunk.sensitivity_error, settle=chunk.settle))
    except Exception:            # a failing point is reported by run_chunk, not here
        pass


def failed_chunk(chunk: Chunk, message: str) -> pd.DataFrame:
    """The rows of a chunk whose Dask workers all died running it: failed, and ``transient``
    (never stored, so that a rerun tries the chunk again)."""
    problems = point_problems(chunk.problem, chunk.names, chunk.values, chunk.first)
    table = failed_rows(problems, chunk.algorithm, chunk.names, chunk.values, message,
                        chunk.curve_dt, chunk.sensitivity)
    table.attrs["transient"] = True
    return table


def ensemble(problem, algorithm, params, *, store=None, chunk_size: int | None = None,
             workers: int | None = None, backend: str | None = None,
             scheduler: str | None = None, wall_budget: float | None = None,
             curve_dt: float | None = None, curve_chain=None, progress: bool = True,
             max_points: int = MAX_POINTS, connect_timeout: float = CONNECT_TIMEOUT_S,
             worker_timeout: float = WORKER_TIMEOUT_S, label: str = "",
             reclaim_store: bool = False, sensitivity=None,
             sensitivity_error: bool = True, settle: float | None = None) -> pd.DataFrame:
    """Solve ``problem`` with ``algorithm`` at every point of ``params`` and summarise each.

    Parameters
    ----------
    problem : SpringSlider
        The problem every point varies.
    algorithm : Algorithm
        Any registered method; the own compiled ones run in compiled batches.
    params : dict of str to sequence of float
        Field name → values, one per point (SI units; :func:`~benchmarks.ensemble.grid`).
    store : str or pathlib.Path, optional
        A directory of Parquet chunks: a run resumes from the verified chunks it holds.
    chunk_size : int, optional
        Points per chunk (default :func:`auto_chunk_size`).
    workers : int, optional
        Threads or processes on this machine (default: all cores).
    backend : str, optional
        ``"threads"`` or ``"processes"`` (default: threads for compiled batches, processes for
        the others, whose Python holds the GIL).
    scheduler : str, optional
        A Dask scheduler's address: the cluster decides the parallelism (not ``workers``).
    wall_budget : float, optional
        Seconds per point.
    curve_dt : float, optional
        Also each point's slip-weakening curve (s): the own compiled methods from their dense
        output (:data:`~benchmarks.ensemble.rows.CURVE_POINTS` times over the last event, a
        second solve), the others from a trajectory saved every ``curve_dt``.
    curve_chain : benchmarks.physics.chain.Chain, optional
        With ``curve_dt``: each curve through this measurement chain (observe's filters,
        sampling and timing: :func:`benchmarks.ensemble.rows.chained_curve`).
    progress : bool
        Show a progress bar.
    max_points : int
        The most points accepted (default :data:`MAX_POINTS`).
    connect_timeout, worker_timeout : float
        Seconds to reach the scheduler, and to wait for a lost worker's result.
    label : str
        The progress bar's label.
    reclaim_store : bool
        A store of another ensemble is cleared, not refused (for the harness's own caches).
    sensitivity : str or sequence of str, optional
        Parameters (as :func:`integrators.solve`'s) to differentiate each limit cycle's four
        metrics by, in the compiled batch (Rodas5P, RadauIIA5; not with ``curve_dt``): the
        columns ``d_<metric>/d_<parameter>`` (SI), NaN without a cycle.
    sensitivity_error : bool
        The sensitivities in the step control (default True).
    settle : float, optional
        :func:`integrators.solve`'s, for every point (its ``message`` says where it stopped).

    Returns
    -------
    pandas.DataFrame
        One row per point in the order given: the parameters, then :data:`benchmarks.ensemble.
        rows.RESULT_COLUMNS` (class, retcode, message, metrics, κ, counters, wall time; a
        failed point: its retcode); ``attrs``: points run and resumed, the call's wall, bad chunks.

    Raises
    ------
    ValueError
        For misuse, before any work (the module docstring for the rest).
    """
    start = time.perf_counter()              # the points' checks count in the wall time
    plan = _plan(problem, algorithm, params, store, chunk_size, workers, backend, scheduler,
                 wall_budget, curve_dt, max_points, reclaim_store, curve_chain,
                 (sensitivity, sensitivity_error), settle)
    bar = dict(unit="point", disable=not progress,
               desc=label or f"ensemble {problem.name or 'problem'}")
    tables, n_resumed = _solve_chunks(plan, store, scheduler, connect_timeout, worker_timeout,
                                      bar)
    table = pd.concat([tables[c.first] for c in plan["chunks"]], ignore_index=True)
    table.attrs = _attrs(plan, n_resumed, time.perf_counter() - start, scheduler)
    return table


def _attrs(plan, n_resumed: int, wall_s: float, scheduler) -> dict:
    """The ``attrs`` of an ensemble's table: how many points ran and were resumed, the wall
    time, how the work was cut and where it ran, the store's bad and stray files."""
    chunk_store, n = plan["store"], len(plan["values"])
    return {"n_points": n, "n_run": n - n_resumed, "n_resumed": n_resumed, "wall_s": wall_s,
            "chunks": len(plan["chunks"]), "chunk_size": plan["chunk_size"],
            "workers": 1 if scheduler else plan["workers"], "backend": plan["backend"],
            "scheduler": scheduler, "batched": plan["batch"],
            "bad_chunks": list(chunk_store.bad) if chunk_store else [],
            "stray_files": list(chunk_store.strays) if chunk_store else []}


def _solve_chunks(plan, store, scheduler, connect_timeout, worker_timeout, bar) -> tuple:
    """The table of every chunk of ``plan`` (:func:`_plan`), those in its store read back and
    the others solved, with ``bar`` (tqdm's options); and how many points were resumed."""
    names, values, chunks, chunk_store = (plan["names"], plan["values"], plan["chunks"],
                                          plan["store"])
    with contextlib.ExitStack() as stack:
        client = None
        if scheduler:                          # before any work; its logs quiet until closed
            stack.enter_context(quiet_distributed())
            client = connect(scheduler, connect_timeout)
            stack.callback(_close, client)
        if chunk_store is not None:
            stack.enter_context(chunk_store)
        tables = {c.first: chunk_store.load(c.first, names, c.values) if chunk_store else None
                  for c in chunks}
        if chunk_store is not None:
            chunk_store.report_strays()
        todo = [c for c in chunks if tables[c.first] is None]
        n_resumed = n_kept = len(values) - sum(len(c.values) for c in todo)
        _run_chunks(todo, tables, chunk_store, tqdm(total=len(values), initial=n_resumed, **bar),
                    n_kept, len(values), store,
                    (plan["own_threads"], plan["workers"], plan["backend"], client,
                     worker_timeout))
    return tables, n_resumed


def _plan(problem, algorithm, params, store, chunk_size, workers, backend, scheduler,
          wall_budget, curve_dt, max_points, reclaim_store, curve_chain=None,
          sensitive=(None, True), settle=None) -> dict:
    """:func:`ensemble`'s arguments checked (ValueError before any work) and its points cut
    into chunks, with the store they are kept in (``sensitive``: the sensitivity's names and
    error control)."""
    if not isinstance(algorithm, Algorithm):
        raise ValueError(f"algorithm must be an Algorithm instance, got {algorithm!r}")
    settle = check_settle(algorithm, settle, bool(sensitive[0]))
    for name, value in (("wall_budget", wall_budget), ("curve_dt", curve_dt)):
        if value is not None:
            check_positive(name, value)
    batch = batched(algorithm)
    backend = backend or ("threads" if batch else "processes")
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    workers = os.cpu_count() or 1 if workers is None else check_count("workers", workers)
    names, values = check_points(problem, params, max_points)
    chunk_size = (auto_chunk_size(len(values), algorithm) if chunk_size is None
                  else check_count("chunk_size", chunk_size))
    problems = point_problems(problem, names, values)     # every point valid, or say which
    _check_settle_points(problems, settle, names, values)
    sensitive = _sensitivity(problem, problems, algorithm, curve_dt, *sensitive,
                             (names, values))
    if curve_dt and not batch:                            # the saved trajectory fits memory
        Output(save_every=curve_dt).interval(max(p.t_end for p in problems))
    own_threads = batch and backend == "threads" and scheduler is None
    chunks = _chunks(problem, algorithm, names, values, problems, chunk_size, wall_budget,
                     curve_dt, workers if own_threads else None, curve_chain, sensitive,
                     settle)
    chunk_store = (ChunkStore(store, identity_of(problem, algorithm, names, values, chunk_size,
                                                 wall_budget, curve_dt, curve_chain,
                                                 *sensitive, settle=settle),
                               reclaim_store)
                   if store is not None else None)
    return dict(names=names, values=values, chunks=chunks, store=chunk_store, batch=batch,
                backend=backend, workers=workers, chunk_size=chunk_size,
                own_threads=own_threads)


def _check_settle_points(problems, settle: float, names, values) -> None:
    """ValueError naming the first point whose loading forbids ``settle``
    (:func:`integrators.core.solve.settle_refusal`)."""
    for i, problem in enumerate(problems if settle else ()):
        why = settle_refusal(problem)
        if why:
            at = ", ".join(f"{n} = {v:g}" for n, v in zip(names, values[i]))
            raise ValueError(f"point {i} ({at}): {why}")


def _chunks(problem, algorithm, names, values, problems, chunk_size, wall_budget, curve_dt,
            threads: int | None, curve_chain=None, sensitive=((), True),
            settle: float = 0.0) -> list[Chunk]:
    """The points cut into chunks of ``chunk_size``; with ``threads`` (a compiled batch on
    this machine) each chunk carries its points' problems and runs on that many threads."""
    return [Chunk(problem, algorithm, names, values[i:i + chunk_size], i, wall_budget,
                  threads=threads or 1, curve_dt=curve_dt, curve_chain=curve_chain,
                  problems=tuple(problems[i:i + chunk_size]) if threads else None,
                  sensitivity=sensitive[0], sensitivity_error=sensitive[1], settle=settle)
            for i in range(0, len(values), chunk_size)]


def _sensitivity(base, problems, algorithm, curve_dt, names, control,
                 points=((), ())) -> tuple:
    """``(names, control)`` of an ensemble's sensitivities checked: the names resolved
    (:func:`problems.directions.sensitivity_names`), () for none; ValueError for a method
    without them, with curves, or for a name a point's problem lacks (a point without an
    overshoot has no vlf: named by its index and ``points``' values), before any work; the
    warning of :func:`integrators.solve` for a loose tolerance."""
    from problems.directions import sensitive_request, sensitivity_names, warn_loose
    control = sensitive_request(algorithm, names, control)
    if names is None:
        return (), control
    if curve_dt:
        raise ValueError("sensitivity: an ensemble with curves (curve_dt) has no "
                         "sensitivities; ask for one or the other")
    try:                                 # the request itself, judged on the base problem
        resolved, base_error = sensitivity_names(base, names), None
    except ValueError as exc:            # (a name the base lacks may be a point's)
        resolved, base_error = None, str(exc)
    for i, problem in enumerate(problems):
        try:
            resolved = sensitivity_names(problem, resolved or names)
        except ValueError as exc:
            if str(exc) == base_error:   # the request's fault, not the point's
                raise ValueError(base_error) from None
            at = ", ".join(f"{n} = {v:g}" for n, v in zip(points[0], points[1][i]))
            raise ValueError(f"point {i} ({at}): {exc}") from None
    warn_loose(algorithm, 3)
    return resolved, control


def _run_chunks(todo, tables: dict, chunk_store, bar, n_kept: int, n_points: int, store,
                solving: tuple) -> None:
    """Solve the chunks ``todo`` (``solving``: :func:`_solve`'s other arguments) into
    ``tables`` by first point, storing each finished one; a lost cluster's
    :class:`RunStopped` is raised again saying which points are kept."""
    try:
        with bar:
            for chunk, table in _solve(todo, *solving):
                if chunk_store is not None and not table.attrs.get("transient"):
                    chunk_store.save(chunk.first, chunk.values, table)
                    n_kept += len(chunk.values)
                tables[chunk.first] = table
                bar.update(len(chunk.values))
    except RunStopped as exc:             # the cluster is gone: say what is kept
        kept = (f"{n_kept} of {n_points} points are done and kept in {store}: run the "
                "same ensemble again to resume it" if chunk_store is not None else
                f"the {n_points} points are lost (an ensemble resumes only with a store)")
        raise type(exc)(f"{exc}; {kept}") from None


def _close(client) -> None:
    """Close a Dask client; one whose scheduler is gone may fail to say goodbye, which changes
    nothing for the run (its outcome is decided already)."""
    try:
        client.close()
    except Exception:
        pass


def _solve(todo, own_threads, workers, backend, client, worker_timeout):
    """Yield ``(chunk, rows)`` as chunks finish."""
    if not todo:
        return
    if own_threads:                          # this process, numba's threads inside each chunk
        warm_chunk(todo[0])
        for chunk in todo:
            yield chunk, run_chunk(chunk)
        return
    yield from execute(run_chunk, warm_chunk, failed_chunk, todo, workers, backend, client,
                       worker_timeout)
