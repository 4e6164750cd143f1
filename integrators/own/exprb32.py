"""Exprb32: the exponential Rosenbrock method of order 3 with the exponential Rosenbrock–Euler
method (order 2) embedded, with the exact 3×3 Jacobian.

Hochbruck, Ostermann & Schweitzer (2009), Exponential Rosenbrock-type methods, SIAM J. Numer.
Anal. 47, 786–803; Hochbruck & Ostermann (2010), Acta Numerica 19, 209–286, §2.4 (checked
against LeXInt, Deka & Einkemmer, ``EXPRB32.py``). With J = f'(z_n), g(z) = f(z) − J z and
D2 = g(U2) − g(z_n):

    U2 = z_n + h φ1(hJ) f(z_n)                      (= the embedded solution)
    z_{n+1} = U2 + 2h φ3(hJ) D2                     error estimate 2h φ3(hJ) D2

φ-functions: :mod:`integrators.own.phi`. Error scale atol + rtol·max(|z_n|, |z_{n+1}|); the
predictive controller with q = 3 (:func:`integrators.own.engine.pred_accept`); cubic Hermite
dense output. Counters: nfev = 1 per attempt + f(z_{n+1}) per accepted step + 2 per start;
njev = 1 per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.core.registry import register
from integrators.own import batch, engine
from integrators.own.compiled import CompiledAlgorithm
from integrators.own.phi import matvec, phi_functions, remainder_diff

__all__ = ["Exprb32", "exprb_workspace"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def exprb_workspace():
    """J, the φ-functions P (5 × 3 × 3), φ1(hJ/2) and scratch vectors (7 × 3)."""
    return np.empty((3, 3)), np.empty((5, 3, 3)), np.empty((3, 3)), np.empty((7, 3))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z, f, out, f1, D):
    J, P, half, w = ws
    rtol, atol = p[engine.P_RTOL], p[engine.P_ATOL]
    for i in range(3):
        for j in range(3):
            half[i, j] = J[i, j] * hs
    phi_functions(half, 3, P, half)
    v1, u, fu, d2, t = w[1], w[2], w[3], w[4], w[6]
    matvec(P[1], f, v1)                     # φ1(hJ) f
    for i in range(3):
        u[i] = z[i] + hs * v1[i]
    engine.f_of(p, u, fu)
    for i in range(3):
        t[i] = hs * v1[i]
    remainder_diff(J, z, f, t, fu, d2)
    matvec(P[3], d2, t)
    errmax = 0.0
    for i in range(3):
        w[0, i] = 2.0 * hs * t[i]
        out[i] = u[i] + w[0, i]
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
class Exprb32(CompiledAlgorithm):
    """Exponential Rosenbrock exprb32 (Hochbruck, Ostermann & Schweitzer 2009): order 3,
    embedded exponential Rosenbrock–Euler (order 2) for the error estimate, exact 3×3 Jacobian
    and its φ-functions, adaptive. ``rhs="numba"`` only."""

    name: ClassVar[str] = "Exprb32"
    kind: ClassVar[str] = "exponential"
    family: ClassVar[str] = "exponential Rosenbrock (exact Jacobian)"
    order: ClassVar[int] = 3
    stiff: ClassVar[bool] = True
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop, φ-functions and Jacobian are compiled with numba")
    kernel: ClassVar = kernel
    workspace: ClassVar = exprb_workspace
    fixed: ClassVar = fixed
    batch_kernel: ClassVar = solve_batch
    batch_serial: ClassVar = solve_batch_serial
    constants: ClassVar[dict] = dict(INIT_EXPONENT=0.2, Q=3.0, STICK_PEAKS=0, FSAL=0,
                                     HERMITE=1, STAGES=1)
