"""RadauIIA5's forward sensitivities: the derivative of each accepted step's collocation
equations, its dense output and its error estimate (:mod:`integrators.own.radau5` follows the
engine with them; :mod:`integrators.own.sensitivity` does the rest, as for Rodas5P).

The stage increments Z_s solve Z = h (A ⊗ I) F(z0 + Z). Differentiated along θ with the step
held, dZ solves the 9×9 system

    (I − h A ⊗ J_s) dZ = h (A ⊗ I) (J_s S + ∂f/∂θ(z0 + Z_s)),   S ← S + dZ_3,

J_s the Jacobian at stage s: the collocation method applied to the sensitivity equation and
solved exactly (a direct, not a simplified Newton, solve: the sensitivities do not inherit the
iteration's tolerance). The slider's h rows are explicit (J's row for h is (0, −w, 0)) and
are eliminated: the LU (partial pivoting) of the 6×6 system left is made once per step and
serves every direction. The error estimate err = (μ/h − J0)⁻¹ (f(z0) + e·Z/h) moves by
(μ/h − J0)⁻¹ (dJ0 err + J0 S + ∂f/∂θ(z0) + e·dZ/h), dJ0 = ∂J/∂z·S + ∂J/∂θ at z0.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from integrators.own import engine
from integrators.own.linalg import lu_solve3
from integrators.own.radau5_tableau import A, C1, C2, E_ERR, MU

__all__ = ["workspace", "step_sensitivities", "dense_sensitivities", "error_sensitivities"]

#: the error estimate's row of the workspace's dZ (rows 0–2: the stages)
ERROR_ROW = 3
P_RTOL, P_ATOL = engine.P["RTOL"], engine.P["ATOL"]


@njit(cache=True, nogil=True, error_model="numpy")
def workspace(n_s):
    """Room for ``n_s`` directions: the stages' Jacobians (rows 0–2; row 3 at z0) and ∂f/∂θ,
    the second derivatives at z0, dZ (n_s, 8, 3: the stages', then the error estimate's), the
    6×6 matrix, its pivots and a right-hand side; dJ0 (or the stages' J S + ∂f/∂θ) and f for
    the error estimate's; a copy of RadauIIA5's last accepted step (its ``last``), restored
    when the sensitivities reject a trial the state passed."""
    return (np.empty((8, 3, 3)), np.zeros((8, 3, n_s)), np.zeros((3, 3, 3)),
            np.zeros((3, 3, n_s)), np.zeros((n_s, 8, 3)), np.empty((6, 6)),
            np.zeros(6, np.int64), np.zeros(9), np.zeros((3, 3)), np.zeros(3),
            np.zeros((5, 3)))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _lu6(a, piv):
    """In-place LU of the 6×6 ``a`` with partial pivoting; False if a pivot is zero."""
    regular = True
    for k in range(6):
        p = k
        for i in range(k + 1, 6):
            if abs(a[i, k]) > abs(a[p, k]):
                p = i
        piv[k] = p
        regular &= a[p, k] != 0.0
        if p != k:
            for j in range(6):
                a[k, j], a[p, j] = a[p, j], a[k, j]
        if a[k, k] != 0.0:
            for i in range(k + 1, 6):
                a[i, k] /= a[k, k]
                for j in range(k + 1, 6):
                    a[i, j] -= a[i, k] * a[k, j]
    return regular


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _solve6(a, piv, b):
    """Solve in place for ``b[0:6]`` with :func:`_lu6`'s factors."""
    for k in range(6):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
    for i in range(1, 6):
        acc = b[i]
        for j in range(i):
            acc -= a[i, j] * b[j]
        b[i] = acc
    for i in range(5, -1, -1):
        acc = b[i]
        for j in range(i + 1, 6):
            acc -= a[i, j] * b[j]
        b[i] = acc / a[i, i]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def step_sensitivities(partials, p, dirs, hs, Z, u, sw, z0, S):
    """S (row n: ∂z/∂θ_n) from the accepted step ``hs`` at ``z0`` (stage increments ``Z``)
    to its end, in place, and each direction's dZ in sw[4][n, 0:3] (module docstring);
    ``partials`` as :func:`integrators.own.rodas5p_stages.stage_sensitivities` takes it.
    False if the system is singular.

    The slider's J has the row (0, a, 0) for h (a = −w), so the 9×9 system's h rows are
    dZ_s,h = r_s,h + h Σ_l A_sl a_l dZ_l,u: substituted into the others, they leave a 6×6
    system in the stages' (u, s) parts (a third of the 9×9's LU). ``partials`` must give
    that row (the slider's :func:`integrators.own.sensitivity._partials` does)."""
    jst, fst, dk, B, piv, r, g = sw[0], sw[1], sw[4], sw[5], sw[6], sw[7], sw[8]
    for s in range(3):
        for i in range(3):
            u[i] = z0[i] + Z[s, i]
        partials(p, dirs, u, jst, fst, s)
    for s in range(3):                  # B = I − h A⊗J' − h² (A⊗J'_h)(A⊗a) on (u, s)
        for i in range(2):
            for m in range(3):
                through_h = 0.0
                for l in range(3):
                    through_h += A[s, l] * jst[l, i + 1, 0] * A[l, m]
                B[2 * s + i, 2 * m] = (-hs * A[s, m] * jst[m, i + 1, 1]
                                       - hs * hs * through_h * jst[m, 0, 1])
                B[2 * s + i, 2 * m + 1] = -hs * A[s, m] * jst[m, i + 1, 2]
            B[2 * s + i, 2 * s + i] += 1.0
    regular = _lu6(B, piv)
    for n in range(S.shape[0]):
        for l in range(3):              # g_l = J_l S + ∂f/∂θ at stage l
            for i in range(3):
                g[l, i] = (fst[l, i, n] + jst[l, i, 0] * S[n, 0] + jst[l, i, 1] * S[n, 1]
                           + jst[l, i, 2] * S[n, 2])
        for s in range(3):              # r_s,h = h Σ_l A_sl g_l,h, into r[6 + s]
            r[6 + s] = hs * (A[s, 0] * g[0, 0] + A[s, 1] * g[1, 0] + A[s, 2] * g[2, 0])
        for s in range(3):              # the (u, s) rows, the h rows substituted
            for i in range(2):
                acc = 0.0
                for l in range(3):
                    acc += A[s, l] * (g[l, i + 1] + jst[l, i + 1, 0] * r[6 + l])
                r[2 * s + i] = hs * acc
        _solve6(B, piv, r)
        for s in range(3):
            dk[n, s, 1], dk[n, s, 2] = r[2 * s], r[2 * s + 1]
            dk[n, s, 0] = r[6 + s] + hs * (A[s, 0] * jst[0, 0, 1] * r[0]
                                           + A[s, 1] * jst[1, 0, 1] * r[2]
                                           + A[s, 2] * jst[2, 0, 1] * r[4])
        for i in range(3):
            S[n, i] += dk[n, 2, i]
    return regular


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def error_sensitivities(partials, second, p, dirs, hs, M, piv, f0, Z, x, u, sw, z0, S):
    """Each direction's derivative of the error estimate the step's test took into
    sw[4][n, ERROR_ROW], S the sensitivities at the step's start (module docstring; where the
    first estimate fails the state's test, the second, (μ/h − J0)⁻¹ (f(z0 + err) + e·Z/h), as
    :mod:`integrators.own.radau5` takes it). M, piv: the factors of I − (h/μ) J0 the attempt
    made; ``x`` a (1, 3) and ``u`` a 3-vector scratch."""
    jst, fst, hyy, hyt, dk, err = sw[0], sw[1], sw[2], sw[3], sw[4], sw[7]
    fr = hs / MU
    rtol, atol = p[P_RTOL], p[P_ATOL]
    partials(p, dirs, z0, jst, fst, 3)
    second(p, dirs, z0, hyy, hyt)
    for i in range(3):
        x[0, i] = fr * (f0[i] + _ez(Z, i) / hs)
    lu_solve3(M, piv, x, 0)
    worst = 0.0
    for i in range(3):
        err[i] = x[0, i]
        worst = max(worst, abs(err[i]) / (atol + rtol * max(abs(z0[i]), abs(z0[i] + Z[2, i]))))
    second_estimate = worst > 1.0       # it decided the state's test
    if second_estimate:
        for i in range(3):
            u[i] = z0[i] + err[i]
        partials(p, dirs, u, jst, fst, 4)
        fe = sw[9]
        engine.f_of(p, u, fe)
        for i in range(3):
            x[0, i] = fr * (fe[i] + _ez(Z, i) / hs)
        lu_solve3(M, piv, x, 0)
        for i in range(3):
            err[3 + i] = x[0, i]
    dj = sw[8]
    for n in range(S.shape[0]):
        for i in range(3):
            for j in range(3):
                acc = hyt[i, j, n]
                for k in range(3):
                    acc += hyy[i, j, k] * S[n, k]
                dj[i, j] = acc
        for i in range(3):
            u[i] = S[n, i]
        _error_rhs(fr, fst, jst, 3, dj, err, 0, dk, n, u, hs, x)
        lu_solve3(M, piv, x, 0)
        for i in range(3):
            dk[n, ERROR_ROW, i] = x[0, i]
        if second_estimate:
            for i in range(3):
                u[i] = S[n, i] + x[0, i]
            _error_rhs(fr, fst, jst, 4, dj, err, 3, dk, n, u, hs, x)
            lu_solve3(M, piv, x, 0)
            for i in range(3):
                dk[n, ERROR_ROW, i] = x[0, i]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _error_rhs(fr, fst, jst, at, dj, err, k, dk, n, s, hs, x):
    """x[0] = (h/μ)(J s + ∂f/∂θ + dJ0 err + e·dZ/h) for direction n: J and ∂f/∂θ in slot
    ``at`` (the estimate's point), err the estimate at err[k:k + 3]."""
    for i in range(3):
        acc = fst[at, i, n] + (E_ERR[0] * dk[n, 0, i] + E_ERR[1] * dk[n, 1, i]
                               + E_ERR[2] * dk[n, 2, i]) / hs
        for j in range(3):
            acc += jst[at, i, j] * s[j] + dj[i, j] * err[k + j]
        x[0, i] = fr * acc


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _ez(Z, i):
    """(e·Z)_i over the stage rows 0–2 of ``Z``."""
    return E_ERR[0] * Z[0, i] + E_ERR[1] * Z[1, i] + E_ERR[2] * Z[2, i]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_sensitivities(sw, dD):
    """The dense output's dD (dD[r, n]: D[r]'s derivative along direction n) of the step
    :func:`step_sensitivities` last differentiated: the collocation polynomial's, as
    :mod:`integrators.own.radau5` forms D from Z."""
    dk = sw[4]
    for n in range(dD.shape[1]):
        for i in range(3):
            w1 = (dk[n, 0, i] - C1 * dk[n, 2, i]) / (C1 * (1.0 - C1))
            w2 = (dk[n, 1, i] - C2 * dk[n, 2, i]) / (C2 * (1.0 - C2))
            dD[1, n, i] = (w1 - w2) / (C1 - C2)
            dD[0, n, i] = w1 - C1 * dD[1, n, i]
            dD[2, n, i] = 0.0
