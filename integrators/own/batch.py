"""Many solves of one own method in one compiled call, each summarised in compiled code.

An ensemble (:mod:`benchmarks.ensemble`) runs one method on many variants of a problem. For the
methods on the compiled engine, a batch of points is one numba call: a ``prange`` loop (the GIL
released, numba's threads) in which each point is a whole solve (:func:`integrators.own.engine.run`
through the method's ``kernel``, exactly as :func:`integrators.solve` calls it with
``max_points=2``) followed by its limit-cycle summary (:func:`integrators.core.cycles.find_cycle`,
the end state and the class). Python only builds the per-point inputs and reads the outputs.

Inputs, one row per point: ``P`` the engine's parameters (:data:`integrators.own.engine.P`; the
wall deadline is set when the point starts), ``Z0`` the ODE state at τ = 0, ``C`` the physics the
summary needs (:data:`C`). Output: ``R`` (:data:`R`): the engine's status and counters, the solve's
wall time, where it stopped, the events and the summary (with :func:`find_cycle`'s entries at
``R[:, R["FOUND"]:]``); ``CURVE`` (points × n × 4), with n > 1 for slip-weakening curves: τ and
the ODE state (h, u, s) at n times spread evenly over the last event of each point with a limit cycle (with a
margin ``C[MARGIN]`` > 0: n // MARGIN_SHARE of them before the event, as many after, spaced
quadratically out to the margin, the rest over the event; then the last event that ends two
margins before the run does, so that the run's end does not cut its margin short), from a
second solve of that point that takes the same steps (its dense output at those times; the
counters in ``R`` are both solves'), NaN for the others. n = 0: one solve per point.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from integrators.core import cycles
from integrators.core.clock import monotonic
from integrators.core.events import H0, H_MAX, IN_EVENT, N_EVENTS, REC_SIZE
from integrators.own import engine as E
from problems.formulations import SLIP_LAW
from problems.slider import TAU_END_MAX

__all__ = ["C", "N_C", "R", "N_R", "BATCH", "SERIAL", "run_batch", "run_serial", "fresh", "record",
           "CYCLE_RTOL", "CYCLE_MAX_PERIOD", "CYCLE_MIN_REPEATS", "EVENTS_START", "LAST_CYCLE"]

#: the numba options of a method's ``batch`` entry point, and of its single-threaded one
BATCH = dict(cache=True, nogil=True, parallel=True, error_model="numpy")
SERIAL = dict(cache=True, nogil=True, error_model="numpy")
#: C, per point: seconds per unit of τ, F0 (N), newtons per unit of h (k Lc), v0 (m/s), Lc (m),
#: Fn (N), a, b, vLs (m/s), t_end (s), the growth rate of steady sliding at the end's load speed
#: (1/s), the wall budget (s), the load point's speed at the end (m/s), radiation damping (N s/m),
#: the curve's margin before and after the event (units of τ; 0: the event alone)
C = dict(TS=0, F0=1, FORCE_H=2, V0=3, LC=4, FN=5, A=6, B=7, V_SLOW=8, T_END=9, GROWTH=10,
         BUDGET=11, V_END=12, DAMPING=13, MARGIN=14)
(_TS, _F0, _FORCE_H, _V0, _LC, _FN, _A, _B, _V_SLOW, _T_END, _GROWTH, _BUDGET, _V_END,
 _DAMPING, _MARGIN) = range(15)
N_C = 15
#: with a margin, this fraction of a curve's rows lies before the event and as many after it
MARGIN_SHARE = 6
#: R, per point: the engine's status, nfev, njev, accepted and rejected steps, (re)starts, the
#: solve's wall time (s), the time reached (s), events, class (index in CLASSIFICATIONS), the end
#: state's three offsets and the growth rate of steady sliding (C's), and find_cycle's output
R = dict(STATUS=0, NFEV=1, NJEV=2, STEPS=3, REJECTED=4, STARTS=5, WALL_S=6, T_STOP=7,
         N_EVENTS=8, CLASS=9, LOG_V=10, STATE_OFFSET=11, FORCE_OFFSET=12, GROWTH=13, FOUND=14)
(_STATUS, _NFEV, _NJEV, _STEPS, _REJECTED, _STARTS, _WALL_S, _T_STOP, _N_EVENTS, _CLASS, _LOG_V,
 _STATE_OFFSET, _FORCE_OFFSET, _R_GROWTH, _FOUND) = range(15)
N_R = _FOUND + cycles.N_F
#: the limit-cycle search of :func:`benchmarks.physics.metrics.summarize` (its defaults)
CYCLE_RTOL, CYCLE_MAX_PERIOD, CYCLE_MIN_REPEATS = 1e-3, 4, 2
#: the time since the last event in a cycle search's result (no event for this long: quiet)
_GAP = cycles.F["GAP"]
EVENTS_START = 64
_NO_LIMIT = 1 << 62
# the engine's layouts as plain ints (compiled code reads module-level ints as constants)
_DEADLINE, _TAU_END, _LAW, _BETA = (E.P[k] for k in ("DEADLINE", "TAU_END", "LAW", "BETA"))
_FAST_UNTIL, _NEED_START, _NEXT_SAVE, _ST_STARTS, _LAST_T = (
    E.ST[k] for k in ("FAST_UNTIL", "NEED_START", "NEXT_SAVE", "STARTS", "LAST_T"))
_ZC = E.ZROW["ZC"]
# the classes with a limit cycle are the first ones (their curves are kept)
LAST_CYCLE = len(cycles.CYCLES) - 1
assert cycles.CLASSIFICATIONS[:len(cycles.CYCLES)] == cycles.CYCLES


@njit(cache=True, nogil=True, error_model="numpy")
def _summarize(law_code, beta, c, ev, n_ev, z_end, t_end, r):
    """The limit-cycle summary into ``r`` of a run that reached its end ``t_end`` (s; where a
    settled run stopped, for one that did) in the state ``z_end``: the events in SI units
    (:func:`integrators.core.events.events_table`'s formulas), their metrics, the cycle search
    and the end state (:mod:`problems.slider`'s conversions), the class."""
    ts, f0, fh, lc = c[_TS], c[_F0], c[_FORCE_H], c[_LC]
    t0, t1 = np.empty(n_ev), np.empty(n_ev)
    s0, s1 = np.empty(n_ev), np.empty(n_ev)
    x = np.empty((n_ev, 4))
    for i in range(n_ev):
        t0[i], t1[i] = ev[i, 0] * ts, ev[i, 1] * ts
        s0[i], s1[i] = lc * ev[i, 6], lc * ev[i, 7]
        x[i, 0] = t0[i] - t0[i - 1] if i > 0 else np.nan
        x[i, 1] = ((f0 + fh * ev[i, 2]) - (f0 + fh * ev[i, 3])) / c[_FN]
        x[i, 2] = s1[i] - s0[i]
        x[i, 3] = c[_V0] * ev[i, 4]
    found = r[_FOUND:]
    cycles.find_cycle(t0, t1, s0, s1, x, t_end, CYCLE_RTOL, CYCLE_MAX_PERIOD,
                      CYCLE_MIN_REPEATS, c[_V_SLOW], found)
    h, u, s = z_end[0], z_end[1], z_end[2]
    psi = s if law_code == SLIP_LAW else math.exp(s)
    eta = u + beta * s
    v = c[_V0] * math.exp(eta - beta * (psi if law_code == SLIP_LAW else math.log(psi)))
    fs = f0 + fh * h
    theta = psi * (c[_B] * c[_FN]) if law_code == SLIP_LAW else psi * lc / c[_V0]
    log_v, state, force = cycles.end_offsets(law_code, c[_A], c[_B], lc, c[_V0], c[_FN], f0,
                                             c[_V_END], v, fs, theta, c[_DAMPING])
    r[_LOG_V], r[_STATE_OFFSET], r[_FORCE_OFFSET] = log_v, state, force
    r[_CLASS] = cycles.classify(found[0], found[1], c[_GROWTH], log_v, state, force,
                                found[_GAP], TAU_END_MAX * ts - t_end)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def fresh(z0, saved):
    """The engine's arrays (st, Z, G) and events table at the start of a solve from ``z0``,
    ``z0`` saved as the first save point, as :meth:`integrators.own.compiled.
    CompiledAlgorithm.run` makes them."""
    st, Z, G = np.zeros(E.N_ST), np.zeros((E.N_Z, 3)), np.zeros((3, 4))
    rec = E.REC
    for k in range(REC_SIZE):
        st[rec + k] = np.nan
    st[rec + IN_EVENT], st[rec + N_EVENTS] = 0.0, 0.0
    st[rec + H_MAX], st[rec + H0] = z0[0], z0[0]
    st[_FAST_UNTIL], st[_NEED_START] = -np.inf, 1.0
    for i in range(3):
        Z[_ZC, i] = z0[i]
        saved[0, i] = z0[i]
    st[_NEXT_SAVE] = 1.0
    return st, Z, G, np.empty((EVENTS_START, 8))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _run(kernel, workspace, p, z0, dirs, grid, saved):
    """One solve from ``z0`` with the save grid ``grid`` (τ) into ``saved``, as
    :meth:`integrators.own.compiled.CompiledAlgorithm.run` does it: ``(status, st, ev)``. A
    run that settled (:data:`integrators.own.engine.SETTLED`) leaves the state where it stopped
    in ``saved``'s last row."""
    st, Z, G, ev = fresh(z0, saved)
    ws = workspace()
    sc = E.scratch()
    while True:
        status = kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, _NO_LIMIT)
        if status == E.GROW:
            bigger = np.empty((2 * ev.shape[0], 8))
            bigger[:ev.shape[0]] = ev
            ev = bigger
        elif status != E.CHUNK:
            break
    if status == E.SETTLED:
        for i in range(3):
            saved[saved.shape[0] - 1, i] = Z[_ZC, i]
    return status, st, ev


@njit(cache=True, nogil=True, error_model="numpy")
def _curve_grid(tau_s: float, tau_e: float, tau_end: float, margin: float, n: int):
    """The second solve's save grid: 0, the n curve times, τ_end. Without a margin, n times
    evenly over [τ_s, τ_e]; with one, m = n // MARGIN_SHARE before τ_s and m after τ_e at
    quadratically growing distances up to the margin (held inside the run), and the other
    n − 2m evenly over the event."""
    fine = np.empty(n + 2)
    fine[0], fine[n + 1] = 0.0, tau_end
    m = n // MARGIN_SHARE if margin > 0.0 else 0
    before = min(margin, 0.5 * tau_s)
    after = min(margin, 0.5 * (tau_end - tau_e))
    inside = n - 2 * m
    for j in range(m):
        fine[j + 1] = tau_s - before * ((m - j) / m) ** 2
        fine[n - j] = tau_e + after * ((m - j) / m) ** 2
    for j in range(inside):
        fine[m + j + 1] = tau_s + (tau_e - tau_s) * j / (inside - 1)
    return fine


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def record(status, st, ev, p, c, saved, r) -> int:
    """A solve's status, counters and (if it reached its end, or settled) summary into ``r``;
    the number of events (``saved``: its states at τ = 0 and τ_end, or where it settled)."""
    rec = E.REC
    n_ev = int(st[rec + N_EVENTS])
    r[_STATUS], r[_NFEV], r[_NJEV] = status, st[E.NFEV], st[E.NJEV]
    r[_STEPS], r[_REJECTED], r[_STARTS] = st[E.STEPS], st[E.REJECTED], st[_ST_STARTS]
    r[_T_STOP], r[_N_EVENTS] = st[E.TAU] * c[_TS], n_ev
    for k in range(_CLASS, N_R):
        r[k] = np.nan
    r[_R_GROWTH] = c[_GROWTH]
    # DONE with the end not saved: a restart within 1e-12 τ_end of the end (the single solve's
    # Solution then stops short of t_end, and summarize calls it failed too)
    if status == E.DONE and st[_NEXT_SAVE] == 2.0:
        _summarize(int(p[_LAW]), p[_BETA], c, ev, n_ev, saved[1], c[_T_END], r)
    elif status == E.SETTLED:
        r[_T_STOP] = st[_LAST_T] * c[_TS]
        _summarize(int(p[_LAW]), p[_BETA], c, ev, n_ev, saved[1], r[_T_STOP], r)
    else:
        r[_CLASS] = cycles.FAILED
    return n_ev


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _one(kernel, workspace, p0, z0, c, dirs, r, curve):
    """One point: the solve as :meth:`integrators.own.compiled.CompiledAlgorithm.run` does it
    with the save grid (0, t_end), then its summary, into ``r``. With ``curve`` of n > 0 rows,
    a point with a limit cycle is solved a second time, the same steps (the save grid never
    changes them), saving its ODE state at n times spread evenly over its last event, start
    and end included (and, with a margin, before and after it: :func:`_curve_grid`): the rows
    of ``curve`` are (τ, h, u, s) there (NaN otherwise)."""
    start = monotonic()
    p = p0.copy()
    p[_DEADLINE] = start + c[_BUDGET]
    grid = np.array([0.0, p[_TAU_END]])
    saved = np.empty((2, 3))
    status, st, ev = _run(kernel, workspace, p, z0, dirs, grid, saved)
    n_ev = record(status, st, ev, p, c, saved, r)
    n = curve.shape[0]
    for j in range(n):
        for i in range(4):
            curve[j, i] = np.nan
    if n > 1 and n_ev > 0 and r[_CLASS] <= LAST_CYCLE:
        stop = st[_LAST_T] if status == E.SETTLED else p[_TAU_END]
        k = n_ev - 1             # the last event whose margin the run's end does not cut
        while c[_MARGIN] > 0.0 and k > 0 and ev[k, 1] + 2.0 * c[_MARGIN] > stop:
            k -= 1
        tau_s, tau_e = ev[k, 0], ev[k, 1]
        if 0.0 < tau_s < tau_e < p[_TAU_END]:
            fine = _curve_grid(tau_s, tau_e, p[_TAU_END], c[_MARGIN], n)
            kept = np.empty((n + 2, 3))
            p[_DEADLINE] = monotonic() + c[_BUDGET]      # the second solve's own budget
            again, st2, _ = _run(kernel, workspace, p, z0, dirs, fine, kept)
            # (a settled run settles again at the same event: the same steps)
            if ((again == E.DONE and st2[_NEXT_SAVE] == n + 2.0)
                    or (again == E.SETTLED and st2[_NEXT_SAVE] > n)):
                for j in range(n):
                    curve[j, 0] = fine[j + 1]
                    for i in range(3):
                        curve[j, i + 1] = kept[j + 1, i]
            r[_NFEV] += st2[E.NFEV]         # the counters are the work done: both passes
            r[_NJEV] += st2[E.NJEV]
            r[_STEPS] += st2[E.STEPS]
            r[_REJECTED] += st2[E.REJECTED]
    r[_WALL_S] = monotonic() - start


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def run_serial(kernel, workspace, P, Z0, C, dirs, R, CURVE):
    """:func:`run_batch` on the calling thread, in order: for a process of a pool or a Dask
    worker (one thread each already). No OpenMP region is started, so it is also safe in a
    process forked from one that ran :func:`run_batch` (GNU OpenMP aborts a forked child that
    starts a parallel region)."""
    for i in range(P.shape[0]):
        _one(kernel, workspace, P[i], Z0[i], C[i], dirs, R[i], CURVE[i])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def run_batch(kernel, workspace, P, Z0, C, dirs, R, order, CURVE):
    """Every point of the batch (rows of ``P``, ``Z0``, ``C``) into its row of ``R``, in
    parallel, taken in the order ``order`` (a permutation): the body of each method's compiled
    ``batch`` entry point. numba's threading layer here (OpenMP) gives each thread one
    contiguous block of the loop, whatever ``parallel_chunksize`` says; neighbouring points cost
    alike (a whole corner of a grid can take 30× the median), so a shuffled order balances the
    threads where the grid's order would leave one thread with most of the work."""
    for k in prange(P.shape[0]):
        i = order[k]
        _one(kernel, workspace, P[i], Z0[i], C[i], dirs, R[i], CURVE[i])
