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
floor, atol means what it means in scipy and SUNDIALS. A trial with a non-finite error is rejected with h/10 (NR's FMAX does that with a
NaN); τ + h == τ is ``StepUnderflow``; a non-finite accepted state ``NonFinite``. First step
after each ``start``: Hairer's heuristic (Hairer, Nørsett & Wanner, Solving ODEs I, §II.4, as
scipy's ``select_initial_step``); then h is kept across ``advance`` calls. A step that would pass
``t_out`` is shortened to land on it; the next one is the step proposed before, if larger.

Cost: explicit, so in the stick phase stability, not accuracy, limits the step (the η relaxation,
rate D/w, SPEC §2): ~1e−7 in τ, ~6e7 steps for the 20 s paper example. The loop runs in one
numba function, up to 2^16 accepted steps per Python call (the wall budget is checked between
calls). nfev = 6·steps + 5·rejected + 2·starts: 5 per attempt, f at each accepted state (the next
step's first stage and the slope of the interpolant: no extra evaluation), f(z0) and the initial
step's trial per ``start``. njev = 0.

Events: after each accepted step the kernel evaluates the four root functions of
:mod:`integrators.events` (linear in z); on a sign change in a direction that counts it places
the crossings on the step's cubic Hermite interpolant (z, f at both ends) by bisection to the
last bit, earliest first, with the cursor semantics of :mod:`integrators.dense_roots`. One
exception: a ``PEAK`` crossing at w ≤ E_slow is not reported (it cannot be an event's peak: an
event starts at w > 10 E_slow and ends at w ≤ E_slow). At the stability limit the stiff mode is
not fully damped, and near the minimum of w in the stick phase C h − D η (= w u') jitters about
zero: 2e4 (rtol 1e−6) to 3e5 (1e−8) such crossings per cycle, each a return to Python that
would cost more than the integration and change nothing in the events table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.events import AT_ROOT, END, PEAK, carry_signs, sign_change
from integrators.events import compiled_roots as _roots
from integrators.kernel_stepper import CompiledAlgorithm, KernelStepper
from integrators.registry import register
from problems.formulations import ode_rhs

__all__ = ["CashKarp45"]

REACHED, ROOT, CHUNK, NONFINITE, UNDERFLOW = range(5)
# st: the last step [TAU_OLD, TAU], the step size H, CURSOR ≤ TAU the last time handed out and
# T_RET the time returned, counters. Rows of Z: z and f at TAU and at TAU_OLD, the state
# returned. Rows of G: root-function values at the cursor; roots found there (±1: direction).
_TAU, _TAU_OLD, _H, _CURSOR, _T_RET, _STEPS, _REJECTED, _NFEV = range(8)
_Z, _F, _ZO, _FO, _ZR = range(5)

# Cash–Karp tableau (NR rkck): stages B, 5th-order weights C, C − (4th-order weights) as DC
B21, B31, B32, B41, B42, B43 = 0.2, 3.0 / 40.0, 9.0 / 40.0, 0.3, -0.9, 1.2
B51, B52, B53, B54 = -11.0 / 54.0, 2.5, -70.0 / 27.0, 35.0 / 27.0
B61, B62, B63 = 1631.0 / 55296.0, 175.0 / 512.0, 575.0 / 13824.0
B64, B65 = 44275.0 / 110592.0, 253.0 / 4096.0
C1, C3, C4, C6 = 37.0 / 378.0, 250.0 / 621.0, 125.0 / 594.0, 512.0 / 1771.0
DC1, DC3, DC4 = C1 - 2825.0 / 27648.0, C3 - 18575.0 / 48384.0, C4 - 13525.0 / 55296.0
DC5, DC6 = -277.0 / 14336.0, C6 - 0.25
SAFETY, PGROW, PSHRNK, ERRCON = 0.9, -0.2, -0.25, 1.89e-4      # ERRCON = (5/SAFETY)^(1/PGROW)


#: crossings placed in one scan at most: each moves the cursor forward, so this only stops a
#: pathological step (a root function at zero to the bit) from scanning for ever
MAX_PASSES = 64


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def cursor_time(t0, dt, x, lo, hi):
    """The time of the fraction x of the step [t0, t0 + dt], within [lo, hi], rounded up so that
    (t − t0)/dt ≥ x: the cursor must sit on the far side of a crossing just placed at x, where
    the root function has the sign it is given (else the next pass finds the same crossing, and
    the one after it the same in reverse, for ever)."""
    t = min(max(t0 + x * dt, lo), hi)
    while t < hi and (t - t0) / dt < x:
        t = np.nextafter(t, np.inf)
    return t


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def crossed(G, g, dirs, stick_peaks):
    """Has a root function changed sign, in a direction that counts, between the cursor (G[0])
    and the new step end (g)? With ``stick_peaks`` False a PEAK crossing at w ≤ E_slow (END
    negative at both ends) does not count (see the module docstring)."""
    for k in range(4):
        sign = sign_change(G[0, k], g[k])
        if (sign != 0 and (dirs[k] == 0 or dirs[k] == sign)
                and (stick_peaks or k != PEAK or G[0, END] > 0.0 or g[END] > 0.0)):
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _f(q, h, u, s, zb, fb):
    """ode_rhs on scalars, so that the stages stay in registers (twice as fast as in arrays);
    q = (law, β, C, D, E)."""
    zb[0], zb[1], zb[2] = h, u, s
    ode_rhs(q[0], q[1], q[2], q[3], q[4], zb, fb)
    return fb[0], fb[1], fb[2]


@njit(cache=True, error_model="numpy", inline="always")
def _step(p, Z, zb, fb, tau, h, t_out):
    """One accepted step (NR rkqs) of proposed size h from (tau, Z[_Z], Z[_F]), shortened to land
    on t_out; its start goes to Z[_ZO], Z[_FO]. Returns (-1, UNDERFLOW or NONFINITE; the new τ;
    the next h; attempts)."""
    q, rtol, atol = (int(p[0]), p[1], p[2], p[3], p[4]), p[5], p[6]
    z0, z1, z2, f0, f1, f2 = Z[_Z, 0], Z[_Z, 1], Z[_Z, 2], Z[_F, 0], Z[_F, 1], Z[_F, 2]
    hs, last = (t_out - tau, True) if tau + h >= t_out else (h, False)
    attempts = 0
    while True:
        if tau + hs == tau:
            return UNDERFLOW, tau, hs, attempts
        attempts += 1
        a0, a1, a2 = _f(q, z0 + hs * B21 * f0, z1 + hs * B21 * f1, z2 + hs * B21 * f2, zb, fb)
        b0, b1, b2 = _f(q, z0 + hs * (B31 * f0 + B32 * a0), z1 + hs * (B31 * f1 + B32 * a1),
                        z2 + hs * (B31 * f2 + B32 * a2), zb, fb)
        c0, c1, c2 = _f(q, z0 + hs * (B41 * f0 + B42 * a0 + B43 * b0),
                        z1 + hs * (B41 * f1 + B42 * a1 + B43 * b1),
                        z2 + hs * (B41 * f2 + B42 * a2 + B43 * b2), zb, fb)
        d0, d1, d2 = _f(q, z0 + hs * (B51 * f0 + B52 * a0 + B53 * b0 + B54 * c0),
                        z1 + hs * (B51 * f1 + B52 * a1 + B53 * b1 + B54 * c1),
                        z2 + hs * (B51 * f2 + B52 * a2 + B53 * b2 + B54 * c2), zb, fb)
        g0, g1, g2 = _f(q, z0 + hs * (B61 * f0 + B62 * a0 + B63 * b0 + B64 * c0 + B65 * d0),
                        z1 + hs * (B61 * f1 + B62 * a1 + B63 * b1 + B64 * c1 + B65 * d1),
                        z2 + hs * (B61 * f2 + B62 * a2 + B63 * b2 + B64 * c2 + B65 * d2), zb, fb)
        e0 = hs * (DC1 * f0 + DC3 * b0 + DC4 * c0 + DC5 * d0 + DC6 * g0)
        e1 = hs * (DC1 * f1 + DC3 * b1 + DC4 * c1 + DC5 * d1 + DC6 * g1)
        e2 = hs * (DC1 * f2 + DC3 * b2 + DC4 * c2 + DC5 * d2 + DC6 * g2)
        errmax = max(abs(e0) / (atol + rtol * (abs(z0) + abs(hs * f0))),
                     abs(e1) / (atol + rtol * (abs(z1) + abs(hs * f1))),
                     abs(e2) / (atol + rtol * (abs(z2) + abs(hs * f2))))
        if errmax <= 1.0:                               # False for NaN
            break
        last = False
        hs = max(SAFETY * hs * errmax ** PSHRNK, 0.1 * hs) if np.isfinite(errmax) else 0.1 * hs
    Z[_ZO], Z[_FO] = Z[_Z], Z[_F]
    Z[_Z, 0] = z0 = z0 + hs * (C1 * f0 + C3 * b0 + C4 * c0 + C6 * g0)
    Z[_Z, 1] = z1 = z1 + hs * (C1 * f1 + C3 * b1 + C4 * c1 + C6 * g1)
    Z[_Z, 2] = z2 = z2 + hs * (C1 * f2 + C3 * b2 + C4 * c2 + C6 * g2)
    Z[_F, 0], Z[_F, 1], Z[_F, 2] = _f(q, z0, z1, z2, zb, fb)
    h_next = SAFETY * hs * errmax ** PGROW if errmax > ERRCON else 5.0 * hs
    h_next = max(h_next, h) if last else h_next     # a shortened step says nothing about h
    finite = True
    for i in range(3):
        finite &= np.isfinite(Z[_Z, i]) and np.isfinite(Z[_F, i])
    return -1 if finite else NONFINITE, t_out if last else tau + hs, h_next, attempts


@njit(cache=True, error_model="numpy")
def _hermite(Z, x, dt, out):
    """The cubic Hermite interpolant of the step [TAU_OLD, TAU] at the fraction x of it."""
    x2, x3 = x * x, x * x * x
    a, b, c, d = 2 * x3 - 3 * x2 + 1, (x3 - 2 * x2 + x) * dt, 3 * x2 - 2 * x3, (x3 - x2) * dt
    out[:] = a * Z[_ZO] + b * Z[_FO] + c * Z[_Z] + d * Z[_F]


@njit(cache=True, error_model="numpy")
def _scan(st, p, Z, G, dirs, t_end):
    """The earliest crossing that counts in (CURSOR, t_end] of the last step: True, with it at
    T_RET, Z[_ZR], G[1]; else False, the cursor moved to t_end. A crossing in a direction that
    does not count only moves the cursor and its signs (G[0])."""
    t0, dt = st[_TAU_OLD], st[_TAU] - st[_TAU_OLD]
    x_end = (t_end - t0) / dt
    zt, gt, g_end, g_new, x_root = np.empty(3), np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    z_end = Z[_Z].copy()
    if t_end < st[_TAU]:
        _hermite(Z, x_end, dt, z_end)
    _roots(p, z_end, g_end)
    passes = 0
    while True:
        x_cur = (st[_CURSOR] - t0) / dt
        _hermite(Z, x_cur, dt, zt)
        _roots(p, zt, g_new)
        for k in range(4):
            g0, g1, ga, lo, hi = G[0, k], g_end[k], g_new[k], x_cur, x_end
            if sign_change(g0, g1) == 0:
                hi = np.inf
            elif ga == 0.0 or (ga > 0.0 and g1 > 0.0) or (ga < 0.0 and g1 < 0.0):
                hi = x_cur            # the interpolant is past it already: at the cursor
            while lo < hi < np.inf:   # bisection to the last bit; hi keeps the far side's sign
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                _hermite(Z, mid, dt, zt)
                _roots(p, zt, gt)
                if gt[k] != 0.0 and (gt[k] > 0.0) == (ga > 0.0):
                    lo = mid
                else:
                    hi = mid
            x_root[k] = hi
        best = x_root.min()
        if best == np.inf or passes > MAX_PASSES:
            carry_signs(G[0], g_end)
            st[_CURSOR] = st[_T_RET] = t_end
            Z[_ZR], G[0] = z_end, g_end
            return False
        passes += 1
        t_root = (st[_CURSOR] if best == x_cur else t_end if best == x_end
                  else cursor_time(t0, dt, best, st[_CURSOR], t_end))
        if best == x_end:
            Z[_ZR] = z_end
        else:
            _hermite(Z, best, dt, Z[_ZR])
        _roots(p, Z[_ZR], g_new)
        G[1] = 0.0
        for k in range(4):
            if x_root[k] == best:
                sign = 1.0 if g_end[k] > G[0, k] else -1.0
                g_new[k] = sign * max(abs(g_new[k]), AT_ROOT)    # the sign after the crossing
                if (dirs[k] == 0 or dirs[k] == sign) and (k != PEAK or g_new[END] > 0.0):
                    G[1, k] = sign
        carry_signs(G[0], g_new)
        st[_CURSOR], G[0] = t_root, g_new
        if G[1].any():
            st[_T_RET] = t_root
            return True


@njit(cache=True, error_model="numpy")
def _advance(st, p, Z, G, dirs, t_out, n_max):
    """Scan the last step, then step towards t_out (at most ``n_max`` accepted steps). Returns
    REACHED or ROOT (at T_RET, Z[_ZR]), CHUNK, NONFINITE or UNDERFLOW."""
    zb, fb, g = np.empty(3), np.empty(3), np.empty(4)
    status = -1 if np.isfinite(Z[_F]).all() else NONFINITE
    n = attempts = 0
    while status < 0:
        if st[_CURSOR] < st[_TAU] and _scan(st, p, Z, G, dirs, min(st[_TAU], t_out)):
            status = ROOT
        elif st[_CURSOR] >= t_out:
            if st[_CURSOR] == st[_TAU]:
                Z[_ZR], st[_T_RET] = Z[_Z], st[_TAU]
            status = REACHED
        elif n >= n_max:
            status = CHUNK
        else:
            status, tau, h, tried = _step(p, Z, zb, fb, st[_TAU], st[_H], t_out)
            attempts += tried
            if status != UNDERFLOW:           # a step was accepted
                n += 1
                st[_TAU_OLD], st[_TAU], st[_H] = st[_TAU], tau, h
            if status < 0:
                _roots(p, Z[_Z], g)
                if not crossed(G, g, dirs, False):  # else the scan at the top places them
                    carry_signs(G[0], g)
                    st[_CURSOR], G[0] = tau, g
    st[_STEPS] += n
    st[_REJECTED] += attempts - n
    st[_NFEV] += 5 * attempts + n
    return status


@register
@dataclass(frozen=True)
class CashKarp45(CompiledAlgorithm):
    """Cash–Karp embedded Runge–Kutta 4(5), explicit, adaptive, with the step control of
    Numerical Recipes §16.2 (``rkqs``). Order 5: the 5th-order solution is propagated.

    Needs ``rtol`` and ``atol`` (the test is |err_i| ≤ atol + rtol·(|z_i| + |h f_i|): NR's yscal,
    with atol as the absolute floor) and the compiled right-hand side (``rhs="numba"`` only). ``max_steps``
    (accepted steps, whole solve) defaults to ETD's 2e8, not 5e7: in the stick phase stability,
    not accuracy, sets the step: the 20 s paper example takes 6.3e7 steps, and the count barely
    moves between rtol 1e−3 and 1e−10.
    Cash & Karp (1990), ACM TOMS 16, 201–222; Press et al. (1992).
    """

    max_steps: int = 200_000_000

    name: ClassVar[str] = "CashKarp45"
    family: ClassVar[str] = "explicit Runge–Kutta (Cash–Karp 4(5))"
    order: ClassVar[int] = 5
    stiff: ClassVar[bool] = False
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop is compiled with numba and calls the compiled right-hand side; the "
        "python-tier explicit RK45 is scipy-RK45")

    def make_stepper(self, nd, budget):
        return _CashKarpStepper(self, nd, budget)


class _CashKarpStepper(KernelStepper):
    """The segment protocol over :func:`_advance` (:class:`integrators.kernel_stepper.KernelStepper`)."""

    def kernel(self, t_out, n_max):
        return _advance(self._st, self._p, self._Z, self._G, self._dirs, t_out, n_max)
