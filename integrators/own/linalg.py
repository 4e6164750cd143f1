"""3×3 linear algebra for the linearly implicit methods, written to be inlined into a step.

One exit per function: numba cannot prune the reference counting of the arrays otherwise
(~5 ns per array).
"""

from __future__ import annotations

from numba import njit

__all__ = ["lu3", "lu_solve3", "factor", "hurwitz3"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def lu3(a, piv):
    """In-place LU of the 3×3 ``a`` with partial pivoting (rows swapped whole, as LAPACK
    getrf), the diagonal of U stored as its reciprocals (a solve multiplies: a division's
    latency, ~15 cycles, three times per solve in a dependent chain, was a tenth of a
    Rosenbrock attempt); False if a pivot is zero."""
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
        inv = 1.0 / a[k, k]
        a[k, k] = inv
        for i in range(k + 1, 3):
            a[i, k] *= inv
            for j in range(k + 1, 3):
                a[i, j] -= a[i, k] * a[k, j]
    return regular


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def lu_solve3(a, piv, b, r):
    """Solve in place for row r of ``b`` with the factors of :func:`lu3`."""
    for k in range(3):
        p = piv[k]
        if p != k:
            b[r, k], b[r, p] = b[r, p], b[r, k]
    b[r, 1] -= a[1, 0] * b[r, 0]
    b[r, 2] -= a[2, 0] * b[r, 0] + a[2, 1] * b[r, 1]
    b[r, 2] *= a[2, 2]
    b[r, 1] = (b[r, 1] - a[1, 2] * b[r, 2]) * a[1, 1]
    b[r, 0] = (b[r, 0] - a[0, 1] * b[r, 1] - a[0, 2] * b[r, 2]) * a[0, 0]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def factor(hg, J, M, piv):
    """M = I − hg·J, factored in place; False if singular."""
    for i in range(3):
        for j in range(3):
            M[i, j] = -hg * J[i, j]
        M[i, i] += 1.0
    return lu3(M, piv)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def hurwitz3(J):
    """True if every eigenvalue of the 3×3 ``J`` has a negative real part (Routh–Hurwitz on
    λ³ + a2 λ² + a1 λ + a0 = det(λI − J): a2 > 0, a0 > 0, a2 a1 > a0); False for NaN."""
    a2 = -(J[0, 0] + J[1, 1] + J[2, 2])
    a1 = ((J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]) + (J[0, 0] * J[2, 2] - J[0, 2] * J[2, 0])
          + (J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]))
    a0 = -(J[0, 0] * (J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1])
           - J[0, 1] * (J[1, 0] * J[2, 2] - J[1, 2] * J[2, 0])
           + J[0, 2] * (J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]))
    return a2 > 0.0 and a0 > 0.0 and a2 * a1 > a0
