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
floats, so compiled integrators can call them (inlined: a call would cost reference counting of
its array arguments, about as much as f itself); :class:`OdeForm` wraps them for Python callers.

The friction laws in one place: every law-specific formula of the ODE, DAE and ETD forms is in
the section "the laws" below (:func:`state_rate`, :func:`state_rate_partials`,
:func:`ln_slip_rate`, :func:`etd_targets`, and their Python counterparts), dispatched on the law
code (:data:`LAW_CODES`). An unknown code is refused by :func:`check_law_code` wherever Python
hands one over, and gives NaN, never another law's formulas, in compiled code
(docs/adding-a-law.md says how to add a law).
"""

from __future__ import annotations


import numpy as np
from numba import njit

__all__ = ["ode_rhs", "ode_jacobian", "OdeForm", "to_ode_state", "from_ode_state", "dae_residual",
           "dae_jacobian", "dae_initial", "DaeForm", "DAE_DIFFERENTIAL", "SLIP_LAW", "AGING_LAW",
           "LAW_CODES", "check_law_code", "state_rate", "state_rate_partials", "ln_slip_rate",
           "etd_targets", "s_of_psi", "psi_of_s", "psi_rate"]

# --- the laws ---------------------------------------------------------------------------------
#: codes of the friction laws in compiled code (``FrictionLaw.code``)
SLIP_LAW, AGING_LAW = 0, 1
LAW_CODES = {SLIP_LAW: "slip", AGING_LAW: "aging"}


def check_law_code(code) -> int:
    """``code`` if it is a friction-law code the compiled forms know, else ValueError."""
    if isinstance(code, bool) or not isinstance(code, (int, np.integer)) or int(code) not in LAW_CODES:
        raise ValueError(f"unknown friction-law code {code!r}: the compiled forms know "
                         f"{dict(LAW_CODES)} (docs/adding-a-law.md says how to add one)")
    return int(code)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def state_rate(law, u, s, w):
    """s' in the ODE form: −w (u + s) (slip law), e^(−s) − w (aging law); NaN for another code."""
    if law == SLIP_LAW:
        return -w * (u + s)
    if law == AGING_LAW:
        return np.exp(-s) - w
    return np.nan


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def state_rate_partials(law, u, s, w):
    """(∂s'/∂u, ∂s'/∂s) of :func:`state_rate`."""
    if law == SLIP_LAW:
        return -w * (u + s) - w, -w
    if law == AGING_LAW:
        return -w, -np.exp(-s)
    return np.nan, np.nan


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def ln_slip_rate(law, beta, eta, psi):
    """ln w from the friction-law constraint (Eq. 32 slip law, Eq. 62 aging law)."""
    if law == SLIP_LAW:
        return eta - beta * psi
    if law == AGING_LAW:
        return eta - beta * np.log(psi)
    return np.nan


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def etd_targets(law, beta, c, d, h, lnw, w, psi):
    """The ETD's frozen targets (ηss, Ψss) at (h, w, Ψ): Eqs. 36–40 (slip), 63–65 (aging)."""
    if law == SLIP_LAW:
        return (c * h - beta * w * w * (lnw + psi)) / d, -lnw
    if law == AGING_LAW:
        return (c * h + beta * w / psi - beta * w * w) / d, 1.0 / w
    return np.nan, np.nan


def s_of_psi(law_code: int, psi):
    """The ODE form's s: Ψ (slip law) or ln Ψ (aging law); arrays welcome."""
    return psi if check_law_code(law_code) == SLIP_LAW else np.log(psi)


def psi_of_s(law_code: int, s):
    """Ψ from the ODE form's s (inverse of :func:`s_of_psi`)."""
    return s if check_law_code(law_code) == SLIP_LAW else np.exp(s)


def psi_rate(law_code: int, psi, ds):
    """Ψ' from s' (the chain rule of :func:`s_of_psi`)."""
    return ds if check_law_code(law_code) == SLIP_LAW else psi * ds



@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def ode_rhs(law, beta, c, d, e, z, out):
    """Write dz/dτ into ``out`` (law 0 = slip, 1 = aging)."""
    h, u, s = z[0], z[1], z[2]
    w = np.exp(u)
    out[0] = e - w
    out[1] = (c * h - d * (u + beta * s)) / w
    out[2] = state_rate(law, u, s, w)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def ode_jacobian(law, beta, c, d, e, z, jac):
    """Write ∂(dz/dτ)/∂z into the 3×3 ``jac``."""
    h, u, s = z[0], z[1], z[2]
    w = np.exp(u)
    inv_w = 1.0 / w
    fu = (c * h - d * (u + beta * s)) * inv_w
    jac[0, 0], jac[0, 1], jac[0, 2] = 0.0, -w, 0.0
    jac[1, 0], jac[1, 1], jac[1, 2] = c * inv_w, -d * inv_w - fu, -d * beta * inv_w
    dfs_du, dfs_ds = state_rate_partials(law, u, s, w)
    jac[2, 0], jac[2, 1], jac[2, 2] = 0.0, dfs_du, dfs_ds


def to_ode_state(law_code: int, beta: float, x) -> np.ndarray:
    """(h, η, Ψ) → (h, u, s)."""
    h, eta, psi = x
    s = s_of_psi(law_code, psi)
    return np.array([h, eta - beta * s, s])


def from_ode_state(law_code: int, beta: float, z: np.ndarray):
    """(h, u, s) arrays → (h, η, Ψ) arrays."""
    h, u, s = z[..., 0], z[..., 1], z[..., 2]
    return h, u + beta * s, psi_of_s(law_code, s)


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
def dae_residual(law, beta, c, d, e, y, yp, out):
    """Write F(y, y') of the DAE form into ``out`` (length 4)."""
    h, u, s, eta = y[0], y[1], y[2], y[3]
    w = np.exp(u)
    fs = state_rate(law, u, s, w)
    out[0] = yp[0] - (e - w)
    out[1] = u - (eta - beta * s)
    out[2] = yp[2] - fs
    out[3] = yp[3] - ((c * h - d * eta) / w + beta * fs)


@njit(cache=True, error_model="numpy")
def dae_jacobian(law, beta, c, d, e, y, cj, jac):
    """Write ∂F/∂y + cj ∂F/∂y' into the 4×4 ``jac`` (IDA's iteration matrix)."""
    h, u, s, eta = y[0], y[1], y[2], y[3]
    w = np.exp(u)
    dfs_du, dfs_ds = state_rate_partials(law, u, s, w)
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
