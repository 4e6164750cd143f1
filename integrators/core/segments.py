"""One driver for every adaptive backend: segments, restarts, events, decimation, counters.

A backend supplies a :class:`SegmentSolver`, a thin adapter over its library:

* ``start(tau0, z0, e, t_bound)`` — (re)initialise at τ0, state z0 = (h, u, s) of the shared ODE
  form, loading E = ``e``, never integrating past ``t_bound``;
* ``advance(t_out)`` — integrate towards ``t_out`` (≤ t_bound) and return an :class:`Advance`:
  either at ``t_out`` or earlier, at the first root of the four root functions of
  :mod:`integrators.core.events`, located by the library's own root finding;
* ``stats`` — the counters so far, a :class:`Stats` summed over restarts (a frozen value the
  adapter replaces as it counts); an adapter with a ``finish()`` folds its live solver's
  counters in there, so the run's are read after it (``AdaptiveAlgorithm.run``).

The driver owns what is common: the loading state (a segment per piece of the load-point
history, :func:`problems.loading.load_segment`; the overshoot after an event's end), the :class:`EventRecorder`, the save grid, progress and budgets, and the
conversion to a :class:`RawRun`. So every backend has the same event semantics and counters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from integrators.core.events import DIRECTIONS, EventRecorder, root_derivatives
from integrators.core.solution import RawRun, ReturnCode, Stats
from problems.formulations import from_ode_state, to_ode_state
from problems.loading import load_segment

__all__ = ["Advance", "SegmentSolver", "run_segments", "directional_roots", "save_grid"]

_BUDGET_STOPS = (ReturnCode.WALL_TIME, ReturnCode.MAX_STEPS)


@dataclass
class Advance:
    """Where ``advance`` stopped: τ, state z = (h, u, s), the indices of the root functions
    found there (empty when ``t_out`` was reached) and the outcome."""

    tau: float
    z: np.ndarray
    roots: list[int] = field(default_factory=list)
    retcode: ReturnCode = ReturnCode.SUCCESS
    message: str = ""


class SegmentSolver(Protocol):
    stats: Stats

    def start(self, tau0: float, z0: np.ndarray, e: float, t_bound: float) -> None: ...

    def advance(self, t_out: float) -> Advance: ...


def directional_roots(nd, e: float, z: np.ndarray, found, signs=None) -> list[int]:
    """Keep the roots crossed in the direction that counts (``events.DIRECTIONS``).

    ``signs`` are the crossing directions if the library reports them (SUNDIALS' root info);
    otherwise they are taken from the time derivatives of the root functions at z.
    """
    if signs is None:
        d = root_derivatives(nd, e, z)
        signs = [np.sign(d[k]) for k in found]
    return [k for k, sgn in zip(found, signs) if DIRECTIONS[k] == 0 or DIRECTIONS[k] == sgn]


def save_grid(problem, nd, output):
    """The save targets in τ, ending in inf; the times asked for in s (``save_at``; None for a
    uniform grid); whether the start is not one of them (it is kept as the first saved point,
    then dropped)."""
    grid_s = None
    if output.save_at is not None:
        grid_s = output.times(problem.t_end)
        grid = grid_s / nd.time_scale
        if grid_s[-1] == problem.t_end:
            grid[-1] = nd.tau_end
    else:
        # every save_dtau by repeated addition, as the targets have always been (a target one
        # rounding off moves a library's steps, and with them what its runs are on record as)
        save_dtau = output.interval(problem.t_end) / nd.time_scale
        count = int(math.ceil(nd.tau_end / save_dtau)) + 2
        grid = np.concatenate(([0.0], np.cumsum(np.full(count, save_dtau))))
    return np.append(grid, np.inf), grid_s, grid[0] > 0.0


def run_segments(problem, solver: SegmentSolver, output, budget, progress,
                 check_every: int = 50) -> RawRun:
    """Integrate ``problem`` to t_end with ``solver``; see the module docstring."""
    nd = problem.nondimensional()
    two_speed = nd.two_speed
    grid, grid_s, unasked = save_grid(problem, nd, output)
    given = grid_s is not None
    z = to_ode_state(nd.law_code, nd.beta, nd.x0)
    tau, load, fast_until = 0.0, 0.0, -math.inf
    rec = EventRecorder(nd.x0[0])
    saved_t, saved_z = [0.0], [z.copy()]
    i_save = 0 if unasked else 1
    retcode, message = ReturnCode.SUCCESS, ""
    tiny = 1e-12 * nd.tau_end
    calls = 0
    while tau < nd.tau_end - tiny and retcode is ReturnCode.SUCCESS:
        e, t_bound = load_segment(nd.history, tau, fast_until, nd.tau_end, tiny)
        solver.start(tau, z, e, t_bound)
        tau0_seg, load0_seg = tau, load
        while True:
            adv = solver.advance(min(grid[i_save], t_bound))
            calls += 1
            if adv.retcode is not ReturnCode.SUCCESS:
                retcode, message = adv.retcode, adv.message
                if adv.retcode in _BUDGET_STOPS and np.all(np.isfinite(adv.z)):
                    tau, z = adv.tau, np.array(adv.z, dtype=float)   # a valid state: keep it
                break
            tau, z = adv.tau, np.array(adv.z, dtype=float)
            if not np.all(np.isfinite(z)):
                retcode = ReturnCode.NON_FINITE
                message = f"non-finite state at t = {tau * nd.time_scale:.9g} s"
                break
            load = load0_seg + e * (tau - tau0_seg)
            ended = False
            for k in sorted(adv.roots):
                ended = rec.root(k, tau, z, load) or ended
            if adv.roots or tau >= t_bound - tiny:
                # a root or the segment's end, never a save point: the save grid changes no
                # measure (integrators.core.events; the driver sees no step ends)
                rec.observe(float(z[0]))
            if tau >= grid[i_save] - tiny:
                # a save time as it was asked for (τ and back is not exact)
                saved_t.append(grid_s[i_save] if given and tau <= grid[i_save] + tiny
                               else tau * nd.time_scale)
                saved_z.append(z.copy())
                while grid[i_save] <= tau + tiny:
                    i_save += 1
            if calls % check_every == 0:
                if progress:
                    progress(tau * nd.time_scale)
                if budget.exceeded():
                    retcode = ReturnCode.WALL_TIME
                    message = (f"wall-time budget of {budget.wall_s} s used up at "
                               f"t = {tau * nd.time_scale:.6g} s of {problem.t_end:g} s")
                    break
            if ended and two_speed:
                fast_until = tau + nd.tau_fast
                break
            if tau >= t_bound - tiny:
                break
    if progress:
        progress(tau * nd.time_scale)
    if saved_t[-1] < tau * nd.time_scale and (not given or retcode is not ReturnCode.SUCCESS):
        saved_t.append(tau * nd.time_scale)
        saved_z.append(z)
    if unasked:
        saved_t, saved_z = saved_t[1:], saved_z[1:]
    h, eta, psi = from_ode_state(nd.law_code, nd.beta, np.array(saved_z))
    return RawRun(t=np.array(saved_t),
                  y=np.column_stack(problem.dimensional_state(h, eta, psi)),
                  events=rec.table(problem, nd), stats=solver.stats, retcode=retcode,
                  message=message)
