"""Rosenbrock23: Shampine & Reichelt (1997), The MATLAB ODE suite, SIAM J. Sci. Comput. 18, 1–22
(ode23s), as Julia's OrdinaryDiffEq ``Rosenbrock23``, with the analytic Jacobian.

With d = 1/(2 + √2), e32 = 6 + √2, M = I − d h J and J = ∂f/∂z at the step's start:

    k1 = M⁻¹ F0                            F0 = f(z0)
    F1 = f(z0 + h k1/2),  k2 = M⁻¹ (F1 − k1) + k1,   z1 = z0 + h k2
    F2 = f(z1),           k3 = M⁻¹ (F2 − e32 (k2 − F1) − 2 (k1 − F0))
    err = M⁻¹ h/6 (k1 − 2 k2 + k3)

Order 2 (propagated), L-stable, error estimate O(h³); F2 is the next step's F0 (FSAL). Where
every eigenvalue of J has a negative real part (Routh–Hurwitz, :func:`~integrators.own.linalg.
hurwitz3`) the estimate is filtered by M⁻¹ (Shampine's device, as Radau5's: Hairer & Wanner II,
§IV.8, (8.20)): unfiltered, an offset δ of a stiff component from its slow manifold at the
step's start, which the L-stable step removes, reads as an error of ≈ 1.6 δ at every step size
(hλ → −∞: k1 ≈ −δ/(d h), k3 ≈ 3.24 δ/(d h)), and after an aging-law deep lock (the manifold
moving at ~7000 in u per unit τ, integrators.own.engine) the step size fell to the floor. M⁻¹
leaves the non-stiff components' estimate as it was to O(h λ). Not where J has an unstable
mode: there M⁻¹ would shrink a growing error too (before the plunge of a lock ∂u'/∂u ~ +1e15
and a trial of h = 1e−3 that sends u up by 4, the wrong way, read as 6e−4 filtered). Error scale atol + rtol·max(|z0|, |z1|); Hairer's RODAS controller with q = 3
(:func:`integrators.own.engine.rodas_accept`). Dense output: the cubic Hermite interpolant of
(z, f) at both ends, one order better than ode23s' quadratic continuous extension, at no cost.
Counters: nfev = 2 per attempt + 2 per start; njev = 1 per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.core.registry import register
from integrators.own import batch, engine
from integrators.own.compiled import CompiledAlgorithm
from integrators.own.linalg import factor, hurwitz3, lu_solve3

__all__ = ["Rosenbrock23"]

D23 = 1.0 / (2.0 + math.sqrt(2.0))
E32 = 6.0 + math.sqrt(2.0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _workspace():
    """J, M (the LU), piv, K (the stages and the error), u (a stage's argument), fb (f there)."""
    return (np.empty((3, 3)), np.empty((3, 3)), np.empty(3, np.int64), np.empty((4, 3)),
            np.empty(3), np.empty(3))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z0, f0, z1, f1, D):
    J, M, piv, K, u, fb = ws
    rtol, atol = p[engine.P_RTOL], p[engine.P_ATOL]
    regular = factor(hs * D23, J, M, piv)
    for i in range(3):
        K[0, i] = f0[i]
    lu_solve3(M, piv, K, 0)
    for i in range(3):
        u[i] = z0[i] + 0.5 * hs * K[0, i]
    engine.f_of(p, u, fb)                   # F1
    for i in range(3):
        K[1, i] = fb[i] - K[0, i]
    lu_solve3(M, piv, K, 1)
    for i in range(3):
        K[1, i] += K[0, i]
        z1[i] = z0[i] + hs * K[1, i]
    engine.f_of(p, z1, f1)                  # F2
    for i in range(3):
        K[2, i] = f1[i] - E32 * (K[1, i] - fb[i]) - 2.0 * (K[0, i] - f0[i])
    lu_solve3(M, piv, K, 2)
    for i in range(3):
        K[3, i] = hs / 6.0 * (K[0, i] - 2.0 * K[1, i] + K[2, i])
    if hurwitz3(J):                         # filtered where the modes damp (docstring)
        lu_solve3(M, piv, K, 3)
    errmax = 0.0
    for i in range(3):
        r = abs(K[3, i]) / (atol + rtol * max(abs(z0[i]), abs(z1[i])))
        if not r <= errmax:         # max() would drop a NaN and accept the trial
            errmax = r
    return errmax if regular and np.isfinite(errmax) else np.inf


@njit(**engine.NO_NRT)
def kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max):
    return engine.run(engine.prepare_jacobian, _attempt, engine.rodas_reject, engine.rodas_accept,
                      ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max, engine.no_sense, ())


@njit(cache=True, nogil=True, error_model="numpy")
def fixed(p, z0, hs, n):
    return engine.fixed_steps(engine.prepare_jacobian, _attempt, _workspace, p, z0, hs, n)


@njit(**batch.BATCH)
def solve_batch(P, Z0, C, dirs, R, order, CURVE):
    batch.run_batch(kernel, _workspace, P, Z0, C, dirs, R, order, CURVE)


@njit(**batch.SERIAL)
def solve_batch_serial(P, Z0, C, dirs, R, CURVE):
    batch.run_serial(kernel, _workspace, P, Z0, C, dirs, R, CURVE)


@register
@dataclass(frozen=True)
class Rosenbrock23(CompiledAlgorithm):
    """Shampine–Reichelt Rosenbrock 2(3) (MATLAB ode23s, Julia Rosenbrock23), L-stable, with the
    analytic Jacobian, adaptive (Hairer's RODAS control), events on the cubic Hermite dense
    output. Order 2; its global error is ~30–300× rtol (1e−6 on the limit cycle takes rtol ≈
    1e−9). Needs ``rtol``, ``atol`` and ``rhs="numba"``."""

    name: ClassVar[str] = "Rosenbrock23"
    kind: ClassVar[str] = "rosenbrock"
    family: ClassVar[str] = "Rosenbrock (Shampine–Reichelt 2(3), analytic Jacobian)"
    order: ClassVar[int] = 2
    stiff: ClassVar[bool] = True
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop is compiled with numba and calls the compiled right-hand side and "
        "Jacobian")
    kernel: ClassVar = kernel
    workspace: ClassVar = _workspace
    fixed: ClassVar = fixed
    batch_kernel: ClassVar = solve_batch
    batch_serial: ClassVar = solve_batch_serial
    constants: ClassVar[dict] = dict(INIT_EXPONENT=1.0 / 3, Q=3.0, STICK_PEAKS=1, FSAL=1,
                                     HERMITE=1, STAGES=2)
