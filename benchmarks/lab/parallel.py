"""Independent pieces of one ``lab fit`` (each law's fit, each parameter's profile) on the
machine's cores: this process and forked copies of it take the pieces in turn.

A fork shares what this process has compiled and read (numba's machine code, the record), so
a piece starts at once; a worker sends back only its results (pickled). While they run, each
process's BLAS has one thread: two processes with OpenBLAS's two threads each on two cores
took 8.8–9.6 s on the 75,220-sample sepiolite step against 6.7–7.4 s with one (three runs
each, interleaved), and one thread costs nothing on the fit's small matrices.

Where fork is not available, or one worker is asked for, the pieces run here one after
another. The results are the same either way: every piece is a deterministic function of what
it was handed.
"""

from __future__ import annotations

import os
import signal

__all__ = ["run_all", "cores"]

#: the pieces of the current :func:`run_all`, inherited by its forked workers (a closure does
#: not pickle; an index does)
_PIECES: list = []


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


def _take(counter, out: dict) -> None:
    """Pieces claimed and run until none is left or one raises: ``out[i]`` is (True, result)
    or (False, the exception)."""
    while (i := _claim(counter)) < len(_PIECES):
        try:
            out[i] = (True, _PIECES[i]())
        except Exception as exc:            # noqa: BLE001 (raised where the caller is)
            out[i] = (False, exc)
            return


def _work(conn, counter) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # Ctrl-C is the parent's to handle
    from threadpoolctl import threadpool_limits
    out: dict = {}
    with threadpool_limits(limits=1, user_api="blas"):     # as the parent's, after the fork
        _take(counter, out)
    try:
        conn.send(out)
    except Exception as exc:                # noqa: BLE001 (a result or error that won't pickle)
        conn.send({i: (False, RuntimeError(f"{type(exc).__name__}: {exc}")) for i in out})
    conn.close()


def run_all(pieces: list, workers: int) -> list:
    """Each of ``pieces`` (calls without arguments) called; their results in order. With
    ``workers`` > 1, this process and ``workers`` − 1 forked ones take the pieces in turn. An
    exception in a piece is raised here (the first piece's, in order)."""
    import multiprocessing
    global _PIECES
    workers = min(workers, len(pieces))
    if workers <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        return [p() for p in pieces]
    from threadpoolctl import threadpool_limits
    ctx = multiprocessing.get_context("fork")
    _PIECES = list(pieces)
    counter, procs, out = ctx.Value("i", 0), [], {}
    with threadpool_limits(limits=1, user_api="blas"):
        _run(ctx, counter, procs, out, workers)
    for i in range(len(pieces)):
        if i not in out:                    # a worker stopped at its error before this one
            continue
        ok, value = out[i]
        if not ok:
            raise value
    return [out[i][1] for i in range(len(pieces))]


def _run(ctx, counter, procs: list, out: dict, workers: int) -> None:
    """The workers started, this process's share taken, their results into ``out``."""
    global _PIECES
    try:
        for _ in range(workers - 1):
            here, there = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_work, args=(there, counter), daemon=True)
            proc.start()
            there.close()
            procs.append((proc, here))
        _take(counter, out)
        for proc, here in procs:
            try:
                out.update(here.recv())
            except EOFError:
                raise RuntimeError(f"a worker of this run stopped (exit code "
                                   f"{proc.exitcode}) before sending its results") from None
            proc.join()
    except BaseException:                   # Ctrl-C included: the workers are stopped
        for proc, _ in procs:
            proc.terminate()
        raise
    finally:
        _PIECES = []
