"""Cash–Karp Runge–Kutta 4(5) with the step control of Numerical Recipes, compiled with numba.

The "adaptive Runge–Kutta (Press et al. 1992)" of the paper's ETD speed-up claim (SPEC §5).
Explicit, 6 stages, adaptive; the 5th-order solution is carried (local extrapolation, as NR
does), the error estimate is y5 − y4. Cash & Karp (1990), ACM Trans. Math. Softw. 16, 201–222
(tableau); Press et al. (1992), Numerical Recipes in C, 2nd ed., §16.2 (``rkck``, ``rkqs``,
``odeint``: the control):

    errmax = max_i |yerr_i| / (atol + rtol·(|z_i| + |h f_i|))      (f = dz/dτ at the step start)
    errmax > 1: reject, h ← max(0.9 h errmax^−1/4, h/10)
    errmax ≤ 1: accept; next h = 0.9 h errmax^−1/5, at most 5 h

NR's test is |yerr_i| ≤ eps·(|z_i| + |h f_i| + TINY); with eps = rtol and atol for the absolute
floor, atol means what it means in scipy and SUNDIALS. A trial with a non-finite error, or whose
end state or rates are not finite, is rejected with h/10 (NR's FMAX does that with a NaN). The
initial step, the landing on the end of a loading segment, underflow and the events are the
engine's (:mod:`integrators.own.engine`).

Cost: explicit, so in the stick phase stability, not accuracy, limits the step (the η relaxation,
rate D/w, SPEC §2): ~1e−7 in τ, ~6e7 steps for the 20 s paper example. nfev = 6·steps +
5·rejected + 2·starts (f at each accepted state is the next step's first stage and the slope of
the cubic Hermite dense output); njev = 0. At the stability limit the stiff mode is not fully
damped and near the minimum of w in the stick phase C h − D η (= w u') jitters about zero, so
PEAK crossings at w ≤ E_slow are not reported (``STICK_PEAKS`` = 0, :mod:`integrators.own.engine`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.core.registry import register
from integrators.own import batch, engine
from integrators.own.compiled import CompiledAlgorithm

__all__ = ["CashKarp45"]

# Cash–Karp tableau (NR rkck): stages B, 5th-order weights C, C − (4th-order weights) as DC
B21, B31, B32, B41, B42, B43 = 0.2, 3.0 / 40.0, 9.0 / 40.0, 0.3, -0.9, 1.2
B51, B52, B53, B54 = -11.0 / 54.0, 2.5, -70.0 / 27.0, 35.0 / 27.0
B61, B62, B63 = 1631.0 / 55296.0, 175.0 / 512.0, 575.0 / 13824.0
B64, B65 = 44275.0 / 110592.0, 253.0 / 4096.0
C1, C3, C4, C6 = 37.0 / 378.0, 250.0 / 621.0, 125.0 / 594.0, 512.0 / 1771.0
DC1, DC3, DC4 = C1 - 2825.0 / 27648.0, C3 - 18575.0 / 48384.0, C4 - 13525.0 / 55296.0
DC5, DC6 = -277.0 / 14336.0, C6 - 0.25


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _workspace():
    """A stage's argument and f there."""
    return np.empty(3), np.empty(3)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _f(p, h, u, s, ws):
    """f on scalars, so that the stages stay in registers (twice as fast as in arrays)."""
    zb, fb = ws
    zb[0], zb[1], zb[2] = h, u, s
    engine.f_of(p, zb, fb)
    return fb[0], fb[1], fb[2]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(p, hs, ws, z, f, z1, f1, D):
    rtol, atol = p[engine.P_RTOL], p[engine.P_ATOL]
    z0, z1_, z2, f0, f1_, f2 = z[0], z[1], z[2], f[0], f[1], f[2]
    a0, a1, a2 = _f(p, z0 + hs * B21 * f0, z1_ + hs * B21 * f1_, z2 + hs * B21 * f2, ws)
    b0, b1, b2 = _f(p, z0 + hs * (B31 * f0 + B32 * a0), z1_ + hs * (B31 * f1_ + B32 * a1),
                    z2 + hs * (B31 * f2 + B32 * a2), ws)
    c0, c1, c2 = _f(p, z0 + hs * (B41 * f0 + B42 * a0 + B43 * b0),
                    z1_ + hs * (B41 * f1_ + B42 * a1 + B43 * b1),
                    z2 + hs * (B41 * f2 + B42 * a2 + B43 * b2), ws)
    d0, d1, d2 = _f(p, z0 + hs * (B51 * f0 + B52 * a0 + B53 * b0 + B54 * c0),
                    z1_ + hs * (B51 * f1_ + B52 * a1 + B53 * b1 + B54 * c1),
                    z2 + hs * (B51 * f2 + B52 * a2 + B53 * b2 + B54 * c2), ws)
    g0, g1, g2 = _f(p, z0 + hs * (B61 * f0 + B62 * a0 + B63 * b0 + B64 * c0 + B65 * d0),
                    z1_ + hs * (B61 * f1_ + B62 * a1 + B63 * b1 + B64 * c1 + B65 * d1),
                    z2 + hs * (B61 * f2 + B62 * a2 + B63 * b2 + B64 * c2 + B65 * d2), ws)
    e0 = hs * (DC1 * f0 + DC3 * b0 + DC4 * c0 + DC5 * d0 + DC6 * g0)
    e1 = hs * (DC1 * f1_ + DC3 * b1 + DC4 * c1 + DC5 * d1 + DC6 * g1)
    e2 = hs * (DC1 * f2 + DC3 * b2 + DC4 * c2 + DC5 * d2 + DC6 * g2)
    z1[0] = z0 + hs * (C1 * f0 + C3 * b0 + C4 * c0 + C6 * g0)
    z1[1] = z1_ + hs * (C1 * f1_ + C3 * b1 + C4 * c1 + C6 * g1)
    z1[2] = z2 + hs * (C1 * f2 + C3 * b2 + C4 * c2 + C6 * g2)
    r0 = abs(e0) / (atol + rtol * (abs(z0) + abs(hs * f0)))
    r1 = abs(e1) / (atol + rtol * (abs(z1_) + abs(hs * f1_)))
    r2 = abs(e2) / (atol + rtol * (abs(z2) + abs(hs * f2)))
    if r0 != r0 or r1 != r1 or r2 != r2:    # max() would drop a NaN and accept the trial
        return np.inf
    return max(r0, r1, r2)


@njit(**engine.NO_NRT)
def kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max):
    return engine.run(engine.prepare_nothing, _attempt, engine.nr_reject, engine.nr_accept,
                      ws, sc, st, p, Z, G, dirs, grid, saved, ev, n_max, engine.no_sense, ())


@njit(cache=True, nogil=True, error_model="numpy")
def fixed(p, z0, hs, n):
    return engine.fixed_steps(engine.prepare_nothing, _attempt, _workspace, p, z0, hs, n)


@njit(**batch.BATCH)
def solve_batch(P, Z0, C, dirs, R, order, CURVE):
    batch.run_batch(kernel, _workspace, P, Z0, C, dirs, R, order, CURVE)


@njit(**batch.SERIAL)
def solve_batch_serial(P, Z0, C, dirs, R, CURVE):
    batch.run_serial(kernel, _workspace, P, Z0, C, dirs, R, CURVE)


@register
@dataclass(frozen=True)
class CashKarp45(CompiledAlgorithm):
    """Cash–Karp embedded Runge–Kutta 4(5), explicit, adaptive, with the step control of
    Numerical Recipes §16.2 (``rkqs``). Order 5: the 5th-order solution is propagated.

    Needs ``rtol`` and ``atol`` (the test is ``|err_i| ≤ atol + rtol·(|z_i| + |h f_i|)``: NR's
    yscal, with atol as the absolute floor) and the compiled right-hand side (``rhs="numba"``
    only). ``max_steps`` (accepted steps, whole solve) defaults to ETD's 2e8, not 5e7: in the
    stick phase stability, not accuracy, sets the step: the 20 s paper example takes 6.3e7
    steps, and the count barely moves between rtol 1e−3 and 1e−10.
    Cash & Karp (1990), ACM TOMS 16, 201–222; Press et al. (1992)."""

    max_steps: int = 200_000_000

    name: ClassVar[str] = "CashKarp45"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge–Kutta (Cash–Karp 4(5))"
    order: ClassVar[int] = 5
    stiff: ClassVar[bool] = False
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop is compiled with numba and calls the compiled right-hand side; the "
        "python-tier explicit RK45 is scipy-RK45")
    kernel: ClassVar = kernel
    workspace: ClassVar = _workspace
    fixed: ClassVar = fixed
    batch_kernel: ClassVar = solve_batch
    batch_serial: ClassVar = solve_batch_serial
    constants: ClassVar[dict] = dict(INIT_EXPONENT=0.2, Q=5.0, STICK_PEAKS=0, FSAL=0,
                                     HERMITE=1, STAGES=5)
