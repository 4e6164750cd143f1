"""numbalsoda's LSODA (Adams/BDF switching) on the shared ODE form, with a compiled right-hand side.

numbalsoda 0.3.4 offers one function, ``lsoda(funcptr, u0, t_eval, data, rtol, atol, mxstep)``:
a C function pointer as right-hand side (so ``rhs="python"`` is refused), no root finding, no
dense output, no Jacobian argument and no statistics. What this adapter adds:

* one numba ``cfunc``, ``_rhs``, for every problem: it reads the law, β, C, D and E from the
  ``data`` array and counts nfev, step attempts (``steps``; ``rejected`` is unavailable, 0) and
  finite-difference Jacobians (``njev``) itself; it stops LSODA at the step budget or a safe
  block end by returning inf and cutting numbalsoda's output loop (``_cut``);
* events located to the integration tolerance: LSODA runs in blocks over a grid of ≥ 16 points
  per half period π/√C; a numba kernel finds the grid intervals with a sign change that counts
  (``_block_roots``), each is re-integrated over 128 sub-points and the crossing bisected to the
  last bit on the cubic Hermite interpolant (``_sub_roots``);
* a guard against LSODA's cold starts in the stick phase that never leave Adams.

numbalsoda is imported at the first solve (its import compiles its own driver, ~9 s). Why each
of these is done this way, and what was measured: docs/external-adapters.md.

Reference: Petzold (1983), SIAM J. Sci. Stat. Comput. 4, 136–148; Hindmarsh (1983), ODEPACK;
numbalsoda: N. Wogan, https://github.com/Nicholaswogan/numbalsoda (LSODA.cpp).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.metadata
import importlib.util
import math
from collections import deque
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import carray, cfunc, njit

from integrators.core.events import DIRECTIONS, END, PEAK, compiled_roots, sign_change
from integrators.core.registry import AdaptiveAlgorithm, register
from integrators.core.clock import monotonic
from integrators.core.crossings import carry_last_root, queue_crossings
from integrators.core.segments import Advance
from integrators.core.solution import ReturnCode, Stats
from problems.formulations import N_Q, Q_E, form_vector, ode_rhs
from problems.loading import ln_load_rate

__all__ = ["NumbaLSODA"]

# registration needs numbalsoda installed; it is imported at the first solve (_library)
if importlib.util.find_spec("numbalsoda") is None:
    raise ImportError("No module named 'numbalsoda'")
_VERSION = importlib.metadata.version("numbalsoda")

# The data array handed to the cfunc: the parameters of ode_rhs, the counters, and what decides
# when the cfunc stops LSODA (_KILL says why: 1 stuck start, 2 step budget, 3 end of block);
# after them the call's output times, which the wrapper reads from there too (see _cut).
# (the problem vector q of problems.formulations first)
(_NFEV, _ATTEMPTS, _T_LAST, _LIMIT,             # counters and the step budget
 _NJEV, _YB0, _YB1, _YB2,                       # Jacobians, and the state they perturb
 _GUARD_N, _GUARD_DT, _GUARD_COUNT, _GUARD_T,   # stuck-start guard...
 _GUARD_U, _U_STIFF,                            # ...below this ln w
 _BLOCK, _U_ONSET, _U_END, _T_ARM, _ARMED,      # block ends: entering an event...
 _TWO_SPEED, _IN_EVENT, _END_DT, _END_KILL_T,   # ...and after an event's end (two-speed)
 _DEADLINE,                                     # the wall budget's end (monotonic clock)
 _KILL, _KILL_T, _NT) = range(N_Q, N_Q + 27)
_DATA_LEN = N_Q + 27                 # then the output times of the call (_NT of them)
_E = Q_E
_STUCK, _BUDGET, _BLOCK_END, _WALL = 1.0, 2.0, 3.0, 4.0
_CLOCK_EVERY = 1024                  # step attempts between two readings of the clock
_KILL_VALUE = np.inf

_BLOCK_MAX = 65536                   # grid points per lsoda call at most (memory)
_POINTS_PER_HALF_PERIOD = 16
_N_SUB = 128                         # sub-points of an interval with a sign change
_MXSTEP = 1_000_000                  # LSODA's per-interval limit; the budget is the cfunc's
_GUARD_ATTEMPTS = 300
_GUARD_DU = 0.01
_FIRST_FRACTIONS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)


@njit(cache=True)
def _watch(t, u, data):
    """At each new step attempt (trial time t, trial ln w = u): should LSODA be stopped?"""
    if data[_ATTEMPTS] > data[_LIMIT]:
        return _BUDGET
    if data[_ATTEMPTS] % _CLOCK_EVERY == 0.0 and monotonic() > data[_DEADLINE]:
        return _WALL
    if data[_GUARD_N] > 0.0:
        data[_GUARD_COUNT] += 1.0
        if data[_GUARD_COUNT] >= data[_GUARD_N]:
            # stuck: tiny steps in a stiff state where nothing happens (a fast transient
            # legitimately takes many steps, but it moves)
            if (t - data[_GUARD_T] < data[_GUARD_DT] and u < data[_U_STIFF]
                    and abs(u - data[_GUARD_U]) < _GUARD_DU):
                return _STUCK
            data[_GUARD_COUNT] = 0.0
            data[_GUARD_T] = t
            data[_GUARD_U] = u
    if data[_BLOCK] > 0.0:
        if t >= data[_T_ARM]:
            if u < data[_U_ONSET]:
                data[_ARMED] = 1.0
            elif data[_ARMED] > 0.0:
                return _BLOCK_END
        if data[_TWO_SPEED] > 0.0:
            if u > data[_U_ONSET]:
                data[_IN_EVENT] = 1.0
            elif data[_IN_EVENT] > 0.0 and u < data[_U_END] and data[_END_KILL_T] == np.inf:
                data[_END_KILL_T] = t + data[_END_DT]
            if t > data[_END_KILL_T]:
                return _BLOCK_END
    return 0.0


@njit(cache=True)
def _cut(buf, t):
    """Make numbalsoda's wrapper return soon after a stop at the trial time t (LSODA itself
    does not reliably fail on the cfunc's inf: module docstring). The wrapper returns at the
    first output time below the one before; LSODA is integrating towards an output time at most
    the first one at or after t (the step started past the one before), so the one after that is
    set to −inf. The times are _run's copy in the data array, the caller's are untouched."""
    nt = int(buf[_NT])
    lo, hi = 0, nt                      # first index with time ≥ t
    while lo < hi:
        mid = (lo + hi) // 2
        if buf[_DATA_LEN + mid] < t:
            lo = mid + 1
        else:
            hi = mid
    if lo + 1 < nt:
        buf[_DATA_LEN + lo + 1] = -np.inf


@njit(cache=True)
def _rebase(z, data):
    data[_YB0] = z[0]
    data[_YB1] = z[1]
    data[_YB2] = z[2]


# --- event kernels: root functions on a whole block, bracketing, Hermite bisection -----------
# q: the problem vector, then ln 10 E_slow, ln E_slow, ln E: the levels of events.root_functions
# (same operations, so the same values to the bit)
_LN_10ES, _LN_ES, _LN_E = N_Q, N_Q + 1, N_Q + 2
_DIRS = np.array(DIRECTIONS, dtype=np.float64)


@njit(cache=True, nogil=True, error_model="numpy")
def _roots(q, z, g):
    """events.root_functions at z, into g."""
    compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], z, g)


@njit(cache=True, nogil=True, error_model="numpy")
def _counts(k, a, b, end_a, end_b):
    """Whether g_k crosses zero from a to b in a direction that counts (the convention of
    events.sign_change); a PEAK crossing only where w > E_slow at an end
    of the interval (end_a or end_b > 0: the stick-phase jitter of C h − D η is not a peak)."""
    sign = sign_change(a, b)
    return sign != 0 and (_DIRS[k] == 0.0 or _DIRS[k] == sign) and (k != PEAK or end_a > 0.0 or end_b > 0.0)


@njit(cache=True, nogil=True, error_model="numpy")
def _block_roots(q, Y, n, g_first, G, cross):
    """Root functions at the rows 1..n−1 of a block (row 0: ``g_first``, signs carried over a
    restart) into G; the intervals (i, i+1) with a crossing that counts into ``cross``.
    Returns how many."""
    G[0] = g_first
    m = 0
    for i in range(1, n):
        _roots(q, Y[i], G[i])
        for k in range(4):
            if _counts(k, G[i - 1, k], G[i, k], G[i - 1, END], G[i, END]):
                cross[m] = i - 1
                m += 1
                break
    return m


@njit(cache=True, nogil=True, error_model="numpy")
def _hermite(za, fa, zb, fb, x, dt, out):
    x2, x3 = x * x, x * x * x
    a, b, c, d = 2 * x3 - 3 * x2 + 1, (x3 - 2 * x2 + x) * dt, 3 * x2 - 2 * x3, (x3 - x2) * dt
    for i in range(3):
        out[i] = a * za[i] + b * fa[i] + c * zb[i] + d * fb[i]


@njit(cache=True, nogil=True, error_model="numpy")
def _sub_roots(q, ts, Z, g_a, g_b, R):
    """The crossings that count between the sub-points (ts, Z) of one grid interval, each
    placed on the cubic Hermite interpolant of its sub-interval (z and f = dz/dτ at both ends;
    the root functions are linear in z) by bisection to the last bit; the far end keeps the
    sign after the crossing. The interval's end values of g are ``g_a``, ``g_b`` (signs carried
    over a restart). Rows of R: (τ, kind, sign, z0, z1, z2). Returns (roots, rhs calls)."""
    n = ts.shape[0]
    g0, g1, gt = g_a.copy(), np.empty(4), np.empty(4)
    fa, fb, zt = np.empty(3), np.empty(3), np.empty(3)
    m, nfev = 0, 0
    for j in range(n - 1):
        if j == n - 2:
            g1[:] = g_b
        else:
            _roots(q, Z[j + 1], g1)
        have_f = False
        for k in range(4):
            if not _counts(k, g0[k], g1[k], g0[END], g1[END]):
                continue
            dt = ts[j + 1] - ts[j]
            if not have_f:
                ode_rhs(q, Z[j], fa)
                ode_rhs(q, Z[j + 1], fb)
                nfev += 2
                have_f = True
            left_pos = g0[k] > 0.0
            lo, hi = 0.0, 1.0
            while True:
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                _hermite(Z[j], fa, Z[j + 1], fb, mid, dt, zt)
                _roots(q, zt, gt)
                if gt[k] != 0.0 and (gt[k] > 0.0) == left_pos:
                    lo = mid
                else:
                    hi = mid
            if hi == 1.0:
                zt[:] = Z[j + 1]
            else:
                _hermite(Z[j], fa, Z[j + 1], fb, hi, dt, zt)
            _roots(q, zt, gt)
            if k == PEAK and not gt[END] > 0.0:
                continue                         # at the root w ≤ E_slow: not a peak
            R[m, 0] = ts[j + 1] if hi == 1.0 else ts[j] + hi * dt
            R[m, 1] = k
            R[m, 2] = 1.0 if g1[k] > g0[k] else -1.0
            R[m, 3:6] = zt
            m += 1
        g0[:] = g1
    return m, nfev


@njit(cache=True, nogil=True, error_model="numpy")
def _reached(usol, t_eval, kill_t):
    """How many leading rows of the output buffer (of len(t_eval) rows) LSODA reached before
    it failed or the cfunc stopped it: the wrapper writes none after a failure, and the
    buffer is NaN where it did not write; rows at or after the kill time are not trusted."""
    for i in range(1, t_eval.shape[0]):
        if not (np.isfinite(usol[i, 0]) and np.isfinite(usol[i, 1]) and np.isfinite(usol[i, 2])
                and t_eval[i] < kill_t):
            return i
    return t_eval.shape[0]


@njit(cache=True, nogil=True, error_model="numpy")
def _reset(usol):
    """NaN again in the leading rows the last call wrote (they are contiguous, and once LSODA's
    state is NaN it stays NaN): the buffer is reset at the cost of what was used, not of its
    length."""
    for i in range(usol.shape[0]):
        if np.isnan(usol[i, 0]) and np.isnan(usol[i, 1]) and np.isnan(usol[i, 2]):
            return
        usol[i, 0] = usol[i, 1] = usol[i, 2] = np.nan


@njit(cache=True, nogil=True, error_model="numpy")
def _grid(start, t_req, dg, j0, n_max, match, t_bound, out):
    """A block's output times into out: start, then t_req + dg·j for j = j0, j0+1, … strictly
    between start and t_bound (by more than ``match``), then t_bound if the segment ends within
    n_max points. Returns how many."""
    out[0] = start
    n = 1
    for i in range(n_max):
        t = t_req + dg * float(j0 + i)
        if start + match < t < t_bound - match:
            out[n] = t
            n += 1
    if n - 1 < n_max:
        out[n] = t_bound
        n += 1
    return n


def _rhs(t, u, du, p):
    """The right-hand side handed to LSODA, compiled as a cfunc with ``lsoda_sig``."""
    data = carray(p, (_DATA_LEN,))
    z = carray(u, (3,))
    out = carray(du, (3,))
    if t != data[_T_LAST]:                  # a new abscissa: a new step attempt
        data[_ATTEMPTS] += 1.0
        data[_T_LAST] = t
        if data[_KILL] == 0.0:
            why = _watch(t, z[1], data)
            if why != 0.0:
                data[_KILL] = why
                data[_KILL_T] = t
                _cut(carray(p, (_DATA_LEN + int(data[_NT]),)), t)
        _rebase(z, data)
    else:
        # LSODA's finite-difference Jacobian: at the t of the call before, one column per
        # call, each the state of that call with one component perturbed (then restored)
        moved = (z[0] != data[_YB0]) + (z[1] != data[_YB1]) + (z[2] != data[_YB2])
        if moved == 1:
            if z[0] != data[_YB0]:
                data[_NJEV] += 1.0
        else:
            _rebase(z, data)
    data[_NFEV] += 1.0
    if data[_KILL] != 0.0:
        out[0] = _KILL_VALUE
        out[1] = _KILL_VALUE
        out[2] = _KILL_VALUE
        return
    ode_rhs(data, z, out)


@functools.cache
def _library():
    """numbalsoda's signature and C entry point, and ours built on them: the address of the
    compiled ``_rhs`` and ``run``, numbalsoda's ``lsoda`` writing into a buffer the caller
    keeps filled with NaN (after a failure the rows it did not reach stay NaN, which tells how
    far it got; ``lsoda`` allocates its output uninitialised)."""
    from numbalsoda import lsoda_sig
    from numbalsoda.driver import lsoda_wrapper

    rhs = cfunc(lsoda_sig, cache=True, error_model="numpy")(_rhs)

    @njit
    def run(funcptr, u0, t_eval, data, rtol, atol, mxstep, usol):
        neq, nt = u0.shape[0], t_eval.shape[0]
        success = np.array(999, np.int32)
        lsoda_wrapper(funcptr, neq, u0.ctypes.data, data.ctypes.data, nt, t_eval.ctypes.data,
                      usol.ctypes.data, rtol, atol, mxstep, success.ctypes.data)
        ok = True
        if success != 1:
            ok = False
        return ok

    return rhs.address, run


class _Abort(Exception):
    """An lsoda call failed where no state can be returned but the current one."""

    def __init__(self, advance: Advance):
        super().__init__(advance.message)
        self.advance = advance


@register
@dataclass(frozen=True)
class NumbaLSODA(AdaptiveAlgorithm):
    """LSODA (Petzold 1983) from numbalsoda: Adams (orders 1–12) / BDF (orders 1–5) switching on
    detected stiffness, adaptive, finite-difference Jacobian.

    Needs ``rtol`` and ``atol`` (required: no default accuracy; ``atol`` applies to every
    component of (h, ln w, Ψ or ln Ψ)), ``max_steps`` (step attempts, whole solve) and the
    compiled right-hand side (``rhs="numba"`` only). Events by sign changes on a grid,
    re-integration of the interval and bisection on a cubic Hermite interpolant (module
    docstring). Reference: Petzold (1983), SIAM J. Sci.
    Stat. Comput. 4, 136–148; Hindmarsh (1983), ODEPACK.
    """

    name: ClassVar[str] = "numbalsoda-LSODA"
    family: ClassVar[str] = "Adams/BDF (LSODA)"
    order: ClassVar[int] = 12
    library: ClassVar[str] = "numbalsoda"
    package: ClassVar[str] = "numbalsoda"
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "lsoda"
    compiled: ClassVar[bool] = True
    rhs_tiers: ClassVar[tuple[str, ...]] = ("numba",)
    rhs_tiers_reason: ClassVar[str] = (
        "numbalsoda calls the right-hand side from C through a function pointer, a numba "
        "cfunc, which a Python function cannot provide")

    @classmethod
    def library_version(cls) -> str:
        return f"numbalsoda {_VERSION} (C++ port of ODEPACK LSODA)"

    def make_stepper(self, nd, budget):
        return _LsodaStepper(self, nd, budget)


class _LsodaStepper:
    """The segment protocol over block-wise ``lsoda`` calls (see the module docstring).

    The buffer ``_T``/``_Y``/``_G`` (grid times, states, root-function values) holds the current
    block; grid points up to index ``_k`` have been handed out or scanned; ``_cross`` lists the
    intervals (T[i], T[i+1]] with a crossing that counts; ``_queue`` the located roots of the
    last scanned interval not yet reported.
    """

    def __init__(self, algorithm: NumbaLSODA, nd, budget=None):
        self.algorithm = algorithm
        self.nd = nd
        self.budget = budget
        self.stats = Stats()
        # the data array with room for the output times of a call, and the output buffer
        # (NaN where the last call did not write); both grow to the longest call
        self._buf = np.zeros(_DATA_LEN + 1024)
        self._ubuf = np.full((1024, 3), np.nan)
        d = self._data = self._buf[:_DATA_LEN]
        d[:N_Q] = form_vector(nd, nd.e_slow)
        d[_T_LAST] = np.nan
        d[_LIMIT] = float(algorithm.max_steps)
        d[_DEADLINE] = math.inf if budget is None else budget.deadline()
        d[_U_ONSET], d[_U_END] = math.log(10.0 * nd.e_slow), math.log(nd.e_slow)
        d[_TWO_SPEED] = float(nd.two_speed)
        self._funcptr, self._lsoda = _library()
        # the parameters of the event kernels (E and ln E are set by start)
        self._q = np.concatenate([form_vector(nd, nd.e_slow),
                                  [math.log(10.0 * nd.e_slow), math.log(nd.e_slow), 0.0]])
        self._dcap = nd.grid_tau / _POINTS_PER_HALF_PERIOD
        self._dt_out = 0.0            # spacing of the driver's output times, learned
        self._last_request = None
        self._last_root = None        # (tau, z, [(kind, sign after crossing)], e)

    # --- the protocol ---------------------------------------------------------------------------

    def start(self, tau0, z0, e, t_bound):
        self._e = float(e)
        self._data[_E] = self._q[_E] = self._e
        self._q[_LN_E] = ln_load_rate(self._e)
        z0 = np.array(z0, dtype=float)
        g0 = np.empty(4)
        _roots(self._q, z0, g0)
        carry_last_root(self._last_root, tau0, z0, g0, self._e, self.nd.quasi_static)
        self._T, self._Y, self._G = np.array([float(tau0)]), z0[None, :], g0[None, :]
        self._cross = np.empty(0, dtype=int)
        self._k = 0
        self._queue = deque()
        self._t, self._z = float(tau0), z0
        self._t_bound = float(t_bound)
        self._dg = self._dcap         # grid spacing of the buffer
        self._failure = None          # an Advance to return once the buffer is used up

    def advance(self, t_out):
        t_out = float(t_out)
        if self._last_request is not None and t_out > self._last_request:
            self._dt_out = max(self._dt_out, t_out - self._last_request)
        self._last_request = t_out
        try:
            while True:
                if self._queue:
                    t, z, kinds, signs = self._queue[0]
                    if t <= t_out:
                        self._queue.popleft()
                        self._t, self._z = t, z
                        self._last_root = (t, z, list(zip(kinds, signs)), self._e)
                        return Advance(t, z, roots=kinds)
                    return self._value_at(t_out)
                # skip the intervals without crossings, up to t_out or the next crossing
                k, last = self._k, len(self._T) - 1
                pos = int(np.searchsorted(self._cross, k))
                nxt = int(self._cross[pos]) if pos < len(self._cross) else last
                j = int(np.searchsorted(self._T, t_out - self._match()))
                if j <= nxt:
                    self._k = max(k, j)
                    return self._value_at(t_out)
                if nxt == last:
                    self._k = last
                    if self._failure is not None:
                        return self._failure
                    self._extend(t_out)
                    continue
                self._scan(nxt)
                self._k = nxt + 1
        except _Abort as abort:
            return abort.advance

    # --- lsoda calls ----------------------------------------------------------------------------

    def _run(self, z0, t_eval, guard: bool, block: bool, onset: bool = True):
        """One lsoda call; counters updated. Returns (rows, n, ok): the n rows LSODA reached
        (see ``_reached``); ``_data[_KILL]`` tells whether and why the cfunc stopped it. With
        ``block``, the call ends on entering an event (unless not ``onset``) and, under two-
        speed loading, soon after an event's end."""
        a = self.algorithm
        nt = len(t_eval)
        if nt > len(self._ubuf):
            size = 1 << (nt - 1).bit_length()
            buf = np.zeros(_DATA_LEN + size)
            buf[:_DATA_LEN] = self._data
            self._buf, self._data = buf, buf[:_DATA_LEN]
            self._ubuf = np.full((size, 3), np.nan)
        d = self._data
        d[_KILL], d[_KILL_T] = 0.0, np.inf
        # a call shorter than one grid interval is not guarded: stuck, it costs no more than
        # the restarts would
        d[_GUARD_N] = (_GUARD_ATTEMPTS if guard and t_eval[-1] - t_eval[0] > 0.5 * self._dg
                       else 0.0)
        d[_GUARD_DT], d[_GUARD_COUNT], d[_GUARD_T], d[_GUARD_U] = self._dg, 0.0, t_eval[0], z0[1]
        # stiff: the stiff eigenvalue ~ D/w is over 100 per grid interval (w < D·dg/100); only
        # there can Adams be stuck at its stability limit, and only there is BDF so cheap
        # (no inertial relaxation without mass: never stiff that way)
        d[_U_STIFF] = (math.log(self.nd.d * self._dg / 100.0) if self.nd.d > 0.0
                       else -math.inf)
        d[_BLOCK], d[_ARMED] = float(block), 0.0
        d[_T_ARM] = t_eval[0] + 4.0 * self._dg if onset else np.inf
        d[_IN_EVENT], d[_END_DT], d[_END_KILL_T] = 0.0, 3.0 * self._dg, np.inf
        d[_NT] = nt
        te = self._buf[_DATA_LEN:_DATA_LEN + nt]
        te[:] = t_eval                      # a copy: _cut may write into it
        ok = self._lsoda(self._funcptr, np.ascontiguousarray(z0, dtype=float), te, self._buf,
                         a.rtol, a.atol, _MXSTEP, self._ubuf)
        # the cfunc keeps the counters in the data array over the whole solve
        self.stats = Stats(nfev=int(d[_NFEV]), njev=int(d[_NJEV]), steps=int(d[_ATTEMPTS]))
        n = _reached(self._ubuf, t_eval, d[_KILL_T])
        rows = self._ubuf[:n].copy()
        _reset(self._ubuf)
        return rows, n, ok

    def _integrate(self, z0, t_eval, block: bool = False):
        """lsoda from z0 through t_eval, a stuck cold start restarted (module docstring).
        Returns (rows, n, ok): the first n points of t_eval were reached (not all: failure,
        budget, end of block)."""
        t_eval = np.asarray(t_eval, dtype=float)
        z = np.ascontiguousarray(z0, dtype=float)
        pieces, i, variant, ok = [], 0, 0, True
        while i < len(t_eval) - 1:
            te = t_eval[i:]
            guard = variant <= len(_FIRST_FRACTIONS)      # the last try runs unguarded
            extra = 0 < variant <= len(_FIRST_FRACTIONS)
            if extra:
                te = np.insert(te, 1, te[0] + _FIRST_FRACTIONS[variant - 1] * (te[1] - te[0]))
            rows, n, ok = self._run(z, te, guard, block)
            if extra and n > 1:
                rows, n = np.delete(rows, 1, axis=0), n - 1
            pieces.append(rows[1:] if pieces else rows)
            if self._data[_KILL] != _STUCK:
                break
            variant = variant + 1 if n == 1 else 1
            i += n - 1
            z = rows[n - 1]
        if not pieces:                           # t_eval of one point
            return z[None, :].copy(), 1, ok
        rows = pieces[0] if len(pieces) == 1 else np.concatenate(pieces)
        return rows, len(rows), ok

    def _failed(self, t_from: float, t_to: float, z, ok: bool) -> Advance:
        a = self.algorithm
        if self._data[_KILL] == _WALL:
            return Advance(t_from, z, retcode=ReturnCode.WALL_TIME,
                           message=f"wall-time budget of {self.budget.wall_s} s used up "
                                   f"between t = {t_from * self.nd.time_scale:.6g} s and "
                                   f"{t_to * self.nd.time_scale:.6g} s")
        if self._data[_KILL] == _BUDGET or self.stats.steps >= a.max_steps:
            return Advance(t_from, z, retcode=ReturnCode.MAX_STEPS,
                           message=f"step budget of {a.max_steps} used up "
                                   f"between tau = {t_from:.9g} and {t_to:.9g}")
        if ok:
            return Advance(t_from, z, retcode=ReturnCode.NON_FINITE,
                           message=f"non-finite state between tau = {t_from:.9g} and {t_to:.9g}")
        return Advance(t_from, z, retcode=ReturnCode.FAILURE,
                       message=f"LSODA failed between tau = {t_from:.9g} and {t_to:.9g} "
                               "(numbalsoda returns only success=False; LSODA printed its "
                               "reason on stderr)")

    def _state_at(self, t0: float, z0, t: float) -> np.ndarray:
        """Re-integrate from (t0, z0) to t."""
        if t == t0:
            return np.array(z0)
        usol, n, ok = self._integrate(z0, [t0, t])
        if n < 2:
            raise _Abort(self._failed(t0, t, np.array(z0), ok))
        return usol[1]

    # --- grid, scan, root location --------------------------------------------------------------

    def _match(self) -> float:
        """Times closer than this are the same grid point (the driver accumulates its output
        times, so they differ from ours in the last bits)."""
        return 1e-7 * self._dg

    def _value_at(self, t: float) -> Advance:
        """The state at t inside the buffer: a grid point, or re-integrated from the one before."""
        T, Y = self._T, self._Y
        i = int(np.searchsorted(T, t))
        for j in (i - 1, i):
            if 0 <= j < len(T) and abs(T[j] - t) <= self._match():
                f = np.empty(3)
                ode_rhs(self._q, Y[j], f)
                z = Y[j] + f * (t - T[j])      # first-order shift by a few ulps of t
                break
        else:
            j = max(i - 1, 0)
            z = self._state_at(T[j], Y[j], t)
        self._t, self._z = t, z
        return Advance(t, z)

    def _extend(self, t_req: float) -> None:
        """Integrate the next block from the buffer's last point, through a grid containing the
        driver's output times (spaced ``_dt_out``, learned) subdivided to at most ``_dcap``; a
        failure is kept in ``_failure`` for when it is reached."""
        a = self.algorithm
        if self.stats.steps >= a.max_steps:
            raise _Abort(Advance(self._t, self._z, retcode=ReturnCode.MAX_STEPS,
                                 message=f"step budget of {a.max_steps} used up at "
                                         f"tau = {self._t:.9g}"))
        start, z_start = self._T[-1], self._Y[-1]
        dout = self._dt_out if self._dt_out > 0.0 else t_req - start
        self._dg = dg = dout / max(1, math.ceil(dout / self._dcap - 1e-9))
        match = self._match()
        j0 = math.ceil((start + match - t_req) / dg)
        n_max = min(_BLOCK_MAX, int((self._t_bound - start) / dg) + 2)
        t_eval = np.empty(n_max + 2)
        t_eval = t_eval[:_grid(start, t_req, dg, j0, n_max, match, self._t_bound, t_eval)]
        usol, n, ok = self._integrate(z_start, t_eval, block=True)
        if n == 1 and self._data[_KILL] == _BLOCK_END:     # ended before its first point
            usol, n, ok = self._integrate(z_start, t_eval[:2])
        if n < len(t_eval) and self._data[_KILL] != _BLOCK_END:
            self._failure = self._failed(t_eval[n - 1], t_eval[n], usol[n - 1], ok)
        if n == 1:
            raise _Abort(self._failure or self._failed(start, t_eval[1], z_start, ok))
        self._T, self._Y = t_eval[:n].copy(), usol
        G, cross = np.empty((n, 4)), np.empty(n, dtype=np.int64)
        m = _block_roots(self._q, usol, n, self._G[self._k].copy(), G, cross)
        self._G, self._cross, self._k = G, cross[:m], 0

    def _scan(self, k: int) -> None:
        """Locate the crossings that count in (T[k], T[k+1]] and queue them in time order: one
        lsoda call through the interval at ``_N_SUB`` sub-points brackets them, cubic Hermite
        interpolation between the two sub-points of each bracket places them (``_sub_roots``)."""
        ta, tb = self._T[k], self._T[k + 1]
        ts = np.linspace(ta, tb, _N_SUB + 1)
        rows, n, ok = self._integrate(self._Y[k], ts)
        if n < _N_SUB:
            raise _Abort(self._failed(ta, tb, self._Y[k], ok))
        usol = np.empty((_N_SUB + 1, 3))
        usol[:_N_SUB] = rows[:_N_SUB]
        usol[-1] = self._Y[k + 1]            # the block's value at T[k+1] is the one we keep
        R = np.empty((4 * _N_SUB, 6))
        m, nfev = _sub_roots(self._q, ts, usol, self._G[k], self._G[k + 1], R)
        self._data[_NFEV] += nfev
        self.stats = dataclasses.replace(self.stats, nfev=int(self._data[_NFEV]))
        roots = [(R[i, 0], int(R[i, 1]), int(R[i, 2]), R[i, 3:6].copy()) for i in range(m)]
        roots.sort(key=lambda r: r[0])
        queue_crossings(self._queue, roots)
