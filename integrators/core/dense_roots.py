"""Root location on a step's dense output, for steppers that have no root finding of their own.

:class:`DenseStepper` turns "take one step, then interpolate inside it" (scipy's ``OdeSolver``
interface) into the ``advance(t_out)`` of :mod:`integrators.core.segments`: within each step it
brackets sign changes of the four root functions between a cursor and the target and refines the
earliest with Brent's method, as ``solve_ivp`` does for its events.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import brentq

from integrators.core.events import AT_ROOT, DIRECTIONS, RootFunctions, sign_change
from integrators.core.segments import Advance
from integrators.core.solution import ReturnCode, Stats

__all__ = ["DenseStepper"]

_EPS = 4 * np.finfo(float).eps


class DenseStepper:
    """Adapter base: subclasses implement ``_new_solver(tau0, z0, e, t_bound)`` returning an
    object with ``step()``, ``status``, ``t``, ``t_old``, ``y`` and ``dense_output()``, and
    ``_count(solver)`` returning its counters other than steps as a :class:`Stats`."""

    def __init__(self, nd, budget=None):
        self.nd = nd
        self.budget = budget        # checked inside long advances, not only between them
        self.steps = 0              # accepted steps over the whole solve
        self._counted = Stats()     # the finished solvers' counters
        self._solver = None

    @property
    def stats(self) -> Stats:
        """The counters so far, summed over restarts (the live solver's once ``finish``ed)."""
        return dataclasses.replace(self._counted, steps=self.steps)

    def start(self, tau0, z0, e, t_bound):
        if self._solver is not None:
            self._counted += self._count(self._solver)
        self._e = e
        self._solver = self._new_solver(tau0, np.asarray(z0, float), e, t_bound)
        self._cursor, self._z_cursor = tau0, np.asarray(z0, float)
        self._roots = RootFunctions(self.nd, e)
        self._g = self._roots(self._z_cursor)
        self._dense = None

    def finish(self):
        if self._solver is not None:
            self._counted += self._count(self._solver)
            self._solver = None

    def _g_at(self, t):
        return self._roots(self._dense(t))

    def advance(self, t_out):
        s = self._solver
        while True:
            if self._dense is not None and self._cursor < s.t:
                t_end = min(s.t, t_out)
                z_end = s.y if t_end == s.t else self._dense(t_end)
                g_end = self._roots(z_end)
                found = self._earliest_root(t_end, g_end)
                if found is not None:
                    return found
                self._cursor, self._z_cursor, self._g = t_end, np.array(z_end), g_end
                if t_end >= t_out:
                    return Advance(t_end, self._z_cursor)
            if s.status != "running":      # reached t_bound
                return Advance(self._cursor, self._z_cursor)
            message = s.step()
            self.steps += 1
            if self.budget is not None and self.steps % 100 == 0 and self.budget.exceeded():
                return Advance(s.t, s.y, retcode=ReturnCode.WALL_TIME,
                               message=f"wall-time budget of {self.budget.wall_s} s used up at "
                                       f"t = {s.t * self.nd.time_scale:.6g} s")
            if s.status == "failed":
                code = (ReturnCode.STEP_UNDERFLOW if "step size" in str(message).lower()
                        else ReturnCode.FAILURE)
                return Advance(s.t, s.y, retcode=code, message=str(message))
            if not np.all(np.isfinite(s.y)):
                return Advance(s.t, s.y, retcode=ReturnCode.NON_FINITE,
                               message=f"non-finite state at tau = {s.t:.9g}")
            self._dense = s.dense_output()

    def _earliest_root(self, t_end, g_end):
        """The first sign change in (cursor, t_end] of any root function, refined; roots in a
        direction that does not count only move the cursor's signs."""
        g0 = self._g
        changed = [k for k in range(len(g0)) if sign_change(g0[k], g_end[k]) != 0]
        if not changed:
            return None
        roots = []
        for k in changed:
            g_a = self._g_at(self._cursor)[k]
            if g_a == 0.0 or np.sign(g_a) == np.sign(g_end[k]):
                # the step's interpolant at its start differs from the previous state by
                # round-off (LSODA's does): the crossing is at the start of the bracket
                t_root = self._cursor
            else:
                t_root = brentq(lambda t: self._g_at(t)[k], self._cursor, t_end,
                                xtol=1e-14 * max(1.0, abs(t_end)), rtol=_EPS)
            roots.append((t_root, k))
        t_root = min(r[0] for r in roots)
        at_root = [k for t, k in roots if t == t_root]
        z_root = self._dense(t_root)
        g_new = self._roots(z_root)
        counted = []
        for k in at_root:
            up = g_end[k] > g0[k]
            g_new[k] = abs(g_new[k]) or AT_ROOT
            if not up:
                g_new[k] = -g_new[k]       # the sign after the crossing
            if DIRECTIONS[k] == 0 or DIRECTIONS[k] == (1 if up else -1):
                counted.append(k)
        self._cursor, self._z_cursor, self._g = t_root, z_root, g_new
        if not counted:       # only roots that do not count: keep going within the step
            return self._earliest_root(t_end, g_end) or None
        return Advance(t_root, z_root, roots=counted)
