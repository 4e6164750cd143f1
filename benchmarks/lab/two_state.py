"""The quasi-static slider with two state variables, compiled: the forward model of a laboratory
fit with (b2, Dc2), which :class:`problems.SpringSlider` (one state) does not hold.

In friction units, with Lk = ln(v0 θk/Dck) (0 at steady sliding at v0)::

    μ = μ0 + a ln(v/v0) + b L1 + b2 L2           dμ/dt = k′ (vL − v)
    aging:  dLk/dt = (v0/Dck) e^(−Lk) − v/Dck      slip:  dLk/dt = −(v/Dck) (ln(v/v0) + Lk)
    Nagata: dL1/dt = the aging law's − (c/b) dμ/dt (the first state only)

(Dieterich 1979, Ruina 1983; two state variables as in Blanpied et al. 1998 and RSFit3000;
b2 may be negative, an evolution that strengthens, as clays show.) Solved for (μ, L1, L2) with
Rodas5P: the engine's stage loop (:func:`integrators.own.rodas5p.stages`: order 5, its
4th-order dense output) on the analytic Jacobian, elementary step control on atol + rtol·|y|, a
restart at each switch of the load point; μ at the record's times from the dense output. Each
state's rate is the problems' own (:func:`problems.formulations.state_rate`, in the time
Dck/v0 of its state, Lk being the ODE form's s), under the problems' law codes: an unknown code
gives NaN, never another law's formulas. A law's stress-rate coupling (the Nagata law's c) acts
on the first state only. It is checked against
:mod:`benchmarks.lab.independent_model` (scipy's Radau) and, with b2 = 0, against the project's
slider (tests/test_lab_fit.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from integrators.own.rodas5p import stages, workspace
from problems.formulations import N_Q, Q_E, Q_LAW, Q_LAWP, state_rate, state_rate_partials
from problems._validate import units_checked_already
from problems.friction import compiled_law_code, law_from_name, law_parameters

__all__ = ["two_state_friction", "MAX_STEPS"]

#: steps per run before it is given up (a NaN result)
MAX_STEPS = 2_000_000
# p: the first state's problem vector q (problems.formulations: its law code, its γ at Q_LAWP
# and the load point's speed over v0 at Q_E), the second's, then a, b, dc, b2, dc2, k, v0, μ0
# and the load point's speed vl (m/s)
_Q1, _Q2 = 0, N_Q
_A, _B, _DC, _B2, _DC2, _K, _V0, _MU0, _VL = range(2 * N_Q, 2 * N_Q + 9)
N_P = 2 * N_Q + 9


@njit(cache=True, error_model="numpy", inline="always")
def _ln_w(p, y):
    """ln(v/v0) from the friction: (μ − μ0 − b L1 − b2 L2)/a."""
    return (y[0] - p[_MU0] - p[_B] * y[1] - p[_B2] * y[2]) / p[_A]


@njit(cache=True, error_model="numpy")
def _rate(p, y, f):
    """(dμ/dt, dL1/dt, dL2/dt) at y into ``f``."""
    u = _ln_w(p, y)
    w = math.exp(u)
    f[0] = p[_K] * (p[_VL] - p[_V0] * w)
    f[1] = p[_V0] / p[_DC] * state_rate(p[_Q1:_Q1 + N_Q], u, y[1], w)
    f[2] = p[_V0] / p[_DC2] * state_rate(p[_Q2:_Q2 + N_Q], u, y[2], w)


@njit(cache=True, error_model="numpy")
def _jacobian(p, y, jac):
    """∂f/∂(μ, L1, L2) at y into ``jac``."""
    u = _ln_w(p, y)
    w = math.exp(u)
    du = (1.0 / p[_A], -p[_B] / p[_A], -p[_B2] / p[_A])          # ∂u/∂(μ, L1, L2)
    for j in range(3):
        jac[0, j] = -p[_K] * p[_V0] * w * du[j]
    for s in range(2):
        q0, scale = (_Q1, p[_V0] / p[_DC]) if s == 0 else (_Q2, p[_V0] / p[_DC2])
        r_u, r_s = state_rate_partials(p[q0:q0 + N_Q], u, y[1 + s], w)
        for j in range(3):
            jac[1 + s, j] = scale * r_u * du[j]
        jac[1 + s, 1 + s] += scale * r_s


@njit(cache=True, error_model="numpy")
def _dense_mu(t, h, y, y1, D, time):
    """μ at ``time`` in the step [t, t + h] from Rodas5P's 4th-order dense output."""
    x = (time - t) / h
    w = 1.0 - x
    return w * y[0] + x * (y1[0] + w * (D[0, 0] + x * (D[1, 0] + x * D[2, 0])))


@njit(cache=True, error_model="numpy")
def _run(p, velocities, bounds, times, rtol, atol, out):
    """μ at ``times`` (within [bounds[0], bounds[-1]]) into ``out``; returns the steps taken,
    or −1 if a run failed."""
    ws = workspace()
    y, f, y1, D = np.zeros(3), np.empty(3), np.empty(3), np.empty((3, 3))
    y[0] = p[_MU0]
    i_out, steps, n_out = 0, 0, times.shape[0]
    while i_out < n_out and times[i_out] <= bounds[0]:
        out[i_out] = y[0]
        i_out += 1
    for piece in range(velocities.shape[0]):
        t, t_end = bounds[piece], bounds[piece + 1]
        p[_VL] = velocities[piece]
        p[_Q1 + Q_E] = p[_Q2 + Q_E] = velocities[piece] / p[_V0]
        h = 1e-6 * (t_end - t)
        while t < t_end:
            if steps > MAX_STEPS:
                return -1
            h = min(h, t_end - t)
            _rate(p, y, f)
            _jacobian(p, y, ws[0])
            err = stages(_rate, p, rtol, atol, h, ws, y, f, y1, D)
            while err > 1.0:
                h *= 0.1 if err == np.inf else max(0.2, 0.9 * err ** -0.2)
                if h < 1e-14 * max(abs(t), 1.0):
                    return -1
                err = stages(_rate, p, rtol, atol, h, ws, y, f, y1, D)
            steps += 1
            t_new = t + h if t + h < t_end else t_end
            while i_out < n_out and times[i_out] <= t_new:
                out[i_out] = _dense_mu(t, h, y, y1, D, times[i_out])
                i_out += 1
            t = t_new
            y[:] = y1
            h *= min(5.0, 0.9 * err ** -0.2) if err > 0 else 5.0
    return steps


def _parameters(law, a, b, dc, k, b2, dc2, c, v0, mu0):
    """The vector p of :func:`_run` (the module's comment), the law's code and γ from
    :mod:`problems.friction` (ValueError for a law it does not know)."""
    params = dict(a=a, b=b, lc=dc, v0=v0)
    if "c" in law_parameters(law):
        params["c"] = c
    with units_checked_already():      # a fit's trial values are no user's typing
        one = law_from_name(law, **params)
    p = np.zeros(N_P)
    p[_Q1 + Q_LAW] = p[_Q2 + Q_LAW] = compiled_law_code(one)
    p[_Q1 + Q_LAWP] = one.stress_coefficient / b * k * dc if one.stress_coefficient else 0.0
    p[[_A, _B, _DC, _B2, _DC2, _K, _V0, _MU0]] = a, b, dc, b2, dc2, k, v0, mu0
    return p


def two_state_friction(times, velocities, switch_times, a, b, dc, k, b2=0.0, dc2=1.0,
                       law="aging", c=0.0, mu0=0.6, rtol=1e-10, atol=1e-10):
    """μ at the record's times of the two-state slider (the module docstring) on a load point
    at ``velocities`` between ``switch_times``, from steady sliding at the first speed.

    Parameters
    ----------
    times : array of float
        The record's times (s, from 0, increasing).
    velocities : sequence of float
        The load point's speed on each piece (m/s); v0 is the first.
    switch_times : sequence of float
        When the load point changes speed (s), one fewer than ``velocities``.
    a, b, b2 : float
        The direct effect and the two states' evolution effects (b2 may be negative).
    dc, dc2 : float
        The two states' critical slips (m).
    k : float
        The stiffness in friction per slip, k′ = k/Fn (1/m).
    law : str
        A law of :data:`problems.friction.LAWS` (its evolution, for both states).
    c : float
        The law's stress-rate coefficient (the Nagata law's c), on the first state only.
    mu0 : float
        Steady-state friction at v0.
    rtol, atol : float
        The step control's tolerances on (μ, L1, L2).

    Returns
    -------
    mu : ndarray
        μ at ``times``; NaN everywhere if the run failed.
    steps : int
        The steps taken (−1 if the run failed).

    Raises
    ------
    ValueError
        For a law the compiled forms do not know, or a law's parameter out of its range.
    """
    times = np.ascontiguousarray(times, dtype=float)
    p = _parameters(law, a, b, dc, k, b2, dc2, c, float(velocities[0]), mu0)
    bounds = np.array([0.0, *switch_times, max(float(times[-1]), *switch_times)])
    out = np.empty(len(times))
    steps = _run(p, np.asarray(velocities, dtype=float), bounds, times, rtol, atol, out)
    if steps < 0 or not np.isfinite(out).all():
        out[:] = np.nan
    return out, steps
