"""The compiled engine of the project's own adaptive methods: one solve, one numba call.

A method contributes four compiled functions and a few constants (:doc:`docs/own-methods.md`
says how to add one); the engine owns everything else, once:

* ``prepare(p, z0, f0, ws) -> int``: work done once per step at its start, reused by the
  retries of a rejected attempt (a Jacobian, say); returns the Jacobians it evaluated;
* ``attempt(p, hs, ws, z0, f0, z1, f1, D) -> errmax``: one trial step of size hs from
  (z0, f0 = f(z0)): the solution into z1, the error divided by its scale (≤ 1 accepts; inf when
  the trial failed), and either f1 = f(z1) (``fsal`` methods, whose error estimate needs it) or
  nothing (the engine evaluates f1 once the error test passes), and the coefficients D of its own
  dense output (``hermite`` False; else the engine builds the cubic Hermite interpolant);
* a controller, ``reject(p, errmax, hs) -> hs`` and ``accept(st, p, errmax, hs) -> h`` (those of
  this module: :func:`nr_reject`/:func:`nr_accept`, :func:`rodas_reject`/:func:`rodas_accept`,
  :func:`pred_reject`/:func:`pred_accept`);
* ``workspace()``: its scratch arrays, made once per solve by Python and passed in (the
  kernel is compiled without reference counting, :data:`NO_NRT`, and allocates nothing).

Dense output, one form for every method: z(τ0 + x h) = (1 − x) z0 + x (z1 + (1 − x)(D1 + x (D2 +
x D3))); the cubic Hermite interpolant of (z, f) at both ends is D1 = h f0 − Δz,
D2 = Δz − h f1 − D1, D3 = 0.

:func:`run` is the whole solve: steps (each shortened to land on the end of its loading segment,
never on a save point), the event scan on the dense output after each step, the events table, the
two-speed loading switch and its restarts, the save grid filled from the dense output, the step
and wall-time budgets and the counters. It returns to Python only when done, when it has taken
``n_max`` accepted steps (a progress bar, Ctrl-C), or to have its events table enlarged. All its
state is in arrays (layouts below), so a call resumes where the last one stopped.

Events: the four root functions of :mod:`integrators.core.events`, evaluated after each accepted
step; on a sign change in a direction that counts, the crossings are placed on the dense output
by bisection to the last bit, earliest first; a crossing in a direction that does not count only
moves the cursor. The recorder's extremes of h are read at the roots, the segment ends and every
accepted step's end, never at a save point (:mod:`integrators.core.events`), so the events table
does not depend on the save grid, to the bit. A restart at a root keeps the root's sign after
the crossing, or the first step would find the same crossing again. Methods at their stability
limit in the stick phase (the explicit CashKarp45, the exponential Rosenbrock methods' undamped
jitter) set ``stick_peaks`` False: a PEAK crossing at w ≤ E_slow is not an event's peak (an
event starts at w > 10 E_slow and ends at w ≤ E_slow) and is not reported.

The arrest (a deep lock): with mass, w u' = L(u) = C h − D (u + β s) − G w. When an event ends
with friction far above the spring force (b ≫ a, a small, a stiff or light slider), w falls
linearly to nearly zero and u = ln w plunges to the rest point ue of L (ue ≈ −60 for W2 at
b = 0.05) in a time ≈ w/|L|, which shrinks below the resolution of τ (one ulp) as w falls:
every step-size control then underflows (the peers too: CVODE, Radau, BDF). No linearised step
can jump the plunge either: ∂u'/∂u = −(D + L)/w is large and *positive* while u − ue > 1, so a
Rosenbrock stage moves u the wrong way. The engine takes the plunge in its limit instead
(:func:`_arrest`) when a step underflows, or FLOOR_STEPS steps in a row make no progress (each
below FLOOR_REL·τ), with mass and u more than ARREST_MIN_DROP above ue: τ advanced by a bound
T of the plunge's duration, h and s by T times their rates at the rest point, u set to the rest
point there, and that step accepted only if its error (the rates' variation over T) passes the
error test; then the controller restarts (nfev: 3 per arrest). A method that still cannot
advance (an explicit one, whose stability limit w/D after the lock is ~1e−30 in τ) stops with
UNDERFLOW. In the lock u' = L/w is rounding over w (~1e17 for w ~ 1e−27), so a step proposed
below the resolution of τ is tried at it, and the cubic Hermite dense output falls back to the
chord for a component whose slopes would bulge it off by more than its size (:func:`hermite`);
that rounding also makes PEAK cross back and forth there (``Solution.meta["roots"]["peak"]``
counts them; the events recorder reads a peak only within an event).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from integrators.core.clock import monotonic
from integrators.core.cycles import settled
from integrators.core.events import (AT_ROOT, END, H_EXTREMUM, PEAK, REC_SIZE, carry_signs,
                                     compiled_roots, new_recorder, observe, record, sign_change)
from integrators.core.events import N_EVENTS as _REC_N
from problems.formulations import (N_Q, Q_BETA, Q_C, Q_D, Q_E, Q_G, Q_LAW, Q_QS, ode_jacobian,
                                   ode_rhs, peak_function)
from problems.loading import H_TAU_FAST, LN_E_HOLD, load_segment

__all__ = ["run", "scratch", "NO_NRT", "fixed_steps", "rhs", "jacobian", "hermite", "new_state",
           "P", "ST", "ZROW", "DONE", "CHUNK", "GROW", "NONFINITE", "UNDERFLOW", "MAX_STEPS",
           "WALL_TIME", "SETTLED", "prepare_jacobian", "prepare_nothing", "nr_reject", "nr_accept",
           "rodas_reject", "rodas_accept", "pred_reject", "pred_accept", "no_sense"]

# --- layouts -------------------------------------------------------------------------------
#: st: the last step [TAU_OLD, TAU], its proposed successor H, the CURSOR ≤ TAU up to which
#: roots and saves are done, T_RET the time of a root found; counters; the controller's memory
#: (h and error of the last accepted step, accepted steps since the start, last attempt
#: rejected); the driver: the loading segment (start, load there, end, end of the fast loading),
#: the next save point, the events recorder, the last root (for a restart there), the point
#: handed on last (a failure's final state), a restart pending.
ST = dict(TAU=0, TAU_OLD=1, H=2, CURSOR=3, T_RET=4, STEPS=5, REJECTED=6, NFEV=7, NJEV=8,
          HACC=9, ERRACC=10, NACC=11, REJECT=12, TAU0=13, LOAD0=14, T_BOUND=15, FAST_UNTIL=16,
          NEXT_SAVE=17, REC=18, LR_TAU=27, LR_E=28, LR_VALID=29, LAST_T=30, NEED_START=31,
          STARTS=32, ROOTS=33, ARRESTS=37, FLOOR=38)
(TAU, TAU_OLD, H, CURSOR, T_RET, STEPS, REJECTED, NFEV, NJEV, HACC, ERRACC, NACC, REJECT, TAU0,
 LOAD0, T_BOUND, FAST_UNTIL, NEXT_SAVE) = range(18)
REC = 18                        # the events recorder's state (integrators.core.events), REC_SIZE
(LR_TAU, LR_E, LR_VALID, LAST_T, NEED_START, STARTS,
 ROOTS) = range(REC + REC_SIZE, REC + REC_SIZE + 7)
ARRESTS = ROOTS + 4
FLOOR = ARRESTS + 1             # accepted steps in a row at the resolution of τ
N_ST = FLOOR + 1
#: rows of Z: z and f at TAU, z and f at TAU_OLD, the dense output's D1–D3, the state at T_RET,
#: the state at the last root, the state handed on last
ZROW = dict(Z=0, F=1, ZO=2, FO=3, D1=4, D2=5, D3=6, ZR=7, LRZ=8, ZC=9)
_Z, _F, _ZO, _FO, _D1, _D2, _D3, _ZR, _LRZ, _ZC = range(10)
N_Z = 10
#: p: the problem vector q of :mod:`problems.formulations` (its E is the current segment's), the
#: tolerances, the root functions' thresholds ln(10 E_slow), ln E_slow, ln E; the run (τ_end,
#: two-speed flag, step budget, wall deadline); the method (exponent of the initial-step guess,
#: controller order q, stick_peaks, fsal, hermite, f evaluations per attempt, and those of the
#: last attempt beyond them); SETTLE, the relative tolerance of a settled cycle (0: run to
#: τ_end; :func:`integrators.core.cycles.settled`); from N_P on, the load-point history
#: (:func:`problems.loading.history_vector`)
P = dict(LAW=Q_LAW, BETA=Q_BETA, C=Q_C, D=Q_D, E=Q_E, RTOL=N_Q, ATOL=N_Q + 1,
         LN_10E_SLOW=N_Q + 2, LN_E_SLOW=N_Q + 3, LN_E=N_Q + 4, TAU_END=N_Q + 5,
         TWO_SPEED=N_Q + 6, MAX_STEPS=N_Q + 7, DEADLINE=N_Q + 8, INIT_EXPONENT=N_Q + 9,
         Q=N_Q + 10, STICK_PEAKS=N_Q + 11, FSAL=N_Q + 12, HERMITE=N_Q + 13, STAGES=N_Q + 14,
         MORE_F=N_Q + 15, SETTLE=N_Q + 16)
(_RTOL, _ATOL, _LN_10ES, _LN_ES, _LN_E, _TAU_END, _TWO_SPEED, _MAX_STEPS, _DEADLINE,
 _INIT_EXPONENT, _Q, _STICK_PEAKS, _FSAL, _HERMITE, _STAGES, _MORE_F,
 _SETTLE) = range(N_Q, N_Q + 17)
_E = Q_E
N_P = N_Q + 17
#: where a method's ``attempt`` reads the tolerances; where one whose f evaluations per attempt
#: vary (Newton iterations) adds those beyond p[STAGES], which the engine counts and clears
P_RTOL, P_ATOL, P_MORE_F = _RTOL, _ATOL, _MORE_F

#: what :func:`run` returns; SETTLED: stopped at the end of an event, its cycle settled
#: (p[SETTLE] > 0), the state there handed on (st[LAST_T], Z[ZC]) and the save points up to it
#: saved
DONE, CHUNK, GROW, NONFINITE, UNDERFLOW, MAX_STEPS, WALL_TIME, SETTLED = range(8)
#: the settled test's longest period and repeats (:mod:`integrators.core.cycles`' defaults)
SETTLE_MAX_PERIOD, SETTLE_REPEATS = 4, 2
_OK = -1
#: crossings placed in one scan at most: each moves the cursor forward, so this only stops a
#: pathological step (a root function at zero to the bit) from scanning for ever
MAX_PASSES = 64
#: a step of at most FLOOR_REL·τ (~4000 units in the last place of τ) makes no progress: from τ
#: to 2τ would take 1e12 of them. After FLOOR_STEPS of them in a row the run is stuck (an
#: explicit method in a deep lock, whose stability limit w/D is ~1e−30, "advances" an ulp or so
#: a step; a plunge the steps follow down to the resolution of τ): treated as an underflow
FLOOR_REL, FLOOR_STEPS = 2.0 ** -40, 100
#: accepted steps between two readings of the clock (~20 ns each)
CLOCK_EVERY = 256
#: the numba options of a method's ``kernel``: no reference counting. With it, every array
#: argument of an inlined function and every view costs an atomic increment and decrement
#: (~50 a step, a third of a Rosenbrock23 attempt); without it the kernel may not allocate,
#: so the arrays come in as arguments (``ws``, :func:`scratch`).
NO_NRT = dict(cache=True, nogil=True, error_model="numpy", _nrt=False)

# the right-hand side and Jacobian (both inlined where compiled code calls them)
rhs, jacobian = ode_rhs, ode_jacobian


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def f_of(p, z, out):
    """f(z) into ``out`` under the current segment's loading."""
    rhs(p, z, out)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def roots(p, z, g):
    """The four root functions of :mod:`integrators.core.events` at z, into g."""
    compiled_roots(p, p[_LN_10ES], p[_LN_ES], p[_LN_E], z, g)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def prepare_jacobian(p, z0, f0, ws):
    """A ``prepare`` for linearly implicit methods: the exact Jacobian at the step's start into
    ws[0]."""
    jacobian(p, z0, ws[0])
    return 1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def prepare_nothing(p, z0, f0, ws):
    """A ``prepare`` for explicit methods."""
    return 0


# --- controllers -------------------------------------------------------------------------------
# Numerical Recipes §16.2 (rkqs), with p[Q] unused: shrink by errmax^(-1/4), grow by errmax^(-1/5)
_NR_SAFETY, _NR_PGROW, _NR_PSHRNK, _NR_ERRCON = 0.9, -0.2, -0.25, 1.89e-4


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def nr_reject(p, errmax, hs):
    """NR's rkqs after a failed trial: h·max(0.9 errmax^(−1/4), 1/10); h/10 for a non-finite one."""
    if np.isfinite(errmax):
        return max(_NR_SAFETY * hs * errmax ** _NR_PSHRNK, 0.1 * hs)
    return 0.1 * hs


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def nr_accept(st, p, errmax, hs):
    """NR's rkqs after an accepted step: 0.9 h errmax^(−1/5), at most 5 h."""
    return _NR_SAFETY * hs * errmax ** _NR_PGROW if errmax > _NR_ERRCON else 5.0 * hs


# Hairer's RODAS (rodas.f): fac = errmax^(1/q)/0.9 within [1/5, 6], Gustafsson's predictive
# controller on accepted steps, no increase right after a rejection
_SAFETY, _FAC_MIN, _FAC_MAX = 0.9, 1.0 / 6.0, 5.0      # h_new/h in [FAC_MIN, FAC_MAX]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def rodas_reject(p, errmax, hs):
    """RODAS after a failed trial: h/fac; h/10 for a non-finite trial."""
    if errmax == np.inf:
        return hs * 0.1
    return hs * (1.0 / min(1.0 / _FAC_MIN, max(1.0 / _FAC_MAX, errmax ** (1.0 / p[_Q]) / _SAFETY)))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def rodas_accept(st, p, errmax, hs):
    """RODAS after an accepted step, with Gustafsson's predictive controller (rodas.f, PRED)."""
    q = p[_Q]
    fac = min(1.0 / _FAC_MIN, max(1.0 / _FAC_MAX, errmax ** (1.0 / q) / _SAFETY))
    if st[NACC] >= 1:
        gus = st[HACC] / hs * (errmax * errmax / st[ERRACC]) ** (1.0 / q) / _SAFETY
        fac = max(fac, min(1.0 / _FAC_MIN, max(1.0 / _FAC_MAX, gus)))
    st[HACC], st[ERRACC], st[NACC] = hs, max(1e-2, errmax), st[NACC] + 1
    h_next = hs / fac
    if st[REJECT] != 0.0:
        h_next = min(h_next, hs)
    return h_next


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def pred_reject(p, errmax, hs):
    """After a failed trial: h·max(0.9 errmax^(−1/q), 1/10); h/10 for a non-finite trial."""
    if np.isfinite(errmax):
        return max(0.9 * hs * errmax ** (-1.0 / p[_Q]), 0.1 * hs)
    return 0.1 * hs


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def pred_accept(st, p, errmax, hs):
    """After an accepted step: the elementary 0.9 r (r = errmax^(−1/q)) within 5, or less if
    Gustafsson's predictive controller asks for less ((h/h_acc) 0.9 r²/r_acc within [1/5, 5],
    r_acc = max(1e−2, err_acc)^(−1/q) kept in ``st``: one power per step); not above h after a
    rejection."""
    expo = -1.0 / p[_Q]
    r = errmax ** expo if errmax > 0.0 else np.inf
    grow = min(5.0, 0.9 * r)
    if st[NACC] >= 1.0 and errmax > 0.0:
        grow = min(grow, max(0.2, min(5.0, hs / st[HACC] * 0.9 * r * r / st[ERRACC])))
    st[HACC], st[ERRACC] = hs, r if errmax >= 1e-2 else 0.01 ** expo
    st[NACC] += 1.0
    h_next = hs * grow
    if st[REJECT] != 0.0:
        h_next = min(h_next, hs)
    return h_next


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _copy(src, dst):
    """dst[:] = src, which the kernel (no reference counting) cannot write."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


# --- dense output, events ----------------------------------------------------------------------
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def hermite(hs, z0, f0, z1, f1, D):
    """The cubic Hermite interpolant of (z, f) at both ends of a step, in the engine's form;
    the chord for a component whose cubic would bulge off the chord by more than the larger of
    its end values and 1 (module docstring: a slope that is rounding, not a rate)."""
    for i in range(3):
        dz = z1[i] - z0[i]
        d1 = hs * f0[i] - dz
        d2 = dz - hs * f1[i] - d1
        # x (1 − x)(D1 + x D2) is at most (|D1| + |D2|)/4 off the chord
        if not 0.25 * (abs(d1) + abs(d2)) <= max(abs(z0[i]), abs(z1[i]), 1.0):
            d1 = d2 = 0.0
        D[0, i] = d1
        D[1, i] = d2
        D[2, i] = 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _dense(Z, x, out):
    """The dense output of the step [TAU_OLD, TAU] at the fraction x of it."""
    y = 1.0 - x
    for i in range(3):
        out[i] = y * Z[_ZO, i] + x * (Z[_Z, i] + y * (Z[_D1, i] + x * (Z[_D2, i]
                                                                      + x * Z[_D3, i])))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _dense_at(Z, i, x):
    """Component i of :func:`_dense` at x (the same operations)."""
    y = 1.0 - x
    return y * Z[_ZO, i] + x * (Z[_Z, i] + y * (Z[_D1, i] + x * (Z[_D2, i] + x * Z[_D3, i])))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _root_at(p, Z, k, x):
    """Root function k of :func:`roots` on the dense output at x, alone (the same value)."""
    if k == 0:
        return _dense_at(Z, 1, x) - p[_LN_10ES]
    if k == 1:
        return _dense_at(Z, 1, x) - p[_LN_ES]
    if k == 2:
        return _dense_at(Z, 1, x) - p[_LN_E]
    return peak_function(p, (_dense_at(Z, 0, x), _dense_at(Z, 1, x), _dense_at(Z, 2, x)))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bisect(p, Z, k, up, lo, hi):
    """Bisection of root function k on [lo, hi] to the last bit (lo on the side ``up`` says,
    a zero on the far side): the far end. Written as runs of steps to one side, each a loop
    whose exit is a branch (an if/else of lo = mid, hi = mid becomes a select, whose dependency
    chain the processor cannot speculate past)."""
    while True:
        while True:                     # a run of steps that move lo
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                return hi
            gm = _root_at(p, Z, k, mid)
            if not (gm != 0.0 and (gm > 0.0) == up):
                break
            lo = mid
        hi = mid
        while True:                     # a run of steps that move hi
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                return hi
            gm = _root_at(p, Z, k, mid)
            if gm != 0.0 and (gm > 0.0) == up:
                break
            hi = mid
        lo = mid


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _cursor_time(t0, dt, x, lo, hi):
    """The time of the fraction x of the step [t0, t0 + dt], within [lo, hi], rounded up so that
    (t − t0)/dt ≥ x: the cursor must sit on the far side of a crossing just placed at x, where
    the root function has the sign it is given (else the next pass finds the same crossing, and
    the one after it the same in reverse, for ever)."""
    t = min(max(t0 + x * dt, lo), hi)
    while t < hi and (t - t0) / dt < x:
        t = np.nextafter(t, np.inf)
    return t


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _crossed(G, g, dirs, stick_peaks):
    """Has a root function changed sign, in a direction that counts, between the cursor (G[0])
    and the new step end (g)?"""
    for k in range(4):
        sign = sign_change(G[0, k], g[k])
        if (sign != 0 and (dirs[k] == 0 or dirs[k] == sign)
                and (stick_peaks or k != PEAK or G[0, END] > 0.0 or g[END] > 0.0)):
            return True
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def _scan(st, p, Z, G, dirs, stick_peaks, t_end, w):
    """The earliest crossing that counts in (CURSOR, t_end] of the last step: True, with it at
    T_RET, Z[ZR], G[1]; else False, the cursor moved to t_end. A crossing in a direction that
    does not count only moves the cursor and its signs (G[0]). ``w``: 3 × 4 scratch."""
    t0, dt = st[TAU_OLD], st[TAU] - st[TAU_OLD]
    x_end = (t_end - t0) / dt
    zt, z_end, g_end, g_new, x_root = w[0, :3], w[1, :3], w[2], w[3], w[5]
    if t_end < st[TAU]:
        _dense(Z, x_end, z_end)
    else:
        _copy(Z[_Z], z_end)
    roots(p, z_end, g_end)
    passes = 0
    while True:
        x_cur = (st[CURSOR] - t0) / dt
        _dense(Z, x_cur, zt)
        roots(p, zt, g_new)
        for k in range(4):
            g0, g1, ga, lo, hi = G[0, k], g_end[k], g_new[k], x_cur, x_end
            if sign_change(g0, g1) == 0:
                hi = np.inf
            elif ga == 0.0 or (ga > 0.0 and g1 > 0.0) or (ga < 0.0 and g1 < 0.0):
                hi = x_cur            # the interpolant is past it already: at the cursor
            if lo < hi < np.inf:      # bisection to the last bit; hi keeps the far side's sign
                hi = _bisect(p, Z, k, ga > 0.0, lo, hi)
            x_root[k] = hi
        best = x_root[0]                  # x_root.min() (which allocates), NaN included
        for k in range(1, 4):
            if x_root[k] < best or x_root[k] != x_root[k]:
                best = x_root[k]
        if best == np.inf or passes > MAX_PASSES:
            carry_signs(G[0], g_end)
            st[CURSOR] = st[T_RET] = t_end
            _copy(z_end, Z[_ZR])
            _copy(g_end, G[0])
            return False
        passes += 1
        t_root = (st[CURSOR] if best == x_cur else t_end if best == x_end
                  else _cursor_time(t0, dt, best, st[CURSOR], t_end))
        if best == x_end:
            _copy(z_end, Z[_ZR])
        else:
            _dense(Z, best, Z[_ZR])
        roots(p, Z[_ZR], g_new)
        for k in range(4):
            G[1, k] = 0.0
        for k in range(4):
            if x_root[k] == best:
                sign = 1.0 if g_end[k] > G[0, k] else -1.0
                g_new[k] = sign * max(abs(g_new[k]), AT_ROOT)    # the sign after the crossing
                if ((dirs[k] == 0 or dirs[k] == sign)
                        and (stick_peaks or k != PEAK or g_new[END] > 0.0)):
                    G[1, k] = sign
        carry_signs(G[0], g_new)
        st[CURSOR] = t_root
        _copy(g_new, G[0])
        if G[1, 0] != 0.0 or G[1, 1] != 0.0 or G[1, 2] != 0.0 or G[1, 3] != 0.0:
            st[T_RET] = t_root
            return True


# --- start, step ---------------------------------------------------------------------------------
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _max_abs_ratio(a, b):
    """max_i |a_i| / b_i over 3 entries, NaN if any ratio is NaN (as ``np.max``)."""
    m = abs(a[0]) / b[0]
    for i in range(1, 3):
        r = abs(a[i]) / b[i]
        if r > m or r != r:
            m = r
        if m != m:
            break
    return m


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _initial_step(p, z, f, t_left, w):
    """Hairer's initial step from (z, f = f(z)) (Hairer, Nørsett & Wanner I, §II.4, on the
    scale of the error test, as scipy's ``select_initial_step``), at most ``t_left``; one f
    evaluation (``w``: 3 × 3 scratch)."""
    rtol, atol = p[_RTOL], p[_ATOL]
    trial, f1, scale = w[0], w[1], w[2]
    for i in range(3):
        scale[i] = atol + rtol * abs(z[i])
    d0, d1 = _max_abs_ratio(z, scale), _max_abs_ratio(f, scale)
    small = d0 if not d1 < d0 else d1                            # Python's min(d0, d1)
    h0 = 0.01 * d0 / d1 if small >= 1e-5 else 1e-6
    for i in range(3):
        trial[i] = z[i] + h0 * f[i]
    f_of(p, trial, f1)
    for i in range(3):
        f1[i] = f1[i] - f[i]
    big = _max_abs_ratio(f1, scale) / h0
    big = big if big > d1 else d1                                # Python's max(d1, ·): inf if
    if big > 1e-15:                                              # the trial overflowed
        h1 = (0.01 / big) ** p[_INIT_EXPONENT]
    else:
        h1 = 1e-3 * h0 if 1e-3 * h0 > 1e-6 else 1e-6
    h = 100.0 * h0
    second = h1 if h1 > 0.0 else 1e-3 * h0
    if second < h:
        h = second
    if t_left < h:
        h = t_left
    return h


@njit(cache=True, nogil=True, error_model="numpy")
def start(st, p, Z, G, tau0, z0, e, t_bound, w):
    """(Re)start at τ0 from z0 under the loading rate ``e`` (``w``: 3 × 3 scratch): f(z0),
    Hairer's initial step (:func:`_initial_step`), the root functions at τ0, the controller's
    memory cleared. At a root just reported the root's sign after its crossing is kept
    (H_EXTREMUM only if the loading is unchanged: u − ln E moves with E, and so does PEAK
    without mass)."""
    p[_E] = e
    p[_LN_E] = math.log(e) if e > 0.0 else LN_E_HOLD
    z, f = Z[_Z], Z[_F]
    for i in range(3):
        z[i] = z0[i]
    f_of(p, z, f)
    st[H] = _initial_step(p, z, f, t_bound - tau0, w)
    st[TAU] = st[TAU_OLD] = st[CURSOR] = tau0
    st[NFEV] += 2.0
    st[STARTS] += 1.0
    st[NACC] = st[REJECT] = 0.0
    st[T_BOUND] = t_bound
    roots(p, z, G[0])
    if st[LR_VALID] != 0.0 and st[LR_TAU] == tau0:
        same = True
        for i in range(3):
            same &= Z[_LRZ, i] == z[i]
        for k in range(4):
            sign = G[2, k]
            # H_EXTREMUM (u − ln E) moves with E, and without mass PEAK (K (E − w) − β s')
            moves = k == H_EXTREMUM or (k == PEAK and p[Q_QS] != 0.0)
            if (same and sign != 0.0 and (not moves or st[LR_E] == e)
                    and G[0, k] * sign <= 0.0):
                G[0, k] = sign * AT_ROOT


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _finite(a):
    ok = True
    for i in range(3):
        ok &= np.isfinite(a[i])
    return ok


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _step(prepare, attempt, reject, accept, st, p, Z, ws, z0, f0, z1, f1, D, t_land):
    """One accepted step of proposed size st[H] from (TAU, Z[Z], Z[F]), shortened to land on
    t_land; its start goes to Z[ZO], Z[FO], its dense output to Z[D1:D3]. Returns (_OK,
    UNDERFLOW or NONFINITE; the new τ; the next h; attempts). z0, f0, z1, f1: scratch rows,
    made once per solve (a view made per step costs an atomic reference count each way)."""
    tau, h = st[TAU], st[H]
    for i in range(3):
        z0[i], f0[i] = Z[_Z, i], Z[_F, i]
    st[NJEV] += prepare(p, z0, f0, ws)
    hs, last = (t_land - tau, True) if tau + h >= t_land else (h, False)
    if tau + hs == tau:
        # a proposal below the resolution of τ (Hairer's initial step where f is rounding over a
        # tiny w, module docstring) is tried at it: only a trial rejected there underflows
        hs = np.nextafter(tau, np.inf) - tau
    fsal, stages = p[_FSAL] != 0.0, p[_STAGES]
    attempts, errmax = 0, np.inf
    while True:
        if tau + hs == tau:
            return UNDERFLOW, tau, hs, attempts
        attempts += 1
        errmax = attempt(p, hs, ws, z0, f0, z1, f1, D)
        st[NFEV] += stages + p[_MORE_F]
        p[_MORE_F] = 0.0
        if errmax <= 1.0:                               # False for NaN
            if not fsal:                # f at the end: the next step's f0, the interpolant's slope
                f_of(p, z1, f1)
                st[NFEV] += 1.0
            if _finite(z1) and _finite(f1):
                break
            # an end state whose rates overflow (e^u after a loose tolerance's overshoot) is a
            # failed trial, not a result
            errmax = np.inf
        last = False
        st[REJECT] = 1.0
        hs = reject(p, errmax, hs)
    h_next = accept(st, p, errmax, hs)
    st[REJECT] = 0.0
    if last:
        h_next = max(h_next, h)     # a shortened step says nothing about h
    if p[_HERMITE] != 0.0:
        hermite(hs, z0, f0, z1, f1, D)
    for i in range(3):
        Z[_ZO, i], Z[_FO, i], Z[_Z, i], Z[_F, i] = z0[i], f0[i], z1[i], f1[i]
        for r in range(3):
            Z[_D1 + r, i] = D[r, i]
    return _OK, t_land if last else tau + hs, h_next, attempts


#: an arrest (:func:`_arrest`) is taken only from this far (in u = ln w) above the rest point
#: of the fast subsystem, a force excess of 4 A: its duration bound needs more than 2, and
#: nearer the rest point the linearised steps are damped and take the approach themselves
ARREST_MIN_DROP = 4.0
#: ln(2^52): the e-folds of the last unit of u's approach to its rest point, down to rounding
_LN_ULP = 36.05


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _rest_point(p, h, s):
    """The rest point of u at frozen (h, s): L(u) = C h − D (u + β s) − G e^u = 0 (w u' = L).
    L decreases with L' ≤ −D; with damping, Newton from the undamped root (where L ≤ 0, L
    concave) descends monotonically to it."""
    c, d, g, beta = p[Q_C], p[Q_D], p[Q_G], p[Q_BETA]
    ue = c * h / d - beta * s
    if g != 0.0:
        for _ in range(200):
            ge = g * math.exp(ue)
            nxt = ue + (c * h - d * (ue + beta * s) - ge) / (d + ge)
            if not nxt < ue:
                break
            ue = nxt
    return ue


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _arrest(st, p, Z, z0, f0, z1, f1, D, t_land):
    """The step that stops a slider with mass which the step control cannot resolve (the
    module docstring's *arrest*): from (τ, z0) to τ + T, T a bound of the fall of u to its
    rest point; then the controller restarts. Returns (τ + T, the next h), or (−1, 0) where it
    does not apply: no mass, a fall of less than ARREST_MIN_DROP, a T past the segment's end, a
    rest point outside the floating-point range, or an error test failed.
    z0, f0: the state at τ and f there; z1, f1, D: scratch, left as the step's end and its
    (linear) dense output."""
    tau = st[TAU]
    if p[Q_QS] != 0.0:
        return -1.0, 0.0
    h, u0, s = z0[0], z0[1], z0[2]
    ue = _rest_point(p, h, s)
    drop = u0 - ue
    if not (drop > ARREST_MIN_DROP and np.isfinite(ue)):
        return -1.0, 0.0
    # the fall's duration: T = ∫ e^u du / |L(u)| from ue (to rounding) to u0, |L| ≥ D (u − ue):
    # ∫ e^x/x over [1, Δ] ≤ (e^Δ/Δ + e^(Δ/2))/(1 − 2/Δ) (by parts), the last unit ≤ e·ln(2^52)
    d = p[Q_D]
    w0 = math.exp(u0)
    fall = (w0 / (d * drop) + w0 * math.exp(-0.5 * drop) / d) / (1.0 - 2.0 / drop)
    tau1 = tau + fall + math.e * _LN_ULP * math.exp(ue) / d
    if not tau1 > tau:
        tau1 = np.nextafter(tau, np.inf)
    if not tau1 <= t_land:
        return -1.0, 0.0
    span = tau1 - tau
    # h and s move on at their rates fe at the rest point (the aging law's healing, 1/Ψ, can
    # be ~600); u sits at the rest point of the new (h, s). Over the span the rates differ
    # from fe by terms in w ≤ w0 (h' = E − w, s' affine in w or, slip law, −w (u + s)): at
    # most |f(z0) − fe| + w0 Δ; and by the change of (h, s) itself: |f1 − fe|. Their sum
    # times the span is the step's error, tested as any step's.
    fe = D[0]
    z1[0], z1[1], z1[2] = h, ue, s
    f_of(p, z1, fe)
    z1[0], z1[2] = h + span * fe[0], s + span * fe[2]
    z1[1] = _rest_point(p, z1[0], z1[2])
    f_of(p, z1, f1)
    st[NFEV] += 2.0
    if not (_finite(z1) and _finite(f1) and _finite(fe)):
        return -1.0, 0.0
    rtol, atol = p[_RTOL], p[_ATOL]
    err = 0.0
    for i in (0, 2):
        drift = abs(f0[i] - fe[i]) + w0 * drop + abs(f1[i] - fe[i])
        r = span * drift / (atol + rtol * max(abs(z0[i]), abs(z1[i])))
        if not r <= err:
            err = r
    if not err <= 1.0:
        return -1.0, 0.0
    for i in range(3):
        Z[_ZO, i], Z[_FO, i], Z[_Z, i], Z[_F, i] = z0[i], f0[i], z1[i], f1[i]
        for r in range(3):
            Z[_D1 + r, i] = 0.0
    st[NACC] = st[REJECT] = st[FLOOR] = 0.0
    st[ARRESTS] += 1.0
    st[NFEV] += 1.0
    return tau1, _initial_step(p, z1, f1, t_land - tau1, D)


# --- the driver: saves, events, loading ---------------------------------------------------------
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _save_until(st, Z, grid, saved, t_hi, inclusive, zt):
    """Fill the save points of ``grid`` up to t_hi (or just before it) from the dense output of
    the last step. The events recorder never sees them (the save grid changes no measure):
    it observes the roots, the segment ends and the step ends."""
    k, n = int(st[NEXT_SAVE]), grid.shape[0]
    t0, dt = st[TAU_OLD], st[TAU] - st[TAU_OLD]
    while k < n and (grid[k] < t_hi or (inclusive and grid[k] == t_hi)):
        if grid[k] == st[TAU]:
            for i in range(3):
                saved[k, i] = Z[_Z, i]
        else:
            _dense(Z, (grid[k] - t0) / dt, zt)
            for i in range(3):
                saved[k, i] = zt[i]
        k += 1
    st[NEXT_SAVE] = k


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _hand_on(st, Z, tau, row):
    """The state at τ (row ``row`` of Z) is the one handed on (a restart's, a failure's)."""
    st[LAST_T] = tau
    for i in range(3):
        Z[_ZC, i] = Z[row, i]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def run(prepare, attempt, reject, accept, ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max,
        sense, sa):
    """The solve (module docstring), resumed from the state in ``st``, ``Z``, ``G`` and ``p``:
    at most ``n_max`` accepted steps. ``ws``: the method's workspace, ``sc``: the engine's
    (:func:`scratch`); ``grid``: the save times (τ), ``saved``: the states there; ``ev``: the
    events table. Returns DONE, CHUNK, GROW (``ev`` full), NONFINITE, UNDERFLOW, MAX_STEPS,
    WALL_TIME or SETTLED; the counters are in ``st``. ``sense(op, arg, st, p, Z, G, ws, grid, sa)`` is told
    of every step, root, save, segment end and restart (the ``SENSE_*`` codes), before the
    recorder sees them, so that forward sensitivities (:mod:`integrators.own.sensitivity`, in
    the arrays ``sa``) can follow the solve; :func:`no_sense` for a plain solve.

    The caller compiles it without numba's reference counting (``_nrt=False``, see
    :data:`NO_NRT`), so it allocates nothing: every array comes in as an argument."""
    z0, f0, z1, f1, D, scan_w, g, zt = sc
    z_now, g_cur = Z[_Z], G[0]
    tau_end, two_speed = p[_TAU_END], p[_TWO_SPEED] != 0.0
    hist = p[N_P:]
    stick_peaks = p[_STICK_PEAKS] != 0.0
    tiny = 1e-12 * tau_end
    rec = st[REC:REC + REC_SIZE]
    n = 0
    while True:
        if st[NEED_START] != 0.0:
            tau = st[LAST_T]
            if tau >= tau_end - tiny:
                # a restart within tiny of the end (a load switch there): the save points
                # left, the end's among them, take the state handed on
                k = int(st[NEXT_SAVE])
                while k < grid.shape[0] and grid[k] <= tau + tiny:
                    for i in range(3):
                        saved[k, i] = Z[_ZC, i]
                    k += 1
                k_first = st[NEXT_SAVE]
                st[NEXT_SAVE] = k
                sense(SENSE_SAVE_HANDED, k_first, st, p, Z, G, ws, grid, sa)
                return DONE
            e, t_bound = load_segment(hist, tau, st[FAST_UNTIL], tau_end, tiny)
            sense(SENSE_LOAD, tau, st, p, Z, G, ws, grid, sa)
            st[LOAD0] = st[LOAD0] + p[_E] * (tau - st[TAU0])     # the load at τ
            st[TAU0] = tau
            start(st, p, Z, G, tau, Z[_ZC], e, t_bound, D)
            sense(SENSE_RESTART, tau, st, p, Z, G, ws, grid, sa)
            st[NEED_START] = 0.0
            if not _finite(Z[_F]):
                return NONFINITE
        if st[CURSOR] < st[TAU]:
            if rec[_REC_N] >= ev.shape[0]:
                return GROW
            found = _scan(st, p, Z, G, dirs, stick_peaks, st[TAU], scan_w)
            t_ret = st[T_RET]
            k0 = st[NEXT_SAVE]
            _save_until(st, Z, grid, saved, t_ret, not found, zt)
            sense(SENSE_SAVE, k0, st, p, Z, G, ws, grid, sa)
            if found:
                sense(SENSE_ROOT, t_ret, st, p, Z, G, ws, grid, sa)
                z = Z[_ZR]
                load = st[LOAD0] + p[_E] * (t_ret - st[TAU0])
                ended = False
                for k in range(4):
                    if G[1, k] != 0.0:
                        st[ROOTS + k] += 1.0
                        ended = record(rec, ev, k, t_ret, z[0], z[1], load) or ended
                observe(rec, z[0])
                st[LR_TAU], st[LR_E], st[LR_VALID] = t_ret, p[_E], 1.0
                _copy(z, Z[_LRZ])
                _copy(G[1], G[2])
                _hand_on(st, Z, t_ret, _ZR)
                if ended and p[_SETTLE] > 0.0 and settled(ev, int(rec[_REC_N]), p[_SETTLE],
                                                          SETTLE_MAX_PERIOD, SETTLE_REPEATS):
                    _save_until(st, Z, grid, saved, t_ret, True, zt)
                    return SETTLED
                if ended and two_speed:
                    st[FAST_UNTIL] = t_ret + hist[H_TAU_FAST]
                    st[NEED_START] = 1.0
                continue
            sense(SENSE_STEP_END, st[TAU], st, p, Z, G, ws, grid, sa)
            observe(rec, Z[_Z, 0])              # the step's end, its roots done
            _hand_on(st, Z, st[TAU], _Z)
        if st[CURSOR] >= st[T_BOUND]:           # the end of the segment: restart or done
            sense(SENSE_SEGMENT_END, st[TAU], st, p, Z, G, ws, grid, sa)
            observe(rec, Z[_Z, 0])
            _hand_on(st, Z, st[TAU], _Z)
            st[NEED_START] = 1.0
            continue
        if st[STEPS] >= p[_MAX_STEPS]:
            return MAX_STEPS
        if n >= n_max:
            return CHUNK
        if n % CLOCK_EVERY == CLOCK_EVERY - 1 and monotonic() > p[_DEADLINE]:
            return WALL_TIME
        if st[FLOOR] >= FLOOR_STEPS:            # stuck at the resolution of τ: an underflow
            _copy(Z[_Z], z0)
            _copy(Z[_F], f0)
            status, tau, h, tried = UNDERFLOW, st[TAU], st[H], 0
        else:
            status, tau, h, tried = _step(prepare, attempt, reject, accept, st, p, Z, ws,
                                          z0, f0, z1, f1, D, st[T_BOUND])
        st[REJECTED] += tried - (1 if status != UNDERFLOW else 0)
        if status == UNDERFLOW:
            tau, h = _arrest(st, p, Z, z0, f0, z1, f1, D, st[T_BOUND])
            if tau < 0.0:
                return UNDERFLOW
            sense(SENSE_ARREST, tau, st, p, Z, G, ws, grid, sa)
        else:
            sense(SENSE_STEP, tau, st, p, Z, G, ws, grid, sa)
        n += 1
        st[STEPS] += 1
        if tau - st[TAU] <= FLOOR_REL * st[TAU]:
            st[FLOOR] += 1.0
        else:
            st[FLOOR] = 0.0
        st[TAU_OLD], st[TAU], st[H] = st[TAU], tau, h
        roots(p, z_now, g)
        if not _crossed(G, g, dirs, stick_peaks):   # else the scan at the top places them
            k0 = st[NEXT_SAVE]
            _save_until(st, Z, grid, saved, tau, True, zt)
            sense(SENSE_SAVE, k0, st, p, Z, G, ws, grid, sa)
            sense(SENSE_STEP_END, tau, st, p, Z, G, ws, grid, sa)
            observe(rec, z_now[0])              # the step's end (one comparison a step)
            carry_signs(g_cur, g)
            st[CURSOR] = tau
            _copy(g, g_cur)
            _hand_on(st, Z, tau, _Z)


#: what :func:`run` tells ``sense``: a step accepted (its start in Z[ZO], h in st[HACC]), an
#: arrest taken, the save points from ``arg`` on filled, the ones from ``arg`` on given the
#: state handed on, a root located at τ = ``arg`` (before the recorder sees it), a step's end
#: or a segment's end observed, the load at a restart about to move on, a restart made
(SENSE_STEP, SENSE_ARREST, SENSE_SAVE, SENSE_SAVE_HANDED, SENSE_ROOT, SENSE_STEP_END,
 SENSE_SEGMENT_END, SENSE_LOAD, SENSE_RESTART) = range(9)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def no_sense(op, arg, st, p, Z, G, ws, grid, sa):
    """The ``sense`` of a plain solve: nothing."""
    return None


@njit(cache=True, nogil=True)
def scratch():
    """The engine's scratch arrays for :func:`run`: z0, f0, z1, f1 (a step's ends), D (its dense
    output), the event scan's 6 × 4, the root functions, a state (compiled, so that a batch of
    solves can make them too)."""
    return (np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty((3, 3)),
            np.empty((6, 4)), np.empty(4), np.empty(3))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def fixed_steps(prepare, attempt, workspace, p, z0, hs, n):
    """``n`` steps of size ``hs`` from z0, each accepted, no error control (order studies):
    the end state. The same ``prepare`` and ``attempt`` as the adaptive runs."""
    ws = workspace()
    z, f, z1, f1, D = z0.copy(), np.empty(3), np.empty(3), np.empty(3), np.empty((3, 3))
    f_of(p, z, f)
    for _ in range(n):
        prepare(p, z, f, ws)
        attempt(p, hs, ws, z, f, z1, f1, D)
        if p[_FSAL] == 0.0:
            f_of(p, z1, f1)
        z[:] = z1
        f[:] = f1
    return z


def new_state(nd, rtol: float, atol: float, constants: dict, max_steps: int, deadline: float):
    """The arrays (st, p, Z, G) of a solve of the nondimensional problem ``nd`` at τ = 0;
    ``constants``: the method's INIT_EXPONENT, Q, STICK_PEAKS, FSAL, HERMITE, STAGES."""
    from problems.formulations import form_vector, to_ode_state
    from problems.loading import ln_load_rate
    q = form_vector(nd, nd.e_slow)
    st, Z, G = np.zeros(N_ST), np.zeros((N_Z, 3)), np.zeros((3, 4))
    p = np.zeros(N_P + len(nd.history))
    p[:N_Q] = q
    p[_RTOL], p[_ATOL] = rtol, atol
    p[_LN_10ES], p[_LN_ES] = math.log(10.0 * nd.e_slow), math.log(nd.e_slow)
    p[_LN_E] = ln_load_rate(nd.e_slow)
    p[_TAU_END], p[_TWO_SPEED] = nd.tau_end, float(nd.two_speed)
    p[_MAX_STEPS], p[_DEADLINE] = max_steps, deadline
    for key, value in constants.items():
        p[P[key]] = value
    p[N_P:] = nd.history
    st[REC:REC + REC_SIZE] = new_recorder(nd.x0[0])
    st[FAST_UNTIL] = -math.inf
    st[NEED_START] = 1.0
    Z[_ZC] = to_ode_state(nd.law_code, nd.beta, nd.x0)
    return st, p, Z, G
