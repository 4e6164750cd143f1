"""The pieces of one lab fit on several processes (:mod:`benchmarks.lab.parallel`): the same
results, in order, as one after another; errors raised here."""

import functools
import os
import threading

import pytest

from benchmarks.lab.parallel import cores, run_all


def _square(x):
    return x * x, os.getpid()


def _fails(x):
    raise ValueError(f"piece {x} refused")


def _lock():
    return threading.Lock()            # does not pickle


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_the_results_come_in_order_whatever_the_workers(workers):
    pieces = [functools.partial(_square, x) for x in range(7)]
    out = run_all(pieces, workers)
    assert [v for v, _ in out] == [x * x for x in range(7)]
    if workers == 1:
        assert {pid for _, pid in out} == {os.getpid()}


def _wait_for_both(barrier):
    barrier.wait(timeout=30)               # returns only when both processes are in here
    return os.getpid()


def test_forked_workers_take_pieces():
    # two pieces that each wait for the other: they can only both finish in two processes
    import multiprocessing
    barrier = multiprocessing.get_context("fork").Barrier(2)
    pids = run_all([functools.partial(_wait_for_both, barrier)] * 2, 2)
    assert len(set(pids)) == 2 and os.getpid() in pids


def _here_waits(barrier):
    barrier.wait(timeout=30)               # a worker must be at the barrier too
    return "here", os.getpid()


def test_here_runs_in_this_process_beside_the_workers():
    # `here` waits for a piece at a barrier: it returns only if a worker runs that piece at
    # the same time; its result comes last, in this process
    import multiprocessing
    barrier = multiprocessing.get_context("fork").Barrier(2)
    out = run_all([functools.partial(_wait_for_both, barrier)], 2,
                  here=functools.partial(_here_waits, barrier))
    assert out[-1] == ("here", os.getpid()) and out[0] != os.getpid()


@pytest.mark.parametrize("workers", [1, 2])
def test_here_comes_last_whatever_the_workers(workers):
    out = run_all([functools.partial(_square, x) for x in range(3)], workers,
                  here=lambda: os.getpid())
    assert [v for v, _ in out[:-1]] == [0, 1, 4] and out[-1] == os.getpid()


class _Odd(ValueError):
    def __init__(self, a, b):
        super().__init__(f"{a} and {b}")


def _odd(sleep):
    import time
    time.sleep(sleep)
    raise _Odd(1, 2)


def test_an_error_that_pickle_cannot_rebuild_keeps_its_text():
    # _Odd pickles but cannot be rebuilt (two arguments): the worker's error keeps its text
    with pytest.raises(Exception, match="1 and 2"):
        run_all([functools.partial(_sleep, 0.5), functools.partial(_odd, 0.0)], 2)


def _nested():
    return run_all([functools.partial(_square, x) for x in range(3)], 2)


def test_a_run_inside_a_piece_runs_whole():
    # each piece runs its own run_all: here and in a worker (there one after another)
    out = run_all([_nested, _nested, functools.partial(_square, 5)], 2)
    assert [v for v, _ in out[0]] == [v for v, _ in out[1]] == [0, 1, 4] and out[2][0] == 25


@pytest.mark.parametrize("workers", [1, 2])
def test_an_error_in_a_piece_is_raised_here(workers):
    pieces = [functools.partial(_square, 1), functools.partial(_fails, 2),
              functools.partial(_square, 3)]
    with pytest.raises(ValueError, match="piece 2 refused"):
        run_all(pieces, workers)


def _sleep(s):
    import time
    time.sleep(s)


def test_a_result_that_does_not_pickle_is_an_error_naming_why():
    # the worker's result comes back pickled: a lock cannot, and says so here (the first
    # piece keeps this process busy while the worker takes the lock's)
    with pytest.raises(RuntimeError, match="pickle|lock"):
        run_all([functools.partial(_sleep, 0.5), _lock], 2)


def test_no_pieces_and_the_cores():
    assert run_all([], 2) == [] and cores() >= 1
