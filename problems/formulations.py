"""The ODE form shared by the adaptive backends: z = (h, u, s), nondimensional (SPEC §2).

    h = (Fs − F0)/(k Lc)       u = ln w = ln(v/v0)       s = Ψ (slip law) or ln Ψ (aging law)

Why this choice: the slip rate spans ~10 orders of magnitude over a cycle (1e−8 to 5e−2 m/s), so
v itself is a terrible variable for a mixed absolute/relative error test, while ln w stays O(10).
The aging-law state Ψ = v0 θ/Lc ~ 1/w spans as many decades, hence ln Ψ; the slip-law state
Ψ = θ/B ~ −ln w is already O(10). With η = u + β s the friction-law constraint is built in:

    h' = E − e^u
    u' = (C h − D η) e^(−u)
    s' = −e^u (u + s)             (slip law)
    s' = e^(−s) − e^u             (aging law)

The Jacobian is analytic (:func:`ode_jacobian`). Both functions are numba-compiled and take plain
floats, so compiled integrators can call them; :class:`OdeForm` wraps them for Python callers.
"""

from __future__ import annotations


import numpy as np
from numba import njit

__all__ = ["ode_rhs", "ode_jacobian", "OdeForm", "to_ode_state", "from_ode_state", "dae_residual",
           "dae_jacobian", "dae_initial", "DaeForm", "DAE_DIFFERENTIAL"]


@njit(cache=True, error_model="numpy")
def ode_rhs(law, beta, c, d, e, z, out):
    """Write dz/dτ into ``out`` (law 0 = slip, 1 = aging)."""
    h, u, s = z[0], z[1], z[2]
    w = np.exp(u)
    out[0] = e - w
    out[1] = (c * h - d * (u + beta * s)) / w
    if law == 0:
        out[2] = -w * (u + s)
    else:
        out[2] = np.exp(-s) - w


@njit(cache=True, error_model="numpy")
def ode_jacobian(law, beta, c, d, e, z, jac):
    """Write ∂(dz/dτ)/∂z into the 3×3 ``jac``."""
    h, u, s = z[0], z[1], z[2]
    w = np.exp(u)
    inv_w = 1.0 / w
    fu = (c * h - d * (u + beta * s)) * inv_w
    jac[0, 0], jac[0, 1], jac[0, 2] = 0.0, -w, 0.0
    jac[1, 0], jac[1, 1], jac[1, 2] = c * inv_w, -d * inv_w - fu, -d * beta * inv_w
    if law == 0:
        jac[2, 0], jac[2, 1], jac[2, 2] = 0.0, -w * (u + s) - w, -w
    else:
        jac[2, 0], jac[2, 1], jac[2, 2] = 0.0, -w, -np.exp(-s)


def to_ode_state(law_code: int, beta: float, x) -> np.ndarray:
    """(h, η, Ψ) → (h, u, s)."""
    h, eta, psi = x
    if law_code == 0:
        return np.array([h, eta - beta * psi, psi])
    return np.array([h, eta - beta * np.log(psi), np.log(psi)])


def from_ode_state(law_code: int, beta: float, z: np.ndarray):
    """(h, u, s) arrays → (h, η, Ψ) arrays."""
    h, u, s = z[..., 0], z[..., 1], z[..., 2]
    return h, u + beta * s, (s if law_code == 0 else np.exp(s))


class OdeForm:
    """Python callables ``f(τ, z)`` and ``jac(τ, z)`` of the ODE form at loading E = ``e``.

    ``rhs_tier`` picks the implementation: ``"numba"`` (the compiled functions above) or
    ``"python"`` (plain numpy, what a user would write).
    """

    def __init__(self, nd, e: float, rhs_tier: str = "numba"):
        if rhs_tier not in ("numba", "python"):
            raise ValueError(f"rhs_tier must be 'numba' or 'python', got {rhs_tier!r}")
        self.args = (nd.law_code, nd.beta, nd.c, nd.d, e)
        self.tier = rhs_tier

    def f(self, tau, z):
        out = np.empty(3)
        if self.tier == "numba":
            ode_rhs(*self.args, z, out)
        else:
            ode_rhs.py_func(*self.args, z, out)
        return out

    def jac(self, tau, z):
        out = np.empty((3, 3))
        if self.tier == "numba":
            ode_jacobian(*self.args, z, out)
        else:
            ode_jacobian.py_func(*self.args, z, out)
        return out


# --- the DAE form (IDA and other DAE solvers) -----------------------------------------------
#
# y = (h, u, s, η): the ODE state plus the friction η = (Ft − F0)/A as a differential variable,
# with the slip rate u = ln w demoted to an algebraic variable tied by the friction law:
#
#     0 = h' − (E − e^u)
#     0 = u − (η − β s)                               (the constraint; ∂/∂u = 1: index 1)
#     0 = s' − f_s(u, s)
#     0 = η' − [(C h − D η) e^(−u) + β f_s(u, s)]     (Eq. 26/60 with ln w = u)
#
# so that v, Ft and θ are tied exactly as in SPEC §1. ``DAE_DIFFERENTIAL`` marks the
# differential components (IDA's ``id`` vector).

DAE_DIFFERENTIAL = np.array([1.0, 0.0, 1.0, 1.0])


@njit(cache=True, error_model="numpy")
def _state_rate(law, u, s, w):
    if law == 0:
        return -w * (u + s)
    return np.exp(-s) - w


@njit(cache=True, error_model="numpy")
def dae_residual(law, beta, c, d, e, y, yp, out):
    """Write F(y, y') of the DAE form into ``out`` (length 4)."""
    h, u, s, eta = y[0], y[1], y[2], y[3]
    w = np.exp(u)
    fs = _state_rate(law, u, s, w)
    out[0] = yp[0] - (e - w)
    out[1] = u - (eta - beta * s)
    out[2] = yp[2] - fs
    out[3] = yp[3] - ((c * h - d * eta) / w + beta * fs)


@njit(cache=True, error_model="numpy")
def dae_jacobian(law, beta, c, d, e, y, cj, jac):
    """Write ∂F/∂y + cj ∂F/∂y' into the 4×4 ``jac`` (IDA's iteration matrix)."""
    h, u, s, eta = y[0], y[1], y[2], y[3]
    w = np.exp(u)
    if law == 0:
        dfs_du, dfs_ds = -w * (u + s) - w, -w
    else:
        dfs_du, dfs_ds = -w, -np.exp(-s)
    feta = (c * h - d * eta) / w
    for i in range(4):
        for j in range(4):
            jac[i, j] = 0.0
    jac[0, 0] = cj
    jac[0, 1] = w
    jac[1, 1] = 1.0
    jac[1, 2] = beta
    jac[1, 3] = -1.0
    jac[2, 1] = -dfs_du
    jac[2, 2] = cj - dfs_ds
    jac[3, 0] = -c / w
    jac[3, 1] = feta - beta * dfs_du
    jac[3, 2] = -beta * dfs_ds
    jac[3, 3] = cj + d / w


def dae_initial(nd, e: float, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Consistent (y0, y'0) of the DAE form from the ODE state z0 = (h, u, s)."""
    h, u, s = z0
    eta = u + nd.beta * s
    y0 = np.array([h, u, s, eta])
    f = np.empty(3)
    ode_rhs(nd.law_code, nd.beta, nd.c, nd.d, e, z0, f)
    # η' = u' + β s' along the constraint; u' is the ODE's
    yp0 = np.array([f[0], f[1], f[2], f[1] + nd.beta * f[2]])
    return y0, yp0


class DaeForm:
    """Python callables of the DAE form at loading E = ``e``, in the ``rhs_tier`` of
    :class:`OdeForm` (``"numba"`` or ``"python"``)."""

    def __init__(self, nd, e: float, rhs_tier: str = "numba"):
        if rhs_tier not in ("numba", "python"):
            raise ValueError(f"rhs_tier must be 'numba' or 'python', got {rhs_tier!r}")
        self.args = (nd.law_code, nd.beta, nd.c, nd.d, e)
        self._res = dae_residual if rhs_tier == "numba" else dae_residual.py_func
        self._jac = dae_jacobian if rhs_tier == "numba" else dae_jacobian.py_func

    def residual(self, tau, y, yp, out):
        self._res(*self.args, y, yp, out)

    def jacobian(self, tau, y, cj, out):
        self._jac(*self.args, y, cj, out)
