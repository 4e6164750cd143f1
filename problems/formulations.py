"""The ODE form shared by the adaptive backends: z = (h, u, s), nondimensional (SPEC §2).

    h = (Fs − F0)/(k Lc)       u = ln w = ln(v/v0)       s = Ψ (slip law) or ln Ψ (aging, Nagata)

Why this choice: the slip rate spans ~10 orders of magnitude over a cycle (1e−8 to 5e−2 m/s), so
v itself is a terrible variable for a mixed absolute/relative error test, while ln w stays O(10).
The aging-law state Ψ = v0 θ/Lc ~ 1/w spans as many decades, hence ln Ψ; the slip-law state
Ψ = θ/B ~ −ln w is already O(10). With η = u + β s the friction-law constraint is built in:

    h' = E − e^u
    u' = (C h − D η) e^(−u) − G                  (with mass: the force balance m v' = Fs − Ft − ηr v)
    u' = (K (E − e^u) − β s') / (1 + R e^u)      (quasi-static, m = 0: Fs = Ft + ηr v, differentiated)
    s' = −e^u (u + s)                           (slip law)
    s' = e^(−s) − e^u                           (aging law)
    s' = e^(−s) − e^u − γ (E − e^u)             (Nagata law, γ = (c/b) k Lc/Fn)

with radiation damping ηr (N s/m): G = ηr Lc/(m v0) with mass, R = ηr v0/A without; K = k Lc/A.

The problem reaches compiled code as one float vector q (:func:`form_vector`, layout ``Q_*``):
law code, β, C (K when quasi-static), D, E, G (R when quasi-static), the quasi-static flag and the
law's parameter (γ). Backends put q at the head of their own parameter arrays. The Jacobian is
analytic (:func:`ode_jacobian`). The functions are numba-compiled, so compiled integrators can
call them (inlined: a call would cost reference counting of its array arguments, about as much
as f itself); :class:`OdeForm` wraps them for Python callers.

The friction laws in one place: every law-specific formula of the ODE, DAE and ETD forms is in
the section "the laws" below, one block per law (its state rate, the rate's partial derivatives,
the constraint ln w, the ETD's frozen targets), and four dispatchers on the law code
(:data:`LAW_CODES`) with one line per law. An unknown code is refused by :func:`check_law_code`
wherever Python hands one over, and gives NaN, never another law's formulas, in compiled code
(docs/adding-a-law.md says how to add a law).
"""

from __future__ import annotations


import numpy as np
from numba import njit

__all__ = ["ode_rhs", "ode_jacobian", "OdeForm", "to_ode_state", "from_ode_state", "dae_residual",
           "dae_jacobian", "dae_initial", "DaeForm", "dae_differential", "SLIP_LAW", "AGING_LAW",
           "NAGATA_LAW", "LAW_CODES", "check_law_code", "state_rate", "state_rate_partials",
           "state_rate_second_partials",
           "ln_slip_rate", "etd_targets", "s_of_psi", "psi_of_s", "psi_rate", "form_vector",
           "slip_rate_rate", "peak_function", "Q_LAW", "Q_BETA", "Q_C", "Q_D", "Q_E", "Q_G",
           "Q_QS", "Q_LAWP", "N_Q"]

# --- the problem vector ---------------------------------------------------------------------
#: q: the law code, β = b/a, C = k Lc²/(m v0²) (K = k Lc/A quasi-static), D = A Lc/(m v0²),
#: the loading rate E = vL/v0, G = ηr Lc/(m v0) (R = ηr v0/A quasi-static), the quasi-static
#: flag (1.0: no mass) and the law's parameter (γ of the Nagata law, else 0)
Q_LAW, Q_BETA, Q_C, Q_D, Q_E, Q_G, Q_QS, Q_LAWP = range(8)
N_Q = 8


def form_vector(nd, e: float) -> np.ndarray:
    """The problem vector q of the nondimensional problem ``nd`` under loading rate E = ``e``."""
    return np.array([check_law_code(nd.law_code), nd.beta, nd.c, nd.d, e, nd.g,
                     float(nd.quasi_static), nd.law_param])


# --- the laws ---------------------------------------------------------------------------------
#: codes of the friction laws in compiled code (``FrictionLaw.code``)
SLIP_LAW, AGING_LAW, NAGATA_LAW = 0, 1, 2
LAW_CODES = {SLIP_LAW: "slip", AGING_LAW: "aging", NAGATA_LAW: "nagata"}
#: the laws whose ODE-form state s is ln Ψ (the others: s = Ψ)
LOG_STATE_LAWS = frozenset({AGING_LAW, NAGATA_LAW})


def check_law_code(code) -> int:
    """``code`` if it is a friction-law code the compiled forms know, else ValueError."""
    if isinstance(code, bool) or not isinstance(code, (int, np.integer, float, np.floating)) \
            or not np.isfinite(code) or code != int(code) or int(code) not in LAW_CODES:
        raise ValueError(f"unknown friction-law code {code!r}: the compiled forms know "
                         f"{dict(LAW_CODES)} (docs/adding-a-law.md says how to add one)")
    return int(code)


# The slip law: s = Ψ = θ/B; ln w = η − βΨ. ETD (x = (h, η, Ψ)): Ψ' = −w (Ψ − (−ln w)).
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _slip_rate(q, u, s, w):
    return -w * (u + s)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _slip_partials(q, u, s, w):
    return -w * (u + s) - w, -w


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _slip_second(q, u, s, w):
    return -w * (u + s) - 2.0 * w, -w, 0.0, 0.0, 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _slip_ln_w(beta, eta, psi):
    return eta - beta * psi


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _slip_targets(q, h, lnw, w, psi):
    """Eqs. 36–40: (ηss, Ψss, the rate of Ψ's relaxation)."""
    return (q[Q_C] * h - q[Q_BETA] * w * w * (lnw + psi)) / q[Q_D], -lnw, w


# The aging law: s = ln Ψ, Ψ = v0 θ/Lc; ln w = η − β ln Ψ. ETD: Ψ' = −w (Ψ − 1/w).
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _aging_rate(q, u, s, w):
    return np.exp(-s) - w


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _aging_partials(q, u, s, w):
    return -w, -np.exp(-s)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _aging_second(q, u, s, w):
    return -w, 0.0, np.exp(-s), 0.0, 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _log_state_ln_w(beta, eta, psi):
    return eta - beta * np.log(psi)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _aging_targets(q, h, lnw, w, psi):
    """Eqs. 63–65."""
    beta = q[Q_BETA]
    return (q[Q_C] * h + beta * w / psi - beta * w * w) / q[Q_D], 1.0 / w, w


# The Nagata law: the aging law's s and constraint, with −γ (E − w) in s' (the spring's stress
# rate dμ/dτ = (k Lc/Fn)(E − w), times c/b). ETD: Ψ' = −r (Ψ − 1/r), r = w + γ (E − w).
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _nagata_rate(q, u, s, w):
    return np.exp(-s) - w - q[Q_LAWP] * (q[Q_E] - w)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _nagata_partials(q, u, s, w):
    return -w * (1.0 - q[Q_LAWP]), -np.exp(-s)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _nagata_second(q, u, s, w):
    return -w * (1.0 - q[Q_LAWP]), 0.0, np.exp(-s), -(q[Q_E] - w), w


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _nagata_targets(q, h, lnw, w, psi):
    beta = q[Q_BETA]
    r = w + q[Q_LAWP] * (q[Q_E] - w)
    eta_ss = (q[Q_C] * h + beta * w * (1.0 / psi - r)) / q[Q_D]
    # r changes sign where w = γE/(γ − 1) (γ > 1); at r = 0 exactly 1/r is inf and the relaxation
    # inf·0: a tiny r of the same sign gives the limit Ψ0 + s instead
    rr = r if abs(r) >= 1e-300 else (1e-300 if r >= 0.0 else -1e-300)
    return eta_ss, 1.0 / rr, rr


# The dispatchers: one line per law; an unknown code gives NaN.
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def state_rate(q, u, s, w):
    """s' in the ODE form at (u, s), w = e^u."""
    law = int(q[Q_LAW])
    if law == SLIP_LAW:
        return _slip_rate(q, u, s, w)
    if law == AGING_LAW:
        return _aging_rate(q, u, s, w)
    if law == NAGATA_LAW:
        return _nagata_rate(q, u, s, w)
    return np.nan


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def state_rate_partials(q, u, s, w):
    """(∂s'/∂u, ∂s'/∂s) of :func:`state_rate`."""
    law = int(q[Q_LAW])
    if law == SLIP_LAW:
        return _slip_partials(q, u, s, w)
    if law == AGING_LAW:
        return _aging_partials(q, u, s, w)
    if law == NAGATA_LAW:
        return _nagata_partials(q, u, s, w)
    return np.nan, np.nan


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def state_rate_second_partials(q, u, s, w):
    """(∂²s'/∂u², ∂²s'/∂u∂s, ∂²s'/∂s², ∂s'/∂γ, ∂²s'/∂u∂γ) of :func:`state_rate`, γ the law's
    parameter q[Q_LAWP] (∂²s'/∂s∂γ is 0 for every law here): forward sensitivities
    differentiate the Jacobian with them."""
    law = int(q[Q_LAW])
    if law == SLIP_LAW:
        return _slip_second(q, u, s, w)
    if law == AGING_LAW:
        return _aging_second(q, u, s, w)
    if law == NAGATA_LAW:
        return _nagata_second(q, u, s, w)
    return np.nan, np.nan, np.nan, np.nan, np.nan


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def ln_slip_rate(law, beta, eta, psi):
    """ln w from the friction-law constraint (Eq. 32 slip law, Eq. 62 aging and Nagata laws)."""
    if law == SLIP_LAW:
        return _slip_ln_w(beta, eta, psi)
    if law == AGING_LAW or law == NAGATA_LAW:
        return _log_state_ln_w(beta, eta, psi)
    return np.nan


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def etd_targets(q, h, lnw, w, psi):
    """The ETD's frozen targets at (h, w, Ψ) with mass and without damping: (ηss, Ψss, the
    relaxation rate of Ψ). The damping's −G w/D in ηss is added by the caller."""
    law = int(q[Q_LAW])
    if law == SLIP_LAW:
        return _slip_targets(q, h, lnw, w, psi)
    if law == AGING_LAW:
        return _aging_targets(q, h, lnw, w, psi)
    if law == NAGATA_LAW:
        return _nagata_targets(q, h, lnw, w, psi)
    return np.nan, np.nan, np.nan


def s_of_psi(law_code: int, psi):
    """The ODE form's s: Ψ (slip law) or ln Ψ (aging, Nagata law); arrays welcome."""
    return np.log(psi) if check_law_code(law_code) in LOG_STATE_LAWS else psi


def psi_of_s(law_code: int, s):
    """Ψ from the ODE form's s (inverse of :func:`s_of_psi`)."""
    return np.exp(s) if check_law_code(law_code) in LOG_STATE_LAWS else s


def psi_rate(law_code: int, psi, ds):
    """Ψ' from s' (the chain rule of :func:`s_of_psi`)."""
    return psi * ds if check_law_code(law_code) in LOG_STATE_LAWS else ds


# --- the force balance ------------------------------------------------------------------------
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def slip_rate_rate(q, h, u, s, w, ds):
    """u' at (h, u, s), w = e^u, s' = ``ds``: the force balance with mass, or its derivative
    without (module docstring)."""
    if q[Q_QS] != 0.0:
        return (q[Q_C] * (q[Q_E] - w) - q[Q_BETA] * ds) / (1.0 + q[Q_G] * w)
    return (q[Q_C] * h - q[Q_D] * (u + q[Q_BETA] * s)) / w - q[Q_G]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def peak_function(q, z):
    """A function with the sign of u' (zero at a peak of the slip rate): w u' with mass,
    (1 + R w) u' without. With mass and no damping it is C h − D η, the same operations as
    before damping existed (so the same values to the bit)."""
    h, u, s = z[0], z[1], z[2]
    if q[Q_QS] != 0.0:
        w = np.exp(u)
        return q[Q_C] * (q[Q_E] - w) - q[Q_BETA] * state_rate(q, u, s, w)
    g = q[Q_C] * h - q[Q_D] * (u + q[Q_BETA] * s)
    if q[Q_G] != 0.0:
        g -= q[Q_G] * np.exp(u)
    return g


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def ode_rhs(q, z, out):
    """Write dz/dτ into ``out``."""
    h, u, s = z[0], z[1], z[2]
    w = np.exp(u)
    ds = state_rate(q, u, s, w)
    out[0] = q[Q_E] - w
    out[1] = slip_rate_rate(q, h, u, s, w, ds)
    out[2] = ds


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def ode_jacobian(q, z, jac):
    """Write ∂(dz/dτ)/∂z into the 3×3 ``jac``."""
    h, u, s = z[0], z[1], z[2]
    beta, c = q[Q_BETA], q[Q_C]
    w = np.exp(u)
    dfs_du, dfs_ds = state_rate_partials(q, u, s, w)
    jac[0, 0], jac[0, 1], jac[0, 2] = 0.0, -w, 0.0
    if q[Q_QS] != 0.0:
        ds = state_rate(q, u, s, w)
        inv = 1.0 / (1.0 + q[Q_G] * w)
        num = c * (q[Q_E] - w) - beta * ds
        jac[1, 0] = 0.0
        jac[1, 1] = (-c * w - beta * dfs_du) * inv - num * q[Q_G] * w * inv * inv
        jac[1, 2] = -beta * dfs_ds * inv
    else:
        d = q[Q_D]
        inv_w = 1.0 / w
        fu = (c * h - d * (u + beta * s)) * inv_w
        jac[1, 0], jac[1, 1], jac[1, 2] = c * inv_w, -d * inv_w - fu, -d * beta * inv_w
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


def _tier(rhs_tier: str) -> str:
    if rhs_tier not in ("numba", "python"):
        raise ValueError(f"rhs_tier must be 'numba' or 'python', got {rhs_tier!r}")
    return rhs_tier


class OdeForm:
    """Python callables ``f(τ, z)`` and ``jac(τ, z)`` of the ODE form at loading E = ``e``.

    ``rhs_tier`` picks the implementation: ``"numba"`` (the compiled functions above) or
    ``"python"`` (plain numpy, what a user would write).
    """

    def __init__(self, nd, e: float, rhs_tier: str = "numba"):
        self.tier = _tier(rhs_tier)
        self.q = form_vector(nd, e)
        self._f = ode_rhs if rhs_tier == "numba" else ode_rhs.py_func
        self._jac = ode_jacobian if rhs_tier == "numba" else ode_jacobian.py_func

    def f(self, tau, z):
        out = np.empty(3)
        self._f(self.q, z, out)
        return out

    def jac(self, tau, z):
        out = np.empty((3, 3))
        self._jac(self.q, z, out)
        return out


# --- the DAE form (IDA and other DAE solvers) -----------------------------------------------
#
# y = (h, u, s, η): the ODE state plus the friction η = (Ft − F0)/A, with the slip rate u = ln w
# an algebraic variable tied by the friction law. With mass, η is differential:
#
#     0 = h' − (E − e^u)
#     0 = u − (η − β s)                               (the constraint; ∂/∂u = 1: index 1)
#     0 = s' − f_s(u, s)
#     0 = η' − [u'(h, u, s) + β f_s(u, s)]            (Eq. 26/60 with ln w = u)
#
# Without mass (quasi-static) the force balance itself is the last equation, algebraic in η:
#
#     0 = K h − η − R e^u                             (Fs = Ft + ηr v; with the constraint, index 1)
#
# so that v, Ft and θ are tied exactly as in SPEC §1. :func:`dae_differential` marks the
# differential components (IDA's ``id`` vector).

#: the differential components of the DAE with mass (IDA's ``id``)
DAE_DIFFERENTIAL = np.array([1.0, 0.0, 1.0, 1.0])
_DAE_DIFFERENTIAL_QS = np.array([1.0, 0.0, 1.0, 0.0])


def dae_differential(nd) -> np.ndarray:
    """IDA's ``id`` vector of the DAE form of ``nd``: 1.0 for a differential component."""
    return (_DAE_DIFFERENTIAL_QS if nd.quasi_static else DAE_DIFFERENTIAL).copy()


@njit(cache=True, error_model="numpy")
def dae_residual(q, y, yp, out):
    """Write F(y, y') of the DAE form into ``out`` (length 4)."""
    h, u, s, eta = y[0], y[1], y[2], y[3]
    beta = q[Q_BETA]
    w = np.exp(u)
    fs = state_rate(q, u, s, w)
    out[0] = yp[0] - (q[Q_E] - w)
    out[1] = u - (eta - beta * s)
    out[2] = yp[2] - fs
    if q[Q_QS] != 0.0:
        out[3] = q[Q_C] * h - eta - q[Q_G] * w
    else:
        out[3] = yp[3] - ((q[Q_C] * h - q[Q_D] * eta) / w - q[Q_G] + beta * fs)


@njit(cache=True, error_model="numpy")
def dae_jacobian(q, y, cj, jac):
    """Write ∂F/∂y + cj ∂F/∂y' into the 4×4 ``jac`` (IDA's iteration matrix)."""
    h, u, s, eta = y[0], y[1], y[2], y[3]
    beta, c = q[Q_BETA], q[Q_C]
    w = np.exp(u)
    dfs_du, dfs_ds = state_rate_partials(q, u, s, w)
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
    if q[Q_QS] != 0.0:
        jac[3, 0] = c
        jac[3, 1] = -q[Q_G] * w
        jac[3, 3] = -1.0
    else:
        d = q[Q_D]
        feta = (c * h - d * eta) / w
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
    ode_rhs(form_vector(nd, e), np.asarray(z0, dtype=float), f)
    # η' = u' + β s' along the constraint; u' is the ODE's
    yp0 = np.array([f[0], f[1], f[2], f[1] + nd.beta * f[2]])
    return y0, yp0


class DaeForm:
    """Python callables of the DAE form at loading E = ``e``, in the ``rhs_tier`` of
    :class:`OdeForm` (``"numba"`` or ``"python"``)."""

    def __init__(self, nd, e: float, rhs_tier: str = "numba"):
        _tier(rhs_tier)
        self.q = form_vector(nd, e)
        self._res = dae_residual if rhs_tier == "numba" else dae_residual.py_func
        self._jac = dae_jacobian if rhs_tier == "numba" else dae_jacobian.py_func

    def residual(self, tau, y, yp, out):
        self._res(self.q, y, yp, out)

    def jacobian(self, tau, y, cj, out):
        self._jac(self.q, y, cj, out)
