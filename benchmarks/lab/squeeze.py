"""A least-squares problem of n residuals and p parameters, told to scipy's trust region in p + 1
numbers: what a long record's fit needs once the model gives its exact Jacobian.

scipy's ``least_squares`` (trf) reads the residuals r and the Jacobian J only through ‖r‖, Jᵀr
and JᵀJ (its step, its quadratic model, the scaling by J's column norms and its tests), yet does
an SVD and several products of n rows at every step. Told instead

    J̃ = [R; 0] with RᵀR = JᵀJ,      r̃ = (R⁻ᵀ Jᵀr, (‖r‖² − ‖R⁻ᵀ Jᵀr‖²)^½)

at each point (R from the eigenvectors of the column-scaled JᵀJ, which also stands a rank-
deficient J: Jᵀr then has no part in its null space), it takes the same steps on a 75,000-sample
record at a fraction of the cost. "The same" as far as the Gram matrix holds J: directions whose
singular values are under ~3e−8 of the largest (after scaling the columns) count as lost, where
trf on the n rows would still step along them (on a flat valley the two can end at different
points of equal squares). :func:`compress` builds (r̃, J̃) in two compiled passes over
the samples, without forming the projected J: the residuals are r = P(ỹ − W g) and J = −P W ∂g/∂x
with P the projection off an orthonormal linear basis Q (the level and trend).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["compress"]

#: eigenvalues of the column-scaled JᵀJ under this fraction of the largest count as zero
RANK_FLOOR = 1e-15


#: rows of A formed at a time in the first pass, whose products go to BLAS: a block of a few
#: tens of kB stays in the cache (0.97 against 1.32 ms a call on 75,220 samples and 4
#: parameters, timed by hand)
BLOCK = 1024


@njit(cache=True, error_model="numpy")
def _passes(wmu, w, g, d, scales, q, r):
    """r ← P(wmu − w g) in place; returns (AᵀA − (QᵀA)ᵀ(QᵀA), Aᵀr, r·r) for A = −w d scales,
    the full problem's Jacobian (J = P A). Aᵀr is summed in a second pass over the projected
    r, not as Aᵀu − (QᵀA)ᵀQᵀu: near the fit's optimum that difference cancels to nothing."""
    n, p = d.shape
    m = q.shape[1]
    qu, qa, gram = np.zeros(m), np.zeros((m, p)), np.zeros((p, p))
    a = np.empty((BLOCK, p))
    for start in range(0, n, BLOCK):
        end = min(start + BLOCK, n)
        for i in range(start, end):
            r[i] = wmu[i] - w[i] * g[i]
            for j in range(p):
                a[i - start, j] = -w[i] * d[i, j] * scales[j]
        block, qb = a[:end - start], q[start:end]
        gram += block.T @ block
        qa += qb.T @ block
        qu += qb.T @ r[start:end]
    ar = np.zeros(p)
    rr = 0.0
    for i in range(n):
        s = r[i]
        for k in range(m):
            s -= q[i, k] * qu[k]
        r[i] = s
        rr += s * s
        for j in range(p):
            ar[j] -= w[i] * d[i, j] * scales[j] * s
    gram -= qa.T @ qa
    return gram, ar, rr


def compress(wmu, w, g, d, scales, q):
    """(r̃, J̃, r) of the module docstring: ``wmu`` the weighted data ỹ (n), ``w`` the weights,
    ``g`` the model (n), ``d`` its derivatives (n × p) and ``scales`` their columns' factors
    (to the fitted coordinates), ``q`` the linear basis (n × m, orthonormal); r the projected
    residuals themselves (n). Every input finite."""
    r = np.empty(len(wmu))
    gram, ar, rr = _passes(np.ascontiguousarray(wmu), np.ascontiguousarray(w),
                       np.ascontiguousarray(g), np.ascontiguousarray(d),
                       np.ascontiguousarray(scales, dtype=float), np.ascontiguousarray(q), r)
    scale = np.sqrt(np.clip(np.diag(gram), 0.0, None))
    scale[~(scale > 0)] = 1.0
    lam, vec = np.linalg.eigh(gram / np.outer(scale, scale))
    keep = lam > max(lam.max(initial=0.0), 0.0) * RANK_FLOOR
    root = np.sqrt(np.where(keep, lam, 0.0))
    top = np.where(keep, vec.T @ (ar / scale) / np.where(keep, root, 1.0), 0.0)
    rest = math.sqrt(max(rr - float(top @ top), 0.0))
    jac = np.vstack([root[:, None] * vec.T * scale, np.zeros(len(scale))])
    return np.append(top, rest), jac, r
