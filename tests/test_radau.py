"""RadauIIA5 (integrators/own/radau5.py): its constants, its collocation dense output, its
Newton iteration's failures and counters. Its order and accuracy are checked beside the
Rosenbrock methods (tests/test_rosenbrock.py)."""

import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import integrators as I
import problems as P
from integrators.own import radau5
from problems.formulations import OdeForm, to_ode_state


def test_constants():
    """A is Radau IIA's (row sums c, the collocation conditions A c^(k−1) = c^k / k for k ≤ 3,
    b = the last row: stiffly accurate), T is a real eigenbasis of A⁻¹ with the block form the
    Newton iteration assumes, and the error weights are RADAU5's (Hairer's DD1–DD3,
    ``radau5.f``: −(13 + 7√6)/3, (−13 + 7√6)/3, −1/3); μ and α ± iβ are the eigenvalues of A⁻¹
    (3 + 3^(2/3) − 3^(1/3) and 3 + (3^(1/3) − 3^(2/3))/2 ± i (3^(5/6) + 3^(7/6))/2, Hairer &
    Wanner IV.8, as scipy's radau.py writes them)."""
    a, c, e, t, ti, mu, alpha, beta = radau5.radau_constants()
    for k in (1, 2, 3):
        np.testing.assert_allclose(a @ c ** (k - 1), c ** k / k, rtol=1e-14)
    block = ti @ np.linalg.inv(a) @ t
    np.testing.assert_allclose(block, [[mu, 0, 0], [0, alpha, beta], [0, -beta, alpha]],
                               atol=1e-12)
    np.testing.assert_allclose(t @ ti, np.eye(3), atol=1e-14)
    assert mu == pytest.approx(3 + 3 ** (2 / 3) - 3 ** (1 / 3), rel=1e-14)
    assert alpha == pytest.approx(3 + 0.5 * (3 ** (1 / 3) - 3 ** (2 / 3)), rel=1e-14)
    assert beta == pytest.approx(0.5 * (3 ** (5 / 6) + 3 ** (7 / 6)), rel=1e-14)
    s6 = np.sqrt(6.0)
    np.testing.assert_allclose(e, [-(13 + 7 * s6) / 3, (-13 + 7 * s6) / 3, -1 / 3], rtol=1e-15)


@pytest.mark.slow                   # 6 s (two scipy Radau runs at 1e−12, 1e−13): make test-slow
def test_dense_output_is_the_collocation_polynomial():
    """Saved points between steps come from the collocation polynomial (order 3 inside a step,
    exact at its nodes): on the paper example at rtol = atol = 1e−10, 400 save points agree
    with scipy's Radau at 1e−12 (its dense output of ~ its own steps checked by a second run at
    1e−13) to 1e−8 in v relative (measured 3e−9); the saved grid does not change the steps."""
    problem = P.paper_example(t_end=2.0)
    method = I.RadauIIA5(rtol=1e-10, atol=1e-10)
    saved = I.solve(problem, method, max_points=400)
    bare = I.solve(problem, method, max_points=2)
    assert saved.success and saved.stats.steps == bare.stats.steps
    nd = problem.nondimensional()
    form = OdeForm(nd, nd.e_slow)
    z0 = to_ode_state(nd.law_code, nd.beta, nd.x0)
    tau = saved.t / nd.time_scale
    ref = [solve_ivp(form.f, (0.0, tau[-1]), z0, method="Radau", jac=form.jac, t_eval=tau,
                     rtol=tol, atol=tol).y for tol in (1e-12, 1e-13)]
    assert np.abs(ref[0][1] - ref[1][1]).max() < 1e-9
    v_ref = problem.law.v0 * np.exp(ref[1][1])
    np.testing.assert_allclose(saved.v, v_ref, rtol=1e-8)


def test_counters():
    """One Jacobian per step; at least 3 f per attempt (one Newton iteration), at most
    3·NEWTON_MAXITER + 1, plus one per accepted step and 2 per start (W2 with its two-speed
    restarts, rtol 1e−5: rejected steps included)."""
    sol = I.solve(P.window("W2", "slip", t_end=0.05), I.RadauIIA5(rtol=1e-5, atol=1e-5),
                  max_points=2)
    s, starts = sol.stats, sol.meta["starts"]
    assert sol.success and starts >= 2 and s.rejected > 0
    newton = s.nfev - s.steps - 2 * starts
    attempts = s.steps + s.rejected
    assert 3 * attempts <= newton <= (3 * radau5.NEWTON_MAXITER + 1) * attempts
    assert s.njev == s.steps


@pytest.mark.slow                      # several seconds: make test-slow
def test_newton_failure_halves_the_step():
    """One attempt, called directly: from the paper example's start a step of 10⁻⁴ τ passes,
    one of 1 τ (the inertial period is ~0.02 τ) cannot converge and reports NEWTON_FAIL after
    at most NEWTON_MAXITER iterations (3 f each, counted in p[MORE_F]); the RODAS controller
    turns that into a halving."""
    from integrators.own import engine as E
    method = I.RadauIIA5(rtol=1e-8, atol=1e-8)
    nd = P.paper_example().nondimensional()
    _, p, Z, _ = E.new_state(nd, method.rtol, method.atol, method.constants, 10, np.inf)
    z0, f0 = Z[E.ZROW["ZC"]].copy(), np.empty(3)
    E.rhs(p, z0, f0)
    z1, f1, D = np.empty(3), np.empty(3), np.empty((3, 3))
    outcome = {}
    for hs in (1e-4, 1.0):
        ws = radau5._workspace()
        E.prepare_jacobian(p, z0, f0, ws)
        p[E.P_MORE_F] = 0.0
        outcome[hs] = radau5._attempt(p, hs, ws, z0, f0, z1, f1, D), p[E.P_MORE_F]
    assert outcome[1e-4][0] < 1.0 and outcome[1e-4][1] >= 3
    assert outcome[1.0][0] == radau5.NEWTON_FAIL
    assert 3 <= outcome[1.0][1] <= 3 * radau5.NEWTON_MAXITER
    q = np.zeros(E.P["Q"] + 1)
    q[E.P["Q"]] = 4.0
    assert E.rodas_reject(q, radau5.NEWTON_FAIL, 1.0) == pytest.approx(0.5)


def test_batch_matches_solve():
    """The batch entry point runs the same kernel: a point of a batch reports the events of
    the single solve (W2/slip, 40 s)."""
    problem = P.window("W2", "slip")
    method = I.RadauIIA5(rtol=1e-6, atol=1e-6)
    single = I.solve(problem, method, max_points=2)
    from integrators.own import batch as B
    rows = method.solve_batch([problem, dataclasses.replace(problem)], parallel=False)
    assert single.success
    assert (rows[:, B.R["N_EVENTS"]] == len(single.events)).all()
