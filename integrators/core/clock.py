"""A wall clock readable inside compiled code, so that a budget is honoured inside a kernel.

:func:`monotonic` is POSIX ``clock_gettime(CLOCK_MONOTONIC)`` in seconds, the clock behind
Python's ``time.perf_counter`` on Linux, so a deadline computed in Python
(:meth:`integrators.core.solve.Budget.deadline`) can be compared with it in a numba function or cfunc.
It is a numba intrinsic (a direct call of the C library's function, no Python object involved):
it caches with the function that uses it, and costs ~20 ns.
"""

from __future__ import annotations

import time

from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core.extending import intrinsic

__all__ = ["monotonic", "CLOCK_MONOTONIC"]

#: the id of the monotonic clock (on Linux the clock of ``time.perf_counter``)
CLOCK_MONOTONIC = time.CLOCK_MONOTONIC


@intrinsic
def _clock_gettime(typingctx):
    def codegen(context, builder, signature, args):
        i32, i64, f64 = ir.IntType(32), ir.IntType(64), ir.DoubleType()
        timespec = ir.LiteralStructType([i64, i64])
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(i32, [i32, timespec.as_pointer()]), "clock_gettime")
        ts = cgutils.alloca_once(builder, timespec)
        builder.call(fn, [ir.Constant(i32, CLOCK_MONOTONIC), ts])
        zero = ir.Constant(i32, 0)
        sec = builder.load(builder.gep(ts, [zero, zero]))
        nsec = builder.load(builder.gep(ts, [zero, ir.Constant(i32, 1)]))
        return builder.fadd(builder.sitofp(sec, f64),
                            builder.fmul(builder.sitofp(nsec, f64), ir.Constant(f64, 1e-9)))
    return types.float64(), codegen


@njit(cache=True, nogil=True)
def monotonic() -> float:
    """Seconds of the monotonic clock (``time.perf_counter()`` on Linux), in compiled code."""
    return _clock_gettime()
