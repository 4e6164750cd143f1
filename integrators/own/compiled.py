"""The Python side of the own adaptive methods: arrays in, one compiled call, a ``RawRun`` out.

:class:`CompiledAlgorithm` is the base of every method built on :mod:`integrators.own.engine`.
A subclass names its compiled entry points (``kernel`` and ``fixed``, module-level numba
functions of its own module that call :func:`integrators.own.engine.run` and
:func:`integrators.own.engine.fixed_steps` with its step), its ``workspace`` and its constants;
``run`` does the rest: the save grid, the state and scratch arrays, the call (repeated only for a progress bar, every
:data:`CHUNK_STEPS` accepted steps, or to enlarge the events table) and the conversion.
``Solution.meta`` reports the engine's (re)starts, the roots reported of each kind, the arrests
and ``kernel_s``, the wall time spent in the compiled calls (s): a whole ``solve`` call's wall time
less it is what the Python side costs.
"""

from __future__ import annotations

import math
import time
from typing import Callable, ClassVar

import numpy as np

from integrators.core.cache import FIRST_COMPILE, SENSITIVE_COMPILE, announce_compile
from integrators.core.events import DIRECTIONS, N_EVENTS, events_table
from integrators.core.registry import AdaptiveAlgorithm
from integrators.core.solution import RawRun, ReturnCode, Stats
from integrators.own import batch as B
from integrators.own import engine as E
from integrators.own import sensitivity as SE
from problems.formulations import from_ode_state

__all__ = ["CompiledAlgorithm", "failure", "settled_message", "CHUNK_STEPS"]

#: accepted steps per compiled call when a progress bar is shown (~0.05 s), and without one
#: (~0.5 s: Ctrl-C is seen between calls); the wall budget is read inside
CHUNK_STEPS = 1 << 16
LONG_CHUNK_STEPS = 1 << 20
_EVENTS_START = 64
_DIRS = np.array(DIRECTIONS, dtype=np.int64)
#: the engine's starting arrays by (problem, method, settings), so that repeated solves of one
#: problem (a study's repeats, a fit's forward model) skip making them: at most this many kept
_STARTS: dict = {}
_STARTS_KEPT = 64
#: the root functions, in the order of :mod:`integrators.core.events` (``Solution.meta["roots"]``)
ROOT_NAMES = ("start", "end", "h_extremum", "peak")


def failure(status: int, t_stop: float, max_steps: int, wall_s: float | None,
             t_end: float) -> tuple[ReturnCode, str]:
    """The retcode and message of an engine status other than DONE, stopped at ``t_stop`` (s)."""
    at = f"t = {t_stop:.6g} s"
    return {
        E.NONFINITE: (ReturnCode.NON_FINITE, f"non-finite state at {at}"),
        E.UNDERFLOW: (ReturnCode.STEP_UNDERFLOW, f"step size underflow (t + h == t, or "
                                                 f"{E.FLOOR_STEPS} steps in a row below "
                                                 f"{E.FLOOR_REL:.1e} t) at {at}"),
        E.MAX_STEPS: (ReturnCode.MAX_STEPS, f"step budget of {max_steps} used up at {at}"),
        E.WALL_TIME: (ReturnCode.WALL_TIME, f"wall-time budget of {wall_s} s used up at {at} "
                                            f"of {t_end:g} s"),
    }[status]


def settled_message(t_stop: float, t_end: float) -> str:
    """What a run that stopped on its settled cycle (``settle``) says: where it stopped."""
    return f"settled: stopped at t = {t_stop:.6g} s of {t_end:g} s, its cycle repeating"


def _sensitivity_arrays(directions, n_grid: int, n_events: int, error_control: bool,
                        workspace):
    """The arrays of :func:`integrators.own.sensitivity.sense` for ``directions`` (None: a
    plain solve), the method's stage workspace made by ``workspace``."""
    if not directions:
        return None
    return SE.arrays(SE.direction_matrix(directions), n_grid, n_events, error_control,
                     workspace)


class CompiledAlgorithm(AdaptiveAlgorithm):
    """An adaptive method of this project on the compiled engine: the whole solve (events,
    loading switches, save grid, budgets) runs in numba, so it offers the numba tier only."""

    library: ClassVar[str] = "rsfbench (numba)"
    package: ClassVar[str] = "own"
    compiled: ClassVar[bool] = True
    settles: ClassVar[bool] = True
    rhs_tiers: ClassVar[tuple[str, ...]] = ("numba",)
    #: the compiled entry points (set by each method module) and the method's workspace
    #: (a compiled function returning its scratch arrays: the kernel allocates nothing)
    kernel: ClassVar[Callable]
    fixed: ClassVar[Callable]
    workspace: ClassVar[Callable]
    #: the method's batch entry points (:func:`integrators.own.batch.run_batch` and
    #: :func:`~integrators.own.batch.run_serial` with its kernel)
    batch_kernel: ClassVar[Callable]
    batch_serial: ClassVar[Callable]
    #: the engine's method constants (integrators.own.engine.P): INIT_EXPONENT, Q, STICK_PEAKS,
    #: FSAL, HERMITE, STAGES
    constants: ClassVar[dict] = {}

    @classmethod
    def library_version(cls) -> str:
        import numba
        return f"numba {numba.__version__}"

    def run(self, problem, output, budget, progress, sensitivity=(), sensitivity_error=False,
            settle=0.0):
        """The solve; with ``sensitivity`` (:class:`problems.directions.Direction` objects)
        also the forward sensitivities along them (:mod:`integrators.own.sensitivity`), in
        ``RawRun.sensitivity``, with their error in the step control if
        ``sensitivity_error``; with ``settle`` > 0, stopped at the end of the event where its
        cycle has settled to that relative tolerance (:func:`integrators.core.cycles.
        settled`)."""
        nd = problem.nondimensional()
        grid_t = output.times(problem.t_end)
        # the kernel saves the start as the grid's first point: one not asked for is dropped
        unasked = grid_t[0] > 0.0
        if unasked:
            grid_t = np.concatenate(([0.0], grid_t))
        grid = grid_t / nd.time_scale
        if grid_t[-1] == problem.t_end:
            grid[-1] = nd.tau_end
        st, p, Z, G = self._start(nd, budget.deadline() if budget is not None else math.inf)
        p[E.P["SETTLE"]] = settle
        saved, ev = np.empty((len(grid), 3)), np.empty((_EVENTS_START, 8))
        saved[0] = Z[E.ZROW["ZC"]]
        st[E.ST["NEXT_SAVE"]] = 1
        n_max = CHUNK_STEPS if progress is not None else LONG_CHUNK_STEPS
        # the scratch arrays made by numpy (the compiled makers' boxing costs microseconds)
        ws, sc = type(self).workspace.py_func(), E.scratch.py_func()
        sa = _sensitivity_arrays(sensitivity, len(grid), len(ev), sensitivity_error,
                                 type(self).sensitivity_workspace)
        kernel = type(self).kernel if sa is None else type(self).sensitive_kernel
        what, expected = ("", FIRST_COMPILE) if sa is None else ("sensitive ", SENSITIVE_COMPILE)
        announce_compile(kernel, f"the {self.name} {what}kernel", expected)
        kernel_s = 0.0
        while True:
            start = time.perf_counter()
            status = (kernel(ws, sc, st, p, Z, G, _DIRS, grid, saved, ev, n_max) if sa is None
                      else kernel(ws, sc, st, p, Z, G, _DIRS, grid, saved, ev, n_max, sa))
            kernel_s += time.perf_counter() - start
            if status == E.GROW:
                ev = np.concatenate([ev, np.empty_like(ev)])
                if sa is not None:
                    sa = SE.grow_events(sa)
            elif status == E.CHUNK:
                if progress is not None:
                    progress(st[E.CURSOR] * nd.time_scale)
                if budget is not None and budget.exceeded():
                    status = E.WALL_TIME
                    break
            else:
                break
        if progress is not None:
            progress(st[E.CURSOR] * nd.time_scale)
        raw = self._raw(problem, nd, status, st, Z, grid_t, saved, ev, budget)
        raw.meta["kernel_s"] = kernel_s
        if status == E.SETTLED:
            raw.meta["settle"] = settle
        if sa is not None:
            raw.sensitivity = SE.physical(problem, sensitivity, saved[:len(raw.t)], sa,
                                          ev[:int(st[E.REC + N_EVENTS])])
        if unasked:
            raw.t, raw.y = raw.t[1:], raw.y[1:]
            if raw.sensitivity is not None:
                raw.sensitivity.y = raw.sensitivity.y[1:]
        return raw

    #: has forward sensitivities (:mod:`integrators.own.sensitivity`: Rodas5P's stages,
    #: RadauIIA5's collocation equations), the kernel that carries them and the maker of
    #: their stage workspace
    sensitive: ClassVar[bool] = False
    sensitive_kernel: ClassVar[Callable | None] = None
    #: the compiled batch entry points with sensitivities, parallel and serial
    #: (:mod:`integrators.own.batch_sensitivity`)
    sensitive_batch: ClassVar[tuple | None] = None
    sensitivity_workspace: ClassVar[Callable | None] = None

    def _start(self, nd, deadline: float):
        """The arrays (st, p, Z, G) of a solve of ``nd`` (:func:`integrators.own.engine.
        new_state`), copied from the last ones made for the same problem and settings."""
        key = (id(nd), type(self), self.rtol, self.atol, self.max_steps)
        made = _STARTS.get(key)
        if made is None or made[0] is not nd:           # (the problem is held: ids stay unique)
            if len(_STARTS) >= _STARTS_KEPT:
                _STARTS.clear()
            made = (nd, E.new_state(nd, self.rtol, self.atol, self.constants, self.max_steps,
                                    math.inf))
            _STARTS[key] = made
        st, p, Z, G = (a.copy() for a in made[1])
        p[E.P["DEADLINE"]] = deadline
        return st, p, Z, G

    def _raw(self, problem, nd, status, st, Z, grid_t, saved, ev, budget) -> RawRun:
        ts = nd.time_scale
        n = int(st[E.ST["NEXT_SAVE"]])
        t, z = grid_t[:n], saved[:n]
        retcode, message = ReturnCode.SUCCESS, ""
        meta = {}
        if status == E.SETTLED:
            t_stop = st[E.ST["LAST_T"]] * ts
            message, meta["settled_s"] = settled_message(t_stop, problem.t_end), t_stop
            if n < len(grid_t) and not (n and t[-1] >= t_stop):    # the stop, if cut short
                t, z = np.append(t, t_stop), np.vstack([z, Z[E.ZROW["ZC"]]])
        elif status != E.DONE:
            retcode, message = failure(status, st[E.TAU] * ts, self.max_steps,
                                       budget.wall_s if budget else None, problem.t_end)
            # the state where it stopped: the end of the last step if it is a valid one (a
            # budget ran out), else the last state handed on
            budget_stop = status in (E.MAX_STEPS, E.WALL_TIME)
            tau_stop, z_stop = ((st[E.TAU], Z[0]) if budget_stop and np.isfinite(Z[0]).all()
                                else (st[E.ST["LAST_T"]], Z[E.ZROW["ZC"]]))
            if tau_stop * ts > (t[-1] if n else -np.inf):
                t, z = np.append(t, tau_stop * ts), np.vstack([z, z_stop])
        h, eta, psi = from_ode_state(nd.law_code, nd.beta, z)
        stats = Stats(nfev=int(st[E.NFEV]), njev=int(st[E.NJEV]), steps=int(st[E.STEPS]),
                      rejected=int(st[E.REJECTED]))
        roots = st[E.ST["ROOTS"]:E.ST["ROOTS"] + 4].astype(int).tolist()
        meta.update(starts=int(st[E.ST["STARTS"]]), roots=dict(zip(ROOT_NAMES, roots)),
                    arrests=int(st[E.ST["ARRESTS"]]))
        y = np.empty((len(t), 3))
        y[:, 0], y[:, 1], y[:, 2] = problem.dimensional_state(h, eta, psi)
        return RawRun(t=t, y=y,
                      events=events_table(ev[:int(st[E.REC + N_EVENTS])], problem, nd),
                      stats=stats, retcode=retcode, message=message, meta=meta)

    def batch_inputs(self, problems, wall_budget: float | None = None,
                     curve_margin: float = 0.0, settle: float = 0.0):
        """The per-point inputs (P, Z0, C) of :mod:`integrators.own.batch` for ``problems``
        (``curve_margin``: s before and after the event a curve reaches; ``settle``:
        :meth:`run`'s)."""
        from problems.stability import growth_rates
        n = len(problems)
        growth = growth_rates(problems)          # kept on each problem: once per point
        width = E.N_P + max((len(p.nondimensional().history) for p in problems), default=0)
        # a shorter history is padded with zeros: its piece count says where it ends
        P, Z0, C = np.zeros((n, width)), np.empty((n, 3)), np.empty((n, B.N_C))
        budget = math.inf if wall_budget is None else wall_budget
        for i, problem in enumerate(problems):
            nd = problem.nondimensional()
            _, p, Z, _ = E.new_state(nd, self.rtol, self.atol, self.constants, self.max_steps,
                                     math.inf)
            P[i, :len(p)] = p
            P[i, E.P["SETTLE"]] = settle
            Z0[i] = Z[E.ZROW["ZC"]]
            law = problem.law
            C[i] = (nd.time_scale, problem.f0, nd.force_h, law.v0, law.lc, problem.normal_force,
                    law.a, law.b, problem.loading.v_slow, problem.t_end, growth[i],
                    budget, problem.steady_velocity, problem.radiation_damping,
                    curve_margin / nd.time_scale)
        return P, Z0, C

    def solve_batch(self, problems, wall_budget: float | None = None,
                    parallel: bool = True, curve_points: int = 0, curve_margin: float = 0.0,
                    sensitivity=None, sensitivity_error: bool = True, settle: float = 0.0):
        """Solve and summarise every problem of ``problems`` in one compiled call, on numba's
        threads or (``parallel`` False) on this thread only (:mod:`integrators.own.batch`): one
        row of ``batch.R`` per problem. Each solve is the one :func:`integrators.solve` makes
        with ``max_points=2`` and ``wall_budget``. With ``curve_points`` = n > 1, returns
        ``(R, CURVE)``: also τ and the ODE state z = (h, u, s) at n times spread over the last
        event of each point with a limit cycle (:mod:`integrators.own.batch`; NaN for the
        others), and with ``curve_margin`` (s) > 0 over that much before and after it too.
        With ``sensitivity`` (parameter names, as :func:`integrators.solve`'s), returns
        ``(R, GRAD)``: also the gradient of each point's limit-cycle metrics
        (:mod:`integrators.own.batch_sensitivity`), not with curves. ``settle`` > 0: each
        solve is :func:`integrators.solve`'s with that ``settle`` (not with sensitivities)."""
        if curve_points == 1 or curve_points < 0:
            raise ValueError(f"curve_points must be 0 or at least 2, got {curve_points!r}")
        if sensitivity is not None:
            if settle:
                raise ValueError("settle: a batch with sensitivities runs to t_end; ask for "
                                 "one or the other")
            if curve_points:
                raise ValueError("sensitivity: a batch with curves has no sensitivities; ask "
                                 "for one or the other")
            return self._solve_batch_sensitive(problems, wall_budget, parallel, sensitivity,
                                               sensitivity_error)
        P, Z0, C = self.batch_inputs(problems, wall_budget, curve_margin, settle)
        out = np.empty((len(problems), B.N_R))
        curve = np.empty((len(problems), curve_points, 4))
        if parallel:
            order = np.random.default_rng(0).permutation(len(problems))  # balance the threads
            announce_compile(type(self).batch_kernel, f"the {self.name} batch kernel")
            type(self).batch_kernel(P, Z0, C, _DIRS, out, order, curve)
        else:
            announce_compile(type(self).batch_serial, f"the {self.name} serial batch kernel")
            type(self).batch_serial(P, Z0, C, _DIRS, out, curve)
        return (out, curve) if curve_points else out

    def _solve_batch_sensitive(self, problems, wall_budget, parallel: bool, sensitivity,
                               control: bool):
        """:meth:`solve_batch` with ``sensitivity``: ``(R, GRAD)``, GRAD (points × 4 metrics
        × parameters) in SI units; ValueError for a method without sensitivities or a name a
        point lacks, before any work."""
        from problems.directions import direction, sensitive_request, sensitivity_names
        control = sensitive_request(self, sensitivity, control)
        dirs = [[direction(p, n) for n in sensitivity_names(p, sensitivity)] for p in problems]
        n = len(dirs[0]) if dirs else 0
        D = np.array([SE.direction_matrix(d) for d in dirs]).reshape(len(problems), n, SE.N_DIR)
        X = np.array([SE.si_columns(d) for d in dirs]).reshape(len(problems), n, 4)
        P, Z0, C = self.batch_inputs(problems, wall_budget)
        out, grad = np.empty((len(problems), B.N_R)), np.empty((len(problems), 4, n))
        entry, serial = type(self).sensitive_batch
        if parallel:
            order = np.random.default_rng(0).permutation(len(problems))  # balance the threads
            announce_compile(entry, f"the {self.name} sensitive batch kernel",
                             SENSITIVE_COMPILE)
            entry(P, Z0, C, _DIRS, D, X, float(control), out, grad, order)
        else:
            announce_compile(serial, f"the {self.name} sensitive serial batch kernel",
                             SENSITIVE_COMPILE)
            serial(P, Z0, C, _DIRS, D, X, float(control), out, grad)
        return out, grad

    def fixed_steps(self, nd, z0, span: float, n: int) -> np.ndarray:
        """``n`` equal steps over ``span`` (τ) from z0 under the slow loading, every one
        accepted, no error control (order studies: :func:`benchmarks.devtools.convergence.
        fixed_step_orders`): z at the end."""
        _, p, _, _ = E.new_state(nd._replace(tau_fast=0.0), np.inf, np.inf, self.constants, 0,
                                 math.inf)
        return type(self).fixed(p, np.asarray(z0, dtype=float), span / n, n)
