"""The quasi-static slider with two state variables, compiled: the forward model of a laboratory
fit with (b2, Dc2), which :class:`problems.SpringSlider` (one state) does not hold.

In friction units, with Lk = ln(v0 θk/Dck) (0 at steady sliding at v0)::

    μ = μ0 + a ln(v/v0) + b L1 + b2 L2           dμ/dt = k′ (vL − v)
    aging:  dLk/dt = (v0/Dck) e^(−Lk) − v/Dck      slip:  dLk/dt = −(v/Dck) (ln(v/v0) + Lk)
    Nagata: dL1/dt = the aging law's − (c/b) dμ/dt (the first state only)

(Dieterich 1979, Ruina 1983; two state variables as in Blanpied et al. 1998 and RSFit3000;
b2 may be negative, an evolution that strengthens, as clays show.) Solved for (μ, L1, L2) with
Rodas5P (the project's tableau, :mod:`integrators.own.rodas5p`: order 5, its 4th-order dense
output, the analytic Jacobian), elementary step control on atol + rtol·|y|, a restart at each
switch of the load point; μ at the record's times from the dense output. It is checked against
:mod:`benchmarks.lab.independent_model` (scipy's Radau) and, with b2 = 0, against the project's
slider (tests/test_lab_fit.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from integrators.own.linalg import factor, lu_solve3
from integrators.own.rodas5p import A5P, C5P, G5P, H5P

__all__ = ["two_state_friction", "LAW_CODES", "MAX_STEPS"]

LAW_CODES = {"aging": 0, "slip": 1, "nagata": 2}
#: steps per run before it is given up (a NaN result)
MAX_STEPS = 2_000_000
# p: a, b, dc, b2, dc2, k, c, v0, mu0, law
_A, _B, _DC, _B2, _DC2, _K, _C, _V0, _MU0, _LAW = range(10)


@njit(cache=True, error_model="numpy")
def _rates(p, vl, y, f, jac, with_jac):
    a, v0 = p[_A], p[_V0]
    b = (p[_B], p[_B2])
    dc = (p[_DC], p[_DC2])
    law = int(p[_LAW])
    ln_v = (y[0] - p[_MU0] - b[0] * y[1] - b[1] * y[2]) / a
    v = v0 * math.exp(ln_v)
    f[0] = p[_K] * (vl - v)
    dv = (v / a, -b[0] * v / a, -b[1] * v / a)          # ∂v/∂(μ, L1, L2)
    if with_jac:
        for j in range(3):
            jac[0, j] = -p[_K] * dv[j]
    for s in range(2):
        li = y[1 + s]
        if law == 1:
            x = ln_v + li
            f[1 + s] = -(v / dc[s]) * x
            if with_jac:
                for j in range(3):
                    jac[1 + s, j] = -(x + 1.0) / dc[s] * dv[j]
                jac[1 + s, 1 + s] -= v / dc[s]
        else:
            e = math.exp(-li)
            f[1 + s] = (v0 / dc[s]) * e - v / dc[s]
            if with_jac:
                for j in range(3):
                    jac[1 + s, j] = -dv[j] / dc[s]
                jac[1 + s, 1 + s] -= (v0 / dc[s]) * e
    if law == 2:
        r = p[_C] / b[0]
        f[1] -= r * f[0]
        if with_jac:
            for j in range(3):
                jac[1, j] -= r * jac[0, j]


@njit(cache=True, error_model="numpy")
def _run(p, velocities, bounds, times, rtol, atol, out):
    """μ at ``times`` (within [bounds[0], bounds[-1]]) into ``out``; returns the steps taken,
    or −1 if a run failed."""
    y = np.zeros(3)
    y[0] = p[_MU0]
    f, jac, m = np.empty(3), np.empty((3, 3)), np.empty((3, 3))      # m: I − hγJ, factored
    piv = np.empty(3, np.int64)
    K, u, fb, y1, D = np.empty((8, 3)), np.empty(3), np.empty(3), np.empty(3), np.empty((3, 3))
    i_out, steps = 0, 0
    n_out = times.shape[0]
    while i_out < n_out and times[i_out] <= bounds[0]:
        out[i_out] = y[0]
        i_out += 1
    for piece in range(velocities.shape[0]):
        t, t_end, vl = bounds[piece], bounds[piece + 1], velocities[piece]
        if t_end <= t:
            continue
        h = 1e-6 * (t_end - t)
        while t < t_end:
            if steps > MAX_STEPS:
                return -1
            h = min(h, t_end - t)
            _rates(p, vl, y, f, jac, True)
            while True:
                hg = h * G5P
                ok = factor(hg, jac, m, piv)
                for s in range(8):
                    for i in range(3):
                        acc = y[i]
                        for j in range(s):
                            acc += A5P[s, j] * K[j, i]
                        u[i] = acc
                    if s == 0:
                        for i in range(3):
                            fb[i] = f[i]
                    else:
                        _rates(p, vl, u, fb, jac, False)
                    for i in range(3):
                        acc = 0.0
                        for j in range(s):
                            acc += C5P[s, j] * K[j, i]
                        K[s, i] = hg * fb[i] + G5P * acc
                    lu_solve3(m, piv, K, s)
                err = 0.0
                for i in range(3):
                    y1[i] = u[i] + K[7, i]
                    r = abs(K[7, i]) / (atol + rtol * max(abs(y[i]), abs(y1[i])))
                    if not r <= err:
                        err = r
                if not ok or not np.isfinite(err):
                    err = np.inf
                if err <= 1.0:
                    break
                h *= 0.1 if err == np.inf else max(0.2, 0.9 * err ** -0.2)
                if h < 1e-14 * max(abs(t), 1.0):
                    return -1
            steps += 1
            for r in range(3):
                for i in range(3):
                    acc = 0.0
                    for s in range(8):
                        acc += H5P[r, s] * K[s, i]
                    D[r, i] = acc
            t_new = t + h if t + h < t_end else t_end
            while i_out < n_out and times[i_out] <= t_new:
                x = (times[i_out] - t) / h
                w = 1.0 - x
                out[i_out] = w * y[0] + x * (y1[0] + w * (D[0, 0] + x * (D[1, 0]
                                                                         + x * D[2, 0])))
                i_out += 1
            t = t_new
            for i in range(3):
                y[i] = y1[i]
            h *= min(5.0, 0.9 * err ** -0.2) if err > 0 else 5.0
    return steps


def two_state_friction(times, velocities, switch_times, a, b, dc, k, b2=0.0, dc2=1.0,
                       law="aging", c=0.0, mu0=0.6, rtol=1e-10, atol=1e-10):
    """μ at ``times`` (s, from 0, increasing) of the two-state slider (module docstring) on
    the load point at ``velocities`` (m/s) between ``switch_times`` (s), from steady sliding at
    the first speed (v0 = that speed); ``dc``, ``dc2`` in m, ``k`` = k′ in 1/m. Returns
    (μ, steps); μ is NaN everywhere if the run failed."""
    times = np.ascontiguousarray(times, dtype=float)
    p = np.array([a, b, dc, b2, dc2, k, c, velocities[0], mu0, LAW_CODES[law]], dtype=float)
    bounds = np.array([0.0, *switch_times, max(float(times[-1]), *switch_times)])
    out = np.empty(len(times))
    steps = _run(p, np.asarray(velocities, dtype=float), bounds, times, rtol, atol, out)
    if steps < 0 or not np.isfinite(out).all():
        out[:] = np.nan
    return out, steps
