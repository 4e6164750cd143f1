"""Exprb43: the exponential Rosenbrock method of order 4 with an embedded method of order 3,
with the exact 3×3 Jacobian.

Hochbruck, Ostermann & Schweitzer (2009), SIAM J. Numer. Anal. 47, 786–803; Hochbruck &
Ostermann (2010), Acta Numerica 19, §2.4 (checked against LeXInt's ``EXPRB43.py``). With
J = f'(z_n), g(z) = f(z) − J z and D_i = g(U_i) − g(z_n):

    U2 = z_n + (h/2) φ1(hJ/2) f(z_n)
    U3 = z_n + h φ1(hJ) (f(z_n) + D2)
    z_{n+1} = z_n + h φ1(hJ) f(z_n) + h φ3(hJ)(16 D2 − 2 D3) + h φ4(hJ)(−48 D2 + 12 D3)
    error estimate h φ4(hJ)(−48 D2 + 12 D3)

As :mod:`integrators.own.exprb32` otherwise (q = 4); nfev = 2 per attempt + f(z_{n+1}) per
accepted step + 2 per start.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from numba import njit

from integrators.core.registry import register
from integrators.own import batch, engine
from integrators.own.compiled import CompiledAlgorithm
from integrators.own.exprb32 import exprb_workspace
from integrators.own.phi import matvec, phi_functions, remainder_diff

__all__ = ["Exprb43"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z, f, out, f1, D):
    J, P, half, w = ws
    rtol, atol = p[engine.P_RTOL], p[engine.P_ATOL]
    for i in range(3):
        for j in range(3):
            half[i, j] = J[i, j] * hs       # hJ, overwritten with φ1(hJ/2) below
    phi_functions(half, 4, P, half)
    v1, u, fu, d2, d3, t = w[1], w[2], w[3], w[4], w[5], w[6]
    matvec(P[1], f, v1)                     # φ1(hJ) f
    matvec(half, f, t)
    for i in range(3):
        t[i] *= 0.5 * hs
        u[i] = z[i] + t[i]
    engine.f_of(p, u, fu)
    remainder_diff(J, z, f, t, fu, d2)
    for i in range(3):
        t[i] = f[i] + d2[i]
    matvec(P[1], t, u)
    for i in range(3):
        t[i] = hs * u[i]
        u[i] = z[i] + t[i]
    engine.f_of(p, u, fu)
    remainder_diff(J, z, f, t, fu, d3)
    for i in range(3):
        u[i] = 16.0 * d2[i] - 2.0 * d3[i]
        fu[i] = -48.0 * d2[i] + 12.0 * d3[i]
    matvec(P[3], u, t)
    matvec(P[4], fu, w[0])
    errmax = 0.0
    for i in range(3):
        w[0, i] *= hs
        out[i] = z[i] + hs * (v1[i] + t[i]) + w[0, i]
        r = abs(w[0, i]) / (atol + rtol * max(abs(z[i]), abs(out[i])))
        if not r <= errmax:         # max() would drop a NaN and accept the trial
            errmax = r
    return errmax


@njit(**engine.NO_NRT)
def kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max):
    return engine.run(engine.prepare_jacobian, _attempt, engine.pred_reject, engine.pred_accept,
                      ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max, engine.no_sense, ())


@njit(cache=True, nogil=True, error_model="numpy")
def fixed(p, z0, hs, n):
    return engine.fixed_steps(engine.prepare_jacobian, _attempt, exprb_workspace, p, z0, hs, n)


@njit(**batch.BATCH)
def solve_batch(P, Z0, C, dirs, R, order, CURVE):
    batch.run_batch(kernel, exprb_workspace, P, Z0, C, dirs, R, order, CURVE)


@njit(**batch.SERIAL)
def solve_batch_serial(P, Z0, C, dirs, R, CURVE):
    batch.run_serial(kernel, exprb_workspace, P, Z0, C, dirs, R, CURVE)


@register
@dataclass(frozen=True)
class Exprb43(CompiledAlgorithm):
    """Exponential Rosenbrock exprb43 (Hochbruck, Ostermann & Schweitzer 2009): order 4,
    embedded order 3, exact 3×3 Jacobian and its φ-functions, adaptive. ``rhs="numba"`` only."""

    name: ClassVar[str] = "Exprb43"
    kind: ClassVar[str] = "exponential"
    family: ClassVar[str] = "exponential Rosenbrock (exact Jacobian)"
    order: ClassVar[int] = 4
    stiff: ClassVar[bool] = True
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop, φ-functions and Jacobian are compiled with numba")
    kernel: ClassVar = kernel
    workspace: ClassVar = exprb_workspace
    fixed: ClassVar = fixed
    batch_kernel: ClassVar = solve_batch
    batch_serial: ClassVar = solve_batch_serial
    constants: ClassVar[dict] = dict(INIT_EXPONENT=0.2, Q=4.0, STICK_PEAKS=0, FSAL=0,
                                     HERMITE=1, STAGES=2)
