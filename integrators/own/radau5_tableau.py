"""Radau IIA of order 5: its tableau (A, c), the error estimate's weights e and the real
eigenbasis T of A⁻¹ (:mod:`integrators.own.radau5` describes the method; its forward
sensitivities, :mod:`integrators.own.radau5_sensitivity`, share these)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["radau_constants"]


def radau_constants():
    """(A, c, e, T, T⁻¹, μ, α, β) of Radau IIA order 5: T⁻¹ A⁻¹ T = [[μ, 0, 0], [0, α, β],
    [0, −β, α]]."""
    s6 = math.sqrt(6.0)
    a = np.array([[(88 - 7 * s6) / 360, (296 - 169 * s6) / 1800, (-2 + 3 * s6) / 225],
                  [(296 + 169 * s6) / 1800, (88 + 7 * s6) / 360, (-2 - 3 * s6) / 225],
                  [(16 - s6) / 36, (16 + s6) / 36, 1.0 / 9.0]])
    c = np.array([(4 - s6) / 10, (4 + s6) / 10, 1.0])
    e = np.array([-13 - 7 * s6, -13 + 7 * s6, -1.0]) / 3.0
    values, vectors = np.linalg.eig(np.linalg.inv(a))
    real, cplx = int(np.argmin(abs(values.imag))), int(np.argmax(values.imag))
    t = np.column_stack([vectors[:, real].real, vectors[:, cplx].real, vectors[:, cplx].imag])
    return (a, c, e, t, np.linalg.inv(t), float(values[real].real), float(values[cplx].real),
            float(values[cplx].imag))


A, C, E_ERR, T, TI, MU, ALPHA, BETA = radau_constants()
#: (α − iβ): the complex eigenvalue that the transformed (W2 + i W3) sees
MU_C = complex(ALPHA, -BETA)
C1, C2 = C[0], C[1]
