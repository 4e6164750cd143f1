"""The two solvers of Im, Elsworth, Marone & Leeman's spring-slider comparison (public
repository ``limkjae/SpringSlider-RSF``, MIT licence), ported line by line to numba, and the
events of a trajectory they give, so that their time and achieved error stand beside the
project's methods on their own problem (:func:`problems.external.im_spring_slider`).

* :func:`im_scheme`: their implicit method (``SolverComparison3_IMvsMatlabODE_SpringSlider.m``,
  lines 46–131) at a fixed step (theirs: 1e−4 s). Per step the load point moves by vL Δt and is
  held; θ by backward Euler of the aging law; the slip by the exact solution of the oscillator
  with friction frozen at its end-of-step value; v by the trapezoid rule; v found by Newton's
  method with a forward difference of v/1000, from v_old/1e10, to |v_test/v − 1| ≤ 1e−7
  (loosened ×2 at every iteration after the 100th, for the rest of the run); a v < 0 sets
  v = 0. As published, the θ, slip and friction kept for the next step are those of the
  Newton's last difference evaluation (at v(1 + 1e−3) of the last iterate), not of the
  converged v: the port keeps that too.
* :func:`rk4`: classical fourth-order Runge–Kutta at a fixed step (theirs: 1e−6 s) on their
  ODE (line 157: y = (u, v, θ)). Their script's k4 adds dt·k3/2 to the slip where it means
  dt·k3 (``SolverComparison2…``, line 176); the port uses the classical k4.

MATLAB's ode23s, their third, is the Shampine–Reichelt Rosenbrock 2(3) pair: the project's
``Rosenbrock23`` is the same method.

Both ports take any aging-law slider under constant loading: forces per square metre in their
script are forces here (N, N/m, kg); the equations are the same.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from numba import njit

from integrators.core.solution import EVENT_COLUMNS
from problems.loading import event_thresholds

__all__ = ["im_scheme", "rk4", "trajectory_events", "IM_STEP", "RK4_STEP"]

#: their steps (s)
IM_STEP, RK4_STEP = 1e-4, 1e-6


def _constants(problem) -> tuple:
    if (problem.law.name != "aging" or not hasattr(problem.loading, "vl")
            or not problem.mass > 0 or problem.radiation_damping != 0):
        raise ValueError(f"{problem.name}: Im et al.'s solvers are for a slider with mass, "
                         "no radiation damping, the aging law and constant loading")
    law, init = problem.law, problem.initial_state
    return (law.a, law.b, law.lc, law.v0, problem.mu0, problem.normal_force, problem.stiffness,
            problem.mass, problem.loading.vl, init.v, init.theta, init.fs)


def im_scheme(problem, dt: float = IM_STEP) -> tuple:
    """Their implicit method at the fixed step ``dt`` (s): ``(t, v, slip, fs, newton_breaks)``,
    t from 0 (their output starts at dt; the initial state is prepended here)."""
    return _im(*_constants(problem), problem.t_end, dt)


def rk4(problem, dt: float = RK4_STEP) -> tuple:
    """Classical RK4 on their ODE at the fixed step ``dt`` (s): ``(t, v, slip, fs, reached)``,
    cut at the last finite step; ``reached`` its time (s): short of ``t_end`` where the method
    diverged (a step over its stability bound: ~2.8/|λ|, λ ≈ −a Fn/(m v) at slow slip)."""
    t, v, u, fs, last = _rk4(*_constants(problem), problem.t_end, dt)
    return t[:last + 1], v[:last + 1], u[:last + 1], fs[:last + 1], float(t[last])


@njit(cache=True)
def _im(a, b, dc, v0, mu0, fn, k, m, vl, v_ini, theta_ini, fs_ini, t_end, dt):
    n = int(round(t_end / dt))
    t, v_out, u_out, fs_out = np.empty(n + 1), np.empty(n + 1), np.empty(n + 1), np.empty(n + 1)
    omega = math.sqrt(k / m)
    c, s = math.cos(omega * dt), math.sin(omega * dt)
    xl_old = fs_ini / k
    disp_old, theta_old, v_old = 0.0, theta_ini, v_ini
    t[0], v_out[0], u_out[0], fs_out[0] = 0.0, v_ini, 0.0, fs_ini
    v_eps, breaks = 1e-7, 0
    for i in range(1, n + 1):
        xl = xl_old + dt * vl
        v_diff, iteration, broke = 10.0, 0, False
        v = v_old / 1e10
        theta, disp = theta_old, disp_old
        while abs(v_diff - 1.0) > v_eps:
            iteration += 1
            v_test = v
            dv = v / 1000.0
            theta = (theta_old + dt) / (1.0 + v * dt / dc)
            mu = mu0 + b * math.log(v0 * theta / dc) + a * math.log(v / v0)
            f = xl - mu * fn / k
            disp = (disp_old - f) * c + (v_old / omega) * s + f
            f_original = v_test - ((disp - disp_old) / dt * 2.0 - v_old)
            v = v_test + dv
            theta = (theta_old + dt) / (1.0 + v * dt / dc)
            mu = mu0 + b * math.log(v0 * theta / dc) + a * math.log(v / v0)
            f = xl - mu * fn / k
            disp = (disp_old - f) * c + (v_old / omega) * s + f
            nrf = v - ((disp - disp_old) / dt * 2.0 - v_old)
            v = v_test - f_original / ((nrf - f_original) / dv)
            if v < 0.0:
                broke = True
                break
            v_diff = abs(v_test / v)
            if iteration > 100:
                v_eps *= 2.0
        if broke:
            v, theta, disp = 0.0, theta_old + dt, disp_old
            breaks += 1
        t[i], v_out[i], u_out[i], fs_out[i] = i * dt, v, disp, k * (xl - disp)
        disp_old, theta_old, v_old, xl_old = disp, theta, v, xl
    return t, v_out, u_out, fs_out, breaks


@njit(cache=True)
def _rate(a, b, dc, v0, mu0, fn, k, m, vl, xl0, t, u, v, theta):
    dv = k / m * (t * vl + xl0 - u) - (mu0 + a * math.log(v / v0)
                                       + b * math.log(v0 * theta / dc)) * fn / m
    return v, dv, 1.0 - v * theta / dc


@njit(cache=True)
def _rk4(a, b, dc, v0, mu0, fn, k, m, vl, v_ini, theta_ini, fs_ini, t_end, dt):
    n = int(round(t_end / dt))
    t, v_out, u_out, fs_out = np.empty(n + 1), np.empty(n + 1), np.empty(n + 1), np.empty(n + 1)
    xl0 = fs_ini / k
    u, v, th = 0.0, v_ini, theta_ini
    t[0], v_out[0], u_out[0], fs_out[0] = 0.0, v, u, fs_ini
    p = (a, b, dc, v0, mu0, fn, k, m, vl, xl0)
    for i in range(n):
        ti = i * dt
        k1 = _rate(*p, ti, u, v, th)
        k2 = _rate(*p, ti + dt / 2, u + dt * k1[0] / 2, v + dt * k1[1] / 2, th + dt * k1[2] / 2)
        k3 = _rate(*p, ti + dt / 2, u + dt * k2[0] / 2, v + dt * k2[1] / 2, th + dt * k2[2] / 2)
        k4 = _rate(*p, ti + dt, u + dt * k3[0], v + dt * k3[1], th + dt * k3[2])
        u += dt * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]) / 6
        v += dt * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]) / 6
        th += dt * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]) / 6
        if not (math.isfinite(u) and v > 0.0 and math.isfinite(v) and math.isfinite(th)):
            return t, v_out, u_out, fs_out, i          # diverged: v ≤ 0 has no log
        t[i + 1], v_out[i + 1], u_out[i + 1] = (i + 1) * dt, v, u
        fs_out[i + 1] = k * ((i + 1) * dt * vl + xl0 - u)
    return t, v_out, u_out, fs_out, n


def trajectory_events(t, v, slip, fs, loading) -> pd.DataFrame:
    """The events of a fixed-step trajectory, as :attr:`integrators.Solution.events` has them
    (:data:`EVENT_COLUMNS`): an event starts where v rises through 10 vLs and ends where it
    falls through vLs (:func:`problems.loading.event_thresholds`), each crossing's time and
    slip by linear interpolation between the two steps that straddle it (the method's own
    output is its steps); the peak and the spring force's extremes are the steps'."""
    start, end = event_thresholds(loading)
    rows, i, n, after = [], 1, len(t), 0
    while i < n:
        if v[i - 1] <= start < v[i]:
            j = i
            while j < n and not v[j] < end:
                j += 1
            if j == n:                      # not complete within the run
                break
            t0, u0 = _cross(t, slip, v, i, start)
            t1, u1 = _cross(t, slip, v, j, end)
            peak = i + int(np.argmax(v[i:j]))
            rows.append((t0, t1, float(fs[after:i].max()),
                         float(fs[i - 1:j + 1].min()), float(v[peak]), float(t[peak]), u0, u1))
            after, i = j, j + 1
        else:
            i += 1
    return pd.DataFrame(rows, columns=list(EVENT_COLUMNS))


def _cross(t, slip, v, i, level):
    """(time, slip) where v crosses ``level`` between steps i − 1 and i (linearly)."""
    w = (level - v[i - 1]) / (v[i] - v[i - 1])
    return (float(t[i - 1] + w * (t[i] - t[i - 1])),
            float(slip[i - 1] + w * (slip[i] - slip[i - 1])))
