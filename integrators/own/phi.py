"""φ-functions of hJ for the exponential Rosenbrock methods, and their 3×3 helpers.

:func:`phi_functions`: φ_0..φ_kmax of A = hJ. In the stick phase hJ has one eigenvalue, of the
u mode, down to −1e8, and two slow ones. Plain scaling and squaring (:func:`phi_dense`;
Skaflestad & Wright 2009, Appl. Numer. Math. 59, 783, as EXPINT: a 12-term Taylor series of φ_p
at ‖A/2^s‖ ≤ ½, φ_k = X φ_{k+1} + I/k! downwards, then s doublings φ_k(2X) = 2^−k [φ_0(X) φ_k(X)
+ Σ_{j=1..k} φ_j(X)/(k−j)!]) would need s ≈ log2(|λ|/½) ≈ 25 doublings of p+1 matrices. So the
stiff mode is split off first: with J's zero pattern (∂h'/∂h = ∂h'/∂s = ∂s'/∂h = 0) its
eigenvalue λ solves λ = a11 + a10 a01/λ + a12 a21/(λ − a22) (Newton from a11, 2–3 iterations),
its eigenvector is (a01/λ, 1, a21/(λ − a22)), and with it and e_h, e_s as basis A is block
triangular [[λ, bᵀ], [0, S]] with S the 2×2 slow block. φ_k(λ) in closed form (stable recursion
for λ ≤ −1), φ_k(S) by scaling and squaring (few doublings), the coupling by Parlett's
recurrence F12 = (φ_k(λ) bᵀ − bᵀ φ_k(S))(λI − S)⁻¹, well conditioned as the split is taken only
when λ ≤ −64 and |λ| ≥ 16‖S‖; otherwise :func:`phi_dense`. Both agree with scipy's ``expm`` of
the augmented matrix (Al-Mohy & Higham 2011) to ≤ 5e−10 (split) and 4e−9 (dense) relative along
a cycle, h = 1e−4..10 (a test).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["phi_functions", "phi_dense", "stiff_eigenvalue", "matvec", "remainder_diff"]

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
def _phi_scalar(z):
    """φ_0..φ_4(z) for z ≤ −1, where the recursion φ_k = (φ_{k−1} − 1/(k−1)!)/z is stable."""
    f0 = math.exp(z)
    f1 = (f0 - _INV_FACT[0]) / z
    f2 = (f1 - _INV_FACT[1]) / z
    f3 = (f2 - _INV_FACT[2]) / z
    return f0, f1, f2, f3, (f3 - _INV_FACT[3]) / z


@njit(cache=True, nogil=True, error_model="numpy")
def stiff_eigenvalue(a):
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
        lam = stiff_eigenvalue(a)
    if not lam <= -64.0:
        phi_dense(a, kmax, out, half)
        return
    vh, vs = a[0, 1] / lam, a[2, 1] / (lam - a[2, 2])
    b0, b1 = a[1, 0], a[1, 2]
    s00, s01, s10, s11 = -vh * b0, -vh * b1, -vs * b0, a[2, 2] - vs * b1
    if 16.0 * max(abs(s00) + abs(s10), abs(s01) + abs(s11)) > -lam:
        phi_dense(a, kmax, out, half)
        return
    # φ_k(S) goes to the top left 2 × 2 of out[k] (φ_1(S/2) to that of ``half``), read back
    # before out[k] is written: no scratch arrays (the compiled solve allocates nothing)
    _phi_2x2(s00, s01, s10, s11, kmax, out[:, :2, :2], half[:2, :2])
    fl = _phi_scalar(lam)
    hl1 = (math.exp(0.5 * lam) - _INV_FACT[0]) / (0.5 * lam)      # φ_1(λ/2)
    for k in range(kmax + 2):           # k = kmax + 1: φ_1 of the half matrix, into ``half``
        o = out[k] if k <= kmax else half
        x, f11 = (lam, fl[k]) if k <= kmax else (0.5 * lam, hl1)
        F22 = (o[0, 0], o[0, 1], o[1, 0], o[1, 1])
        sc = 1.0 if k <= kmax else 0.5
        # F12 = (f11 bᵀ − bᵀ F22)(x I − sc S)⁻¹, a 1×2 row
        r0 = sc * (f11 * b0 - (b0 * F22[0] + b1 * F22[2]))
        r1 = sc * (f11 * b1 - (b0 * F22[1] + b1 * F22[3]))
        m00, m01, m10, m11 = x - sc * s00, -sc * s01, -sc * s10, x - sc * s11
        det = m00 * m11 - m01 * m10
        g0, g1 = (r0 * m11 - r1 * m10) / det, (r1 * m00 - r0 * m01) / det
        # back to z coordinates: φ(a) = V F V⁻¹, V⁻¹z = (z_u, z_h − vh z_u, z_s − vs z_u)
        o[1, 0], o[1, 2] = g0, g1
        o[1, 1] = f11 - g0 * vh - g1 * vs
        o[0, 0], o[0, 2] = vh * g0 + F22[0], vh * g1 + F22[1]
        o[2, 0], o[2, 2] = vs * g0 + F22[2], vs * g1 + F22[3]
        o[0, 1] = vh * f11 - (vh * g0 + F22[0]) * vh - (vh * g1 + F22[1]) * vs
        o[2, 1] = vs * f11 - (vs * g0 + F22[2]) * vh - (vs * g1 + F22[3]) * vs


@njit(cache=True, nogil=True, error_model="numpy")
def matvec(a, v, out):
    for i in range(3):
        out[i] = a[i, 0] * v[0] + a[i, 1] * v[1] + a[i, 2] * v[2]


@njit(cache=True, nogil=True, error_model="numpy")
def remainder_diff(J, z, f, dz, fu, out):
    """D = g(z + dz) − g(z) = f(z + dz) − f(z) − J dz; f(z + dz) is given as ``fu``."""
    matvec(J, dz, out)
    for i in range(3):
        out[i] = fu[i] - f[i] - out[i]
