"""CyRK's C++ solvers called from numba (``nbsolve2_ivp``): explicit Runge–Kutta pairs and the
implicit BDF, Radau and LSODA, with a numba ``cfunc`` right-hand side.

CyRK (J. P. Renaud) compiles its solvers in C++ and offers ``nbsolve2_ivp(diffeq_address,
t_span, y0, method, dense_output, args, rtol, atol, max_num_steps, …)`` to numba users: the
right-hand side is a cfunc, nothing runs in Python during the integration. It has no events on
that entry point, so this adapter locates them on CyRK's dense output. Two ways:

* **one compiled call** (:func:`_whole_run`), as a numba user calls it: ``nbsolve2_ivp`` over
  the whole run from compiled code, its crossings located and recorded and the save points
  filled in the same compiled function, so no Python runs per step, per event or per save.
  Taken by the implicit methods on a run with one loading speed throughout (no history
  switches, no two-speed loading), without a progress bar and with the default step budget;
  its events, saves and counters are those of the segment path to the bit (tests/test_cyrk.py).
  A call that stops short (a failure, or more than 2·``CHUNK_STEPS`` steps) is thrown away and
  the run is done again on the segment path, the thrown-away call's counters added. A wall
  budget is read once the call is done (a run past it is reported ``WallTime``);
* otherwise **the segment path** (:mod:`integrators.core.segments`):
  one call over the whole run unless it takes more than 2·``CHUNK_STEPS``
  steps (memory: CyRK keeps every step and its interpolant; the explicit methods take
  millions here, and their first call stops at ``FIRST_CAP``): then calls over spans expected
  to take ``CHUNK_STEPS``/2 (the steps per unit time learned from the calls before). CyRK builds no dense output for a call that ran out
  of steps, so such a call is done again over the shorter span. Under two-speed loading a
  segment ends at an event's end, where the run restarts: so that the restart throws little
  away, the first call of a segment spans 1.25× the last segment's length, or, before one is
  known, ``FIRST_SPAN`` half periods π/√C, and each further call twice the one before. Each
  call is a cold start (first step chosen again), as a new call of a user's would be;
* the crossings that count (``events.DIRECTIONS``; a PEAK only where w > E_slow) between
  consecutive steps, bisected to the last bit on CyRK's dense output, which a compiled kernel
  calls through CyRK's C function (``_dense``), so no Python runs per step or per bisection;
* counters: ``steps`` is CyRK's steps taken, nfev and the finite-difference Jacobians of the
  implicit methods are counted in the cfunc (a column is one call at the abscissa of the call
  before with one component perturbed, counted when the first is); CyRK does not report
  rejected steps (0).

``rhs="python"`` is refused: CyRK's Python entry point (``pysolve_ivp``) calls a Python function
per evaluation, which the study's Python tier of other libraries already measures. The first
solve in a process compiles CyRK's numba entry point and the compiled callers of this module
(numba cannot cache them: CyRK's entry point holds a ctypes pointer); a segment-path call goes
through a compiled caller too (:func:`_call`: from Python, numba's dispatcher types a keyword
call afresh each time, ~70 µs).

Reference: CyRK, https://github.com/jrenaud90/CyRK (C++ ports of scipy's RK23/RK45/DOP853, BDF,
Radau and LSODA; Tsit5, Vern7, Vern8).
"""

from __future__ import annotations

import functools
import importlib.metadata
import importlib.util
import math
from collections import deque
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from llvmlite import ir
from numba import carray, cfunc, njit, types
from numba.extending import intrinsic

from integrators.core.cache import announce_compile
from integrators.core.crossings import carry_last_root, push_crossing, queue_crossings
from integrators.core.events import (DIRECTIONS, END, N_EVENTS, PEAK, START, compiled_roots,
                                     events_table, new_recorder, observe, record, sign_change)
from integrators.core.registry import AdaptiveAlgorithm, register
from integrators.core.segments import Advance, run_segments, save_grid
from integrators.core.solution import RawRun, ReturnCode, Stats
from problems.formulations import N_Q, Q_E, form_vector, from_ode_state, ode_rhs, to_ode_state
from problems.loading import H_TAU_FAST, LN_E_HOLD, ln_load_rate, load_segment

__all__ = ["CyRKRK45", "CyRKDOP853", "CyRKTsit5", "CyRKBDF", "CyRKRadau", "CyRKLSODA",
           "plain_starts"]

if importlib.util.find_spec("CyRK") is None:
    raise ImportError("No module named 'CyRK'")
_VERSION = importlib.metadata.version("CyRK")
from CyRK import nbsolve2_ivp  # noqa: E402  (after the check that CyRK is there)

CHUNK_STEPS = 65_536
#: under two-speed loading, the first call's span in half periods π/√C, until a cycle is known
FIRST_SPAN = 16.0
#: an explicit method's first call: at most this many steps, to learn the steps per unit time
FIRST_CAP = 8192
#: CyRK's status codes (CyrkErrorCodes) this adapter tells apart
_SUCCESS, _MAX_STEPS_USER, _STEP_SPACING = 1, -52, -54

# args handed to the cfunc: the problem vector q of problems.formulations, then the address of
# the counters array
_COUNTERS, _N_ARGS = N_Q, N_Q + 1
_E = Q_E
# the event kernels' q: the problem vector, then ln 10 E_slow, ln E_slow, ln E
_LN_10ES, _LN_ES, _LN_E = N_Q, N_Q + 1, N_Q + 2
# the counters: rhs calls, Jacobian columns' first, the abscissa and state of the call before
(_NFEV, _NJEV, _T_LAST, _Y0, _Y1, _Y2) = range(6)


@intrinsic
def _as_pointer(typingctx, address):
    """The float64 array at an address (an int64): how the cfunc reaches its counters."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
    return sig, codegen


@intrinsic
def _dense(typingctx, function, result, t, out):
    """Call CyRK's ``call`` (int32(size_t result, double t, size_t out)) at its address."""
    sig = types.int32(types.int64, types.int64, types.float64, types.int64)

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        fnty = ir.FunctionType(ir.IntType(32), [i64, ir.DoubleType(), i64])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, [args[1], args[2], args[3]])
    return sig, codegen


def _rhs(dy, t, y, args):
    """The right-hand side handed to CyRK, compiled as a cfunc (void(double*, double, double*,
    double*)); counts its calls and the Jacobian columns (module docstring)."""
    a = carray(args, (_N_ARGS,))
    c = carray(_as_pointer(np.int64(a[_COUNTERS])), (6,))
    z = carray(y, (3,))
    if t == c[_T_LAST] and (z[0] != c[_Y0]) + (z[1] != c[_Y1]) + (z[2] != c[_Y2]) == 1:
        if z[0] != c[_Y0]:
            c[_NJEV] += 1.0
    else:
        c[_T_LAST], c[_Y0], c[_Y1], c[_Y2] = t, z[0], z[1], z[2]
    c[_NFEV] += 1.0
    ode_rhs(a, z, carray(dy, (3,)))


@njit(cache=True, nogil=True, error_model="numpy")
def _step_crossings(call, result, q, T, Y, g):
    """The crossings that count between consecutive steps (T, Y: rows of the steps), each
    bisected to the last bit on the dense output (``_dense`` with CyRK's ``call`` at ``call``
    and the result at ``result``): rows (τ, kind, sign, z0, z1, z2), in time order. ``g`` holds
    the root functions at T[0] (signs carried over a restart); left holding them at T[-1]."""
    ln_end = q[_LN_ES]
    gp, zt = g.copy(), np.empty(3)
    R = np.empty((16, 6))
    m = 0
    for i in range(1, T.shape[0]):
        compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], Y[i], g)
        first = m
        for k in range(4):
            sign = sign_change(gp[k], g[k])
            if sign == 0 or (DIRECTIONS[k] != 0 and DIRECTIONS[k] != sign):
                continue
            if k == PEAK and not (gp[END] > 0.0 or g[END] > 0.0):
                continue           # the stick-phase jitter of C h − D η is not a peak
            hi = _bisect(call, result, q, k, gp[k] > 0.0, T[i - 1], T[i])
            if hi == T[i]:
                zt[0], zt[1], zt[2] = Y[i, 0], Y[i, 1], Y[i, 2]
            else:
                _dense(call, result, hi, zt.ctypes.data)
            if k == PEAK and not zt[1] - ln_end > 0.0:
                continue           # at the root w ≤ E_slow: not a peak
            R = push_crossing(R, m, first, hi, k, sign, zt[0], zt[1], zt[2])
            m += 1
        gp[:] = g
    return R[:m]


@njit(cache=True, nogil=True, error_model="numpy")
def _bisect(call, result, q, k, left_pos, lo, hi):
    """Root function k's crossing in (lo, hi], bisected to the last bit on the dense output
    (``_dense`` with CyRK's ``call`` and the result at ``result``); ``left_pos``: its sign at
    lo."""
    zt, gt = np.empty(3), np.empty(4)
    while True:
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            return hi
        _dense(call, result, mid, zt.ctypes.data)
        compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], zt, gt)
        if gt[k] != 0.0 and (gt[k] > 0.0) == left_pos:
            lo = mid
        else:
            hi = mid


def _event_vector(nd, e: float) -> np.ndarray:
    """The event kernels' q under the loading E = ``e``: the problem vector, then ln 10 E_slow,
    ln E_slow, ln E."""
    return np.concatenate([form_vector(nd, e), [math.log(10.0 * nd.e_slow), math.log(nd.e_slow),
                                                ln_load_rate(e)]])


@njit(error_model="numpy")
def _call(rhs, t0, t1, z0, method, args, rtol, atol, max_steps):
    """One ``nbsolve2_ivp`` call from compiled code, as CyRK's numba users call it (from Python,
    numba's dispatcher types the keyword call every time: ~70 µs a call)."""
    return nbsolve2_ivp(rhs, (t0, t1), z0, method, dense_output=True, args=args, rtol=rtol,
                        atol=atol, max_num_steps=max_steps)


@njit(error_model="numpy")
def _whole_run(rhs, call, method, tau_end, z0, args, q, rtol, atol, max_steps, rec, ev,
               grid, saved):
    """The one-call path (module docstring): ``nbsolve2_ivp`` over [0, τ_end], its crossings
    recorded as the segment driver records them (coincident ones merged, kinds in order), the
    states at the times ``grid`` (increasing, ≤ τ_end) into ``saved`` from the dense output (a
    step's own state where one ends exactly there, as the segment driver takes it). Returns
    (CyRK's status, steps taken, the recorder's event rows, the last step's τ and state)."""
    r = nbsolve2_ivp(rhs, (0.0, tau_end), z0, method, dense_output=True, args=args, rtol=rtol,
                     atol=atol, max_num_steps=max_steps)
    status, taken = r.status, r.steps_taken
    T, Y = r.t, np.ascontiguousarray(r.y.T)
    n = T.shape[0]
    end = Y[n - 1].copy() if n else z0.copy()
    t_last = T[n - 1] if n else 0.0
    if status != _SUCCESS or n < 2 or T[0] != 0.0:
        r.free()
        return status, taken, ev[:0], t_last, end
    g = np.empty(4)
    compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], z0, g)
    R = _step_crossings(call, r._ptr, q, T, Y, g)
    e = q[_E]
    m, i = R.shape[0], 0
    while i < m:
        t = R[i, 0]
        j = i + 1
        while j < m and R[j, 0] - t <= 1e-14 * max(1.0, abs(t)):   # as queue_crossings
            j += 1
        if int(rec[N_EVENTS]) + 1 >= ev.shape[0]:
            ev = np.concatenate((ev, np.empty_like(ev)))
        for k in range(4):                                          # sorted(roots)
            for row in range(i, j):
                if int(R[row, 1]) == k:
                    record(rec, ev, k, t, R[i, 3], R[i, 4], e * t)
        observe(rec, R[i, 3])
        i = j
    observe(rec, end[0])
    step, zt = 0, np.empty(3)
    for k in range(grid.shape[0]):
        while step < n and T[step] < grid[k]:
            step += 1
        if step < n and T[step] == grid[k]:     # a step's end: its state, as the driver's
            saved[k] = Y[step]
        else:
            _dense(call, r._ptr, grid[k], zt.ctypes.data)
            saved[k] = zt
    r.free()
    return status, taken, ev[:int(rec[N_EVENTS])], t_last, end


def _plain_rhs(dy, t, y, args):
    """The right-hand side as a CyRK user writes it: f alone, no counting."""
    ode_rhs(carray(args, (N_Q,)), carray(y, (3,)), carray(dy, (3,)))


@njit(error_model="numpy")
def _plain_run(rhs, call, method, tau_end, z0, q, hist, first_span, rtol, atol, max_steps):
    """The plain call (:func:`plain_starts`) over [0, τ_end]: one ``nbsolve2_ivp`` call per
    loading segment, and under two-speed loading a restart at each event's end, its calls
    spanned and sized as the adapter's (module docstring: a call expected to take more than
    ``CHUNK_STEPS``/2 steps is shortened, one that runs out of steps done again over less), so
    that the two take the same steps. Returns (CyRK's status, steps taken, the event starts'
    τ); the status is −1 for a state that is not finite."""
    tiny = 1e-12 * tau_end
    starts, m = np.empty(16), 0
    z, tau, fast_until, cycle, seg, seg_start = z0.copy(), 0.0, -np.inf, -1.0, 0.0, 0.0
    taken, density, redone = 0, 0.0, 0
    in_event, status = False, _SUCCESS
    while tau < tau_end - tiny and status == _SUCCESS:
        e, bound = load_segment(hist, tau, fast_until, tau_end, tiny)
        if seg > 0.0 and tau < seg:         # the last segment ended at an event's end
            cycle = tau - seg_start
        seg_start, seg = tau, bound
        q[_E] = e
        q[_LN_E] = math.log(e) if e > 0.0 else LN_E_HOLD
        two = hist[H_TAU_FAST] > 0.0
        span = np.inf if not two else (first_span if cycle < 0.0 else 1.25 * cycle)
        while tau < bound - tiny and status == _SUCCESS:
            size = span if density == 0.0 else min(span, 0.5 * CHUNK_STEPS / density)
            t0, t1 = tau, (bound if tau + size >= bound else tau + size)
            r = nbsolve2_ivp(rhs, (tau, t1), z, method, dense_output=True, args=q[:N_Q],
                             rtol=rtol, atol=atol, max_num_steps=max_steps)
            status, n, T = r.status, r.steps_taken, r.t
            taken += n
            if n > 0 and T[T.shape[0] - 1] > t0:
                density = max(n / (T[T.shape[0] - 1] - t0), 1e-300)
            if status == _MAX_STEPS_USER and n > 0 and redone < 64:
                status, redone = _SUCCESS, redone + 1   # no dense output: again over less
            elif status == _SUCCESS:
                tau, starts, m, in_event, ended = _plain_scan(call, r, q, tau, z, starts, m,
                                                              in_event, two)
                if not np.all(np.isfinite(z)):
                    status = -1
                if ended:                   # under two-speed loading: a restart here
                    fast_until, bound = tau + hist[H_TAU_FAST], tau
                span = 2.0 * (t1 - t0)
            r.free()
    return status, taken, starts[:m]


@njit(error_model="numpy")
def _plain_scan(call, r, q, tau, z, starts, m, in_event, stop_at_end):
    """One call's steps from (τ, z): the event starts (and ends) bisected to the last bit on
    its dense output, the starts appended to ``starts``; with ``stop_at_end``, up to the first
    end. Returns (τ reached, starts, m, in_event, whether it stopped at an end); z left
    there."""
    T, Y = r.t, np.ascontiguousarray(r.y.T)
    g, zt = np.empty(4), np.empty(3)
    compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], z, g)
    before, t_before = g.copy(), tau
    for i in range(T.shape[0]):
        if T[i] <= t_before:                # CyRK's first row is the start
            continue
        compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], Y[i], g)
        for k in (START, END):
            if (in_event == (k == END)
                    and sign_change(before[k], g[k]) == DIRECTIONS[k]):
                t = _bisect(call, r._ptr, q, k, before[k] > 0.0, t_before, T[i])
                in_event = k == START
                if k == START:
                    if m == starts.shape[0]:
                        starts = np.concatenate((starts, np.empty_like(starts)))
                    starts[m] = t
                    m += 1
                elif stop_at_end:
                    if t == T[i]:
                        z[:] = Y[i]
                    else:
                        _dense(call, r._ptr, t, zt.ctypes.data)
                        z[:] = zt
                    return t, starts, m, in_event, True
        before[:] = g
        t_before = T[i]
    z[:] = Y[T.shape[0] - 1]
    return T[T.shape[0] - 1], starts, m, in_event, False


@functools.cache
def _plain_library():
    """The plain cfunc's address (compiled once)."""
    double_p = types.CPointer(types.float64)
    return cfunc(types.void(double_p, types.float64, double_p, double_p), cache=True,
                 error_model="numpy")(_plain_rhs).address


def plain_starts(problem, method: str, rtol: float, atol: float):
    """CyRK called plainly, as its numba users call it: a cfunc of f alone (no counters),
    ``nbsolve2_ivp`` from compiled code with dense output, one call per loading segment (and
    under two-speed loading a restart at each event's end, its calls spanned as the adapter's),
    and the event starts bisected to the last bit on the dense output: no extrema, peaks or
    saves. The harness times it beside the adapter (:mod:`benchmarks.studies.target`), so that
    a ratio is published against the faster of the two. Returns (CyRK's steps taken, the
    starts in s; a start of an event still running at the end included), or None if CyRK
    failed or the state is not finite. ``method``: CyRK's name ("RADAU", "BDF", …)."""
    nd = problem.nondimensional()
    call = _library()[0]
    q = _event_vector(nd, nd.e_slow)              # its ln E set per loading segment
    z0 = to_ode_state(nd.law_code, nd.beta, nd.x0)
    status, taken, starts = _plain_run(_plain_library(), call, method, nd.tau_end, z0, q,
                                       nd.history, FIRST_SPAN * nd.grid_tau, rtol, atol,
                                       2 * CHUNK_STEPS)
    return None if status != _SUCCESS else (int(taken), starts * nd.time_scale)


@functools.cache
def _library():
    """The address of CyRK's dense-output call, and the cfunc's."""
    from CyRK.nb import numba_c_api
    announce_compile(_call, "the callers of CyRK's compiled solver", "about 10 s", cached=False)
    double_p = types.CPointer(types.float64)
    rhs = cfunc(types.void(double_p, types.float64, double_p, double_p), cache=True,
                error_model="numpy")(_rhs)
    # both compiled callers are compiled now, whichever path the first (warm-up) run takes
    counters = np.zeros(6)
    args = np.zeros(_N_ARGS)
    args[_COUNTERS] = float(counters.ctypes.data)
    _call(rhs.address, 0.0, 1e-9, np.ones(3), "RADAU", args, 1e-3, 1e-3, 2).free()
    return int(numba_c_api.get_call_call_func_ptr()), rhs.address


@dataclass(frozen=True)
class _CyRK(AdaptiveAlgorithm):
    """Options of every CyRK backend: those of :class:`AdaptiveAlgorithm` (``max_steps``
    counts CyRK's steps taken). Compiled right-hand side only (module docstring)."""

    library: ClassVar[str] = "CyRK"
    package: ClassVar[str] = "cyrk"
    compiled: ClassVar[bool] = True
    method: ClassVar[str] = ""
    rhs_tiers: ClassVar[tuple[str, ...]] = ("numba",)
    rhs_tiers_reason: ClassVar[str] = (
        "the adapter calls CyRK's numba entry point (nbsolve2_ivp), which takes a cfunc; its "
        "Python entry point calls Python per evaluation, as the other libraries' Python tier")

    @classmethod
    def library_version(cls) -> str:
        return f"CyRK {_VERSION} (C++, called from numba)"

    def make_stepper(self, nd, budget):
        return _CyRKStepper(self, nd, budget)

    def run(self, problem, output, budget, progress):
        nd = problem.nondimensional()
        tiny = 1e-12 * nd.tau_end
        e, bound = load_segment(nd.history, 0.0, -math.inf, nd.tau_end, tiny)
        if not (self.stiff and progress is None and not nd.two_speed
                and bound >= nd.tau_end - tiny and self.max_steps > 2 * CHUNK_STEPS):
            return super().run(problem, output, budget, progress)
        raw = _one_call(self, problem, nd, e, output, budget)
        if isinstance(raw, RawRun):
            return raw
        # the call stopped short: the segment path from the start, its first chunk sized by
        # the steps per unit τ just seen, the thrown-away call's work counted (and charged to
        # the step budget)
        wasted, density = raw
        stepper = self.make_stepper(nd, budget)
        stepper.stats = Stats(steps=wasted.steps)
        stepper._counters[_NFEV], stepper._counters[_NJEV] = wasted.nfev, wasted.njev
        stepper._density = density
        try:
            again = run_segments(problem, stepper, output, budget, progress)
        finally:
            stepper.finish()
        again.meta["one_call"] = False
        return again


@register
@dataclass(frozen=True)
class CyRKRK45(_CyRK):
    """Dormand–Prince 5(4) (CyRK's port of scipy's RK45), explicit, adaptive, quartic dense
    output. Reference: Dormand & Prince (1980), J. Comput. Appl. Math. 6, 19–26."""

    name: ClassVar[str] = "CyRK-RK45"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge–Kutta"
    order: ClassVar[int] = 5
    stiff: ClassVar[bool] = False
    method: ClassVar[str] = "RK45"


@register
@dataclass(frozen=True)
class CyRKDOP853(_CyRK):
    """DOP853 (Hairer's 8(5,3) pair, CyRK's port of scipy's), explicit, adaptive, order-7 dense
    output. Reference: Hairer, Nørsett & Wanner (1993), Solving ODEs I, §II.10."""

    name: ClassVar[str] = "CyRK-DOP853"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge–Kutta"
    order: ClassVar[int] = 8
    stiff: ClassVar[bool] = False
    method: ClassVar[str] = "DOP853"


@register
@dataclass(frozen=True)
class CyRKTsit5(_CyRK):
    """Tsitouras 5(4), explicit, adaptive, with its free interpolant. Reference: Tsitouras
    (2011), Comput. Math. Appl. 62, 770–775."""

    name: ClassVar[str] = "CyRK-Tsit5"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge–Kutta"
    order: ClassVar[int] = 5
    stiff: ClassVar[bool] = False
    method: ClassVar[str] = "Tsit5"


@register
@dataclass(frozen=True)
class CyRKBDF(_CyRK):
    """Variable-order BDF (orders 1–5, CyRK's port of scipy's BDF: NDF coefficients, quasi-
    constant step), finite-difference Jacobian. Reference: Shampine & Reichelt (1997), SIAM J.
    Sci. Comput. 18, 1–22."""

    name: ClassVar[str] = "CyRK-BDF"
    kind: ClassVar[str] = "multistep"
    family: ClassVar[str] = "BDF"
    order: ClassVar[int] = 5
    method: ClassVar[str] = "BDF"


@register
@dataclass(frozen=True)
class CyRKRadau(_CyRK):
    """Radau IIA, order 5 (CyRK's port of scipy's Radau), finite-difference Jacobian.
    Reference: Hairer & Wanner (1996), Solving ODEs II, §IV.8."""

    name: ClassVar[str] = "CyRK-Radau"
    kind: ClassVar[str] = "implicit"
    family: ClassVar[str] = "implicit Runge–Kutta (Radau IIA)"
    order: ClassVar[int] = 5
    method: ClassVar[str] = "RADAU"


@register
@dataclass(frozen=True)
class CyRKLSODA(_CyRK):
    """LSODA (Adams/BDF switching; CyRK's C++ port), finite-difference Jacobian. Reference:
    Petzold (1983), SIAM J. Sci. Stat. Comput. 4, 136–148."""

    name: ClassVar[str] = "CyRK-LSODA"
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "lsoda"
    family: ClassVar[str] = "Adams/BDF (LSODA)"
    order: ClassVar[int] = 12
    method: ClassVar[str] = "LSODA"


class _CyRKStepper:
    """The segment protocol over chunked ``nbsolve2_ivp`` calls: ``_T``/``_Y`` are the current
    chunk's steps, ``_result`` its CyRK result (dense output; freed when replaced), ``_queue``
    its crossings not yet reported, ``_failure`` what to return once the chunk is used up."""

    def __init__(self, algorithm: _CyRK, nd, budget=None):
        self.algorithm = algorithm
        self.nd = nd
        self.budget = budget
        self.stats = Stats()
        self._call, self._rhs = _library()
        self._counters = np.zeros(6)
        self._args = np.append(form_vector(nd, nd.e_slow), float(self._counters.ctypes.data))
        if int(self._args[_COUNTERS]) != self._counters.ctypes.data:   # above 2**53
            raise MemoryError("the counters' address does not fit a double exactly")
        self._q = _event_vector(nd, nd.e_slow)     # its E and ln E set by start
        self._two_speed = nd.two_speed
        self._result = None
        self._last_root = None
        self._density = None         # steps per unit τ, learned from the calls before
        self._segment = None         # (start, bound) of the current segment
        self._cycle = None           # length of the last segment ended by a restart
        self.redone = 0              # calls done again (diagnostics)

    def start(self, tau0, z0, e, t_bound):
        self._e = float(e)
        self._args[_E] = self._q[_E] = self._e
        self._q[_LN_E] = ln_load_rate(self._e)
        z0 = np.array(z0, dtype=float)
        g0 = np.empty(4)
        compiled_roots(self._q, self._q[_LN_10ES], self._q[_LN_ES], self._q[_LN_E], z0, g0)
        carry_last_root(self._last_root, tau0, z0, g0, self._e, self.nd.quasi_static)
        self._free()
        self._T, self._Y, self._g = np.array([float(tau0)]), z0[None, :], g0
        self._queue = deque()
        self._t_bound = float(t_bound)
        self._failure = None
        # a segment that ended before its bound ended at an event's end (two-speed loading):
        # the next one is expected to be about as long
        prev = self._segment
        if prev is not None and prev[0] < tau0 < prev[1]:
            self._cycle = tau0 - prev[0]
        self._segment = (float(tau0), float(t_bound))
        self._span = (math.inf if not self._two_speed else
                      FIRST_SPAN * self.nd.grid_tau if self._cycle is None else
                      1.25 * self._cycle)

    def finish(self):
        self._free()

    def _free(self):
        if self._result is not None:
            self._result.free()
            self._result = None

    def advance(self, t_out):
        t_out = float(t_out)
        while True:
            if self._queue and self._queue[0][0] <= t_out:
                t, z, kinds, signs = self._queue.popleft()
                self._last_root = (t, z, list(zip(kinds, signs)), self._e)
                return Advance(t, z, roots=kinds)
            if t_out <= self._T[-1]:
                return Advance(t_out, self._state_at(t_out))
            if self._failure is not None:
                return self._failure
            failure = self._chunk()
            if failure is not None:
                return failure

    def _state_at(self, t: float) -> np.ndarray:
        i = int(np.searchsorted(self._T, t))
        if i < len(self._T) and self._T[i] == t:
            return self._Y[i].copy()
        z = np.empty(3)
        _dense_into(self._call, self._result._ptr, t, z)
        return z

    def _chunk(self) -> Advance | None:
        """One nbsolve2_ivp call from the chunk's last step (span: module docstring); its
        crossings queued; a failure kept for when the chunk is used up (or returned if nothing
        was reached)."""
        a = self.algorithm
        t0, z0 = float(self._T[-1]), self._Y[-1].copy()
        while True:
            left = a.max_steps - self.stats.steps
            if left <= 0:
                return Advance(t0, z0, retcode=ReturnCode.MAX_STEPS,
                               message=f"step budget of {a.max_steps} used up at "
                                       f"tau = {t0:.9g}")
            if self.budget is not None and self.budget.exceeded():
                return Advance(t0, z0, retcode=ReturnCode.WALL_TIME,
                               message=f"wall-time budget of {self.budget.wall_s} s used up at "
                                       f"t = {t0 * self.nd.time_scale:.6g} s")
            span = (self._span if self._density is None else
                    min(self._span, 0.5 * CHUNK_STEPS / self._density))
            # an explicit method's first call is expected to run out (millions of steps here)
            cap = 2 * CHUNK_STEPS if self._density or a.stiff else FIRST_CAP
            t1 = self._t_bound if t0 + span >= self._t_bound else t0 + span
            self._free()
            r = self._result = _call(self._rhs, t0, t1, z0, a.method, self._args, a.rtol, a.atol,
                                     min(cap, left))
            status, taken = int(r.status), int(r.steps_taken)
            # the rhs cfunc counts into _counters over the whole solve; steps are per call
            self.stats = Stats(nfev=int(self._counters[_NFEV]), njev=int(self._counters[_NJEV]),
                               steps=self.stats.steps + taken)
            T = np.array(r.t)
            if taken > 0 and T[-1] > t0:
                self._density = max(taken / (T[-1] - t0), 1e-300)
            if status != _MAX_STEPS_USER:
                self._span = 2.0 * (t1 - t0)
                break
            # CyRK builds no dense output for a call that ran out of steps: the chunk is done
            # again over a shorter span (budget: the steps it took count)
            self.redone += 1
            if taken >= left:
                return Advance(float(T[-1]), np.array(r.y)[:, -1].copy(),
                               retcode=ReturnCode.MAX_STEPS,
                               message=f"step budget of {a.max_steps} used up at "
                                       f"tau = {T[-1]:.9g}")
        Y = np.ascontiguousarray(np.array(r.y).T)
        if len(T) == 0 or T[0] != t0:
            T, Y = np.concatenate(([t0], T)), np.concatenate((z0[None, :], Y))
        if status != _SUCCESS or not np.all(np.isfinite(Y[-1])):
            code = (ReturnCode.STEP_UNDERFLOW if status == _STEP_SPACING else
                    ReturnCode.NON_FINITE if status == _SUCCESS else ReturnCode.FAILURE)
            self._failure = Advance(float(T[-1]), Y[-1].copy(), retcode=code,
                                    message=f"CyRK {a.method} stopped at tau = {T[-1]:.9g} "
                                            f"with status {status}: {r.message}")
            finite = np.all(np.isfinite(Y), axis=1)
            n = len(T) if finite.all() else max(1, int(np.argmin(finite)))
            T, Y = T[:n], Y[:n]
            if n == 1:
                return self._failure
        R = _step_crossings(self._call, r._ptr, self._q, T, Y, self._g)
        self._T, self._Y = T, Y
        queue_crossings(self._queue, ((r[0], r[1], r[2], r[3:6].copy()) for r in R))
        return None


def _one_call(algorithm: _CyRK, problem, nd, e: float, output, budget):
    """The whole run, under the loading E = ``e`` throughout, in one compiled call
    (:func:`_whole_run`, module docstring): a RawRun; where the call stopped short (a failure,
    or the steps of one call used up), its counters and the steps it took per unit τ, for the
    segment path that then runs it from the start."""
    call, rhs = _library()
    counters = np.zeros(6)
    args = np.append(form_vector(nd, e), float(counters.ctypes.data))
    if int(args[_COUNTERS]) != counters.ctypes.data:   # above 2**53
        raise MemoryError("the counters' address does not fit a double exactly")
    q = _event_vector(nd, e)
    taus, times, unasked = _saves(problem, nd, output)
    z0 = to_ode_state(nd.law_code, nd.beta, nd.x0)
    rec, saved = new_recorder(nd.x0[0]), np.empty((len(taus), 3))
    status, taken, ev, t_last, end = _whole_run(
        rhs, call, algorithm.method, nd.tau_end, z0, args, q, algorithm.rtol,
        algorithm.atol, 2 * CHUNK_STEPS, rec, np.empty((16, 8)), taus, saved)
    stats = Stats(nfev=int(counters[_NFEV]), njev=int(counters[_NJEV]), steps=int(taken))
    if status != _SUCCESS or t_last != nd.tau_end or not np.all(np.isfinite(end)):
        return stats, (max(taken / t_last, 1e-300) if taken > 0 and t_last > 0.0 else None)
    retcode, message = ReturnCode.SUCCESS, ""
    if budget is not None and budget.exceeded():
        retcode = ReturnCode.WALL_TIME
        message = (f"wall-time budget of {budget.wall_s} s used up: CyRK's one call over the "
                   "run took longer")
    states = ([] if unasked else [z0]) + list(saved)
    if len(times) > len(states):                # the end, after the save grid's last point
        states.append(end)
    h, eta, psi = from_ode_state(nd.law_code, nd.beta, np.array(states))
    return RawRun(t=np.array(times), y=np.column_stack(problem.dimensional_state(h, eta, psi)),
                  events=events_table(ev, problem, nd), stats=stats, retcode=retcode,
                  message=message, meta={"one_call": True})


def _saves(problem, nd, output):
    """Where the segment driver saves on a run of one loading segment that reaches its end
    (:func:`integrators.core.segments.run_segments`, followed step by step): the τ of each save
    after the start, all ≤ τ_end; the times of the saved points in s (the start's, unless not
    asked for; then one for each τ, then the end's if the driver appends it); whether the start
    was not asked for."""
    grid, grid_s, unasked = save_grid(problem, nd, output)
    tiny, ts, tau_end = 1e-12 * nd.tau_end, nd.time_scale, nd.tau_end
    taus, times, i, tau = [], [0.0], 0 if unasked else 1, 0.0
    while True:
        tau = min(grid[i], tau_end)
        if tau >= grid[i] - tiny:
            taus.append(tau)
            times.append(grid_s[i] if grid_s is not None and tau <= grid[i] + tiny
                         else tau * ts)
            while grid[i] <= tau + tiny:
                i += 1
        if tau >= tau_end - tiny:
            break
    if times[-1] < tau * ts and grid_s is None:
        times.append(tau * ts)
    return np.array(taus), (times[1:] if unasked else times), unasked


@njit(cache=True)
def _dense_into(call, result, t, z):
    """The dense output at t into z (for save points)."""
    _dense(call, result, t, z.ctypes.data)
