"""RadauIIA5: the three-stage Radau IIA collocation method of order 5 (Hairer & Wanner, Solving
ODEs II, §IV.8, the code RADAU5), with the analytic Jacobian.

The stage increments Z_i = Y_i − z0 (nodes c = ((4 − √6)/10, (4 + √6)/10, 1)) solve
Z = h (A ⊗ I) F(z0 + Z) by simplified Newton iterations. With T the real eigenbasis of A⁻¹
(W = T⁻¹ Z; A⁻¹ has one real eigenvalue μ and a pair α ± iβ) each iteration is one real 3×3
solve with μ/h − J and one complex 3×3 solve with (α − iβ)/h − J: both factored once per
attempt (3×3 LU with partial pivoting), J evaluated once per step. T and μ, α, β are computed
from A when the module loads (the tests check T⁻¹A⁻¹T's block form). Newton: at most
``NEWTON_MAXITER`` iterations, stopped as scipy's ``radau.py`` does (the rate of contraction
θ; converged when θ/(1 − θ)·‖ΔW‖ < κ = max(10 ε/rtol, min(0.03, rtol^½)), ‖·‖ the RMS norm
scaled by atol + rtol·|z0|, abandoned when θ ≥ 1 or the rate predicts no convergence in time:
the attempt then reports an error of ``NEWTON_FAIL``, which halves the step). Fixed steps
(infinite tolerances) iterate to rounding instead. Starting values: the last accepted step's
collocation polynomial, extrapolated, when this attempt starts where that step ended; else
zero.

Error estimate (RADAU5's): err = (μ/h − J)⁻¹ (f(z0) + (e·Z)/h), e = (−13 − 7√6, −13 + 7√6,
−1)/3, an O(h⁴) quantity; when it fails the test, Hairer's second estimate
(μ/h − J)⁻¹ (f(z0 + err) + (e·Z)/h) decides (RADAU5 takes it at the first and rejected
steps). Scale atol + rtol·max(|z0|, |z1|), the max norm; the RODAS controller with q = 4.
The tolerances are the user's as given (RADAU5 itself tightens them to 0.1·rtol^(2/3)): the
estimate is of an O(h⁴) quantity, so the achieved error of the fifth-order solution is far
below rtol (the ΔT error of the paper example at rtol = 1e−6 is 2.6e−8: `rsfbench study
engine-speed`).
Dense output: the collocation polynomial (degree 3, through z0 and the three stage values),
in the engine's form with D3 = 0. Counters: nfev = 3 per Newton iteration (+1 for a second
error estimate) per attempt, + f(z1) per accepted step + 2 per start; njev = 1 per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.core.registry import register
from integrators.own import batch, batch_sensitivity, engine, radau5_sensitivity, sensitivity
from integrators.own.compiled import CompiledAlgorithm
from integrators.own.linalg import factor, lu3, lu_solve3
from integrators.own.radau5_tableau import (C, C1, C2, E_ERR, MU, MU_C, T, TI,
                                            radau_constants)

__all__ = ["RadauIIA5", "radau_constants"]

NEWTON_MAXITER = 7
#: fixed steps (order studies: infinite tolerances) iterate to rounding: at most this many
#: iterations, until θ/(1 − θ)·‖ΔW‖ < FIXED_KAPPA in the norm scaled by 1 + |z|
FIXED_MAXITER, FIXED_KAPPA = 50, 1e-14
#: the error an attempt reports when its Newton iteration fails: the RODAS controller then
#: halves the step (h / (NEWTON_FAIL^(1/4) / 0.9) = h/2)
NEWTON_FAIL = (2.0 * 0.9) ** 4


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _workspace():
    """J, M (the real LU), piv, Mc (the complex LU), pivc; Z (stage increments), W (their
    transform), F (f at the stages), x (a real row), y (a complex row), u (a stage's state), last
    (the last accepted step: z0, z1, D1, D2, and h in its last row), scale (the Newton norm's)."""
    return (np.empty((3, 3)), np.empty((3, 3)), np.empty(3, np.int64),
            np.empty((3, 3), np.complex128), np.empty(3, np.int64),
            np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((1, 3)),
            np.empty((1, 3), np.complex128), np.empty(3), np.zeros((5, 3)), np.empty(3))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _start_values(hs, z0, Z, last):
    """Z from the last accepted step's collocation polynomial, if this attempt starts where that
    step ended (its h in last[4, 0] > 0); else zero."""
    same = last[4, 0] > 0.0
    for i in range(3):
        same &= last[1, i] == z0[i]
    for s in range(3):
        x = 1.0 + C[s] * hs / last[4, 0] if same else 0.0
        for i in range(3):
            if same:
                Z[s, i] = ((1.0 - x) * last[0, i] + x * last[1, i]
                           + x * (1.0 - x) * (last[2, i] + x * last[3, i]) - z0[i])
            else:
                Z[s, i] = 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _newton(p, hs, ws, z0, scale, kappa, iterations, predict):
    """The simplified Newton iteration for Z (ws), at most ``iterations``, abandoned early when
    the rate predicts no convergence in time if ``predict``; returns (converged, f
    evaluations)."""
    J, M, piv, Mc, pivc, Z, W, F, x, y, u, last, _ = ws
    fr, fc = hs / MU, hs / MU_C          # the solves are scaled: (I − (h/μ) J) = (h/μ)(μ/h − J)
    for s in range(3):
        for i in range(3):
            W[s, i] = TI[s, 0] * Z[0, i] + TI[s, 1] * Z[1, i] + TI[s, 2] * Z[2, i]
    nfev, norm_old, rate, converged = 0, -1.0, -1.0, False
    for k in range(iterations):
        finite = True
        for s in range(3):
            for i in range(3):
                u[i] = z0[i] + Z[s, i]
            engine.f_of(p, u, F[s])
            for i in range(3):
                finite &= np.isfinite(F[s, i])
        nfev += 3
        if not finite:
            break
        for i in range(3):
            g0 = TI[0, 0] * F[0, i] + TI[0, 1] * F[1, i] + TI[0, 2] * F[2, i]
            g1 = TI[1, 0] * F[0, i] + TI[1, 1] * F[1, i] + TI[1, 2] * F[2, i]
            g2 = TI[2, 0] * F[0, i] + TI[2, 1] * F[1, i] + TI[2, 2] * F[2, i]
            x[0, i] = fr * g0 - W[0, i]
            y[0, i] = fc * complex(g1, g2) - complex(W[1, i], W[2, i])
        lu_solve3(M, piv, x, 0)
        lu_solve3(Mc, pivc, y, 0)
        acc = 0.0
        for i in range(3):
            d0, d1, d2 = x[0, i], y[0, i].real, y[0, i].imag
            acc += (d0 * d0 + d1 * d1 + d2 * d2) / (scale[i] * scale[i])
            W[0, i] += d0
            W[1, i] += d1
            W[2, i] += d2
        norm = math.sqrt(acc / 9.0)
        if norm_old >= 0.0:
            rate = norm / norm_old
            if not rate < 1.0 or (predict and rate ** (iterations - k) / (1.0 - rate) * norm
                                  > kappa):
                break
        for s in range(3):
            for i in range(3):
                Z[s, i] = T[s, 0] * W[0, i] + T[s, 1] * W[1, i] + T[s, 2] * W[2, i]
        if norm == 0.0 or (rate >= 0.0 and rate / (1.0 - rate) * norm < kappa):
            converged = True
            break
        norm_old = norm
    return converged, nfev


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z0, f0, z1, f1, D):
    J, M, piv, Mc, pivc, Z, W, F, x, y, u, last, scale = ws
    rtol, atol = p[engine.P_RTOL], p[engine.P_ATOL]
    fr = hs / MU
    regular = factor(fr, J, M, piv)
    fc = hs / MU_C
    for i in range(3):
        for j in range(3):
            Mc[i, j] = -fc * J[i, j]
        Mc[i, i] += 1.0
    regular &= lu3(Mc, pivc)
    if not regular:
        return np.inf
    adaptive = np.isfinite(rtol)    # else fixed steps: the collocation equations to rounding
    for i in range(3):
        scale[i] = atol + rtol * abs(z0[i]) if adaptive else 1.0 + abs(z0[i])
    kappa = max(10.0 * 2.220446049250313e-16 / rtol, min(0.03, math.sqrt(rtol))) \
        if adaptive else FIXED_KAPPA
    _start_values(hs, z0, Z, last)
    converged, nfev = _newton(p, hs, ws, z0, scale, kappa,
                              NEWTON_MAXITER if adaptive else FIXED_MAXITER, adaptive)
    for i in range(3):
        z1[i] = z0[i] + Z[2, i]     # (a failed iteration's too: fixed steps take it)
    if not converged:
        p[engine.P_MORE_F] += nfev
        return NEWTON_FAIL
    # the error: (μ/h − J)⁻¹ (f0 + e·Z/h), solved scaled as the iteration's real part
    for i in range(3):
        ze = (E_ERR[0] * Z[0, i] + E_ERR[1] * Z[1, i] + E_ERR[2] * Z[2, i]) / hs
        F[0, i] = ze                            # kept for a second estimate
        x[0, i] = fr * (f0[i] + ze)
    lu_solve3(M, piv, x, 0)
    errmax = _norm(x, z0, z1, rtol, atol)
    if errmax > 1.0:                            # Hairer's second estimate
        for i in range(3):
            u[i] = z0[i] + x[0, i]
        engine.f_of(p, u, f1)
        nfev += 1
        for i in range(3):
            x[0, i] = fr * (f1[i] + F[0, i])
        lu_solve3(M, piv, x, 0)
        errmax = _norm(x, z0, z1, rtol, atol)
    p[engine.P_MORE_F] += nfev
    if errmax <= 1.0:               # the collocation polynomial, kept for the next start
        for i in range(3):
            w1 = (Z[0, i] - C1 * Z[2, i]) / (C1 * (1.0 - C1))
            w2 = (Z[1, i] - C2 * Z[2, i]) / (C2 * (1.0 - C2))
            D[1, i] = (w1 - w2) / (C1 - C2)
            D[0, i] = w1 - C1 * D[1, i]
            D[2, i] = 0.0
            last[0, i], last[1, i], last[2, i], last[3, i] = z0[i], z1[i], D[0, i], D[1, i]
        last[4, 0] = hs
    return errmax if np.isfinite(errmax) else np.inf


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _norm(x, z0, z1, rtol, atol):
    errmax = 0.0
    for i in range(3):
        r = abs(x[0, i]) / (atol + rtol * max(abs(z0[i]), abs(z1[i])))
        if not r <= errmax:         # max() would drop a NaN and accept the trial
            errmax = r
    return errmax


@njit(**engine.NO_NRT)
def kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max):
    return engine.run(engine.prepare_jacobian, _attempt, engine.rodas_reject, engine.rodas_accept,
                      ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max, engine.no_sense, ())


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sensitive_attempt(p, hs, ws, z0, f0, z1, f1, D):
    """:func:`_attempt` (``ws`` its workspace and then the sensitivities' arrays), followed by
    the sensitivities' error test (:func:`integrators.own.sensitivity.radau_error`). A trial
    the state passes and the sensitivities reject leaves ``last`` as it was (the next trial's
    Newton starts from the last accepted step's polynomial, as without sensitivities)."""
    last, kept = ws[11], ws[13][0][10]
    for r in range(5):
        for i in range(3):
            kept[r, i] = last[r, i]
    err = _attempt(p, hs, (ws[0], ws[1], ws[2], ws[3], ws[4], ws[5], ws[6], ws[7], ws[8],
                           ws[9], ws[10], ws[11], ws[12]), z0, f0, z1, f1, D)
    total = sensitivity.radau_error(p, hs, ws, z0, f0, err)
    if err <= 1.0 and not total <= 1.0:
        for r in range(5):
            for i in range(3):
                last[r, i] = kept[r, i]
    return total


@njit(**engine.NO_NRT)
def sensitive_kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max, sa):
    """:func:`kernel` with the forward sensitivities following it
    (:func:`integrators.own.sensitivity.radau_sense`)."""
    wsx = (ws[0], ws[1], ws[2], ws[3], ws[4], ws[5], ws[6], ws[7], ws[8], ws[9], ws[10],
           ws[11], ws[12], sa)
    return engine.run(engine.prepare_jacobian, _sensitive_attempt, engine.rodas_reject,
                      engine.rodas_accept, wsx, sc, st, p, Z, G, dirs, grid, saved, ev, n_max,
                      sensitivity.radau_sense, sa)


@njit(cache=True, nogil=True, error_model="numpy")
def fixed(p, z0, hs, n):
    return engine.fixed_steps(engine.prepare_jacobian, _attempt, _workspace, p, z0, hs, n)


@njit(**batch.BATCH)
def solve_batch(P, Z0, C, dirs, R, order, CURVE):
    batch.run_batch(kernel, _workspace, P, Z0, C, dirs, R, order, CURVE)


@njit(**batch.SERIAL)
def solve_batch_serial(P, Z0, C, dirs, R, CURVE):
    batch.run_serial(kernel, _workspace, P, Z0, C, dirs, R, CURVE)



@njit(**batch.BATCH)
def solve_batch_sensitive(P, Z0, C, dirs, D, X, control, R, GRAD, order):
    batch_sensitivity.run_batch(sensitive_kernel, _workspace, radau5_sensitivity.workspace, P,
                                Z0, C, dirs, D, X, control, R, GRAD, order)


@njit(**batch.SERIAL)
def solve_batch_sensitive_serial(P, Z0, C, dirs, D, X, control, R, GRAD):
    batch_sensitivity.run_serial(sensitive_kernel, _workspace, radau5_sensitivity.workspace, P,
                                 Z0, C, dirs, D, X, control, R, GRAD)

@register
@dataclass(frozen=True)
class RadauIIA5(CompiledAlgorithm):
    """Radau IIA of order 5 (three-stage collocation, RADAU5's simplified Newton iteration in the
    real/complex form and its error estimate), adaptive (RODAS control, q = 4), events and saves
    on its collocation polynomial, analytic Jacobian. Needs ``rtol``, ``atol`` and
    ``rhs="numba"``. Hairer & Wanner, Solving ODEs II, §IV.8."""

    name: ClassVar[str] = "RadauIIA5"
    kind: ClassVar[str] = "implicit"
    family: ClassVar[str] = "implicit Runge–Kutta (Radau IIA 5, analytic Jacobian)"
    order: ClassVar[int] = 5
    stiff: ClassVar[bool] = True
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop is compiled with numba and calls the compiled right-hand side and "
        "Jacobian")
    kernel: ClassVar = kernel
    workspace: ClassVar = _workspace
    fixed: ClassVar = fixed
    batch_kernel: ClassVar = solve_batch
    batch_serial: ClassVar = solve_batch_serial
    sensitive: ClassVar[bool] = True
    sensitive_batch: ClassVar = (solve_batch_sensitive, solve_batch_sensitive_serial)
    sensitive_kernel: ClassVar = sensitive_kernel
    sensitivity_workspace: ClassVar = radau5_sensitivity.workspace
    constants: ClassVar[dict] = dict(INIT_EXPONENT=1.0 / 4, Q=4.0, STICK_PEAKS=1, FSAL=0,
                                     HERMITE=0, STAGES=0)
