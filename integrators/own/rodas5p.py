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
order (tests/test_rosenbrock.py) checks the digits. Dense output: its own 4th-order interpolant,
D_j = Σ_i H_ji k_i (``rosenbrock_interpolants.jl``). Error scale atol + rtol·max(|z0|, |z1|);
Hairer's RODAS controller with q = 5. Counters: nfev = 7 per attempt + f(z1) per accepted step
+ 2 per start; njev = 1 per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.core.registry import register
from integrators.own import batch, engine
from integrators.own.compiled import CompiledAlgorithm
from integrators.own.linalg import factor, lu_solve3

__all__ = ["Rodas5P", "stages", "workspace"]

# Rodas5P (Steinebach 2023), from OrdinaryDiffEq.jl's Rodas5PTableau; C padded to 8×8
G5P = 0.21193756319429014
A5P = np.zeros((8, 8))
A5P[1, :1] = [3.0]
A5P[2, :2] = [2.849394379747939, 0.45842242204463923]
A5P[3, :3] = [-6.954028509809101, 2.489845061869568, -10.358996098473584]
A5P[4, :4] = [2.8029986275628964, 0.5072464736228206, -0.3988312541770524, -0.04721187230404641]
A5P[5, :5] = [-7.502846399306121, 2.561846144803919, -11.627539656261098, -0.18268767659942256,
              0.030198172008377946]
A5P[6, :6] = list(A5P[5, :5]) + [1.0]
A5P[7, :7] = list(A5P[5, :5]) + [1.0, 1.0]
C5P = np.zeros((8, 8))
C5P[1, :1] = [-14.155112264123755]
C5P[2, :2] = [-17.97296035885952, -2.859693295451294]
C5P[3, :3] = [147.12150275711716, -1.41221402718213, 71.68940251302358]
C5P[4, :4] = [165.43517024871676, -0.4592823456491126, 42.90938336958603, -5.961986721573306]
C5P[5, :5] = [24.854864614690072, -3.0009227002832186, 47.4931110020768, 5.5814197821558125,
              -0.6610691825249471]
C5P[6, :6] = [30.91273214028599, -3.1208243349937974, 77.79954646070892, 34.28646028294783,
              -19.097331116725623, -28.087943162872662]
C5P[7, :7] = [37.80277123390563, -3.2571969029072276, 112.26918849496327, 66.9347231244047,
              -40.06618937091002, -54.66780262877968, -9.48861652309627]
H5P = np.array([
    [25.948786856663858, -2.5579724845846235, 10.433815404888879, -2.3679251022685204,
     0.524948541321073, 1.1241088310450404, 0.4272876194431874, -0.17202221070155493],
    [-9.91568850695171, -0.9689944594115154, 3.0438037242978453, -24.495224566215796,
     20.176138334709044, 15.98066361424651, -6.789040303419874, -6.710236069923372],
    [11.419903575922262, 2.8879645146136994, 72.92137995996029, 80.12511834622643,
     -52.072871366152654, -59.78993625266729, -0.15582684282751913, 4.883087185713722]])



@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def workspace():
    """J, M (the LU), piv, K (the stages), u (a stage's argument), fb (f there)."""
    return (np.empty((3, 3)), np.empty((3, 3)), np.empty(3, np.int64), np.empty((8, 3)),
            np.empty(3), np.empty(3))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def stages(rhs, p, rtol, atol, hs, ws, z0, f0, z1, D):
    """One attempt of a step ``hs`` from ``z0`` (``f0`` = f(z0), ws[0] = J(z0)) for the
    right-hand side ``rhs(p, z, out)``: z1 into ``z1``, the dense output's D (an accepted
    attempt only); returns the scaled error (inf if M is singular or the error not finite).
    The slider's kernel and the laboratory's two-state model (:mod:`benchmarks.lab.two_state`)
    share it."""
    J, M, piv, K, u, fb = ws
    hg = hs * G5P
    regular = factor(hg, J, M, piv)
    for s in range(8):
        for i in range(3):
            acc = z0[i]
            for j in range(s):
                acc += A5P[s, j] * K[j, i]
            u[i] = acc
        if s == 0:
            for i in range(3):
                fb[i] = f0[i]
        else:
            rhs(p, u, fb)
        for i in range(3):
            acc = 0.0
            for j in range(s):
                acc += C5P[s, j] * K[j, i]
            K[s, i] = hg * fb[i] + G5P * acc
        lu_solve3(M, piv, K, s)
    errmax = 0.0
    for i in range(3):
        z1[i] = u[i] + K[7, i]
        r = abs(K[7, i]) / (atol + rtol * max(abs(z0[i]), abs(z1[i])))
        if not r <= errmax:         # max() would drop a NaN and accept the trial
            errmax = r
    if errmax <= 1.0:               # the dense output of an accepted step only
        for i in range(3):
            for r in range(3):
                acc = 0.0
                for s in range(8):
                    acc += H5P[r, s] * K[s, i]
                D[r, i] = acc
    return errmax if regular and np.isfinite(errmax) else np.inf


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z0, f0, z1, f1, D):
    return stages(engine.f_of, p, p[engine.P_RTOL], p[engine.P_ATOL], hs, ws, z0, f0, z1, D)


@njit(**engine.NO_NRT)
def kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max):
    return engine.run(engine.prepare_jacobian, _attempt, engine.rodas_reject, engine.rodas_accept,
                      ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max)


@njit(cache=True, nogil=True, error_model="numpy")
def fixed(p, z0, hs, n):
    return engine.fixed_steps(engine.prepare_jacobian, _attempt, workspace, p, z0, hs, n)


@njit(**batch.BATCH)
def solve_batch(P, Z0, C, dirs, R, order, CURVE):
    batch.run_batch(kernel, workspace, P, Z0, C, dirs, R, order, CURVE)


@njit(**batch.SERIAL)
def solve_batch_serial(P, Z0, C, dirs, R, CURVE):
    batch.run_serial(kernel, workspace, P, Z0, C, dirs, R, CURVE)


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
    constants: ClassVar[dict] = dict(INIT_EXPONENT=1.0 / 5, Q=5.0, STICK_PEAKS=1, FSAL=0,
                                     HERMITE=0, STAGES=7)
