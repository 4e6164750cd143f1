"""numbalsoda's LSODA called the way its users call it: once over an output grid, events read
off the grid.

``numbalsoda.lsoda(funcptr, u0, t_eval, data, rtol, atol)`` returns the solution at the times of
``t_eval`` and nothing else: no root finding, no dense output. A user who wants the stick–slip
events integrates over a fine uniform grid and finds the crossings of the event functions
between grid points by linear interpolation. This backend does exactly that, beside the adapter
of :mod:`integrators.external.numbalsoda_backend` (which locates the crossings to the last bit
at extra cost), so that the study shows what the plain way of calling costs and what it gets.

* The grid: ``points_per_half_period`` points per π/√C (half the period of the slider's
  oscillation, the time scale of a slip event). Left at ``None`` it follows the tolerance,
  8·√(10⁻⁶/rtol) (at least 4): linear interpolation misplaces a crossing by O(Δt²), so a user
  asking ten times the accuracy refines the grid about three times.
* One ``lsoda`` call per chunk of ``CHUNK`` grid points (a long run does not fit one output
  array; under two-speed loading the run restarts at every event end, and a chunk bounds what
  the restart throws away). Each call is a cold start of LSODA, as a user's call would be.
* Events: the crossings that count (``events.DIRECTIONS``; a PEAK only where w > E_slow at an
  end of the interval) between consecutive grid points, placed where the linear interpolant
  of the root function is zero; the state there is interpolated linearly too. Save points are
  linear interpolants as well: the grid is this backend's dense output.
* The right-hand side and the counters are the adapter's (nfev, step attempts, finite-
  difference Jacobians counted in the cfunc; budgets stop LSODA from inside it); no stuck-start
  guard: a user's call has none, and a start stuck in Adams ends at the step budget.

What the plain call costs against the adapter, and what it gets: docs/external-adapters.md.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.core.crossings import carry_last_root, push_crossing, queue_crossings
from integrators.core.events import AT_ROOT, END, compiled_roots
from integrators.core.registry import register
from integrators.core.segments import Advance
from integrators.core.solution import ReturnCode
from integrators.external.numbalsoda_backend import (_BLOCK_END, _E, _KILL, _LN_10ES, _LN_E,
                                                     _LN_ES, NumbaLSODA, _Abort, _counts,
                                                     _LsodaStepper, _roots)
from problems.loading import ln_load_rate

__all__ = ["NumbaLSODAGrid", "CHUNK"]

#: grid points per lsoda call at most
CHUNK = 1 << 20


def default_points(rtol: float) -> float:
    """Grid points per half period π/√C when none are given: 8·√(10⁻⁶/rtol), at least 4."""
    return max(4.0, 8.0 * math.sqrt(1e-6 / rtol))


@njit(cache=True, nogil=True, error_model="numpy")
def _grid_crossings(q, T, Y, n, g):
    """The crossings that count between consecutive rows 0..n−1 of a chunk, each where the
    linear interpolant of its root function is zero: rows (τ, kind, sign, z0, z1, z2), in time
    order. ``g`` holds the root functions at row 0 (signs carried over a restart) and is left
    holding them at row n−1."""
    gp = g.copy()
    R = np.empty((16, 6))
    m = 0
    for i in range(1, n):
        compiled_roots(q, q[_LN_10ES], q[_LN_ES], q[_LN_E], Y[i], g)
        first = m
        for k in range(4):
            a, b = gp[k], g[k]
            if not _counts(k, a, b, gp[END], g[END]):
                continue
            x = 1.0 if abs(a) <= AT_ROOT or a == b else min(1.0, a / (a - b))
            if x == 1.0:
                t, z0, z1, z2 = T[i], Y[i, 0], Y[i, 1], Y[i, 2]
            else:
                t = T[i - 1] + x * (T[i] - T[i - 1])
                z0 = Y[i - 1, 0] + x * (Y[i, 0] - Y[i - 1, 0])
                z1 = Y[i - 1, 1] + x * (Y[i, 1] - Y[i - 1, 1])
                z2 = Y[i - 1, 2] + x * (Y[i, 2] - Y[i - 1, 2])
            R = push_crossing(R, m, first, t, k, 1.0 if b > a else -1.0, z0, z1, z2)
            m += 1
        gp[:] = g
    return R[:m]


@register
@dataclass(frozen=True)
class NumbaLSODAGrid(NumbaLSODA):
    """LSODA (Petzold 1983) from numbalsoda, called once per segment over a uniform output grid;
    events found between grid points by linear interpolation (module docstring).

    Takes ``rtol``, ``atol`` (every component), ``max_steps`` (step attempts, whole solve) and
    ``points_per_half_period`` (grid points per π/√C; ``None``: 8·√(10⁻⁶/rtol), at least 4).
    Compiled right-hand side only (``rhs="numba"``).
    """

    points_per_half_period: float | None = None

    name: ClassVar[str] = "numbalsoda-LSODA-grid"

    def __post_init__(self) -> None:
        super().__post_init__()
        m = self.points_per_half_period
        if m is not None and (isinstance(m, bool) or not isinstance(m, (int, float))
                              or not 1.0 <= m <= 1e6):
            raise ValueError("points_per_half_period must be a number in [1, 1e6] or None, "
                             f"got {m!r}")

    def make_stepper(self, nd, budget):
        return _GridStepper(self, nd, budget)


class _GridStepper(_LsodaStepper):
    """The segment protocol over a uniform grid: ``_T``/``_Y`` hold the current chunk (times,
    states), ``_g`` the root functions at its last point, ``_queue`` its crossings not yet reported, ``_failure``
    what to return once the reached part of a failed call is used up."""

    def __init__(self, algorithm: NumbaLSODAGrid, nd, budget=None):
        super().__init__(algorithm, nd, budget)
        m = algorithm.points_per_half_period or default_points(algorithm.rtol)
        self._dg = nd.grid_tau / m
        self._two_speed = nd.two_speed

    def start(self, tau0, z0, e, t_bound):
        self._e = float(e)
        self._data[_E] = self._q[_E] = self._e
        self._q[_LN_E] = ln_load_rate(self._e)
        z0 = np.array(z0, dtype=float)
        g0 = np.empty(4)
        _roots(self._q, z0, g0)
        carry_last_root(self._last_root, tau0, z0, g0, self._e, self.nd.quasi_static)
        self._T, self._Y, self._g = np.array([float(tau0)]), z0[None, :], g0
        self._queue = deque()
        self._t_bound = float(t_bound)
        self._segment = self._t_bound - float(tau0)
        self._failure = None

    def _match(self) -> float:
        """As the adapter's, but a small part of the segment at most: a segment shorter than the
        grid's tolerance (two load switches 1e−9 s apart) would otherwise count as reached at
        its start, and the driver would ask for its end for ever."""
        return min(super()._match(), 1e-3 * self._segment)

    def advance(self, t_out):
        t_out = float(t_out)
        try:
            while True:
                if self._queue and self._queue[0][0] <= t_out:
                    t, z, kinds, signs = self._queue.popleft()
                    self._last_root = (t, z, list(zip(kinds, signs)), self._e)
                    return Advance(t, z, roots=kinds)
                if t_out <= self._T[-1] + self._match():
                    return self._interpolate(min(t_out, self._T[-1]))
                if self._failure is not None:
                    return self._failure
                self._chunk()
        except _Abort as abort:
            return abort.advance

    def _interpolate(self, t: float) -> Advance:
        T, Y = self._T, self._Y
        i = min(max(int(np.searchsorted(T, t)), 1), len(T) - 1)
        x = 0.0 if T[i] == T[i - 1] else (t - T[i - 1]) / (T[i] - T[i - 1])
        return Advance(t, Y[i - 1] + x * (Y[i] - Y[i - 1]))

    def _chunk(self) -> None:
        """One lsoda call over the next ``CHUNK`` grid points (the last is t_bound at the
        segment's end); its crossings queued, a failure kept for when it is reached."""
        a = self.algorithm
        if self.stats.steps >= a.max_steps:
            raise _Abort(Advance(self._T[-1], self._Y[-1], retcode=ReturnCode.MAX_STEPS,
                                 message=f"step budget of {a.max_steps} used up at "
                                         f"tau = {self._T[-1]:.9g}"))
        start, z_start = self._T[-1], self._Y[-1]
        n = min(CHUNK, int((self._t_bound - start) / self._dg) + 1)
        t_eval = start + self._dg * np.arange(n + 1, dtype=float)
        t_eval = t_eval[t_eval < self._t_bound - self._match()]
        t_eval = np.append(t_eval, self._t_bound) if len(t_eval) <= n else t_eval
        rows, n, ok = self._run(z_start, t_eval, guard=False, block=self._two_speed, onset=False)
        if n < len(t_eval) and self._data[_KILL] != _BLOCK_END:
            self._failure = self._failed(t_eval[n - 1], t_eval[n], rows[n - 1], ok)
            if n == 1:
                raise _Abort(self._failure)
        R = _grid_crossings(self._q, t_eval, rows, n, self._g)
        self._T, self._Y = t_eval[:n].copy(), rows
        queue_crossings(self._queue, ((r[0], r[1], r[2], r[3:6].copy()) for r in R))
