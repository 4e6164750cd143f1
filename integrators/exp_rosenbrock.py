"""Exponential Rosenbrock methods exprb32 and exprb43 with the exact 3×3 Jacobian, numba-compiled.

Hochbruck, Ostermann & Schweitzer (2009), Exponential Rosenbrock-type methods, SIAM J. Numer.
Anal. 47, 786–803; tableaux also in Hochbruck & Ostermann (2010), Exponential integrators, Acta
Numerica 19, 209–286, §2.4 (checked against LeXInt, Deka & Einkemmer, ``EXPRB32.py`` and
``EXPRB43.py``). With J = f'(z_n) (:func:`problems.formulations.ode_jacobian`, exact), the
remainder g(z) = f(z) − J z and D_i = g(U_i) − g(z_n):

exprb32, order 3, embedded order 2 (the exponential Rosenbrock–Euler method):

    U2 = z_n + h φ1(hJ) f(z_n)                      (= the embedded solution)
    z_{n+1} = U2 + 2h φ3(hJ) D2                     error estimate 2h φ3(hJ) D2

exprb43, order 4, embedded order 3:

    U2 = z_n + (h/2) φ1(hJ/2) f(z_n)
    U3 = z_n + h φ1(hJ) (f(z_n) + D2)
    z_{n+1} = z_n + h φ1(hJ) f(z_n) + h φ3(hJ)(16 D2 − 2 D3) + h φ4(hJ)(−48 D2 + 12 D3)
    error estimate h φ4(hJ)(−48 D2 + 12 D3)

Both keep their order on the stiff problem: the η relaxation (rate D/w, up to ~1e7 in τ) is in J
and integrated exactly, so nothing lags a moving target as in the paper's ETD (below). Observed
with fixed steps in the stick phase: 3.04 and 4.06, both laws (tests/test_exp_rosenbrock.py).

φ-functions of A = hJ (:func:`phi_functions`). In the stick phase hJ has one eigenvalue, of the
u mode, down to −1e8, and two slow ones. Plain scaling and squaring (:func:`phi_dense`; Skaflestad
& Wright 2009, Appl. Numer. Math. 59, 783, as EXPINT: a 12-term Taylor series of φ_p at
‖A/2^s‖ ≤ ½, φ_k = X φ_{k+1} + I/k! downwards, then s doublings φ_k(2X) = 2^−k [φ_0(X) φ_k(X) +
Σ_{j=1..k} φ_j(X)/(k−j)!]) would need s ≈ log2(|λ|/½) ≈ 25 doublings of p+1 matrices. So the
stiff mode is split off first: with J's zero pattern (∂h'/∂h = ∂h'/∂s = ∂s'/∂h = 0) its
eigenvalue λ solves λ = a11 + a10 a01/λ + a12 a21/(λ − a22) (Newton from a11, 2–3 iterations), its
eigenvector is (a01/λ, 1, a21/(λ − a22)), and with it and e_h, e_s as basis A is block triangular
[[λ, bᵀ], [0, S]] with S the 2×2 slow block. φ_k(λ) in closed form (stable recursion for λ ≤ −1),
φ_k(S) by scaling and squaring (few doublings), the coupling by Parlett's recurrence
F12 = (φ_k(λ) bᵀ − bᵀ φ_k(S))(λI − S)⁻¹, well conditioned as the split is taken only when λ ≤ −64
and |λ| ≥ 16‖S‖; otherwise :func:`phi_dense`. Both agree with scipy's ``expm`` of the augmented
matrix (Al-Mohy & Higham 2011) to ≤ 5e−10 (split) and 4e−9 (dense) relative along a cycle,
h = 1e−4..10 (a test). Cost per attempt: ~0.6 µs (exprb32) and ~1 µs (exprb43) the whole step,
against ~4 µs with the dense path alone and ~20 µs with generic (non-unrolled) loops.

Step control: errmax = max_i |err_i| / (atol + rtol·max(|z_n,i|, |z_{n+1},i|)) (the mixed test of
scipy and SUNDIALS, in Cash–Karp's max norm; no |h f| term: in a stiff method h f of the fast mode
is not a scale). errmax ≤ 1 accepts; the next h is h·min(5, 0.9·errmax^(−1/(q+1))) with q the
embedded order, or less if Gustafsson's predictive controller asks for less (as in
:mod:`integrators.rosenbrock`: (h/h_acc)·0.9·(err_acc/errmax²)^(1/(q+1)) within [0.2, 5], with
h_acc, err_acc those of the step before), and not above h after a rejection; errmax > 1 rejects
with h·max(0.1, 0.9·errmax^(−1/(q+1))), a non-finite error with h/10. Why the predictive part:
where an event nucleates or its slip rate falls, the time scale shortens from step to step and the
step must shrink by ~20 % per step. The elementary controller assumes that the next step's error at
a given h is this one's, so it proposed a step that failed once on nearly every step (W2 aging,
rtol 1e−4: 1097 rejected attempts for 2663 steps, 29 % of the attempts; W4 slip 1e−3: 4512 for
9537); the predictive one extrapolates the trend of the last two steps. With it: 132 for 2689, 946
for 9539, the same errors, and a quarter fewer attempts (each computes the φ-functions, ~1 µs); at
1e−8, +0.7 % steps. Initial step, landing on t_out, UNDERFLOW, NONFINITE, chunks of accepted steps,
restarts at a reported root: as :mod:`integrators.cash_karp` (its adapter is reused).

Cost counters: nfev = (1 + s)·steps + s·rejected + 2·starts with s = 1 (exprb32) or 2 (exprb43)
stage evaluations per attempt, f at each accepted state (the next step's f(z_n) and the slope of
the interpolant), f(z0) and the initial-step trial per start. njev = one exact Jacobian per step,
at its start, reused by its rejected attempts (a step ending in UNDERFLOW counts one too). The
φ-functions are recomputed per attempt and not counted.

Events and dense output: the cubic Hermite interpolant of z (z and f at both ends of the step),
Cash–Karp's in-kernel bisection to the last bit with its cursor semantics (its ``_scan`` is used
as is: the layouts of ``st`` and ``Z`` are shared), PEAK crossings at w ≤ E_slow not reported.
The last event of the paper example and W2 starts within 4e−8–1.2e−7 (exprb32) and 2–4e−9
(exprb43) relative of the reference's at rtol = atol = 1e−8.

Why not an error-controlled ETD
-------------------------------
Decision: no error-controlled variant of the paper's ETD is registered; measured on the paper
example (20 s, err_rec against the reference; prototype kernels around ``etd_kernel.etd_step``
with the controller above, events on a cubic Hermite interpolant so that location is not the
limit; times on the shared 2-core machine):

* Naive, ETD2 − ETD1 as the error of ETD2 (exponent 1/2): steps 2.5e4, 2.3e5, 2.2e6, 2.1e7 at
  tol 1e−3..1e−6 — ×9.5 per decade, steps ∝ 1/tol — for err_rec 3e−2, 2e−3, 1e−6 (a sign change
  of the error), 1.4e−5; 8.2 s at 1e−6. Why: in the stick phase D·h/w ≫ 1, so ETD1's η lands on
  its target ηss frozen at the step's start, one step behind: an O(h) error h·dηss/dτ
  (≈ 0.09 h in u here, dηss/dτ ≈ (C/D)E). ETD2's second half re-targets at the ETD1 end state
  and removes most of it, so ETD2 − ETD1 ≈ ETD1's own error, O(h) (slope 1.00, ratio 1.00 to
  ETD1's one-step error, a test); read as O(h²), it sets h ≈ tol/0.09: N ≈ 400·0.09/tol.
  Meanwhile ETD2's one-step error in u is 2.6e−7–4e−7 for h = 1e−3..1.6e−2, far below the tol
  it is held to at loose tolerances: the estimate measures the wrong method.
* A proper pair (ETDIterated(2) − ETD2, O(h²), slope 2.0): 6.9e3, 4.4e4, 3.2e5 steps at tol
  1e−4, 1e−6, 1e−8 for err_rec 2.7e−4, 2.1e−5, 8.7e−7 (150 ms). It sees the h-dependent error
  but not the frozen-target floor: the exact η trails its moving target by (w/D)·dηss/dτ
  (≈ 2.6e−7 in u per step at τ = 10, flat in h, :mod:`integrators.etd`), and at h ≤ 4e−3 the
  estimate is already 5× below it (a test). No difference of two frozen-target steps with
  h ≫ w/D contains that lag.
* Step doubling (ETDIterated(2), h vs 2 × h/2, exponent 1/3): 7.9e3 and 1.7e4 steps for err_rec
  2e−5 and 1.2e−5 at tol 1e−5, 1e−6 (9, 23 ms); at tol 1e−7 and 1e−8 it collapses to 2.6e5 and
  1.05e8 steps (94 s, err_rec 2.6e−7): the lag does depend on h once h nears w/D (~3e−6), so
  step doubling sees the floor only where removing it means resolving the stiff mode.
* For comparison, the fixed rule Eq. 53: ETDIterated(2) 1.2e5 steps, err_rec 3.3e−6 (46 ms);
  at 1/16 of the paper's steps, 1.9e6 steps and 4e−7 (the floor). Exprb43: 1.2e3 steps for
  9e−7 (tol 1e−4), 3.6e3 steps for 1.2e−7 (tol 1e−6), 1.2e4 steps for 1.3e−9 (tol 1e−8).

So an ETD with frozen coefficients cannot compete: its cheap estimates measure either ETD1's lag
(steps ∝ 1/tol) or only the h-dependent part (accuracy capped by the floor at ~1e−6..3e−7 in
err_rec, which is ∝ the mass), and the estimate that sees the floor forces h ~ w/D. The fix of
the frozen target is the φ-function treatment of the linearised coupling — exponential
Rosenbrock–Euler (the embedded method of exprb32) is ETD1 with the exact J instead of the
diagonal frozen rates — i.e. the methods of this module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from integrators.cash_karp import (_CURSOR, _F, _FO, _H, _NFEV, _REJECTED, _STEPS, _T_RET, _TAU,
                                   _TAU_OLD, _Z, _ZO, _ZR, _roots, _scan, crossed)
from integrators.events import carry_signs
from integrators.kernel_stepper import CompiledAlgorithm, KernelStepper
from integrators.registry import register
from problems.formulations import ode_jacobian, ode_rhs

__all__ = ["Exprb32", "Exprb43", "phi_functions", "phi_dense"]

REACHED, ROOT, CHUNK, NONFINITE, UNDERFLOW = range(5)
_NJEV = 8                     # st[0:8] is Cash–Karp's layout; one more counter
_HACC, _RACC, _NACC = 9, 10, 11       # the controller's memory (see _step)
_METHOD = 10                  # p[10]: 0 exprb32, 1 exprb43
_TAYLOR_TERMS = 12
_THETA = 0.5                  # ‖A/2^s‖₁ ≤ _THETA before the Taylor series
_INV_FACT = np.array([1.0 / math.factorial(k) for k in range(_TAYLOR_TERMS + 5)])
_HALF_POW = np.array([0.5 ** k for k in range(5)])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _mm3(a, b):
    """3×3 product on 9-tuples (row-major), kept in registers."""
    return (a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
            a[0] * b[2] + a[1] * b[5] + a[2] * b[8], a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
            a[3] * b[1] + a[4] * b[4] + a[5] * b[7], a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
            a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
            a[6] * b[2] + a[7] * b[5] + a[8] * b[8])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _get3(out, k):
    o = out[k]
    return (o[0, 0], o[0, 1], o[0, 2], o[1, 0], o[1, 1], o[1, 2], o[2, 0], o[2, 1], o[2, 2])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _put3(o, v, c, diag):
    """o ← c·v (+ diag on the diagonal)."""
    o[0, 0], o[0, 1], o[0, 2] = c * v[0] + diag, c * v[1], c * v[2]
    o[1, 0], o[1, 1], o[1, 2] = c * v[3], c * v[4] + diag, c * v[5]
    o[2, 0], o[2, 1], o[2, 2] = c * v[6], c * v[7], c * v[8] + diag


@njit(cache=True, nogil=True, error_model="numpy")
def phi_dense(a, kmax, out, half):
    """φ_0..φ_kmax of the 3×3 matrix ``a`` into ``out[0..kmax]`` by scaling and squaring;
    φ_1(a/2) into ``half`` (one doubling at least is taken). Unrolled on 9-tuples: generic
    loops over a 3×3 cost ~5× more."""
    n1 = n_inf = 0.0
    for i in range(3):
        n1 = max(n1, abs(a[0, i]) + abs(a[1, i]) + abs(a[2, i]))
        n_inf = max(n_inf, abs(a[i, 0]) + abs(a[i, 1]) + abs(a[i, 2]))
    norm = min(n1, n_inf)      # either bounds the Taylor remainder
    s = 1
    if _THETA < norm < 1e300:     # an infinite norm (an overflowed trial) must not mean 2^63
        s = max(1, int(math.ceil(math.log2(norm / _THETA))))
    sc = 0.5 ** s
    x = (a[0, 0] * sc, a[0, 1] * sc, a[0, 2] * sc, a[1, 0] * sc, a[1, 1] * sc, a[1, 2] * sc,
         a[2, 0] * sc, a[2, 1] * sc, a[2, 2] * sc)
    c = _INV_FACT[_TAYLOR_TERMS + kmax]
    p = (c, 0.0, 0.0, 0.0, c, 0.0, 0.0, 0.0, c)
    for m in range(_TAYLOR_TERMS - 1, -kmax - 1, -1):
        c = _INV_FACT[m + kmax] if m >= 0 else _INV_FACT[kmax + m]
        t = _mm3(x, p)
        p = (t[0] + c, t[1], t[2], t[3], t[4] + c, t[5], t[6], t[7], t[8] + c)
        if m <= 0:
            _put3(out[kmax + m], p, 1.0, 0.0)
    for level in range(s):
        if level == s - 1:
            _put3(half, _get3(out, 1), 1.0, 0.0)
        e = _get3(out, 0)
        for k in range(kmax, -1, -1):
            t = _mm3(e, _get3(out, k))
            for l in range(1, k + 1):
                c = _INV_FACT[k - l]
                o = out[l]
                t = (t[0] + c * o[0, 0], t[1] + c * o[0, 1], t[2] + c * o[0, 2],
                     t[3] + c * o[1, 0], t[4] + c * o[1, 1], t[5] + c * o[1, 2],
                     t[6] + c * o[2, 0], t[7] + c * o[2, 1], t[8] + c * o[2, 2])
            _put3(out[k], t, _HALF_POW[k], 0.0)


@njit(cache=True, nogil=True, error_model="numpy")
def _phi_2x2(s00, s01, s10, s11, kmax, out, half):
    """:func:`phi_dense` for the 2×2 matrix [[s00, s01], [s10, s11]], unrolled."""
    norm = min(max(abs(s00) + abs(s10), abs(s01) + abs(s11)),
               max(abs(s00) + abs(s01), abs(s10) + abs(s11)))
    s = 1
    if _THETA < norm < 1e300:     # an infinite norm (an overflowed trial) must not mean 2^63
        s = max(1, int(math.ceil(math.log2(norm / _THETA))))
    sc = 0.5 ** s
    x00, x01, x10, x11 = s00 * sc, s01 * sc, s10 * sc, s11 * sc
    c = _INV_FACT[_TAYLOR_TERMS + kmax]
    p00, p01, p10, p11 = c, 0.0, 0.0, c
    for m in range(_TAYLOR_TERMS - 1, -kmax - 1, -1):
        c = _INV_FACT[m + kmax] if m >= 0 else _INV_FACT[kmax + m]
        p00, p01, p10, p11 = (x00 * p00 + x01 * p10 + c, x00 * p01 + x01 * p11,
                              x10 * p00 + x11 * p10, x10 * p01 + x11 * p11 + c)
        if m <= 0:
            k = kmax + m
            out[k, 0, 0], out[k, 0, 1], out[k, 1, 0], out[k, 1, 1] = p00, p01, p10, p11
    for level in range(s):
        if level == s - 1:
            half[0, 0], half[0, 1], half[1, 0], half[1, 1] = (out[1, 0, 0], out[1, 0, 1],
                                                              out[1, 1, 0], out[1, 1, 1])
        e00, e01, e10, e11 = out[0, 0, 0], out[0, 0, 1], out[0, 1, 0], out[0, 1, 1]
        for k in range(kmax, -1, -1):
            f00, f01, f10, f11 = out[k, 0, 0], out[k, 0, 1], out[k, 1, 0], out[k, 1, 1]
            t00, t01 = e00 * f00 + e01 * f10, e00 * f01 + e01 * f11
            t10, t11 = e10 * f00 + e11 * f10, e10 * f01 + e11 * f11
            for l in range(1, k + 1):
                c = _INV_FACT[k - l]
                t00 += out[l, 0, 0] * c
                t01 += out[l, 0, 1] * c
                t10 += out[l, 1, 0] * c
                t11 += out[l, 1, 1] * c
            c = _HALF_POW[k]
            out[k, 0, 0], out[k, 0, 1], out[k, 1, 0], out[k, 1, 1] = (t00 * c, t01 * c,
                                                                      t10 * c, t11 * c)


@njit(cache=True, nogil=True, error_model="numpy")
def _phi_scalar(z, kmax, out):
    """φ_0..φ_kmax(z) for z ≤ −1, where the recursion φ_k = (φ_{k−1} − 1/(k−1)!)/z is stable."""
    out[0] = math.exp(z)
    for k in range(1, kmax + 1):
        out[k] = (out[k - 1] - _INV_FACT[k - 1]) / z


@njit(cache=True, nogil=True, error_model="numpy")
def _stiff_eigenvalue(a):
    """The eigenvalue of hJ's u mode: Newton from a11 on λ = a11 + a10 a01/λ + a12 a21/(λ − a22)
    (the characteristic equation, given J's zero pattern); NaN if 8 iterations do not converge
    (2–3 do when the mode is stiff)."""
    p, q, a22 = a[1, 0] * a[0, 1], a[1, 2] * a[2, 1], a[2, 2]
    lam = a[1, 1]
    for _ in range(8):
        g = lam - a[1, 1] - p / lam - q / (lam - a22)
        dg = 1.0 + p / (lam * lam) + q / ((lam - a22) * (lam - a22))
        step = g / dg
        lam -= step
        if abs(step) <= 1e-15 * abs(lam):
            return lam
    return np.nan


@njit(cache=True, nogil=True, error_model="numpy")
def phi_functions(a, kmax, out, half):
    """φ_0..φ_kmax of the 3×3 ``a`` = hJ into ``out[0..kmax]``, φ_1(a/2) into ``half``.

    Stiff case (J's zero pattern, a real eigenvalue λ ≤ −64 of the u mode at least 16× the
    norm of the rest): block triangularisation V⁻¹ a V = [[λ, bᵀ], [0, S]] with the eigenvector
    v = (a01/λ, 1, a21/(λ − a22)) as first column of V and the unit vectors e_h, e_s beside it;
    φ_k(λ) in closed form, φ_k(S) of the 2×2 slow block by scaling and squaring (few doublings:
    S carries only the slow rates), the coupling by Parlett's recurrence
    F12 = (φ_k(λ) bᵀ − bᵀ φ_k(S))(λI − S)⁻¹ (well conditioned: |λ| ≫ ‖S‖). Otherwise, and for
    any other 3×3 matrix, :func:`phi_dense` (its doublings would number log2(|λ|/½), ~25 for the
    stick phase's hD/w ~ 1e7)."""
    lam = np.nan
    if a[0, 0] == 0.0 and a[0, 2] == 0.0 and a[2, 0] == 0.0 and a[1, 1] <= -64.0:
        lam = _stiff_eigenvalue(a)
    if not lam <= -64.0:
        phi_dense(a, kmax, out, half)
        return
    vh, vs = a[0, 1] / lam, a[2, 1] / (lam - a[2, 2])
    b0, b1 = a[1, 0], a[1, 2]
    s00, s01, s10, s11 = -vh * b0, -vh * b1, -vs * b0, a[2, 2] - vs * b1
    if 16.0 * max(abs(s00) + abs(s10), abs(s01) + abs(s11)) > -lam:
        phi_dense(a, kmax, out, half)
        return
    FS, HS, fl, hl = np.empty((kmax + 1, 2, 2)), np.empty((2, 2)), np.empty(kmax + 1), np.empty(2)
    _phi_2x2(s00, s01, s10, s11, kmax, FS, HS)
    _phi_scalar(lam, kmax, fl)
    _phi_scalar(0.5 * lam, 1, hl)
    for k in range(kmax + 2):           # k = kmax + 1: φ_1 of the half matrix, into ``half``
        x, F22, f11 = (lam, FS[k], fl[k]) if k <= kmax else (0.5 * lam, HS, hl[1])
        sc = 1.0 if k <= kmax else 0.5
        # F12 = (f11 bᵀ − bᵀ F22)(x I − sc S)⁻¹, a 1×2 row
        r0 = sc * (f11 * b0 - (b0 * F22[0, 0] + b1 * F22[1, 0]))
        r1 = sc * (f11 * b1 - (b0 * F22[0, 1] + b1 * F22[1, 1]))
        m00, m01, m10, m11 = x - sc * s00, -sc * s01, -sc * s10, x - sc * s11
        det = m00 * m11 - m01 * m10
        g0, g1 = (r0 * m11 - r1 * m10) / det, (r1 * m00 - r0 * m01) / det
        # back to z coordinates: φ(a) = V F V⁻¹, V⁻¹z = (z_u, z_h − vh z_u, z_s − vs z_u)
        o = out[k] if k <= kmax else half
        o[1, 0], o[1, 2] = g0, g1
        o[1, 1] = f11 - g0 * vh - g1 * vs
        o[0, 0], o[0, 2] = vh * g0 + F22[0, 0], vh * g1 + F22[0, 1]
        o[2, 0], o[2, 2] = vs * g0 + F22[1, 0], vs * g1 + F22[1, 1]
        o[0, 1] = vh * f11 - (vh * g0 + F22[0, 0]) * vh - (vh * g1 + F22[0, 1]) * vs
        o[2, 1] = vs * f11 - (vs * g0 + F22[1, 0]) * vh - (vs * g1 + F22[1, 1]) * vs


@njit(cache=True, nogil=True, error_model="numpy")
def _matvec(a, v, out):
    for i in range(3):
        out[i] = a[i, 0] * v[0] + a[i, 1] * v[1] + a[i, 2] * v[2]


@njit(cache=True, nogil=True, error_model="numpy")
def _remainder_diff(J, z, f, dz, fu, out):
    """D = g(z + dz) − g(z) = f(z + dz) − f(z) − J dz; f(z + dz) is given as ``fu``."""
    _matvec(J, dz, out)
    for i in range(3):
        out[i] = fu[i] - f[i] - out[i]


@njit(cache=True, nogil=True, error_model="numpy")
def _attempt(q, method, J, z, f, hs, P, half, w, out):
    """One trial of size hs from (z, f): the solution into ``out``, the error estimate into
    w[0]. Needs P (5×3×3) and half (3×3) as scratch."""
    law, beta, c, d, e = q
    kmax = 3 if method == 0 else 4
    for i in range(3):
        for j in range(3):
            half[i, j] = J[i, j] * hs       # hJ, overwritten with φ1(hJ/2) below
    phi_functions(half, kmax, P, half)
    v1, u, fu, d2, d3, t = w[1], w[2], w[3], w[4], w[5], w[6]
    _matvec(P[1], f, v1)                    # φ1(hJ) f
    if method == 0:
        for i in range(3):
            u[i] = z[i] + hs * v1[i]
        ode_rhs(law, beta, c, d, e, u, fu)
        for i in range(3):
            t[i] = hs * v1[i]
        _remainder_diff(J, z, f, t, fu, d2)
        _matvec(P[3], d2, t)
        for i in range(3):
            w[0, i] = 2.0 * hs * t[i]
            out[i] = u[i] + w[0, i]
        return
    _matvec(half, f, t)
    for i in range(3):
        t[i] *= 0.5 * hs
        u[i] = z[i] + t[i]
    ode_rhs(law, beta, c, d, e, u, fu)
    _remainder_diff(J, z, f, t, fu, d2)
    for i in range(3):
        t[i] = f[i] + d2[i]
    _matvec(P[1], t, u)
    for i in range(3):
        t[i] = hs * u[i]
        u[i] = z[i] + t[i]
    ode_rhs(law, beta, c, d, e, u, fu)
    _remainder_diff(J, z, f, t, fu, d3)
    for i in range(3):
        u[i] = 16.0 * d2[i] - 2.0 * d3[i]
        fu[i] = -48.0 * d2[i] + 12.0 * d3[i]
    _matvec(P[3], u, t)
    _matvec(P[4], fu, w[0])
    for i in range(3):
        w[0, i] *= hs
        out[i] = z[i] + hs * (v1[i] + t[i]) + w[0, i]


@njit(cache=True, nogil=True, error_model="numpy")
def _step(p, st, Z, tau, h, t_out, w, P, half, J, zn):
    """One accepted step of proposed size h from (tau, Z[_Z], Z[_F]), shortened to land on t_out;
    its start goes to Z[_ZO], Z[_FO]. Returns (-1 or UNDERFLOW; the new τ; the next h; attempts;
    f evaluations of trials rejected for a non-finite end)."""
    q = (int(p[0]), p[1], p[2], p[3], p[4])
    rtol, atol, method = p[5], p[6], int(p[_METHOD])
    expo = -1.0 / 3.0 if method == 0 else -0.25      # −1/(q+1), q the embedded order
    z, f = Z[_Z], Z[_F]
    ode_jacobian(q[0], q[1], q[2], q[3], q[4], z, J)
    hs, last = (t_out - tau, True) if tau + h >= t_out else (h, False)
    attempts, rejected, extra = 0, False, 0
    while True:
        if tau + hs == tau:
            return UNDERFLOW, tau, hs, attempts, extra
        attempts += 1
        _attempt(q, method, J, z, f, hs, P, half, w, zn)
        errmax = 0.0
        for i in range(3):
            errmax = max(errmax, abs(w[0, i]) / (atol + rtol * max(abs(z[i]), abs(zn[i]))))
        if errmax <= 1.0:                               # False for NaN
            ode_rhs(q[0], q[1], q[2], q[3], q[4], zn, w[6])
            if np.isfinite(zn).all() and np.isfinite(w[6]).all():
                break
            # an end state whose rates overflow (e^u after a loose tolerance's overshoot) is a
            # failed trial, not a result; its f is outside the per-attempt count
            errmax, extra = np.inf, extra + 1
        last, rejected = False, True
        hs = max(0.9 * hs * errmax ** expo, 0.1 * hs) if np.isfinite(errmax) else 0.1 * hs
    Z[_ZO], Z[_FO] = Z[_Z], Z[_F]
    Z[_Z], Z[_F] = zn, w[6]
    # elementary: 0.9 r with r = errmax^expo; Gustafsson's predictive (rodas.f): (h/h_acc) 0.9
    # (err_acc/errmax²)^(−expo) = (h/h_acc) 0.9 r²/r_acc, r_acc = max(1e−2, err_acc)^expo kept in
    # st (one power per step, as the elementary controller alone)
    r = errmax ** expo if errmax > 0.0 else np.inf
    grow = min(5.0, 0.9 * r)
    if st[_NACC] >= 1.0 and errmax > 0.0:
        grow = min(grow, max(0.2, min(5.0, hs / st[_HACC] * 0.9 * r * r / st[_RACC])))
    st[_HACC], st[_RACC] = hs, r if errmax >= 1e-2 else 0.01 ** expo
    st[_NACC] += 1.0
    h_next = hs * grow
    if rejected:
        h_next = min(h_next, hs)
    h_next = max(h_next, h) if last else h_next     # a shortened step says nothing about h
    return -1, t_out if last else tau + hs, h_next, attempts, extra


@njit(cache=True, nogil=True, error_model="numpy")
def _advance(st, p, Z, G, dirs, t_out, n_max):
    """Cash–Karp's ``_advance`` with the exponential Rosenbrock step and its counters."""
    w, P, half, J, zn = np.empty((7, 3)), np.empty((5, 3, 3)), np.empty((3, 3)), np.empty((3, 3)), \
        np.empty(3)
    g = np.empty(4)
    stages = 1 if int(p[_METHOD]) == 0 else 2
    status = -1 if np.isfinite(Z[_F]).all() else NONFINITE
    n = attempts = calls = extra = 0
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
            status, tau, h, tried, more = _step(p, st, Z, st[_TAU], st[_H], t_out, w, P, half,
                                                J, zn)
            attempts += tried
            extra += more
            calls += 1
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
    st[_NFEV] += stages * attempts + n + extra
    st[_NJEV] += calls
    return status


@njit(cache=True, nogil=True, error_model="numpy")
def fixed_steps(p, z0, tau_span, n):
    """``n`` equal steps over ``tau_span`` from z0, no error control (order tests); returns z."""
    Z = np.zeros((5, 3))
    Z[_Z] = z0
    ode_rhs(int(p[0]), p[1], p[2], p[3], p[4], Z[_Z], Z[_F])
    w, P, half, J, zn = np.empty((7, 3)), np.empty((5, 3, 3)), np.empty((3, 3)), np.empty((3, 3)), \
        np.empty(3)
    q = (int(p[0]), p[1], p[2], p[3], p[4])
    hs = tau_span / n
    for _ in range(n):
        ode_jacobian(q[0], q[1], q[2], q[3], q[4], Z[_Z], J)
        _attempt(q, int(p[_METHOD]), J, Z[_Z], Z[_F], hs, P, half, w, zn)
        Z[_Z] = zn
        ode_rhs(q[0], q[1], q[2], q[3], q[4], Z[_Z], Z[_F])
    return Z[_Z].copy()


class _ExprbStepper(KernelStepper):
    """The segment protocol over :func:`_advance` (:class:`integrators.kernel_stepper.KernelStepper`):
    Cash–Karp's layouts with the method code appended to ``p`` and the Jacobian counter in
    ``st``."""

    n_st = 12

    def __init__(self, algorithm, nd, budget):
        super().__init__(algorithm, nd, budget, extra_p=(float(algorithm.method_code),))

    def reset(self):
        self._st[_NACC] = 0.0

    def kernel(self, t_out, n_max):
        return _advance(self._st, self._p, self._Z, self._G, self._dirs, t_out, n_max)


class _Exprb(CompiledAlgorithm):
    family: ClassVar[str] = "exponential Rosenbrock (exact Jacobian)"
    stiff: ClassVar[bool] = True
    rhs_tiers_reason: ClassVar[str] = (
        "its step loop, φ-functions and Jacobian are compiled with numba")
    method_code: ClassVar[int] = 0
    embedded_order: ClassVar[int] = 2

    def make_stepper(self, nd, budget):
        return _ExprbStepper(self, nd, budget)

    def fixed_steps(self, nd, z0, span: float, n: int) -> np.ndarray:
        """``n`` equal steps over ``span`` (τ) from z0 under the slow loading, no error control
        (order studies: :func:`benchmarks.convergence.fixed_step_orders`): z at the end."""
        p = self.make_stepper(nd, None)._p.copy()
        p[4] = nd.e_slow
        return fixed_steps(p, np.asarray(z0, dtype=float), span, n)


@register
@dataclass(frozen=True)
class Exprb32(_Exprb):
    """Exponential Rosenbrock exprb32 (Hochbruck, Ostermann & Schweitzer 2009): order 3, embedded
    exponential Rosenbrock–Euler (order 2) for the error estimate, exact 3×3 Jacobian and its
    φ-functions, adaptive (module docstring: control, cost, events). ``rhs="numba"`` only."""

    name: ClassVar[str] = "Exprb32"
    order: ClassVar[int] = 3
    method_code: ClassVar[int] = 0
    embedded_order: ClassVar[int] = 2


@register
@dataclass(frozen=True)
class Exprb43(_Exprb):
    """Exponential Rosenbrock exprb43 (Hochbruck, Ostermann & Schweitzer 2009): order 4, embedded
    order 3, exact 3×3 Jacobian and its φ-functions, adaptive (module docstring).
    ``rhs="numba"`` only."""

    name: ClassVar[str] = "Exprb43"
    order: ClassVar[int] = 4
    method_code: ClassVar[int] = 1
    embedded_order: ClassVar[int] = 3
