"""Driver for step-by-step adaptive solvers with dense output (scipy's ``OdeSolver`` classes).

Owns what solve_ivp would do, so that budgets, progress and the two-speed restarts are ours:
the step loop, event location by root finding on the dense output (Brent's method on each
root function of :mod:`integrators.events`), restarts at event ends under two-speed loading and
at the end of the fast-loading window, trajectory decimation, and counters summed over restarts.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from integrators.events import DIRECTIONS, END, EventRecorder, root_functions
from integrators.solution import RawRun, ReturnCode, Stats
from problems.formulations import OdeForm, from_ode_state, to_ode_state

__all__ = ["run_stepper"]

_CHECK_EVERY = 200     # steps between budget/progress checks


def _crossings(g0: np.ndarray, g1: np.ndarray) -> list[int]:
    out = []
    for k, d in enumerate(DIRECTIONS):
        up = g0[k] < 0.0 <= g1[k]
        down = g0[k] > 0.0 >= g1[k]
        if (d >= 0 and up) or (d <= 0 and down):
            out.append(k)
    return out


def run_stepper(problem, make_solver, rhs_tier: str, max_steps: int, output, budget,
                progress) -> RawRun:
    """Integrate with solvers built by ``make_solver(fun, jac, t0, z0, t_bound)``."""
    nd = problem.nondimensional()
    two_speed = problem.loading.two_speed
    save_dtau = output.interval(problem.t_end) / nd.time_scale
    z = to_ode_state(nd.law_code, nd.beta, nd.x0)
    tau, load, fast_until = 0.0, 0.0, -math.inf
    rec = EventRecorder(nd.x0[0])
    saved_t, saved_z = [0.0], [z.copy()]
    next_save = save_dtau
    stats = Stats()
    retcode, message = ReturnCode.SUCCESS, ""
    tiny = 1e-12 * nd.tau_end
    while tau < nd.tau_end - tiny and retcode is ReturnCode.SUCCESS:
        fast = two_speed and fast_until - tau > tiny
        e = nd.e_fast if fast else nd.e_slow
        t_bound = min(nd.tau_end, fast_until) if fast else nd.tau_end
        form = OdeForm(nd, e, rhs_tier)
        solver = make_solver(form.f, form.jac, tau, z, t_bound)
        tau0_seg, load0_seg = tau, load
        g_old = root_functions(nd, e, z)
        restart = False
        while solver.status == "running":
            message_step = solver.step()
            stats.steps += 1
            if solver.status == "failed":
                retcode = (ReturnCode.STEP_UNDERFLOW if "step size" in str(message_step).lower()
                           else ReturnCode.FAILURE)
                message = str(message_step)
                break
            t_new, z_new = solver.t, solver.y
            if not np.all(np.isfinite(z_new)):
                retcode, message = ReturnCode.NON_FINITE, f"non-finite state at t = {t_new * nd.time_scale:.9g} s"
                break
            g_new = root_functions(nd, e, z_new)
            hits = _crossings(g_old, g_new)
            if hits:
                dense = solver.dense_output()
                roots = sorted((brentq(lambda t, k=k: root_functions(nd, e, dense(t))[k],
                                       solver.t_old, t_new, xtol=1e-14 * max(1.0, t_new),
                                       rtol=4 * np.finfo(float).eps), k) for k in hits)
                for t_root, k in roots:
                    z_root = dense(t_root)
                    ended = rec.root(k, t_root, z_root, load0_seg + e * (t_root - tau0_seg))
                    if ended and two_speed:
                        fast_until = t_root + nd.tau_fast
                        t_new, z_new, restart = t_root, z_root, True
                        break
            rec.observe(float(z_new[0]))
            if t_new >= next_save:
                saved_t.append(t_new)
                saved_z.append(np.array(z_new))
                while next_save <= t_new:
                    next_save += save_dtau
            tau, z, g_old = t_new, np.array(z_new), g_new
            load = load0_seg + e * (tau - tau0_seg)
            if restart:
                break
            if stats.steps % _CHECK_EVERY == 0:
                if progress:
                    progress(tau * nd.time_scale)
                if stats.steps >= max_steps:
                    retcode, message = ReturnCode.MAX_STEPS, f"step budget of {max_steps} used up"
                elif budget.exceeded():
                    retcode = ReturnCode.WALL_TIME
                    message = (f"wall-time budget of {budget.wall_s} s used up at "
                               f"t = {tau * nd.time_scale:.6g} s of {problem.t_end:g} s")
                if retcode is not ReturnCode.SUCCESS:
                    break
        stats.nfev += solver.nfev
        stats.njev += getattr(solver, "njev", 0)
    if progress:
        progress(tau * nd.time_scale)
    if saved_t[-1] < tau:
        saved_t.append(tau)
        saved_z.append(z)
    zs = np.array(saved_z)
    h, eta, psi = from_ode_state(nd.law_code, nd.beta, zs)
    return RawRun(t=np.array(saved_t) * nd.time_scale,
                  y=np.column_stack(problem.dimensional_state(h, eta, psi)),
                  events=rec.table(problem, nd), stats=stats, retcode=retcode, message=message)
