"""The quasi-static slider with two state variables, compiled: the forward model of a laboratory
fit with (b2, Dc2), which :class:`problems.SpringSlider` (one state) does not hold.

In friction units, with Lk = ln(v0 θk/Dck) (0 at steady sliding at v0)::

    μ = μ0 + a ln(v/v0) + b L1 + b2 L2           dμ/dt = k′ (vL − v)
    aging:  dLk/dt = (v0/Dck) e^(−Lk) − v/Dck      slip:  dLk/dt = −(v/Dck) (ln(v/v0) + Lk)
    Nagata: dL1/dt = the aging law's − (c/b) dμ/dt (the first state only)

(Dieterich 1979, Ruina 1983; two state variables as in Blanpied et al. 1998 and RSFit3000;
b2 may be negative, an evolution that strengthens, as clays show.) Solved for (μ, L1, L2) with
Rodas5P: the engine's stage loop (:func:`integrators.own.rodas5p_stages.stages`: order 5, its
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
import time

import numpy as np
from numba import njit

from integrators.core.clock import monotonic
from integrators.own.rodas5p_stages import (dense_sensitivities, directions, no_after,
                                            sensitivity_workspace, stage_sensitivities, stages,
                                            workspace)
from problems.formulations import (N_Q, Q_E, Q_LAW, Q_LAWP, state_rate, state_rate_partials,
                                   state_rate_second_partials)
from problems._validate import units_checked_already
from problems.friction import compiled_law_code, law_from_name, law_parameters

__all__ = ["two_state_friction", "two_state_sensitivities", "MAX_STEPS", "SENSITIVE"]

#: steps per run before it is given up (a NaN result)
MAX_STEPS = 2_000_000
#: steps between two readings of the clock (a wall budget's deadline)
CLOCK_EVERY = 256
# p: the first state's problem vector q (problems.formulations: its law code, its γ at Q_LAWP
# and the load point's speed over v0 at Q_E), the second's, then a, b, dc, b2, dc2, k, v0, μ0
# and the load point's speed vl (m/s)
_Q1, _Q2 = 0, N_Q
_A, _B, _DC, _B2, _DC2, _K, _V0, _MU0, _VL = range(2 * N_Q, 2 * N_Q + 9)
N_P = 2 * N_Q + 9
#: the parameters θ whose sensitivities ∂μ/∂θ the model gives, in this order (c: the Nagata
#: law's, through the first state's γ = c k′ Dc/b)
SENSITIVE = ("a", "b", "dc", "k", "b2", "dc2", "c")
_TA, _TB, _TDC, _TK, _TB2, _TDC2, _TC = range(7)
N_T = len(SENSITIVE)


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


@njit(cache=True, error_model="numpy", inline="always")
def _u_theta(p, y, u, m):
    """(∂u/∂θ_m, ∂²u/∂μ∂θ_m, ∂²u/∂L1∂θ_m, ∂²u/∂L2∂θ_m), u = (μ − μ0 − b L1 − b2 L2)/a."""
    a = p[_A]
    if m == _TA:
        return -u / a, -1.0 / (a * a), p[_B] / (a * a), p[_B2] / (a * a)
    if m == _TB:
        return -y[1] / a, 0.0, -1.0 / a, 0.0
    if m == _TB2:
        return -y[2] / a, 0.0, 0.0, -1.0 / a
    return 0.0, 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _gamma_theta(p, gam, m):
    """∂γ/∂θ_m of the first state's γ = c k′ Dc/b (the Nagata law's; 0 for the others, whose
    rates do not depend on γ; c is asked for under the Nagata law only)."""
    if m == _TC:
        return p[_K] * p[_DC] / p[_B]
    if gam == 0.0:              # c = 0 or no such law: no term, even at b = 0
        return 0.0
    if m == _TB:
        return -gam / p[_B]
    if m == _TDC:
        return gam / p[_DC]
    if m == _TK:
        return gam / p[_K]
    return 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _asks_c(which):
    for m in which:
        if m == _TC:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _partials(p, which, y, jac, fth, s):
    """At y: ∂f/∂y into ``jac[s]`` (3×3) and ∂f/∂θ for the parameters ``which`` (indices of
    :data:`SENSITIVE`) into ``fth[s]``'s columns. f = (dμ/dt, dL1/dt, dL2/dt) of :func:`_rate`:
    f0 = k′ (vL − v0 e^u), f_r = (v0/Dc_r) R(u, L_r; γ) for the states."""
    a = p[_A]
    u = _ln_w(p, y)
    w = math.exp(u)
    c0 = -p[_K] * p[_V0] * w                      # ∂f0/∂u
    jac[s, 0, 0], jac[s, 0, 1], jac[s, 0, 2] = c0 / a, -c0 * p[_B] / a, -c0 * p[_B2] / a
    for n in range(which.shape[0]):
        m = which[n]
        ut = _u_theta(p, y, u, m)[0]
        fth[s, 0, n] = c0 * ut + (p[_VL] - p[_V0] * w if m == _TK else 0.0)
    for r in range(1, 3):
        q0, dc, td = (_Q1, p[_DC], _TDC) if r == 1 else (_Q2, p[_DC2], _TDC2)
        q = p[q0:q0 + N_Q]
        g = p[_V0] / dc
        gam = q[Q_LAWP]                              # γ: the first state's only
        rate = state_rate(q, u, y[r], w)
        r_u, r_s = state_rate_partials(q, u, y[r], w)
        r_g = 0.0
        if r == 1 and (gam != 0.0 or _asks_c(which)):
            r_g = state_rate_second_partials(q, u, y[r], w)[3]
        cu = g * r_u
        jac[s, r, 0], jac[s, r, 1], jac[s, r, 2] = cu / a, -cu * p[_B] / a, -cu * p[_B2] / a
        jac[s, r, r] += g * r_s
        for n in range(which.shape[0]):
            m = which[n]
            ut = _u_theta(p, y, u, m)[0]
            d_gam = _gamma_theta(p, gam, m) if r == 1 else 0.0
            fth[s, r, n] = (-rate if m == td else 0.0) * g / dc + g * (r_u * ut + r_g * d_gam)


@njit(cache=True, error_model="numpy")
def _second_partials(p, which, y, hyy, hyt):
    """At y: ∂²f/∂y∂y into ``hyy`` (3×3×3) and ∂²f/∂y∂θ for the parameters ``which`` into
    ``hyt`` (3×3×columns): what dJ, the Jacobian's change with θ along the sensitivities,
    needs (:func:`_partials` has f's names)."""
    a = p[_A]
    u = _ln_w(p, y)
    w = math.exp(u)
    uy = (1.0 / a, -p[_B] / a, -p[_B2] / a)
    c0 = -p[_K] * p[_V0] * w
    for j in range(3):
        for l in range(3):
            hyy[0, j, l] = c0 * uy[j] * uy[l]
    for n in range(which.shape[0]):
        m = which[n]
        ut, ut0, ut1, ut2 = _u_theta(p, y, u, m)
        uyt = (ut0, ut1, ut2)
        for j in range(3):
            hyt[0, j, n] = c0 * (ut * uy[j] + uyt[j]) - (p[_V0] * w * uy[j] if m == _TK else 0.0)
    for r in range(1, 3):
        q0, dc, td = (_Q1, p[_DC], _TDC) if r == 1 else (_Q2, p[_DC2], _TDC2)
        q = p[q0:q0 + N_Q]
        g = p[_V0] / dc
        gam = q[Q_LAWP]
        r_u, r_s = state_rate_partials(q, u, y[r], w)
        r_uu, r_us, r_ss, r_g, r_ug = state_rate_second_partials(q, u, y[r], w)
        for n in range(which.shape[0]):
            m = which[n]
            ut, ut0, ut1, ut2 = _u_theta(p, y, u, m)
            uyt = (ut0, ut1, ut2)
            d_gam = _gamma_theta(p, gam, m) if r == 1 else 0.0
            d_g = -g / dc if m == td else 0.0
            for j in range(3):
                on = 1.0 if j == r else 0.0
                hyt[r, j, n] = (d_g * (r_u * uy[j] + r_s * on)
                                + g * ((r_uu * ut + r_ug * d_gam) * uy[j]
                                       + r_u * uyt[j] + r_us * ut * on))
        for j in range(3):
            for l in range(3):
                hyy[r, j, l] = g * r_uu * uy[j] * uy[l]
        for j in range(3):                           # ∂L_r/∂y = e_r (after the fill)
            hyy[r, j, r] += g * r_us * uy[j]
            hyy[r, r, j] += g * r_us * uy[j]
        hyy[r, r, r] += g * r_ss


@njit(cache=True, error_model="numpy")
def _dense_sensitivity(n, h, s0, s1, dd, time, t):
    """∂μ/∂θ_n at ``time`` in the step [t, t + h]: :func:`_dense_mu` differentiated."""
    x = (time - t) / h
    w = 1.0 - x
    return w * s0[n, 0] + x * (s1[n, 0] + w * (dd[0, n, 0] + x * (dd[1, n, 0]
                                                                 + x * dd[2, n, 0])))


@njit(cache=True, error_model="numpy")
def _run(p, velocities, bounds, times, rtol, atol, out, which, dout, deadline):
    """μ at ``times`` (within [bounds[0], bounds[-1]]) into ``out`` and, for each parameter
    index of ``which`` (:data:`SENSITIVE`; empty: none), ∂μ/∂θ there into ``dout``'s columns;
    returns the steps taken, −1 if a run failed, −2 if it ran past ``deadline`` (the
    monotonic clock's s, :func:`integrators.core.clock.monotonic`; read every
    :data:`CLOCK_EVERY` steps)."""
    ws = workspace()
    n_s = which.shape[0]
    sw, dd = sensitivity_workspace(n_s), np.empty((3, n_s, 3))
    y, f, y1, D = np.zeros(3), np.empty(3), np.empty(3), np.empty((3, 3))
    S, S0 = np.zeros((n_s, 3)), np.zeros((n_s, 3))  # steady sliding at v0 for every θ
    y[0] = p[_MU0]
    i_out, steps, n_out = 0, 0, times.shape[0]
    while i_out < n_out and times[i_out] <= bounds[0]:
        out[i_out] = y[0]
        dout[i_out, :] = 0.0
        i_out += 1
    for piece in range(velocities.shape[0]):
        t, t_end = bounds[piece], bounds[piece + 1]
        p[_VL] = velocities[piece]
        p[_Q1 + Q_E] = p[_Q2 + Q_E] = velocities[piece] / p[_V0]
        h = 1e-6 * (t_end - t)
        while t < t_end:
            if steps > MAX_STEPS:
                return -1
            if steps % CLOCK_EVERY == 0 and monotonic() > deadline:
                return -2
            h = min(h, t_end - t)
            _rate(p, y, f)
            _jacobian(p, y, ws[0])
            err = stages(_rate, no_after, p, rtol, atol, h, ws, y, f, y1, D)
            while err > 1.0:
                h *= 0.1 if err == np.inf else max(0.2, 0.9 * err ** -0.2)
                if h < 1e-14 * max(abs(t), 1.0):
                    return -1
                err = stages(_rate, no_after, p, rtol, atol, h, ws, y, f, y1, D)
            steps += 1
            if n_s:
                S0[:, :] = S
                stage_sensitivities(_partials, _second_partials, directions, p, which, h, ws,
                                    sw, y, S)
                dense_sensitivities(sw, dd)
            t_new = t + h if t + h < t_end else t_end
            while i_out < n_out and times[i_out] <= t_new:
                out[i_out] = _dense_mu(t, h, y, y1, D, times[i_out])
                for n in range(n_s):
                    dout[i_out, n] = _dense_sensitivity(n, h, S0, S, dd, times[i_out], t)
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
                       law="aging", c=0.0, mu0=0.6, rtol=1e-10, atol=1e-10, wall_budget=None):
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
    wall_budget : float or None
        Seconds the run may take (None: no limit but :data:`MAX_STEPS`).

    Returns
    -------
    mu : ndarray
        μ at ``times``; NaN everywhere if the run failed.
    steps : int
        The steps taken: −1 if the run failed (its step budget, a non-finite value), −2 if it
        ran out of its wall budget.

    Raises
    ------
    ValueError
        For a law the compiled forms do not know, or a law's parameter out of its range.
    """
    mu, steps, _ = two_state_sensitivities(times, velocities, switch_times, a, b, dc, k, (),
                                           b2=b2, dc2=dc2, law=law, c=c, mu0=mu0, rtol=rtol,
                                           atol=atol, wall_budget=wall_budget)
    return mu, steps


def two_state_sensitivities(times, velocities, switch_times, a, b, dc, k, sensitivity,
                            b2=0.0, dc2=1.0, law="aging", c=0.0, mu0=0.6, rtol=1e-10,
                            atol=1e-10, wall_budget=None):
    """:func:`two_state_friction` and the forward sensitivities ∂μ/∂θ at the record's times
    for the parameters named in ``sensitivity`` (a subset of :data:`SENSITIVE`; ``k`` is k′):
    each step's Rodas5P stages differentiated on the step's own h, reusing its factorisation
    (the derivative of the computed μ with its steps held, exact to rounding; the step control
    sees μ and the states only). Returns (μ, steps, ∂μ/∂θ as an array of one column per
    name); NaN everywhere and steps < 0 as :func:`two_state_friction`'s if the run failed.
    ValueError for a name not in :data:`SENSITIVE`, or c under a law without it."""
    names = tuple(sensitivity)
    for name in names:
        if name not in SENSITIVE:
            raise ValueError(f"sensitivity: no parameter {name!r} in the laboratory model; "
                             f"it has {', '.join(SENSITIVE)}")
    if "c" in names and "c" not in law_parameters(law):
        raise ValueError(f"sensitivity: the {law} law has no stress coefficient c")
    times = np.ascontiguousarray(times, dtype=float)
    p = _parameters(law, a, b, dc, k, b2, dc2, c, float(velocities[0]), mu0)
    bounds = np.array([0.0, *switch_times, max(float(times[-1]), *switch_times)])
    out, dout = np.empty(len(times)), np.empty((len(times), len(names)))
    which = np.array([SENSITIVE.index(n) for n in names], dtype=np.int64)
    deadline = math.inf if wall_budget is None else time.perf_counter() + wall_budget
    steps = _run(p, np.asarray(velocities, dtype=float), bounds, times, rtol, atol, out, which,
                 dout, deadline)
    if steps < 0 or not (np.isfinite(out).all() and np.isfinite(dout).all()):
        out[:], dout[:], steps = np.nan, np.nan, min(steps, -1)
    return out, steps, dout
