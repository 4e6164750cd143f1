"""Exponential Rosenbrock exprb32/exprb43 (integrators/own/exprb32.py, exprb43.py, phi.py): φ-functions against
scipy's expm, observed order with fixed steps on a stiff segment, agreement with the reference
on the paper example and W2, located event times, counters; and the measurement behind "Why not
an error-controlled ETD" (docs/own-methods.md)."""

import math

import numpy as np
import pytest
import scipy.linalg as sl
from scipy.integrate import solve_ivp

import integrators as I
import problems as P
from benchmarks.devtools.convergence import observed_order
from benchmarks.devtools.errors import errors
from benchmarks.devtools.reference import reference
from integrators.own import phi as X
from integrators.own.etd_kernel import etd_step
from problems.formulations import form_vector
from problems.formulations import OdeForm, to_ode_state

METHODS = [I.Exprb32, I.Exprb43]


def _fixed(cls, nd, z0, span, n):
    """``n`` fixed steps of ``cls`` over ``span`` (τ) from z0, no error control."""
    return cls(rtol=0.5, atol=0.5).fixed_steps(nd, z0, span, n)   # tolerances unused


def _stick_state(nd, tau):
    """z at τ from z0 by 400 exprb43 steps per unit τ (fixed steps; the stick phase before the
    first event: its error, ~1e−11, does not matter to a test that starts from it)."""
    z0 = to_ode_state(nd.law_code, nd.beta, nd.x0)
    return _fixed(I.Exprb43, nd, z0, tau, int(400 * tau))


def _phis_expm(a, kmax):
    """φ_0..φ_kmax(a) column by column from expm of the augmented matrix [[a, e_j, 0], [0, N]]
    with N the nilpotent shift (Al-Mohy & Higham 2011, Eq. 2.11; Saad 1992)."""
    out = np.zeros((kmax + 1, 3, 3))
    out[0] = sl.expm(a)
    m = np.zeros((3 + kmax, 3 + kmax))
    m[:3, :3] = a
    for i in range(kmax - 1):
        m[3 + i, 4 + i] = 1.0
    for col in range(3):
        m[:3, 3] = 0.0
        m[col, 3] = 1.0
        e = sl.expm(m)
        out[1:, :, col] = e[:3, 3:].T
    return out


def test_phi_functions_match_scipy_expm():
    """hJ along the paper example's first cycle (stick phase, event, slip; scipy Radau states,
    ~1.5 s) for h from 1e−4 to 10 in τ: hJ's stiff eigenvalue reaches −1e8. Both the block
    split (phi_functions) and plain scaling and squaring (phi_dense) against expm of the
    augmented matrix, relative to the largest entry of each φ_k: measured ≤ 5e−10 (split) and
    ≤ 4e−9 (dense); expm's own backward error, ~eps·‖hJ‖, is of that order."""
    nd = P.paper_example().nondimensional()
    form = OdeForm(nd, nd.e_slow)
    z0 = to_ode_state(nd.law_code, nd.beta, nd.x0)
    run = solve_ivp(form.f, (0, 60), z0, method="Radau", jac=form.jac, rtol=1e-8, atol=1e-8,
                    dense_output=True)
    peak = run.t[np.argmax(run.y[1])]
    taus = np.concatenate([np.linspace(0, 60, 25), peak + np.linspace(-0.05, 0.05, 9)])
    split_used = slip_seen = 0
    for tau in taus:
        z = run.sol(tau)
        slip_seen += math.exp(z[1]) > 10 * nd.e_slow
        for h in (1e-4, 1e-2, 1.0, 10.0):
            a = form.jac(0.0, z) * h
            want, want_half = _phis_expm(a, 4), _phis_expm(0.5 * a, 1)[1]
            for phi in (X.phi_functions, X.phi_dense):
                got, half = np.empty((5, 3, 3)), np.empty((3, 3))
                phi(a.copy(), 4, got, half)
                for k in range(5):
                    err = np.abs(got[k] - want[k]).max() / np.abs(want[k]).max()
                    assert err < 1e-8, (phi.__name__, tau, h, k, err)
                assert np.abs(half - want_half).max() / np.abs(want_half).max() < 1e-8
            split_used += a[1, 1] <= -64.0 and not np.isnan(X.stiff_eigenvalue(a))
    assert slip_seen >= 3 and split_used >= 40


@pytest.mark.parametrize("law", ["slip", "aging"])
@pytest.mark.parametrize("cls", [pytest.param(I.Exprb32, marks=pytest.mark.slow), I.Exprb43],
                         ids=lambda c: c.name)          # Exprb32's: 8 s, to make test-slow
def test_observed_order_with_fixed_steps_on_a_stiff_segment(cls, law):
    """Paper example, stick phase τ ∈ [5, 9] (hD/w from 1e5 to 1e7: stiff), 4 to 64 equal steps
    without error control: the error of z at τ = 9 against scipy Radau at rtol = atol = 1e−13
    (which agrees with 4096 exprb43 steps to 3e−13) falls at the declared order (measured 3.04
    and 4.06 for both laws: no order reduction, unlike the paper's ETD)."""
    nd = P.paper_example(law).nondimensional()
    z = _stick_state(nd, 5.0)
    form = OdeForm(nd, nd.e_slow)
    span = 4.0
    ref = solve_ivp(form.f, (0, span), z, method="Radau", jac=form.jac, rtol=1e-13,
                    atol=1e-13).y[:, -1]
    assert np.abs(_fixed(I.Exprb43, nd, z, span, 4096) - ref).max() < 1e-11
    ns = np.array([4, 8, 16, 32, 64] if cls.order == 3 else [4, 8, 16, 32])
    err = np.array([np.abs(_fixed(cls, nd, z, span, n) - ref).max() for n in ns])
    assert err.min() > 1e-10                   # far above the reference's own error
    assert observed_order(span / ns, err) == pytest.approx(cls.order, abs=0.15)


@pytest.mark.parametrize("problem", [P.paper_example(), P.window("W2"), P.window("W2", "aging")],
                         ids=lambda p: p.name)
@pytest.mark.parametrize("cls", METHODS, ids=lambda c: c.name)
def test_agrees_with_the_reference_at_tight_tolerance(cls, problem):
    """rtol = atol = 1e−8 against the cached two-solver reference (benchmarks.devtools.reference):
    recurrence interval and friction drop of the last complete event within 1e−6 (measured:
    exprb32 4e−8–1e−7, exprb43 1–2e−9), and that event's start and end times, located on the
    dense output, within 20·rtol relative (measured: exprb32 4e−8–1.2e−7, exprb43 2–4e−9)."""
    tol = 1e-8
    ref = reference(problem)
    sol = I.solve(problem, cls(rtol=tol, atol=tol), max_points=2)
    assert sol.success, sol.message
    e = errors(sol, ref)
    assert e["err_recurrence"] < 1e-6 and e["err_drop"] < 1e-6, e
    n = ref.event_index
    assert len(sol.events) == len(ref.events)
    for col in ("t_start", "t_end"):
        got, want = sol.events[col].iloc[n], ref.events[col].iloc[n]
        assert abs(got - want) / want < 20 * tol, (col, got, want)


@pytest.mark.parametrize("cls", METHODS, ids=lambda c: c.name)
def test_counters(cls):
    """nfev = (1 + s)·steps + s·rejected + 2·starts (s stage evaluations per attempt), one
    Jacobian per step, on W2 (50 ms) with its two-speed restart. Two saved points: a dense
    save grid would set every step (and leave no rejection to count)."""
    sol = I.solve(P.window("W2", "slip", t_end=0.05), cls(rtol=1e-7, atol=1e-7), max_points=2)
    s, stages, starts = sol.stats, 1 if cls.order == 3 else 2, sol.meta["starts"]
    assert sol.success and starts >= 2 and s.rejected > 0
    assert s.nfev == (1 + stages) * s.steps + stages * s.rejected + 2 * starts
    assert s.njev == s.steps


def test_why_not_an_error_controlled_etd():
    """The measurement behind docs/own-methods.md's "Why not an error-controlled ETD": one step
    of the paper's ETD from a stick-phase state of the paper example (τ = 10, w/D = 2.8e−6),
    errors in u = ln w against 64 exprb43 steps. The naive estimate ETD2 − ETD1 is O(h), not
    O(h²): it is ETD1's own one-step lag h·dηss/dτ (ratio ≈ 1), so a controller that treats it
    as O(h²) sets h ∝ tol. ETDIterated's error is the frozen-target floor (w/D)·dηss/dτ ≈ 2.6e−7,
    flat in h, and its embedded estimate ETDIterated − ETD2 (O(h²)) falls below that floor at
    h ≤ 4e−3: no difference of frozen-target steps sees it."""
    nd = P.paper_example().nondimensional()
    z = _stick_state(nd, 10.0)
    x = (z[0], z[1] + nd.beta * z[2], z[2])
    hs = np.array([1e-3, 2e-3, 4e-3, 8e-3, 1.6e-2])

    def u(h, n_iter):
        y = etd_step(form_vector(nd, nd.e_slow), *x, h, n_iter)
        return y[1] - nd.beta * y[2]

    exact = np.array([_fixed(I.Exprb43, nd, z, h, 64)[1] for h in hs])
    u1, u2, u3 = (np.array([u(h, k) for h in hs]) for k in (0, 1, 2))
    naive, embedded = np.abs(u2 - u1), np.abs(u3 - u2)
    assert observed_order(hs, naive) == pytest.approx(1.0, abs=0.05)
    np.testing.assert_allclose(naive / np.abs(u1 - exact), 1.0, atol=0.05)
    floor = np.abs(u3 - exact)
    assert observed_order(hs, floor) < 0.05 and np.all((floor > 1e-7) & (floor < 1e-6))
    assert observed_order(hs, embedded) == pytest.approx(2.0, abs=0.1)
    assert np.all(embedded[:3] < floor[:3] / 5)


@pytest.mark.parametrize("name", ["Exprb32", "Exprb43"])
def test_predictive_control_keeps_rejections_rare_where_the_step_must_shrink(name):
    """W2 aging at rtol = atol = 1e−4: nucleation and the fall of the slip rate need steps that
    shrink ~20 % per step, as the time scale shortens. With the elementary controller
    alone 22 % (Exprb32) and 29 % (Exprb43) of all attempts were rejected (1239 / 4389 steps,
    1097 / 2663); with Gustafsson's predictive step, 2–5 % (measured 104 / 4478, 132 / 2689)."""
    sol = I.solve(P.window("W2", "aging"), getattr(I, name)(rtol=1e-4, atol=1e-4), max_points=2)
    assert sol.success, sol.message
    s = sol.stats
    assert s.rejected < 0.08 * (s.steps + s.rejected), f"{s.rejected} rejected, {s.steps} steps"
