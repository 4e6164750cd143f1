"""Problem definitions: validation, presets against the paper's tables, the two RHS forms."""

import dataclasses
import math

import numpy as np
import pytest

import problems as P
from problems.presets import NORMAL_STRESS, POISSON_RATIO, SHEAR_MODULUS


def _slider(**changes):
    base = dict(mass=1.1e3, stiffness=1.48e8, normal_force=0.9975e6,
                law=P.SlipLaw(a=0.008, b=0.0092, lc=0.5e-6),
                loading=P.ConstantLoading(1e-4),
                initial=P.InitialState(v=1e-4, theta=1.0, fs=6e5), t_end=1.0)
    base.update(changes)
    return P.SpringSlider(**base)


@pytest.mark.parametrize("make, name, value", [
    (lambda: _slider(mass=0.0), "mass", "0.0"),
    (lambda: _slider(mass=-1.0), "mass", "-1.0"),
    (lambda: _slider(stiffness=-5.0), "stiffness", "-5.0"),
    (lambda: _slider(normal_force=0.0), "normal_force", "0.0"),
    (lambda: _slider(t_end=0.0), "t_end", "0.0"),
    (lambda: _slider(t_end=float("inf")), "t_end", "inf"),
    (lambda: _slider(mass=float("nan")), "mass", "nan"),
    (lambda: P.SlipLaw(a=0.008, b=0.0092, lc=0.0), "lc", "0.0"),
    (lambda: P.SlipLaw(a=-0.008, b=0.0092, lc=1e-6), "a", "-0.008"),
    (lambda: P.AgingLaw(a=0.008, b=float("nan"), lc=1e-6), "b", "nan"),
    (lambda: P.NagataLaw(a=0.008, b=-0.001, lc=1e-6), "b", "-0.001"),
    (lambda: P.AgingLaw(a=0.008, b=0.01, lc=1e-6, v0=0.0), "v0", "0.0"),
    (lambda: P.ConstantLoading(0.0), "vl", "0.0"),
    (lambda: P.TwoSpeedLoading(vls=-1e-4, vlf=1e-3, df=0.04), "vls", "-0.0001"),
    (lambda: P.TwoSpeedLoading(vls=1e-4, vlf=0.0, df=0.04), "vlf", "0.0"),
    (lambda: P.TwoSpeedLoading(vls=1e-4, vlf=1e-3, df=-0.1), "df", "-0.1"),
    (lambda: P.InitialState(v=0.0, theta=1.0, fs=1.0), "initial slip rate v", "0.0"),
    (lambda: P.InitialState(v=-1e-5, theta=1.0, fs=1.0), "initial slip rate v", "-1e-05"),
    (lambda: P.InitialState(v=1e-5, theta=float("nan"), fs=1.0), "initial theta", "nan"),
    (lambda: _slider(law=P.AgingLaw(a=0.008, b=0.01, lc=1e-6),
                     initial=P.InitialState(v=1e-4, theta=-1.0, fs=6e5)), "initial theta", "-1.0"),
    # issue 29: impossible values, refused at construction (they ran, or failed mid-solve)
    (lambda: _slider(mu0=-0.1), "mu0", "-0.1"),
    (lambda: _slider(mu0=1e300), "mu0", "1e+300"),
    (lambda: P.SlipLaw(a=1.0, b=0.0092, lc=1e-6), "a", "1"),
    (lambda: P.AgingLaw(a=0.008, b=2.0, lc=1e-6), "b", "2"),
    (lambda: _slider(law=P.SlipLaw(a=0.008, b=0.0, lc=0.5e-6)), "theta", "b = 0"),
])
def test_bad_input_names_parameter_and_value(make, name, value):
    with pytest.raises(ValueError) as err:
        make()
    assert name in str(err.value) and value in str(err.value)


def test_b_zero_is_allowed():
    assert P.AgingLaw(a=0.008, b=0.0, lc=1e-6).b == 0.0


def test_problem_is_frozen_and_hashable():
    p = P.paper_example()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.mass = 2.0
    assert hash(p) == hash(P.paper_example())
    assert p.with_law(b=0.0094).law.b == 0.0094 and p.law.b == 0.0092


def test_paper_example_nondimensional_numbers():
    # SPEC §2: D ≈ 3.6e4 and C ≈ 336 for Lc = 0.5 µm (with k = 1.48e8 N/m)
    nd = P.paper_example().nondimensional()
    assert nd.d == pytest.approx(3.6273e4, rel=1e-4)
    assert nd.c == pytest.approx(336.36, rel=1e-4)
    assert nd.beta == pytest.approx(0.0092 / 0.008)
    assert nd.e_slow == pytest.approx(10.0)


def test_kappa_across_b_equal_a():
    # a sweep crosses b = a (W1's grid: a = 0.008): κ is negative below, infinite at, positive
    # above; before, b = a raised ZeroDivisionError and the point became a failed row
    p = P.window("W1", "slip")
    a = p.law.a
    assert p.with_law(b=a - 1e-4).kappa < 0 < p.with_law(b=a + 1e-4).kappa
    assert p.with_law(b=a).kappa == math.inf


@pytest.mark.parametrize("name", ["W1", "W2", "W3", "W4"])
def test_windows_reproduce_table3_kappa(name):
    w = P.WINDOWS[name]
    assert P.window(name, "slip").kappa == pytest.approx(w.kappa_slip, rel=0.02)
    aging = P.window(name, "aging")
    assert aging.kappa == pytest.approx(w.kappa_aging, rel=1e-9)
    # the aging fit must also give the Discussion's nucleation length Lb = G Lc/((1 − ν) b σn)
    lb = SHEAR_MODULUS * aging.law.lc / ((1 - POISSON_RATIO) * aging.law.b * NORMAL_STRESS)
    assert lb == pytest.approx(w.nucleation_length, rel=1e-9)
    assert aging.law.a < aging.law.b < w.slip_b     # the paper: aging-law b is smaller


def test_window_overrides_and_unknown_name():
    p = P.window("W2", "aging", b=0.01, lc=1e-6)
    assert (p.law.b, p.law.lc) == (0.01, 1e-6)
    assert isinstance(p.loading, P.TwoSpeedLoading) and p.loading.vlf == pytest.approx(1.9717e-3)
    with pytest.raises(ValueError, match="W5"):
        P.window("W5")


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_steady_state_of_the_law(law):
    f = P.law_from_name(law, a=0.008, b=0.0092, lc=0.5e-6, v0=1e-5)
    fn, v = 1e6, 3e-4
    theta = f.steady_state(v, fn)
    assert f.state_rate(v, theta, fn) == pytest.approx(0.0, abs=1e-12)
    assert f.friction(v, theta, fn, 0.6 * fn) == pytest.approx(f.steady_friction(v, fn, 0.6 * fn), rel=1e-14)
    # the constraint inverts the friction law
    assert f.slip_rate(f.friction(v, theta, fn, 0.0), theta, fn, 0.0) == pytest.approx(v, rel=1e-12)


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_nondimensional_rhs_is_the_dimensional_one(law):
    """Chain rule: d/dt of (h, η, Ψ) computed from the dimensional RHS equals the
    nondimensional RHS times dτ/dt."""
    p = P.window("W2", law)
    p = dataclasses.replace(p, initial=P.InitialState(v=3e-4, theta=p.initial_state.theta * 1.3,
                                                      fs=p.initial_state.fs + 200.0))
    nd = p.nondimensional()
    v, fs, theta = p.initial_state.v, p.initial_state.fs, p.initial_state.theta
    dv, dfs, dth = p.rhs(0.0, [v, fs, theta])
    fn, A = p.normal_force, p.law.a * p.normal_force
    dft = A * dv / v + (dth if law == "slip" else p.law.b * fn * dth / theta)
    dpsi = dth / (p.law.b * fn) if law == "slip" else p.law.v0 * dth / p.law.lc
    expected = np.array([dfs / nd.force_h, dft / A, dpsi]) * nd.time_scale
    got = p.rhs_nondimensional(0.0, nd.x0)
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    # and w = exp(η − βΨ) recovers v
    assert p.slip_rate_from_nondimensional(nd.x0[1], nd.x0[2]) == pytest.approx(v, rel=1e-12)


def test_critical_stiffness_and_frequency_formulas():
    p = P.paper_example()
    kcr = P.critical_stiffness(p)
    law, fn, m, v = p.law, p.normal_force, p.mass, 1e-4
    assert kcr == pytest.approx(fn * (law.b - law.a) / law.lc * (1 + m * v * v / (law.a * fn * law.lc)))
    # at k = kcr the characteristic polynomial has a purely imaginary pair at ±iω
    roots = P.characteristic_roots(dataclasses.replace(p, stiffness=kcr))
    osc = roots[np.abs(roots.imag) > 0]
    assert np.abs(osc.real).max() < 1e-9 * np.abs(osc.imag).max()
    assert np.abs(osc.imag).max() == pytest.approx(P.neutral_frequency(p), rel=1e-10)
    assert P.neutral_frequency(p) == pytest.approx(v / law.lc * math.sqrt((law.b - law.a) / law.a))


def test_unknown_law_code_fails_loudly_at_every_entry_point():
    """A law the compiled forms do not know is never run with another law's formulas: the
    problem refuses its class (a subclass included), the Python helpers refuse its code, and
    the compiled functions give NaN, which a solve reports as a failure."""
    from integrators.core.events import root_derivatives
    from integrators.own import engine
    from integrators.own.etd_kernel import coefficients
    from problems import formulations as F
    from problems.friction import AgingLaw, SlipLaw, compiled_law_code

    class NewLaw(AgingLaw):
        code = 3

    class SlipLawVariant(SlipLaw):          # same code, other class: its formulas may differ
        pass

    base = P.paper_example("aging")
    for law in (NewLaw(a=base.law.a, b=base.law.b, lc=base.law.lc),
                SlipLawVariant(a=base.law.a, b=base.law.b, lc=base.law.lc)):
        with pytest.raises(ValueError, match="has no compiled form"):
            dataclasses.replace(base, law=law)
        with pytest.raises(ValueError, match="has no compiled form"):
            compiled_law_code(law)
    nd = base.nondimensional()._replace(law_code=3)
    z, out, jac = np.array([0.1, -2.0, 3.0]), np.empty(3), np.empty((3, 3))
    for call in (lambda: F.check_law_code(3), lambda: F.check_law_code(True),
                 lambda: F.check_law_code(1.5), lambda: F.form_vector(nd, nd.e_slow),
                 lambda: F.to_ode_state(3, nd.beta, nd.x0), lambda: F.from_ode_state(3, 1.0, z),
                 lambda: F.s_of_psi(3, 1.0), lambda: root_derivatives(nd, nd.e_slow, z),
                 lambda: engine.new_state(nd, 1e-6, 1e-6, {}, 10, np.inf)):
        with pytest.raises(ValueError, match="unknown friction-law code"):
            call()
    q = F.form_vector(base.nondimensional(), nd.e_slow)
    q[F.Q_LAW] = 3.0                          # as compiled code would see an unknown code
    F.ode_rhs(q, z, out)
    F.ode_jacobian(q, z, jac)
    assert np.isnan(out[2]) and np.isnan(jac[2, 1:]).all() and np.isfinite(out[:2]).all()
    res = np.empty(4)
    F.dae_residual(q, np.append(z, 0.0), np.zeros(4), res)
    assert np.isnan(res[2])
    assert np.isnan(coefficients(q, 0.1, 0.5, 1.0)).all()


@pytest.mark.parametrize("make, match", [
    (lambda: P.velocity_step_test("aging", c=2.0), "'c' is not a parameter of the aging law"),
    (lambda: P.law_from_name("slip", a=0.008, b=0.01, lc=1e-6, Lc=1e-6), "'Lc' is not a param"),
    (lambda: P.slide_hold_slide_test(holds=3), "holds must be a sequence"),
    (lambda: P.load_problem(3), "the problem file must be a path"),
])
def test_misuse_is_a_value_error_not_a_type_error(make, match):
    """Issue 29: these raised TypeError (a traceback on the command line)."""
    with pytest.raises(ValueError, match=match):
        make()
