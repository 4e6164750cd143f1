"""Rodas5P's tableau, its stage loop and the stages' derivatives: what the engine's Rodas5P
(:mod:`integrators.own.rodas5p`), its forward sensitivities (:mod:`integrators.own.sensitivity`)
and the laboratory's two-state model (:mod:`benchmarks.lab.two_state`) share. The method, the
tableau's source and the controller are described in :mod:`integrators.own.rodas5p`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from integrators.own.linalg import factor, lu_solve3

__all__ = ["stages", "no_after", "workspace", "stage_sensitivities", "sensitivity_workspace",
           "chain", "directions", "dense_change", "dense_products", "dense_sensitivities",
           "A5P", "C5P", "G5P", "H5P"]

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
def no_after(p, s, u, ws):
    """:func:`stages`' ``after`` when nothing is wanted at the stages."""


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def stages(rhs, after, p, rtol, atol, hs, ws, z0, f0, z1, D):
    """One attempt of a step ``hs`` from ``z0`` (``f0`` = f(z0), ws[0] = J(z0)) for the
    right-hand side ``rhs(p, z, out)``: z1 into ``z1``, the dense output's D (an accepted
    attempt only); returns the scaled error (inf if M is singular or the error not finite).
    ``after(p, s, u, ws)`` runs after f at each stage s ≥ 1 (at its argument u): the forward
    sensitivities take the stages' Jacobians there, sharing f's work (:func:`no_after`:
    nothing). ``ws``: :func:`workspace`'s, and after it what ``after`` reads. The slider's
    kernel and the laboratory's two-state model (:mod:`benchmarks.lab.two_state`) share it."""
    J, M, piv, K, u, fb = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5]
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
            after(p, s, u, ws)
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


@njit(cache=True, nogil=True, error_model="numpy")
def sensitivity_workspace(n_s):
    """Room for :func:`stage_sensitivities` with ``n_s`` directions: the stages' Jacobians and
    ∂f/∂θ, the second derivatives at the step's start (zero until a model writes its entries
    that are not), the stages' dK, and M⁻¹'s columns as rows (row k: M⁻¹e_k, so M⁻ᵀ)."""
    return (np.empty((8, 3, 3)), np.zeros((8, 3, n_s)), np.zeros((3, 3, 3)),
            np.zeros((3, 3, n_s)), np.zeros((n_s, 8, 3)), np.empty((3, 3)))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def stage_sensitivities(partials, second, directions, p, dirs, hs, ws, sw, z0, S,
                        staged=False):
    """The forward sensitivities S (row n: ∂z/∂θ_n, one row per direction of ``dirs``) from
    the accepted step ``hs`` at ``z0`` to its end, in place (the dense output's:
    :func:`dense_sensitivities`): the step's stages differentiated (internal
    differentiation on the step's own h, M's factors reused; ``ws`` as :func:`stages` left it)::

        M dK_s = hγ (J(u_s) dU_s + ∂f/∂θ(u_s)) + γ Σ_l C_sl dK_l + hγ dJ K_s,
        dU_s = S + Σ_l A_sl dK_l,   dJ = ∂J/∂z·S + ∂J/∂θ at z0,   S ← dU_7 + dK_7

    (dJ K_s because M = I − hγ J(z0) depends on θ). The model gives ``partials(p, dirs, z,
    jac, fth, s)``: ∂f/∂z into jac[s], ∂f/∂θ into fth[s]'s columns; ``second(p, dirs, z,
    hyy, hyt)``: ∂²f/∂z∂z, ∂²f/∂z∂θ; and ``directions(hg, mi, K, jac, fth, hyy, hyt, dk, S)``
    (hg = hγ, mi M⁻ᵀ), the chain above for each direction, dK into dk[n]: :func:`chain`
    with the model's Jacobian's zeros skipped (the slider's
    :func:`integrators.own.sensitivity.rodas_directions`; :func:`directions`: none skipped).
    ``staged``: the step's :func:`stages` made jac[s] and fth[s] for s ≥ 1 already (its
    ``after``), and nothing has run an attempt since (else they are another step's).
    Allocates nothing."""
    M, piv, K, u = ws[1], ws[2], ws[3], ws[4]       # ws may carry more (a kernel's own)
    jst, fst, hyy, hyt, dk, mi = sw
    partials(p, dirs, z0, jst, fst, 0)
    second(p, dirs, z0, hyy, hyt)
    for s in range(1, 1 if staged else 8):
        for i in range(3):
            acc = z0[i]
            for j in range(s):
                acc += A5P[s, j] * K[j, i]
            u[i] = acc
        partials(p, dirs, u, jst, fst, s)
    for k in range(3):
        for i in range(3):
            mi[k, i] = 1.0 if i == k else 0.0
        lu_solve3(M, piv, mi, k)
    directions(hs * G5P, mi, K, jst, fst, hyy, hyt, dk, S)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def chain(change, products, hg, mi, K, jst, fst, hyy, hyt, dk, S):
    """The stage chain of :func:`stage_sensitivities` for each direction n (row n of S, dK
    into dk[n]; hg = hγ, ``mi`` M⁻¹ by rows), inlined into a model's own compiled
    ``directions``: the model gives ``change(hyy, hyt, n, s0, s1, s2)``, its dJ along n (a
    tuple in its own layout), and ``products(jst, s, d, u0, u1, u2, k0, k1, k2)``,
    J(u_s)·u + dJ·K_s, both inlined, so that the Jacobian's zeros are skipped where the model
    knows them (:func:`dense_change`, :func:`dense_products`: none).

    A direction's stages form a chain. Each stage's sums Σ A_sl dK_l and Σ C_sl dK_l are read
    back from dk (a pull: loads that do not wait on one another; pushing each dK_l into the
    later stages' sums stored and reloaded them), the state is in local variables, and M⁻¹
    replaces the 3×3 solve. The caller's ``fastmath={"contract"}`` fuses products and sums (a
    multiply-add rounds once; no other license)."""
    for n in range(S.shape[0]):
        s0, s1, s2 = S[n, 0], S[n, 1], S[n, 2]
        d = change(hyy, hyt, n, s0, s1, s2)
        u0, u1, u2 = s0, s1, s2
        for s in range(8):
            if s < 6:
                u0, u1, u2 = s0, s1, s2
                for l in range(s):
                    a = A5P[s, l]
                    u0 += a * dk[n, l, 0]
                    u1 += a * dk[n, l, 1]
                    u2 += a * dk[n, l, 2]
            else:                       # A's rows 6 and 7 are row s − 1 plus e_(s−1)
                u0 += dk[n, s - 1, 0]
                u1 += dk[n, s - 1, 1]
                u2 += dk[n, s - 1, 2]
            c0 = c1 = c2 = 0.0
            for l in range(s):
                c = C5P[s, l]
                c0 += c * dk[n, l, 0]
                c1 += c * dk[n, l, 1]
                c2 += c * dk[n, l, 2]
            p0, p1, p2 = products(jst, s, d, u0, u1, u2, K[s, 0], K[s, 1], K[s, 2])
            e0 = hg * (fst[s, 0, n] + p0) + G5P * c0
            e1 = hg * (fst[s, 1, n] + p1) + G5P * c1
            e2 = hg * (fst[s, 2, n] + p2) + G5P * c2
            dk[n, s, 0] = mi[0, 0] * e0 + mi[1, 0] * e1 + mi[2, 0] * e2
            dk[n, s, 1] = mi[0, 1] * e0 + mi[1, 1] * e1 + mi[2, 1] * e2
            dk[n, s, 2] = mi[0, 2] * e0 + mi[1, 2] * e1 + mi[2, 2] * e2
        S[n, 0], S[n, 1], S[n, 2] = u0 + dk[n, 7, 0], u1 + dk[n, 7, 1], u2 + dk[n, 7, 2]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_change(hyy, hyt, n, s0, s1, s2):
    """:func:`chain`'s ``change`` with no zeros known: dJ = ∂J/∂z·S + ∂J/∂θ, by rows."""
    return (hyt[0, 0, n] + hyy[0, 0, 0] * s0 + hyy[0, 0, 1] * s1 + hyy[0, 0, 2] * s2,
            hyt[0, 1, n] + hyy[0, 1, 0] * s0 + hyy[0, 1, 1] * s1 + hyy[0, 1, 2] * s2,
            hyt[0, 2, n] + hyy[0, 2, 0] * s0 + hyy[0, 2, 1] * s1 + hyy[0, 2, 2] * s2,
            hyt[1, 0, n] + hyy[1, 0, 0] * s0 + hyy[1, 0, 1] * s1 + hyy[1, 0, 2] * s2,
            hyt[1, 1, n] + hyy[1, 1, 0] * s0 + hyy[1, 1, 1] * s1 + hyy[1, 1, 2] * s2,
            hyt[1, 2, n] + hyy[1, 2, 0] * s0 + hyy[1, 2, 1] * s1 + hyy[1, 2, 2] * s2,
            hyt[2, 0, n] + hyy[2, 0, 0] * s0 + hyy[2, 0, 1] * s1 + hyy[2, 0, 2] * s2,
            hyt[2, 1, n] + hyy[2, 1, 0] * s0 + hyy[2, 1, 1] * s1 + hyy[2, 1, 2] * s2,
            hyt[2, 2, n] + hyy[2, 2, 0] * s0 + hyy[2, 2, 1] * s1 + hyy[2, 2, 2] * s2)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_products(jst, s, d, u0, u1, u2, k0, k1, k2):
    """:func:`chain`'s ``products`` with no zeros known: J(u_s)·u + dJ·K_s."""
    return (d[0] * k0 + d[1] * k1 + d[2] * k2
            + jst[s, 0, 0] * u0 + jst[s, 0, 1] * u1 + jst[s, 0, 2] * u2,
            d[3] * k0 + d[4] * k1 + d[5] * k2
            + jst[s, 1, 0] * u0 + jst[s, 1, 1] * u1 + jst[s, 1, 2] * u2,
            d[6] * k0 + d[7] * k1 + d[8] * k2
            + jst[s, 2, 0] * u0 + jst[s, 2, 1] * u1 + jst[s, 2, 2] * u2)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def directions(hg, mi, K, jst, fst, hyy, hyt, dk, S):
    """:func:`stage_sensitivities`' ``directions`` for a model whose Jacobian has no zeros to
    skip (the laboratory's two-state model): :func:`chain` with :func:`dense_change` and
    :func:`dense_products`."""
    chain(dense_change, dense_products, hg, mi, K, jst, fst, hyy, hyt, dk, S)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dense_sensitivities(sw, dD):
    """The dense output's dD (dD[r, n] the derivative of D[r] along direction n) of the step
    :func:`stage_sensitivities` last differentiated (its dK in ``sw``): wanted only where a
    step has a save point or a root, so computed apart."""
    dk = sw[4]
    for n in range(dD.shape[1]):
        for i in range(3):
            for r in range(3):
                acc = 0.0
                for s in range(8):
                    acc += H5P[r, s] * dk[n, s, i]
                dD[r, n, i] = acc
