"""Stops by signal: a SIGTERM taken the way a Ctrl-C is, and the blocks neither may split.

* :func:`stop_on_sigterm`: from then on, a SIGTERM to the process raises :class:`Terminated` (a
  ``KeyboardInterrupt``) in its main thread, so that what a Ctrl-C cleans up (the temporary file
  of a write in progress, a sweep's store) is cleaned up; a process forked from it dies of it.
* :func:`stopped_by`: which of the two stopped the run, for its one line and exit status.
* :func:`uninterrupted`: a block that a Ctrl-C or SIGTERM waits for (a file renamed into place
  and the entry that lists it). The signals are deferred by the block's own handlers, not
  masked: a mask holds only for the thread that sets it, and another thread (numba's, a pool's)
  takes a signal sent to the process, whose Python handler then runs in the main thread anyway.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import threading

__all__ = ["Terminated", "stop_on_sigterm", "stopped_by", "note_sigterm", "uninterrupted",
           "handled"]

#: the signals a run is stopped by
STOPS = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """A SIGTERM, raised in the main thread where a Ctrl-C would be (:func:`stop_on_sigterm`)."""


#: not empty once a SIGTERM came: the words of a stop may be re-raised as a plain Ctrl-C
_TERMINATED: list = []


def stop_on_sigterm() -> None:
    """From now on, a SIGTERM to this process takes the path of a Ctrl-C (module docstring).
    A process forked from this one (a pool's worker) dies of it as it would have, once it runs
    Python again."""
    _TERMINATED.clear()
    signal.signal(signal.SIGTERM, functools.partial(_terminate, os.getpid()))


def _terminate(pid: int, signum, frame) -> None:
    if os.getpid() != pid:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGTERM)
        return
    note_sigterm()
    raise Terminated


def note_sigterm() -> None:
    """Record that a SIGTERM stopped the run (for a handler that took it over for a while, as
    the posterior's sampler does)."""
    _TERMINATED.append(True)


def stopped_by() -> tuple[str, int]:
    """What stopped the command, for its line, and its exit status: ("SIGTERM", 143) once a
    SIGTERM came, else ("Ctrl-C", 130)."""
    return ("SIGTERM", 143) if _TERMINATED else ("Ctrl-C", 130)


@contextlib.contextmanager
def handled(signals, handler):
    """``handler`` takes the ``signals`` for the block, and the handlers in place before take
    them back (one set outside Python, which ``signal.getsignal`` cannot give, as the
    default). From the main thread; elsewhere handlers cannot be set, and none runs: the block
    runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, handler) for s in signals}
    try:
        yield
    finally:
        for s, before in previous.items():
            signal.signal(s, signal.SIG_DFL if before is None else before)


@contextlib.contextmanager
def uninterrupted():
    """A Ctrl-C or SIGTERM that comes during the block is raised after it, to the handler that
    was in place (:func:`handled`)."""
    pending = []
    try:
        with handled(STOPS, lambda signum, frame: pending.append(signum)):
            yield
    finally:
        for s in dict.fromkeys(pending):
            signal.raise_signal(s)
