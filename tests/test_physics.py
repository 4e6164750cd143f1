"""Physics facts of SPEC §7, checked with the paper's ETD2 (both laws)."""

import dataclasses

import numpy as np
import pytest

import integrators as I
import problems as P

V = 1e-4   # loading speed of the paper example (m/s)


def _near_steady(law: str, k_factor: float, dv: float, t_end: float):
    """The paper example with k = k_factor·kcr, started at steady sliding with v = (1 + dv)·vL."""
    base = P.paper_example(law=law)
    init = P.steady_initial_state(base.law, base.normal_force, base.mu0, V, v=V * (1 + dv))
    return dataclasses.replace(base, stiffness=k_factor * P.critical_stiffness(base),
                               initial=init, t_end=t_end)


def _oscillation(sol):
    """Peak times and amplitudes of ln(v/vL), and the period from upward zero crossings."""
    x = np.log(sol.v / V)
    i = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:]) & (x[1:-1] > 0)) + 1
    up = sol.t[1:][(x[:-1] < 0) & (x[1:] >= 0)]
    return sol.t[i], x[i], np.diff(up).mean()


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_steady_sliding_is_a_fixed_point(law):
    p = _near_steady(law, k_factor=2.0, dv=0.0, t_end=2.0)
    sol = I.solve(p, I.ETD2())
    assert sol.success
    np.testing.assert_allclose(sol.v, V, rtol=1e-10)
    np.testing.assert_allclose(sol.fs, p.initial_state.fs, rtol=1e-12)
    assert len(sol.events) == 0


@pytest.mark.parametrize("law", ["slip", "aging"])
@pytest.mark.parametrize("k_factor", [0.95, 1.05])
def test_growth_rate_near_critical_stiffness_matches_linear_theory(law, k_factor):
    """Slightly below kcr small oscillations grow, slightly above they decay, at the rate Re s of
    the characteristic polynomial (SPEC §7)."""
    p = _near_steady(law, k_factor, dv=0.01, t_end=1.5)
    sol = I.solve(p, I.ETD2(dtau_max=1e-3), max_points=30_001)
    t_peak, amp, _ = _oscillation(sol)
    keep = t_peak > 0.1                      # after the fast initial layer
    rate = np.polyfit(t_peak[keep], np.log(amp[keep]), 1)[0]
    roots = P.characteristic_roots(p)
    theory = roots[np.abs(roots.imag) > 0].real.max()
    assert np.sign(rate) == np.sign(theory) == (1 if k_factor < 1 else -1)
    assert rate == pytest.approx(theory, rel=0.1)


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_stick_slip_grows_below_critical_stiffness(law):
    p = _near_steady(law, k_factor=0.5, dv=0.01, t_end=3.0)
    sol = I.solve(p, I.ETD2())
    assert sol.success and len(sol.events) >= 1


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_neutral_oscillation_frequency(law):
    p = _near_steady(law, k_factor=1.0, dv=0.01, t_end=1.0)
    sol = I.solve(p, I.ETD2(dtau_max=1e-3), max_points=20_001)
    *_, period = _oscillation(sol)
    assert 2 * np.pi / period == pytest.approx(P.neutral_frequency(p), rel=0.02)
