"""Rosenbrock methods with the analytic Jacobian, compiled with numba: Rosenbrock23 and Rodas5P.

Linearly implicit one-step methods: each stage solves one linear system with the matrix
M = I − γ h J, J = ∂f/∂z the analytic Jacobian of :func:`problems.formulations.ode_jacobian` at
the step's start. No Newton iteration, so no convergence failure; the accuracy needs the exact
J. M is factored once per attempt (3×3 LU with partial pivoting, :func:`_lu3`) and the
factorization serves every stage of it; J is evaluated once per step and reused by the retries
of a rejected attempt (same start point). The problem is autonomous within a segment (E fixed),
so no ∂f/∂τ term appears.

* ``Rosenbrock23``: Shampine & Reichelt (1997), The MATLAB ODE suite, SIAM J. Sci. Comput. 18,
  1–22 (ode23s), as in Julia's OrdinaryDiffEq ``Rosenbrock23``: d = 1/(2 + √2), e32 = 6 + √2,

      k1 = M⁻¹ F0                            F0 = f(z0),  M = I − d h J
      F1 = f(z0 + h k1/2),  k2 = M⁻¹ (F1 − k1) + k1,   z1 = z0 + h k2
      F2 = f(z1),           k3 = M⁻¹ (F2 − e32 (k2 − F1) − 2 (k1 − F0))
      err = h/6 (k1 − 2 k2 + k3)

  Order 2 (propagated), L-stable, error estimate O(h³). F2 is the next step's F0 (FSAL).
  Its global error is ~30–300× rtol (order 2, error per step controlled): 1e−6 on the limit
  cycle takes rtol ≈ 1e−9.
* ``Rodas5P``: Steinebach (2023), Construction of Rosenbrock–Wanner method Rodas5P and numerical
  benchmarks within the Julia differential equations package, BIT Numer. Math. 63, 27. Order 5,
  8 stages (7 new f), stiffly accurate, embedded order 4. Hairer–Wanner's form (Solving ODEs II,
  §IV.7, (7.25)): (I/(γh) − J) k_i = f(z0 + Σ_j a_ij k_j) + Σ_j (c_ij/h) k_j, z1 = z0 +
  Σ_j a_8j k_j + k_8, err = k_8. Tableau (A, C, γ, and H of the dense output) copied from
  OrdinaryDiffEq.jl, ``lib/OrdinaryDiffEqRosenbrock/src/rosenbrock_tableaus.jl``
  (``Rodas5PTableau``); the observed order (tests/test_rosenbrock.py) checks the digits.

Dense output, one form for both: z(τ0 + x h) = (1 − x) z0 + x (z1 + (1 − x)(D1 + x (D2 + x D3))).
Rodas5P: its own 4th-order interpolant, D_j = Σ_i H_ji k_i (OrdinaryDiffEq's
``rosenbrock_interpolants.jl``). Rosenbrock23: the cubic Hermite interpolant of (z, f) at both
ends (F0 and F2 are at hand), D1 = h F0 − (z1 − z0), D2 = (z1 − z0) − h F2 − D1, D3 = 0; it is
one order better than ode23s' quadratic continuous extension, at no cost.

Step control, as CashKarp45's max norm with atol as the absolute floor, but with Hairer's scale:
errmax = max_i |err_i| / (atol + rtol·max(|z0_i|, |z1_i|)) (NR's |h f_i| term would follow the
stiff mode's rate, meaningless for an implicit step). errmax ≤ 1 accepts. The new step is that
of Hairer's RODAS (Solving ODEs II, §IV.8; rodas.f): h/fac, fac = errmax^(1/q)/0.9 clipped to
[1/6, 5], q = 3 (Rosenbrock23) or 5 (Rodas5P), with Gustafsson's predictive controller on
accepted steps (fac ← max(fac, (h_acc/h)(errmax²/err_acc)^(1/q)/0.9)) and no increase right
after a rejection. A non-finite errmax (an overflowing trial: e^u) or a singular M rejects with
h/10; τ + h == τ is ``StepUnderflow``; a non-finite accepted state ``NonFinite``. First step after
each ``start``: Hairer's heuristic as in CashKarp45, with exponent 1/q. A step that would pass
``t_out`` is shortened to land on it; the next one is the step proposed before, if larger.

Cost counting (Stats): njev = one Jacobian per step (the first attempt; retries reuse it), so
njev = steps + the steps that ended in underflow. nfev: Rosenbrock23 2 per attempt (F1, F2);
Rodas5P 7 per attempt and f(z1) per accepted step (the next step's first stage); both + 2 per
``start`` (f(z0) and the initial step's trial): nfev = 2·(steps + rejected) + 2·starts,
resp. 8·steps + 7·rejected + 2·starts. Up to 2^16 accepted steps per Python call.

Events: as CashKarp45 (same kernel logic, on the dense output above): after each accepted step
the four root functions of :mod:`integrators.events` are evaluated at its end; on a sign change in
a direction that counts the crossings are placed on the dense output by bisection to the last
bit, earliest first, with the cursor semantics of :mod:`integrators.dense_roots`. CashKarp45's
exclusion of PEAK crossings at w ≤ E_slow (the stick-phase jitter of an explicit method at its
stability limit) is not needed: these L-stable methods damp the stiff mode, and no such
crossing occurs (tests/test_rosenbrock.py counts them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.cash_karp import _roots as _roots_ck
from integrators.cash_karp import MAX_PASSES, crossed, cursor_time
from integrators.events import AT_ROOT, carry_signs, sign_change
from integrators.kernel_stepper import CompiledAlgorithm, KernelStepper
from integrators.registry import register
from problems.formulations import ode_jacobian, ode_rhs

__all__ = ["Rosenbrock23", "Rodas5P"]

REACHED, ROOT, CHUNK, NONFINITE, UNDERFLOW = range(5)
R23, RODAS5P = 0, 1             # method codes, p[_METHOD]
# st: the last step [TAU_OLD, TAU], the step size H, CURSOR ≤ TAU the last time handed out and
# T_RET the time returned, counters, and the controller's memory (Gustafsson: h and errmax of
# the last accepted step; NACC accepted steps since ``start``; REJECT: the last attempt failed).
(_TAU, _TAU_OLD, _H, _CURSOR, _T_RET, _STEPS, _REJECTED, _NFEV, _NJEV, _HACC, _ERRACC, _NACC,
 _REJECT) = range(13)
# Rows of Z: z and f at TAU, z at TAU_OLD, the dense-output coefficients D1–D3, the state
# returned. p: law, β, C, D, E, rtol, atol, ln(10 E_slow), ln E_slow, ln E, method.
_Z, _F, _ZO, _D1, _D2, _D3, _ZR = range(7)
_METHOD = 10

D23 = 1.0 / (2.0 + math.sqrt(2.0))
E32 = 6.0 + math.sqrt(2.0)

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

# the shared right-hand side and Jacobian, compiled again to be inlined into the stages: a call
# of the compiled ones costs reference counting of its array arguments (~ as much as f itself)
_rhs = njit(cache=True, nogil=True, error_model="numpy", inline="always")(ode_rhs.py_func)
_jac = njit(cache=True, nogil=True, error_model="numpy", inline="always")(ode_jacobian.py_func)

# CashKarp45's root functions, inlined likewise
_roots = njit(cache=True, nogil=True, error_model="numpy", inline="always")(_roots_ck.py_func)

SAFETY, FAC_MIN, FAC_MAX = 0.9, 1.0 / 6.0, 5.0      # hnew/h in [1/FAC_MAX, 1/FAC_MIN]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _lu3(a, piv):
    """In-place LU of the 3×3 ``a`` with partial pivoting (rows swapped whole, as LAPACK
    getrf); False if a pivot is zero. (One exit only, here and in every inlined function:
    numba cannot prune the reference counting of the arrays otherwise, ~5 ns per array.)"""
    regular = True
    for k in range(3):
        p = k
        for i in range(k + 1, 3):
            if abs(a[i, k]) > abs(a[p, k]):
                p = i
        piv[k] = p
        regular &= a[p, k] != 0.0
        if p != k:
            for j in range(3):
                a[k, j], a[p, j] = a[p, j], a[k, j]
        for i in range(k + 1, 3):
            a[i, k] /= a[k, k]
            for j in range(k + 1, 3):
                a[i, j] -= a[i, k] * a[k, j]
    return regular


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _lus3(a, piv, b, r):
    """Solve in place for row r of ``b`` with the factors of :func:`_lu3`."""
    for k in range(3):
        p = piv[k]
        if p != k:
            b[r, k], b[r, p] = b[r, p], b[r, k]
    b[r, 1] -= a[1, 0] * b[r, 0]
    b[r, 2] -= a[2, 0] * b[r, 0] + a[2, 1] * b[r, 1]
    b[r, 2] /= a[2, 2]
    b[r, 1] = (b[r, 1] - a[1, 2] * b[r, 2]) / a[1, 1]
    b[r, 0] = (b[r, 0] - a[0, 1] * b[r, 1] - a[0, 2] * b[r, 2]) / a[0, 0]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _factor(hg, J, M, piv):
    """M = I − hg·J, factored in place; False if singular."""
    for i in range(3):
        for j in range(3):
            M[i, j] = -hg * J[i, j]
        M[i, i] += 1.0
    return _lu3(M, piv)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt23(p, hs, J, M, piv, K, D, z0, f0, z1, f1, u, fb):
    """One trial step of Rosenbrock23 of size hs from (z0, f0 = f(z0)) with the Jacobian J at
    z0: writes z1, f1 = f(z1) and the dense coefficients D (3×3, the cubic Hermite). Returns
    errmax (inf if M is singular or the error not finite). Work arrays, all preallocated (an
    allocation costs as much as an f): M and piv (the LU), K (the stages), u and fb (a stage's
    argument and f there)."""
    law, beta, c, d, e, rtol, atol = int(p[0]), p[1], p[2], p[3], p[4], p[5], p[6]
    regular = _factor(hs * D23, J, M, piv)
    for i in range(3):
        K[0, i] = f0[i]
    _lus3(M, piv, K, 0)
    for i in range(3):
        u[i] = z0[i] + 0.5 * hs * K[0, i]
    _rhs(law, beta, c, d, e, u, fb)          # F1
    for i in range(3):
        K[1, i] = fb[i] - K[0, i]
    _lus3(M, piv, K, 1)
    for i in range(3):
        K[1, i] += K[0, i]
        z1[i] = z0[i] + hs * K[1, i]
    _rhs(law, beta, c, d, e, z1, f1)         # F2
    for i in range(3):
        K[2, i] = f1[i] - E32 * (K[1, i] - fb[i]) - 2.0 * (K[0, i] - f0[i])
    _lus3(M, piv, K, 2)
    errmax = 0.0
    for i in range(3):
        err = hs / 6.0 * (K[0, i] - 2.0 * K[1, i] + K[2, i])
        errmax = max(errmax, abs(err) / (atol + rtol * max(abs(z0[i]), abs(z1[i]))))
        dz = z1[i] - z0[i]
        D[0, i] = hs * f0[i] - dz
        D[1, i] = dz - hs * f1[i] - D[0, i]
        D[2, i] = 0.0
    return errmax if regular and np.isfinite(errmax) else np.inf


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt5p(p, hs, J, M, piv, K, D, z0, f0, z1, f1, u, fb):
    """As :func:`_attempt23`, for Rodas5P; f1 is not computed (the caller does it if the step
    is accepted)."""
    law, beta, c, d, e, rtol, atol = int(p[0]), p[1], p[2], p[3], p[4], p[5], p[6]
    hg = hs * G5P
    regular = _factor(hg, J, M, piv)
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
            _rhs(law, beta, c, d, e, u, fb)
        for i in range(3):
            acc = 0.0
            for j in range(s):
                acc += C5P[s, j] * K[j, i]
            K[s, i] = hg * fb[i] + G5P * acc
        _lus3(M, piv, K, s)
    errmax = 0.0
    for i in range(3):
        z1[i] = u[i] + K[7, i]
        errmax = max(errmax, abs(K[7, i]) / (atol + rtol * max(abs(z0[i]), abs(z1[i]))))
        for r in range(3):
            acc = 0.0
            for s in range(8):
                acc += H5P[r, s] * K[s, i]
            D[r, i] = acc
    return errmax if regular and np.isfinite(errmax) else np.inf


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _attempt(method, p, hs, J, M, piv, K, D, z0, f0, z1, f1, u, fb):
    """One trial step of ``method``; see :func:`_attempt23`."""
    if method == R23:
        errmax = _attempt23(p, hs, J, M, piv, K, D, z0, f0, z1, f1, u, fb)
    else:
        errmax = _attempt5p(p, hs, J, M, piv, K, D, z0, f0, z1, f1, u, fb)
    return errmax


@njit(cache=True, nogil=True, error_model="numpy")
def _step(method, st, p, Z, J, M, piv, K, D, z0, f0, z1, f1, u, fb, t_out):
    """One accepted step of proposed size st[_H] from (st[_TAU], Z[_Z], Z[_F]), shortened to
    land on t_out; its start goes to Z[_ZO], its dense output to Z[_D1:_D3+1]. Returns (-1,
    UNDERFLOW or NONFINITE; the new τ; the next h; attempts)."""
    tau, h = st[_TAU], st[_H]
    q = 3.0 if method == R23 else 5.0
    for i in range(3):
        z0[i], f0[i] = Z[_Z, i], Z[_F, i]
    _jac(int(p[0]), p[1], p[2], p[3], p[4], z0, J)
    st[_NJEV] += 1
    hs, last = (t_out - tau, True) if tau + h >= t_out else (h, False)
    attempts, errmax = 0, np.inf
    while errmax > 1.0 and tau + hs > tau:
        attempts += 1
        errmax = _attempt(method, p, hs, J, M, piv, K, D, z0, f0, z1, f1, u, fb)
        if errmax <= 1.0 and method != R23:     # f at the end: the next step's f0 and the
            _rhs(int(p[0]), p[1], p[2], p[3], p[4], z1, f1)     # dense output's slope
        if errmax <= 1.0 and not (np.isfinite(z1).all() and np.isfinite(f1).all()):
            # an end state whose rates overflow (e^u at a loose tolerance's overshoot) is a
            # failed trial, not a result
            errmax = np.inf
            st[_NFEV] += 1.0 if method != R23 else 0.0      # that f is not in the per-attempt count
        if errmax > 1.0:
            last = False
            st[_REJECT] = 1.0
            hs *= 0.1 if errmax == np.inf else 1.0 / min(
                1.0 / FAC_MIN, max(1.0 / FAC_MAX, errmax ** (1.0 / q) / SAFETY))
    status, tau_new, h_next = UNDERFLOW, tau, hs
    if errmax <= 1.0:
        fac = min(1.0 / FAC_MIN, max(1.0 / FAC_MAX, errmax ** (1.0 / q) / SAFETY))
        if st[_NACC] >= 1:          # Gustafsson's predictive controller (rodas.f, PRED)
            gus = st[_HACC] / hs * (errmax * errmax / st[_ERRACC]) ** (1.0 / q) / SAFETY
            fac = max(fac, min(1.0 / FAC_MIN, max(1.0 / FAC_MAX, gus)))
        st[_HACC], st[_ERRACC], st[_NACC] = hs, max(1e-2, errmax), st[_NACC] + 1
        h_next = hs / fac
        if st[_REJECT] != 0.0:      # no increase right after a rejection
            h_next = min(h_next, hs)
        st[_REJECT] = 0.0
        h_next = max(h_next, h) if last else h_next     # a shortened step says nothing about h
        finite = True
        for i in range(3):
            Z[_ZO, i], Z[_Z, i], Z[_F, i] = z0[i], z1[i], f1[i]
            for r in range(3):
                Z[_D1 + r, i] = D[r, i]
            finite &= np.isfinite(z1[i]) and np.isfinite(f1[i])
        status, tau_new = -1 if finite else NONFINITE, t_out if last else tau + hs
    return status, tau_new, h_next, attempts


@njit(cache=True, nogil=True, error_model="numpy")
def _workspace():
    """The work arrays of :func:`_step`, allocated once per kernel call: J, M, piv, K, D and
    z0, f0, z1, f1, u, fb (see :func:`_attempt23`)."""
    return (np.empty((3, 3)), np.empty((3, 3)), np.empty(3, np.int64), np.empty((8, 3)),
            np.empty((3, 3)), np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3),
            np.empty(3))


@njit(cache=True, nogil=True, error_model="numpy")
def _dense(Z, x, out):
    """The dense output of the step [TAU_OLD, TAU] at the fraction x of it."""
    y = 1.0 - x
    for i in range(3):
        out[i] = y * Z[_ZO, i] + x * (Z[_Z, i] + y * (Z[_D1, i] + x * (Z[_D2, i]
                                                                      + x * Z[_D3, i])))


@njit(cache=True, nogil=True, error_model="numpy")
def _scan(st, p, Z, G, dirs, t_end):
    """The earliest crossing that counts in (CURSOR, t_end] of the last step: True, with it at
    T_RET, Z[_ZR], G[1]; else False, the cursor moved to t_end. A crossing in a direction that
    does not count only moves the cursor and its signs (G[0]). As cash_karp._scan."""
    t0, dt = st[_TAU_OLD], st[_TAU] - st[_TAU_OLD]
    x_end = (t_end - t0) / dt
    zt, gt, g_end, g_new, x_root = np.empty(3), np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    z_end = Z[_Z].copy()
    if t_end < st[_TAU]:
        _dense(Z, x_end, z_end)
    _roots(p, z_end, g_end)
    passes = 0
    while True:
        x_cur = (st[_CURSOR] - t0) / dt
        _dense(Z, x_cur, zt)
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
                _dense(Z, mid, zt)
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
            _dense(Z, best, Z[_ZR])
        _roots(p, Z[_ZR], g_new)
        G[1] = 0.0
        for k in range(4):
            if x_root[k] == best:
                sign = 1.0 if g_end[k] > G[0, k] else -1.0
                g_new[k] = sign * max(abs(g_new[k]), AT_ROOT)    # the sign after the crossing
                if dirs[k] == 0 or dirs[k] == sign:
                    G[1, k] = sign
        carry_signs(G[0], g_new)
        st[_CURSOR], G[0] = t_root, g_new
        if G[1].any():
            st[_T_RET] = t_root
            return True


@njit(cache=True, nogil=True, error_model="numpy")
def _advance(method, st, p, Z, G, dirs, t_out, n_max):
    """Scan the last step, then step towards t_out (at most ``n_max`` accepted steps). Returns
    REACHED or ROOT (at T_RET, Z[_ZR]), CHUNK, NONFINITE or UNDERFLOW. As cash_karp._advance;
    ``method`` is R23 or RODAS5P."""
    J, M, piv, K, D, z0, f0, z1, f1, u, fb = _workspace()
    g = np.empty(4)
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
            status, tau, h, tried = _step(method, st, p, Z, J, M, piv, K, D, z0, f0, z1, f1, u,
                                          fb, t_out)
            attempts += tried
            if status != UNDERFLOW:           # a step was accepted
                n += 1
                st[_TAU_OLD], st[_TAU], st[_H] = st[_TAU], tau, h
            if status < 0:
                _roots(p, Z[_Z], g)
                if not crossed(G, g, dirs, True):   # else the scan at the top places them
                    carry_signs(G[0], g)
                    st[_CURSOR], G[0] = tau, g
    st[_STEPS] += n
    st[_REJECTED] += attempts - n
    st[_NFEV] += (2 * attempts if method == R23 else 7 * attempts + n)
    return status


@njit(cache=True, nogil=True, error_model="numpy")
def fixed_steps(p, z0, hs, n):
    """``n`` steps of size ``hs`` from z0, every one accepted (the order tests): the end
    state. Same :func:`_step` as the adaptive runs, with an infinite tolerance."""
    q, st, Z = p.copy(), np.zeros(13), np.zeros((7, 3))
    q[5] = q[6] = np.inf
    J, M, piv, K, D, z0w, f0, z1, f1, u, fb = _workspace()
    Z[_Z] = z0
    _rhs(int(q[0]), q[1], q[2], q[3], q[4], z0, Z[_F])
    for _ in range(n):
        st[_H] = hs
        _step(int(q[_METHOD]), st, q, Z, J, M, piv, K, D, z0w, f0, z1, f1, u, fb, np.inf)
    return Z[_Z].copy()


class _Rosenbrock(CompiledAlgorithm):
    """What both methods share: options, tiers, the stepper."""

    stiff: ClassVar[bool] = True
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop is compiled with numba and calls the compiled right-hand side and "
        "Jacobian")
    method_code: ClassVar[int] = R23
    error_order: ClassVar[int] = 3          # the error estimate is O(h^error_order)

    def make_stepper(self, nd, budget):
        return _RosenbrockStepper(self, nd, budget)

    def fixed_steps(self, nd, z0, span: float, n: int) -> np.ndarray:
        """``n`` equal steps over ``span`` (τ) from z0 under the slow loading, every one
        accepted (order studies: :func:`benchmarks.convergence.fixed_step_orders`): z at
        the end."""
        p = self.make_stepper(nd, None)._p.copy()
        p[4] = nd.e_slow
        return fixed_steps(p, np.asarray(z0, dtype=float), span / n, n)


@register
@dataclass(frozen=True)
class Rosenbrock23(_Rosenbrock):
    """Shampine–Reichelt Rosenbrock 2(3) (MATLAB ode23s, Julia Rosenbrock23), L-stable, with the
    analytic Jacobian, adaptive (Hairer's RODAS control), events on the cubic Hermite dense
    output. Order 2. Needs ``rtol``, ``atol`` and ``rhs="numba"``. Shampine & Reichelt (1997),
    SIAM J. Sci. Comput. 18, 1–22. See :mod:`integrators.rosenbrock`."""

    name: ClassVar[str] = "Rosenbrock23"
    family: ClassVar[str] = "Rosenbrock (Shampine–Reichelt 2(3), analytic Jacobian)"
    order: ClassVar[int] = 2
    method_code: ClassVar[int] = R23
    error_order: ClassVar[int] = 3


@register
@dataclass(frozen=True)
class Rodas5P(_Rosenbrock):
    """Steinebach's Rodas5P, a stiffly accurate Rosenbrock 5(4) with the analytic Jacobian,
    adaptive (Hairer's RODAS control), events on its 4th-order dense output. Order 5. Needs
    ``rtol``, ``atol`` and ``rhs="numba"``. Steinebach (2023), BIT 63, 27; tableau from
    OrdinaryDiffEq.jl. See :mod:`integrators.rosenbrock`."""

    name: ClassVar[str] = "Rodas5P"
    family: ClassVar[str] = "Rosenbrock (Rodas5P 5(4), analytic Jacobian)"
    order: ClassVar[int] = 5
    method_code: ClassVar[int] = RODAS5P
    error_order: ClassVar[int] = 5


class _RosenbrockStepper(KernelStepper):
    """The segment protocol over :func:`_advance` (:class:`integrators.kernel_stepper.KernelStepper`)."""

    n_st, n_z = 13, 7

    def __init__(self, algorithm: _Rosenbrock, nd, budget):
        super().__init__(algorithm, nd, budget, extra_p=(algorithm.method_code,))
        self.init_exponent = 1.0 / algorithm.error_order

    def reset(self):
        self._st[_NACC] = self._st[_REJECT] = 0.0

    def kernel(self, t_out, n_max):
        return _advance(self.algorithm.method_code, self._st, self._p, self._Z, self._G,
                        self._dirs, t_out, n_max)
