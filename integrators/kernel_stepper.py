"""The segment protocol (:mod:`integrators.segments`) over a compiled adaptive kernel.

One adapter serves CashKarp45, the Rosenbrock methods and the exponential Rosenbrock methods:
each keeps its whole state in arrays that its numba kernel ``_advance`` reads and writes, and
differs only in the kernel, the number of rows of ``Z`` and the exponent of the initial-step
guess.

* ``st``: the last step [TAU_OLD, TAU], the step size H, CURSOR ≤ TAU the last time handed out,
  T_RET the time returned, the counters (layout below; a kernel may append its own memory);
* ``Z``: rows z and f at TAU first, the state returned in row ``zr`` (the last);
* ``G``: row 0 the root functions at the cursor, row 1 the roots found there (±1: direction);
* ``p``: law, β, C, D, E, rtol, atol, ln(10 E_slow), ln E_slow, ln E, then the method's extras.

The kernel returns REACHED or ROOT (at T_RET, state in Z[zr]), CHUNK (``n_max`` accepted steps
done: the wall budget is checked between calls), NONFINITE or UNDERFLOW.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from numba import njit

from integrators.events import AT_ROOT, DIRECTIONS, H_EXTREMUM, compiled_roots
from integrators.registry import AdaptiveAlgorithm
from integrators.segments import Advance
from integrators.solution import ReturnCode, Stats
from problems.formulations import ode_rhs

__all__ = ["CompiledAlgorithm", "KernelStepper", "REACHED", "ROOT", "CHUNK", "NONFINITE", "UNDERFLOW", "CHUNK_STEPS"]

TAU, TAU_OLD, H, CURSOR, T_RET, STEPS, REJECTED, NFEV, NJEV = range(9)
REACHED, ROOT, CHUNK, NONFINITE, UNDERFLOW = range(5)
CHUNK_STEPS = 1 << 16            # accepted steps per kernel call at most (~0.1 s: the wall budget
                                 # is checked between calls)


@njit(cache=True, error_model="numpy", inline="always")
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


@njit(cache=True, error_model="numpy")
def _start(st, Z, G, p, tau0, z0, t_bound, exponent):
    """The arithmetic of :meth:`KernelStepper.start`, compiled (in Python it cost ~40 µs per
    restart, as much as a few hundred steps): z0 and f(z0) into Z, Hairer's initial step
    (Hairer, Nørsett & Wanner I, §II.4, on the scale of the error test) into st[H], the root
    functions at τ0 into G[0]. Python's ``min``/``max`` and numpy's NaN propagation are kept
    as they were, so every step size is the same to the bit."""
    rtol, atol = p[5], p[6]
    z, f, trial, f1, scale = Z[0], Z[1], np.empty(3), np.empty(3), np.empty(3)
    for i in range(3):
        z[i] = z0[i]
    ode_rhs(int(p[0]), p[1], p[2], p[3], p[4], z, f)
    for i in range(3):
        scale[i] = atol + rtol * abs(z[i])
    d0, d1 = _max_abs_ratio(z, scale), _max_abs_ratio(f, scale)
    small = d0 if not d1 < d0 else d1                            # Python's min(d0, d1)
    h0 = 0.01 * d0 / d1 if small >= 1e-5 else 1e-6
    for i in range(3):
        trial[i] = z[i] + h0 * f[i]
    ode_rhs(int(p[0]), p[1], p[2], p[3], p[4], trial, f1)
    for i in range(3):
        f1[i] = f1[i] - f[i]
    big = _max_abs_ratio(f1, scale) / h0
    big = big if big > d1 else d1                                # Python's max(d1, ·): inf if
    if big > 1e-15:                                              # the trial overflowed
        h1 = (0.01 / big) ** exponent
    else:
        h1 = 1e-3 * h0 if 1e-3 * h0 > 1e-6 else 1e-6
    h = 100.0 * h0
    second = h1 if h1 > 0.0 else 1e-3 * h0
    if second < h:
        h = second
    if t_bound - tau0 < h:
        h = t_bound - tau0
    st[H] = h
    st[TAU] = st[CURSOR] = tau0
    st[NFEV] += 2.0
    compiled_roots(p, z, G[0])


class CompiledAlgorithm(AdaptiveAlgorithm):
    """An adaptive method of this project: its step loop is a numba kernel calling the compiled
    right-hand side, so it offers the numba tier only."""

    library: ClassVar[str] = "rsfbench (numba)"
    rhs_tiers: ClassVar[tuple[str, ...]] = ("numba",)

    @classmethod
    def library_version(cls) -> str:
        import numba
        return f"numba {numba.__version__}"


class KernelStepper:
    """``start``/``advance`` over ``kernel``; subclasses set the sizes and call the kernel."""

    n_st = 9                    # length of st (≥ 9)
    n_z = 5                     # rows of Z; the last is the state returned
    init_exponent = 0.2         # of Hairer's initial-step guess: 1/(order of the error estimate)

    def __init__(self, algorithm, nd, budget, extra_p=()):
        self.algorithm, self.nd, self.budget = algorithm, nd, budget
        self.stats = Stats()
        self._st, self._Z, self._G = np.zeros(self.n_st), np.zeros((self.n_z, 3)), np.zeros((2, 4))
        self._p = np.array([nd.law_code, nd.beta, nd.c, nd.d, 0.0, algorithm.rtol, algorithm.atol,
                            math.log(10.0 * nd.e_slow), math.log(nd.e_slow), 0.0, *extra_p])
        self._dirs = np.array(DIRECTIONS, dtype=np.int64)
        self._last_root = None          # (tau, z, [(kind, sign after crossing)], e)

    def kernel(self, t_out: float, n_max: int) -> int:
        raise NotImplementedError

    def reset(self) -> None:
        """Clear a kernel's own memory in ``st`` at a (re)start."""

    def start(self, tau0, z0, e, t_bound):
        st, Z, G, p = self._st, self._Z, self._G, self._p
        self._e = p[4] = float(e)
        p[9] = math.log(self._e)
        _start(st, Z, G, p, float(tau0), np.asarray(z0, dtype=float), float(t_bound),
               float(self.init_exponent))
        self.reset()
        last = self._last_root
        if last is not None and last[0] == tau0 and (last[1] == Z[0]).all():
            # restarting at a root just reported: keep its sign after the crossing, or the
            # first step would find the same crossing again
            for kind, sign in last[2]:
                if (kind != H_EXTREMUM or last[3] == self._e) and G[0, kind] * sign <= 0.0:
                    G[0, kind] = sign * AT_ROOT
        self._sync()

    def _sync(self) -> None:
        st, s = self._st, self.stats
        s.nfev, s.njev, s.steps, s.rejected = (int(st[NFEV]), int(st[NJEV]), int(st[STEPS]),
                                               int(st[REJECTED]))

    def _stop(self, code, what):
        t = self._st[TAU]
        return Advance(t, self._Z[0].copy(), retcode=code,
                       message=f"{what} at t = {t * self.nd.time_scale:.6g} s")

    def advance(self, t_out):
        st, a, zr = self._st, self.algorithm, self.n_z - 1
        while True:
            status = self.kernel(float(t_out), min(CHUNK_STEPS, a.max_steps - int(st[STEPS])))
            self._sync()
            if status == ROOT:
                z, kinds = self._Z[zr].copy(), [k for k in range(4) if self._G[1, k] != 0.0]
                self._last_root = (st[T_RET], z.copy(), [(k, self._G[1, k]) for k in kinds],
                                   self._e)
                return Advance(st[T_RET], z, roots=kinds)
            if status == NONFINITE:
                return self._stop(ReturnCode.NON_FINITE, "non-finite state")
            if status == UNDERFLOW:
                return self._stop(ReturnCode.STEP_UNDERFLOW, "step size underflow (t + h == t)")
            # here too, not only every 50 calls as the driver does: one call can be 1e6 steps
            if self.budget is not None and self.budget.exceeded():
                return self._stop(ReturnCode.WALL_TIME,
                                  f"wall-time budget of {self.budget.wall_s} s used up")
            if status == REACHED:
                return Advance(st[T_RET], self._Z[zr].copy())
            if st[STEPS] >= a.max_steps:
                return self._stop(ReturnCode.MAX_STEPS, f"step budget of {a.max_steps} used up")
