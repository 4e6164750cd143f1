"""The shared ODE and DAE forms: analytic Jacobians against finite differences, consistency of the
DAE's initial conditions, and agreement of the Python and numba right-hand-side tiers."""

import numpy as np
import pytest

import problems as P
from problems.formulations import (DAE_DIFFERENTIAL, DaeForm, OdeForm, dae_initial,
                                   from_ode_state, to_ode_state)

# states along a stick–slip cycle: stick (w ≪ 1), loading speed, mid-event, near the peak
STATES = [(-40.0, -6.0, 5.0), (-30.0, 2.3, -2.3), (-60.0, 7.5, -4.0), (-80.0, 8.5, -8.4)]


def _nd(law):
    return P.window("W2", law).nondimensional()


def _aging_state(z):
    # for the aging law s = ln Ψ; steady state has Ψ = 1/w, i.e. s ≈ −u
    return (z[0], z[1], -z[2] if z[2] < 0 else -z[1] + 0.5)



@pytest.mark.parametrize("law", ["slip", "aging"])
@pytest.mark.parametrize("tier", ["numba", "python"])
@pytest.mark.parametrize("state", STATES)
def test_ode_jacobian_matches_finite_differences(law, tier, state, fd_jacobian):
    nd = _nd(law)
    z = np.array(state if law == "slip" else _aging_state(state), dtype=float)
    form = OdeForm(nd, nd.e_fast, tier)
    np.testing.assert_allclose(form.jac(0.0, z), fd_jacobian(lambda x: form.f(0.0, x), z),
                               rtol=1e-6, atol=1e-6 * np.abs(form.jac(0.0, z)).max())


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_ode_form_is_the_nondimensional_system(law):
    """(h, u, s)' from the ODE form equals the chain rule applied to (h, η, Ψ)' of SPEC §2."""
    p = P.window("W2", law)
    nd = p.nondimensional()
    x = nd.x0 * np.array([1.1, 0.9, 1.2])      # off force balance, so that every rate is nonzero
    z = to_ode_state(nd.law_code, nd.beta, x)
    h, eta, psi = from_ode_state(nd.law_code, nd.beta, z)
    np.testing.assert_allclose([h, eta, psi], x, rtol=1e-14)
    dh, deta, dpsi = p.rhs_nondimensional(0.0, x)
    ds = dpsi if law == "slip" else dpsi / psi
    du = deta - nd.beta * ds
    np.testing.assert_allclose(OdeForm(nd, nd.e_slow).f(0.0, z), [dh, du, ds], rtol=1e-10)


@pytest.mark.parametrize("law", ["slip", "aging"])
@pytest.mark.parametrize("tier", ["numba", "python"])
def test_dae_initial_conditions_are_consistent_and_match_the_ode(law, tier):
    nd = _nd(law)
    z0 = to_ode_state(nd.law_code, nd.beta, nd.x0)
    y0, yp0 = dae_initial(nd, nd.e_slow, z0)
    res = np.empty(4)
    DaeForm(nd, nd.e_slow, tier).residual(0.0, y0, yp0, res)
    np.testing.assert_allclose(res, 0.0, atol=1e-9 * np.abs(yp0).max())
    # the algebraic variable is u = ln w, its derivative is implied, not free
    assert DAE_DIFFERENTIAL.tolist() == [1.0, 0.0, 1.0, 1.0]
    np.testing.assert_allclose(yp0[:3], OdeForm(nd, nd.e_slow).f(0.0, z0), rtol=1e-14)


@pytest.mark.parametrize("law", ["slip", "aging"])
@pytest.mark.parametrize("state", STATES)
def test_dae_iteration_matrix_matches_finite_differences(law, state, fd_jacobian):
    nd = _nd(law)
    z = np.array(state if law == "slip" else _aging_state(state), dtype=float)
    y = np.array([z[0], z[1], z[2], z[1] + nd.beta * z[2] + 0.3])   # off the constraint too
    yp = np.array([0.1, -0.2, 0.3, 0.4])
    form, cj = DaeForm(nd, nd.e_fast), 37.0

    def residual(y_, yp_):
        out = np.empty(4)
        form.residual(0.0, y_, yp_, out)
        return out

    jac = np.empty((4, 4))
    form.jacobian(0.0, y, cj, jac)
    fd = fd_jacobian(lambda x: residual(x, yp), y) + cj * fd_jacobian(lambda x: residual(y, x), yp)
    np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-6 * np.abs(jac).max())


def test_rhs_tier_is_validated():
    nd = _nd("slip")
    with pytest.raises(ValueError, match="rhs_tier"):
        OdeForm(nd, 1.0, "fortran")
    with pytest.raises(ValueError, match="rhs_tier"):
        DaeForm(nd, 1.0, "C")
