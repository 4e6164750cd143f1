"""Where the points of a sweep run: this process, a local pool of processes or threads, or a Dask
cluster, with the guarantees a long unattended run needs.

* **No orphans.** A pool worker watches its parent (:func:`_watch_parent`) and exits within
  :data:`PARENT_POLL_S` once the parent is gone, even when the parent was killed with SIGKILL and
  could not shut its pool down. Workers ignore SIGINT: a Ctrl-C reaches the parent, which cancels
  the pending points (the finished ones are stored) and stops the pool.
* **No silent wait on a cluster.** The scheduler must answer within ``connect_timeout`` before any
  work; while tasks are pending, a cluster left with no worker for ``worker_timeout`` seconds
  ends the run with :class:`ClusterGone`, and losing the scheduler itself (killed, its machine
  gone: the client's futures come back cancelled, its calls raise ``CommClosedError``) with
  :class:`SchedulerLost`. Both are :class:`RunStopped`: the caller adds what is done and kept,
  and a command says it in one line with exit status 1. A task that merely crashed its workers
  (``KilledWorker``) is the failed row of its task instead: the run goes on. A finished
  task's result lives on the worker that computed it: when that worker is lost before the
  result is fetched, the fetch would wait for ever for a recomputation that needs a worker
  (``Future.result`` has no timeout of its own); it is given :data:`RESULT_TIMEOUT_S`, and the
  task, with the others of its batch not yet fetched, goes back to the pending ones, which the
  rule above then ends or a new worker computes.
* **One line, not a log.** While a run uses the cluster, distributed's own loggers are raised to
  CRITICAL: a lost scheduler makes the client log each reconnection attempt with a traceback,
  which a command's standard error must not carry (the run says what happened itself).
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
from concurrent.futures import CancelledError, as_completed

from benchmarks.records.optional import require

__all__ = ["execute", "connect", "quiet_distributed", "RunStopped", "ClusterGone",
           "SchedulerLost", "PARENT_POLL_S", "CONNECT_TIMEOUT_S",
           "WORKER_TIMEOUT_S", "RESULT_TIMEOUT_S"]

#: s between two looks of a pool worker at its parent
PARENT_POLL_S = 0.5
#: s a Dask scheduler has to answer before the sweep is refused
CONNECT_TIMEOUT_S = 10.0
#: s a Dask cluster may have no worker while points are pending
WORKER_TIMEOUT_S = 60.0
#: s to fetch a finished task's result (a chunk's table: milliseconds) before the task is taken
#: for lost with its worker and waited for again
RESULT_TIMEOUT_S = 10.0


class RunStopped(RuntimeError):
    """A run that stopped for a reason outside its arguments (a cluster lost its workers); a
    command says why in one line and exits with status 1."""


class ClusterGone(RunStopped):
    """The Dask cluster cannot run the pending tasks: it has had no worker for longer than the
    run's ``worker_timeout``, or (:class:`SchedulerLost`) its scheduler is gone."""


class SchedulerLost(ClusterGone):
    """The connection to the Dask scheduler was lost while tasks were pending."""


def _watch_parent() -> None:
    """In a pool worker: exit at once when the process that started it is gone (whatever the
    start method: the parent is read here, in the worker)."""
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)
    threading.Thread(target=watch, name="rsfbench-parent-watch", daemon=True).start()


def _init_worker(warm, task) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)      # the parent's handler is the parent's
    _watch_parent()
    warm(task)


def execute(run, warm, failed, tasks: list, workers: int, backend: str, client=None,
            worker_timeout: float = WORKER_TIMEOUT_S):
    """Yield ``(task, run(task))`` as points finish: on the Dask ``client``'s cluster if given
    (see :func:`connect`), else locally. ``warm(task)`` compiles what the tasks need, once per
    worker, before the first point; ``failed(task, message)`` is the row of a point whose Dask
    workers all died running it."""
    if not tasks:
        return
    if client is not None:
        yield from _on_dask(run, warm, failed, tasks, client, worker_timeout)
        return
    if workers == 1 or backend == "threads":
        warm(tasks[0])
    if workers == 1:
        for t in tasks:
            yield t, run(t)
        return
    # deferred: the process pool imports multiprocessing (45 ms) that `rsfbench --help` skips
    from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
    pool = (ProcessPoolExecutor(max_workers=workers, initializer=_init_worker,
                                initargs=(warm, tasks[0]))
            if backend == "processes" else ThreadPoolExecutor(max_workers=workers))
    try:
        futures = {pool.submit(run, t): t for t in tasks}
        for fut in as_completed(futures):
            yield futures[fut], fut.result()
    except BaseException:            # Ctrl-C, a closed generator: do not wait for the rest
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()


def connect(scheduler: str, timeout: float = CONNECT_TIMEOUT_S):
    """A Dask client of ``scheduler``, or ``ValueError`` saying it did not answer in time (or is
    no address)."""
    require("distributed", "ensemble", "a Dask scheduler (--scheduler)")
    from distributed import Client
    with quiet_distributed():
        try:
            return Client(scheduler, timeout=timeout)
        except (OSError, TimeoutError) as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {scheduler!r} within "
                             f"{timeout:g} s ({_one_line(exc)})") from None
        except (ValueError, TypeError) as exc:     # distributed's parsing of the address
            raise ValueError(f"scheduler {scheduler!r} is not a Dask scheduler address such as "
                             f"tcp://host:8786 ({_one_line(exc)})") from None


def _one_line(exc: BaseException) -> str:
    return " ".join(f"{type(exc).__name__}: {exc}".split())[:200]


@contextlib.contextmanager
def quiet_distributed():
    """distributed's loggers at CRITICAL for the block (module docstring: one line, not a log);
    their levels are restored after it."""
    import distributed  # noqa: F401  (its import configures its loggers: set them after it)
    names = ["distributed", *(n for n in list(logging.root.manager.loggerDict)
                              if n.startswith("distributed."))]
    loggers = [logging.getLogger(n) for n in names]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def _on_dask(run, warm, failed, tasks, client, worker_timeout):
    from distributed import wait
    address = client.scheduler.address
    futures = client.map(run, tasks, pure=False)
    index = {f.key: t for f, t in zip(futures, tasks)}
    pending, alone_since = set(futures), None

    def lost(why: str) -> SchedulerLost:
        # a future cancelled by no one here: the client cancels them all when the connection
        # to the scheduler drops (reason "scheduler-connection-lost")
        return SchedulerLost(f"the Dask scheduler at {address} was lost while {len(pending)} "
                             f"of {len(tasks)} tasks were pending ({why})")
    try:
        client.run(warm, tasks[0])               # every current worker; newcomers compile once
    except Exception:                             # a worker that fails to warm still runs tasks;
        pass                                      # a lost scheduler is seen by the wait below
    while pending:
        try:
            done, pending = wait(list(pending), timeout=1.0, return_when="FIRST_COMPLETED")
        except TimeoutError:                      # nothing finished within the second
            done = set()
        except (CancelledError, OSError) as exc:
            raise lost(type(exc).__name__) from None
        done = list(done)
        for i, fut in enumerate(done):
            task = index[fut.key]
            try:
                row = fut.result(timeout=RESULT_TIMEOUT_S)
            except TimeoutError:        # lost with its worker (module docstring), as are the
                pending.update(done[i:])  # others it finished: not one timeout each
                break
            except CancelledError as exc:
                raise lost(type(exc).__name__) from None
            except Exception as exc:              # KilledWorker: the task crashed its workers
                row = failed(task, f"{type(exc).__name__} on the Dask cluster: {exc}")
            yield task, row
        if not pending:
            break
        try:
            workers = client.scheduler_info().get("workers")
        except (CancelledError, OSError, TimeoutError) as exc:
            raise lost(type(exc).__name__) from None
        if client.status != "running":
            raise lost(f"the client is {client.status}")
        if workers:
            alone_since = None
        elif alone_since is None:
            alone_since = time.monotonic()
        elif time.monotonic() - alone_since > worker_timeout:
            for fut in pending:
                fut.cancel()
            raise ClusterGone(
                f"the Dask cluster at {address} has had no worker for {worker_timeout:g} s "
                f"while {len(pending)} of {len(tasks)} tasks were pending: start workers")
