"""Independent pieces of one ``lab fit`` (each law's fit, each parameter's profile) on the
machine's cores: this process and forked copies of it take the pieces in turn.

A fork shares what this process has compiled and read (numba's machine code, the record), so
a piece starts at once; a worker sends back only its results (pickled). While they run, each
process's BLAS has one thread: two processes with OpenBLAS's two threads each on two cores
were slower on the largest real step (timed by hand, fc70830's message), and one thread costs
nothing on the fit's small matrices.

Where fork is not available, or one worker is asked for, the pieces run here one after
another. The results are the same either way: every piece is a deterministic function of what
it was handed.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
import traceback

__all__ = ["run_all", "cores"]


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                  # not on Linux
        return os.cpu_count() or 1


def _claim(counter) -> int:
    with counter.get_lock():
        i = counter.value
        counter.value += 1
    return i


def _take(pieces: list, counter, out: dict, parent: int | None = None) -> None:
    """Pieces claimed and run until none is left, one raises (the others then claim no more)
    or, in a worker, its parent is gone: ``out[i]`` is (True, result) or (False, the
    exception)."""
    while (parent is None or os.getppid() == parent) and \
            (i := _claim(counter)) < len(pieces):
        try:
            out[i] = (True, pieces[i]())
        except Exception as exc:            # noqa: BLE001 (raised where the caller is)
            with counter.get_lock():        # nothing more is started anywhere
                counter.value = len(pieces)
            out[i] = (False, exc)
            return


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it comes back whole through pickle, else a RuntimeError with its text; its
    traceback here is lost either way, so its text goes with it (``remote_traceback``)."""
    text = "".join(traceback.format_exception(exc))
    try:
        back = pickle.loads(pickle.dumps(exc))
        if type(back) is not type(exc) or str(back) != str(exc):
            raise TypeError("changed on the way")
    except Exception:                       # noqa: BLE001 (any failure to rebuild it)
        back = RuntimeError(f"{type(exc).__name__}: {exc}")
    back.remote_traceback = text
    return back


def _work(pieces: list, conn, theirs: list, counter, parent: int) -> None:
    # the parent's ends of the pipes, inherited by the fork, closed: with its own open here, a
    # parent that died unasked (SIGTERM, SIGKILL) left this worker blocked on a full pipe
    for end in theirs:
        end.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # Ctrl-C is the parent's to handle
    signal.signal(signal.SIGTERM, signal.SIG_DFL)   # a SIGTERM kills a worker at once
    from threadpoolctl import threadpool_limits
    out: dict = {}
    with threadpool_limits(limits=1, user_api="blas"):     # as the parent's, after the fork
        _take(pieces, counter, out, parent)
    out = {i: (ok, value if ok else _portable(value)) for i, (ok, value) in out.items()}
    try:
        conn.send(out)
    except BrokenPipeError:                 # the parent is gone: nobody to tell
        pass
    except Exception as exc:                # noqa: BLE001 (a result that won't pickle)
        conn.send({i: (False, RuntimeError(f"{type(exc).__name__}: {exc}")) for i in out})
    conn.close()


def run_all(pieces: list, workers: int, here=None) -> list:
    """Each of ``pieces`` (calls without arguments) called; their results in order. With
    ``workers`` > 1, this process and ``workers`` − 1 forked ones take the pieces in turn (in
    a worker of another run_all, one after another here). ``here``: a call this process
    makes before it takes a piece, whatever the workers (work that must stay in this
    process, such as a figure begun while the workers take the pieces); its result is then
    the list's last. An exception in a piece is raised here (the first piece's, in order);
    once one has raised, no further piece starts."""
    from threadpoolctl import threadpool_limits
    extra = [] if here is None else [here]
    workers = min(workers, len(pieces) + len(extra))
    if workers <= 1 or "fork" not in multiprocessing.get_all_start_methods() or \
            multiprocessing.current_process().daemon:
        with threadpool_limits(limits=1, user_api="blas"):      # as in parallel: the same
            first = [h() for h in extra]                        # sums, to the last digit
            return [p() for p in pieces] + first
    ctx = multiprocessing.get_context("fork")
    counter, out = ctx.Value("i", 0), {}
    with threadpool_limits(limits=1, user_api="blas"):
        first = _run(ctx, list(pieces), counter, out, workers, extra)
    for i in range(len(pieces)):
        if i in out and not out[i][0]:
            exc = out[i][1]
            remote = getattr(exc, "remote_traceback", None)
            # the worker's traceback as the cause (what RSFBENCH_DEBUG=1 shows)
            raise exc from (RuntimeError(f"in a worker:\n{remote}") if remote else None)
    return [out[i][1] for i in range(len(pieces))] + first


def _run(ctx, pieces: list, counter, out: dict, workers: int, here: list) -> list:
    """The workers started (the pieces go to them by the fork itself, never pickled), the
    calls ``here`` made and this process's share taken, the pieces' results into ``out``;
    returns those of ``here``."""
    procs = []
    try:
        for _ in range(workers - 1):
            mine, there = ctx.Pipe(duplex=False)
            ends = [m for _, m in procs] + [mine]
            proc = ctx.Process(target=_work, args=(pieces, there, ends, counter, os.getpid()),
                               daemon=True)
            proc.start()
            there.close()
            procs.append((proc, mine))
        first = [h() for h in here]
        _take(pieces, counter, out)
        for proc, end in procs:
            try:
                out.update(end.recv())
            except EOFError:
                raise RuntimeError(f"a worker of this run stopped (exit code "
                                   f"{proc.exitcode}) before sending its results") from None
            proc.join()
    except BaseException:                   # Ctrl-C included: the workers are stopped
        for proc, _ in procs:
            proc.terminate()
        raise
    return first
