"""Rodas5P: Steinebach (2023), Construction of Rosenbrock–Wanner method Rodas5P and numerical
benchmarks within the Julia differential equations package, BIT Numer. Math. 63, 27.

Order 5, 8 stages (7 new f), stiffly accurate, embedded order 4, with the analytic Jacobian.
Hairer–Wanner's form (Solving ODEs II, §IV.7, (7.25)), γ the diagonal:

    (I/(γh) − J) k_i = f(z0 + Σ_j a_ij k_j) + Σ_j (c_ij/h) k_j,   z1 = z0 + Σ_j a_8j k_j + k_8,
    err = k_8

M = I − γ h J is factored once per attempt (3×3 LU with partial pivoting) and serves every
stage; J is evaluated once per step and reused by the retries of a rejected attempt. Tableau (A,
C, γ, and H of the dense output) copied from OrdinaryDiffEq.jl,
``lib/OrdinaryDiffEqRosenbrock/src/rosenbrock_tableaus.jl`` (``Rodas5PTableau``); the observed
order (tests/test_rosenbrock.py) checks the digits. Dense output: its own 4th-order
interpolant, D_j = Σ_i H_ji k_i (``rosenbrock_interpolants.jl``). The tableau and the stage loop
are in :mod:`integrators.own.rodas5p_stages`, shared with the forward sensitivities
(:mod:`integrators.own.sensitivity`) and the laboratory model. Error scale atol + rtol·max(|z0|, |z1|);
Hairer's RODAS controller with q = 5. Counters: nfev = 7 per attempt + f(z1) per accepted step
+ 2 per start; njev = 1 per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from numba import njit

from integrators.core.registry import register
from integrators.own import batch, batch_sensitivity, engine, sensitivity
from integrators.own.compiled import CompiledAlgorithm
from integrators.own.rodas5p_stages import no_after, sensitivity_workspace, stages, workspace

__all__ = ["Rodas5P"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z0, f0, z1, f1, D):
    return stages(engine.f_of, no_after, p, p[engine.P_RTOL], p[engine.P_ATOL], hs, ws, z0, f0,
                  z1, D)


@njit(**engine.NO_NRT)
def kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max):
    return engine.run(engine.prepare_jacobian, _attempt, engine.rodas_reject, engine.rodas_accept,
                      ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max, engine.no_sense, ())


@njit(cache=True, nogil=True, error_model="numpy")
def fixed(p, z0, hs, n):
    return engine.fixed_steps(engine.prepare_jacobian, _attempt, workspace, p, z0, hs, n)


@njit(**batch.BATCH)
def solve_batch(P, Z0, C, dirs, R, order, CURVE):
    batch.run_batch(kernel, workspace, P, Z0, C, dirs, R, order, CURVE)


@njit(**batch.SERIAL)
def solve_batch_serial(P, Z0, C, dirs, R, CURVE):
    batch.run_serial(kernel, workspace, P, Z0, C, dirs, R, CURVE)



@njit(**batch.BATCH)
def solve_batch_sensitive(P, Z0, C, dirs, D, X, control, R, GRAD, order):
    batch_sensitivity.run_batch(sensitivity.rodas5p_kernel, workspace, sensitivity_workspace, P, Z0, C, dirs, D, X,
                                control, R, GRAD, order)


@njit(**batch.SERIAL)
def solve_batch_sensitive_serial(P, Z0, C, dirs, D, X, control, R, GRAD):
    batch_sensitivity.run_serial(sensitivity.rodas5p_kernel, workspace, sensitivity_workspace, P, Z0, C, dirs, D, X,
                                 control, R, GRAD)

@register
@dataclass(frozen=True)
class Rodas5P(CompiledAlgorithm):
    """Steinebach's Rodas5P, a stiffly accurate Rosenbrock 5(4) with the analytic Jacobian,
    adaptive (Hairer's RODAS control), events on its 4th-order dense output. Order 5.
    Steinebach (2023), BIT 63, 27; tableau from OrdinaryDiffEq.jl."""

    name: ClassVar[str] = "Rodas5P"
    kind: ClassVar[str] = "rosenbrock"
    family: ClassVar[str] = "Rosenbrock (Rodas5P 5(4), analytic Jacobian)"
    order: ClassVar[int] = 5
    stiff: ClassVar[bool] = True
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop is compiled with numba and calls the compiled right-hand side and "
        "Jacobian")
    kernel: ClassVar = kernel
    workspace: ClassVar = workspace
    fixed: ClassVar = fixed
    batch_kernel: ClassVar = solve_batch
    batch_serial: ClassVar = solve_batch_serial
    sensitive: ClassVar[bool] = True
    sensitive_batch: ClassVar = (solve_batch_sensitive, solve_batch_sensitive_serial)
    sensitive_kernel: ClassVar = sensitivity.rodas5p_kernel
    sensitivity_workspace: ClassVar = sensitivity_workspace
    constants: ClassVar[dict] = dict(INIT_EXPONENT=1.0 / 5, Q=5.0, STICK_PEAKS=1, FSAL=0,
                                     HERMITE=0, STAGES=7)
