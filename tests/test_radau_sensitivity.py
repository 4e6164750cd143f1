"""RadauIIA5's step derivatives (integrators/own/radau5_sensitivity.py) against central
differences of the collocation equations solved exactly (a full Newton on the 9×9 system, in
numpy here, sharing nothing with the module but the right-hand side and the tableau): the stage
increments' dZ, S at the step's end, the dense output's dD, and the error estimate's derivative
along the branch the state's test takes (the first estimate, or the second where the first
fails), with the other branch far off, so that a wrong branch fails."""

import numpy as np
import pytest

from integrators.own import engine
from integrators.own import radau5_sensitivity as R
from integrators.own import sensitivity as SE
from integrators.own.linalg import factor
from integrators.own.radau5 import RadauIIA5
from integrators.own.radau5_tableau import A, C, E_ERR, MU
from problems.directions import direction
from problems.formulations import N_Q
from problems.presets import paper_example

PROBLEM = paper_example(law="aging")
NAMES = ("b", "lc", "stiffness")
DIRS = SE.direction_matrix([direction(PROBLEM, n) for n in NAMES])
DQ = np.ascontiguousarray(DIRS[:, :N_Q]).copy()
SCALE = DIRS[:, SE.DIR["SCALE"]]


def _p(rtol):
    return engine.new_state(PROBLEM.nondimensional(), rtol, rtol, RadauIIA5.constants, 10**6,
                            1e30)[1]


def _f(p, z):
    out = np.empty(3)
    engine.f_of(p, np.asarray(z, float), out)
    return out


def _jac(p, z):
    out = np.empty((3, 3))
    engine.jacobian(p, np.asarray(z, float), out)
    return out


def _collocation(p, z0, h):
    """Z with Z = h (A ⊗ I) F(z0 + Z) to rounding (full Newton)."""
    Z = np.zeros((3, 3))
    for _ in range(100):
        F = np.array([_f(p, z0 + Z[s]) for s in range(3)])
        B = np.eye(9)
        for s in range(3):
            for l in range(3):
                B[3 * s:3 * s + 3, 3 * l:3 * l + 3] -= h * A[s, l] * _jac(p, z0 + Z[l])
        d = np.linalg.solve(B, (Z - h * A @ F).ravel()).reshape(3, 3)
        Z -= d
        if np.max(abs(d)) < 1e-17 * (1 + np.max(abs(Z))):
            break
    return Z


def _estimates(p, z0, h, Z):
    fr = h / MU
    M = np.eye(3) - fr * _jac(p, z0)
    ez = E_ERR @ Z / h
    first = np.linalg.solve(M, fr * (_f(p, z0) + ez))
    return first, np.linalg.solve(M, fr * (_f(p, z0 + first) + ez))


def _dense(Z):
    c1, c2 = C[0], C[1]
    w1, w2 = (Z[0] - c1 * Z[2]) / (c1 * (1 - c1)), (Z[1] - c2 * Z[2]) / (c2 * (1 - c2))
    d1 = (w1 - w2) / (c1 - c2)
    return np.array([w1 - c1 * d1, d1])


def _rel(a, b):
    return np.max(abs(a - b)) / np.max(abs(b))


@pytest.mark.parametrize("rtol, h, second", [(1e-2, 1e-6, False), (1e-2, 1e-5, True),
                                             (1e-6, 1e-3, True)])
def test_the_step_derivatives_are_the_collocation_equations_differentiated(rtol, h, second):
    p, z0 = _p(rtol), np.array([1.2, -2.0, 0.5])
    S = np.random.default_rng(1).normal(size=(3, 3)) / SCALE[:, None]
    Z = _collocation(p, z0, h)
    sw, SN, u = R.workspace.py_func(3), S.copy(), np.empty(3)
    R.step_sensitivities.py_func(SE._partials, p, DQ, h, Z, u, sw, z0, SN)
    dD = np.empty((3, 3, 3))
    R.dense_sensitivities.py_func(sw, dD)
    M, piv = np.empty((3, 3)), np.zeros(3, np.int64)
    factor(h / MU, _jac(p, z0), M, piv)
    R.error_sensitivities.py_func(SE._partials, SE._second, p, DQ, h, M, piv, _f(p, z0), Z,
                                  np.empty((1, 3)), u, sw, z0, S)
    first, _ = _estimates(p, z0, h, Z)
    worst = np.max(abs(first) / (rtol + rtol * np.maximum(abs(z0), abs(z0 + Z[2]))))
    assert (worst > 1.0) == second          # the case takes the branch it is meant to
    for n in range(3):
        ends = []
        for sign in (1.0, -1.0):
            e = 1e-6 * SCALE[n]
            pp = p.copy()
            pp[1:N_Q] += sign * e * DQ[n, 1:N_Q]
            zz = z0 + sign * e * S[n]
            Zp = _collocation(pp, zz, h)
            ends.append((Zp, *_estimates(pp, zz, h, Zp), _dense(Zp)))
        d = [(a - b) / (2e-6 * SCALE[n]) for a, b in zip(*ends)]
        assert _rel(sw[4][n, :3], d[0]) < 1e-7, NAMES[n]
        assert _rel(SN[n], S[n] + d[0][2]) < 1e-7, NAMES[n]
        assert _rel(dD[:2, n], d[3]) < 1e-7, NAMES[n]
        taken, other = (d[2], d[1]) if second else (d[1], d[2])
        assert _rel(sw[4][n, R.ERROR_ROW], taken) < 1e-6, NAMES[n]
        assert _rel(sw[4][n, R.ERROR_ROW], other) > 1e-2, NAMES[n]
