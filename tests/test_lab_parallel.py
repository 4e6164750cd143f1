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
    pids = {pid for _, pid in out}
    # one worker: all here; several: forked copies took some (at least this process did one)
    assert (pids == {os.getpid()}) if workers == 1 else os.getpid() in pids


def test_forked_workers_take_pieces():
    # a piece that waits lets the other process take the next: two processes ran
    import time

    def slow(x):
        time.sleep(0.3)
        return os.getpid()
    pids = run_all([functools.partial(slow, x) for x in range(2)], 2)
    assert len(set(pids)) == 2


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
