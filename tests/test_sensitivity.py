"""Forward sensitivities through the engine (integrators/own/sensitivity.py): the derivatives of
the events table, of the saved states and of the cycle's metrics against central differences
of tight solves, under both loadings and the three laws; the solve itself unchanged; misuse
refused before any work."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

from integrators import solve
from integrators.own.exprb43 import Exprb43
from integrators.own.radau5 import RadauIIA5
from integrators.own.rodas5p import Rodas5P
from problems.loading import TwoSpeedLoading
from problems.presets import fault_radiation_damping, paper_example, window
from problems.slider import InitialState, variant

TIGHT = Rodas5P(rtol=1e-12, atol=1e-12)


def _value(problem, name):
    for obj in (problem.law, problem, problem.loading):
        if hasattr(obj, name):
            return float(getattr(obj, name))
    raise KeyError(name)


def _central(problem, name, rel=1e-5, points=50):
    """The events table's central difference along ``name`` by solves at 1e-12 (its error:
    truncation ~rel² of the events' curvature, rounding ~1e-12/rel: ~1e-7 relative)."""
    value = _value(problem, name)
    step = rel * (abs(value) if value else 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ends = [solve(variant(problem, **{name: value + s}), TIGHT, max_points=points)
                for s in (step, -step)]
    return ends, step


def _worst_by_column(exact, central):
    return np.max(np.abs(exact - central), axis=0) / np.max(np.abs(central), axis=0)


CASES = {
    # (problem, parameters): the paper's example under constant loading, W2 under its
    # two-speed loading (the overshoot starts at an event's end: a moving switch), the Nagata
    # law with its c and radiation damping
    "paper-slip": (lambda: paper_example(law="slip", t_end=5.0),
                   ("b", "lc", "a", "stiffness", "mass", "normal_force", "vl")),
    "W2-aging": (lambda: variant(window("W2", law="aging"), t_end=8.0),
                 ("b", "lc", "stiffness", "vls", "vlf", "df")),
    "nagata-damped": (lambda: variant(paper_example(law="nagata", t_end=5.0),
                                      radiation_damping=fault_radiation_damping()),
                      ("b", "lc", "c", "radiation_damping")),
}


SENSITIVE = {"Rodas5P": Rodas5P, "RadauIIA5": RadauIIA5}


@pytest.mark.parametrize("method", sorted(SENSITIVE))
@pytest.mark.parametrize("case", sorted(CASES))
def test_event_derivatives_match_central_differences(case, method):
    """Every column of the events table, every event, every parameter: within 1e-6 of the
    column's scale at rtol 1e-10 with the sensitivities in the error test (3.5e-7 at most when
    this test was written for Rodas5P, with them at 1e-11: what the differences themselves
    resolve; the jump at the overshoot's start with its sign flipped was 0.5 off, the first
    event's largest h before it, h(0) not mirrored, 1.0 off)."""
    make, names = CASES[case]
    problem = make()
    sol = solve(problem, SENSITIVE[method](rtol=1e-10, atol=1e-10), sensitivity=names,
                max_points=50, sensitivity_error=True)
    assert sol.success and len(sol.event_array) >= 3
    for j, name in enumerate(names):
        (up, down), step = _central(problem, name)
        n = len(sol.event_array)
        assert len(up.event_array) == len(down.event_array) == n, name
        central = (up.event_array - down.event_array) / (2 * step)
        worst = _worst_by_column(sol.sensitivity.events[:, :, j], central)
        assert np.all(worst < 1e-6), (name, worst)


def test_the_two_methods_sensitivities_agree_at_a_tight_tolerance():
    """Rodas5P's (stages differentiated) and RadauIIA5's (collocation equations solved for the
    derivative), each error-controlled at 1e-12, on W4/aging (8 events): every column within
    1e-7 of its scale (5e-9 at most when written; before the recorder's extrema took the
    envelope's derivative, the last event's smallest h was 1.8e-6 off in RadauIIA5's, where
    a step end beat the located extremum by a rounding)."""
    from benchmarks.studies.gradients import cases
    problem = dict(cases())["W4/aging"]
    sols = [solve(problem, m(rtol=1e-12, atol=1e-12), sensitivity=("b", "lc"), max_points=2)
            for m in (Rodas5P, RadauIIA5)]
    assert len(sols[0].event_array) == len(sols[1].event_array) >= 6
    for j in range(2):
        worst = _worst_by_column(sols[1].sensitivity.events[:, :, j],
                                 sols[0].sensitivity.events[:, :, j])
        assert np.all(worst < 1e-7), (j, worst)


@pytest.mark.parametrize("method", sorted(SENSITIVE))
def test_saved_state_derivatives_match_central_differences(method):
    """∂(v, fs, θ)/∂θ at the saved times (fixed in seconds) against the same differences."""
    problem = paper_example(law="aging", t_end=3.0)
    names = ("b", "lc", "stiffness")
    sol = solve(problem, SENSITIVE[method](rtol=1e-10, atol=1e-10), sensitivity=names,
                max_points=30)
    for j, name in enumerate(names):
        (up, down), step = _central(problem, name, points=30)
        y = [np.column_stack((s.v, s.fs, s.theta)) for s in (up, down)]
        central = (y[0] - y[1]) / (2 * step)
        worst = _worst_by_column(sol.sensitivity.y[:, :, j], central)
        assert np.all(worst < 1e-5), (name, worst)


@pytest.mark.parametrize("method", sorted(SENSITIVE))
def test_the_sensitivities_change_nothing_of_the_solve(method):
    """The same steps, events and saved states to the bit with and without sensitivities, when
    they are kept out of the step control."""
    problem = window("W4", law="slip", t_end=4.0)
    alg = SENSITIVE[method](rtol=1e-7, atol=1e-7)
    plain = solve(problem, alg, max_points=100)
    sens = solve(problem, alg, max_points=100, sensitivity=("b", "lc"), sensitivity_error=False)
    assert np.array_equal(plain.event_array, sens.event_array)
    assert np.array_equal(plain.v, sens.v) and plain.stats.steps == sens.stats.steps
    assert plain.sensitivity is None and sens.sensitivity.events.shape == (
        len(plain.event_array), 8, 2)


def test_cycle_gradient_matches_differences_of_the_cycle():
    """The limit cycle's four metrics' gradient (means over the last period) against central
    differences of the cycle found at 1e-12 (W4, slip law, 12 s: ~25 events)."""
    from benchmarks.physics.metrics import METRICS, cycle_gradient, summarize
    problem = window("W4", law="slip", t_end=12.0)
    names = ("b", "lc")
    sol = solve(problem, Rodas5P(rtol=1e-10, atol=1e-10), sensitivity=names, max_points=2)
    grad = cycle_gradient(sol)
    assert grad, summarize(sol).reason
    for name in names:
        (up, down), step = _central(problem, name, rel=1e-6)
        cu, cd = summarize(up), summarize(down)
        for m in METRICS:
            central = (getattr(cu, m) - getattr(cd, m)) / (2 * step)
            assert abs(grad[m][name] - central) <= 1e-5 * abs(central), (name, m)


def test_partials_are_the_right_hand_sides_derivatives():
    """∂f/∂z, ∂f/∂θ, ∂²f/∂z∂z and ∂²f/∂z∂θ of the slider's ODE form against central differences
    of its right-hand side and Jacobian (problems/formulations.py), all three laws."""
    from integrators.own import sensitivity as se
    from problems.directions import direction
    from problems.formulations import N_Q, ode_jacobian, ode_rhs
    for law in ("slip", "aging", "nagata"):
        problem = variant(paper_example(law=law), radiation_damping=1e6)
        names = ("a", "b", "lc", "stiffness", "mass", "radiation_damping", "vl") + (
            ("c",) if law == "nagata" else ())
        dq = np.array([direction(problem, n).dq for n in names])
        q = problem.nondimensional().q(problem.nondimensional().e_slow)
        z = np.array([0.3, 1.7, -0.4 if law == "slip" else 0.8])
        jac, fth = np.empty((1, 3, 3)), np.empty((1, 3, len(names)))
        hyy, hyt = np.zeros((3, 3, 3)), np.zeros((3, 3, len(names)))   # as the workspaces
        se._partials(q, dq, z, jac, fth, 0)
        se._second(q, dq, z, hyy, hyt)
        _products_skip_only_zeros(se, jac, hyy, hyt, law)
        f, jz = np.empty(3), np.empty((3, 3))
        ode_jacobian(q, z, jz)
        assert np.allclose(jac[0], jz, rtol=1e-14, atol=0), law
        for n in range(len(names)):
            e = 1e-6
            fq, jq = [], []
            for s in (e, -e):
                out, jo = np.empty(3), np.empty((3, 3))
                ode_rhs(q + s * dq[n] * np.r_[0, np.ones(N_Q - 1)], z, out)
                ode_jacobian(q + s * dq[n] * np.r_[0, np.ones(N_Q - 1)], z, jo)
                fq.append(out), jq.append(jo)
            assert np.allclose(fth[0, :, n], (fq[0] - fq[1]) / (2 * e), rtol=1e-7,
                               atol=1e-9 * np.abs(fq[0]).max()), (law, names[n])
            assert np.allclose(hyt[:, :, n], (jq[0] - jq[1]) / (2 * e), rtol=1e-6,
                               atol=1e-8 * np.abs(jq[0]).max()), (law, names[n])
        for l in range(3):
            dz = np.eye(3)[l] * 1e-6
            up, down = np.empty((3, 3)), np.empty((3, 3))
            ode_jacobian(q, z + dz, up), ode_jacobian(q, z - dz, down)
            assert np.allclose(hyy[:, :, l], (up - down) / 2e-6, rtol=1e-6,
                               atol=1e-8 * np.abs(up).max()), (law, l)
        ode_rhs(q, z, f)


def _products_skip_only_zeros(se, jac, hyy, hyt, law):
    """Rodas5P's stage chain for the slider (``_change``, ``_products``) skips entries of J
    and dJ: J(u)·u + dJ·k it makes must be the dense products', so the skipped ones are zero."""
    rng = np.random.default_rng(3)
    for n in range(hyt.shape[2]):
        s, u, k = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        dj = hyt[:, :, n] + hyy @ s
        d = se._change(hyy, hyt, n, *s)
        got = se._products(jac, 0, d, *u, *k)
        assert np.allclose(got, jac[0] @ u + dj @ k, rtol=1e-13, atol=1e-15), (law, n)


@pytest.mark.parametrize("bad, words", [
    (dict(sensitivity=("b", "zz")), "no parameter 'zz'"),
    (dict(sensitivity=("b", "b")), "named twice"),
    (dict(sensitivity=()), "at least one"),
    (dict(sensitivity=("c",)), "no parameter 'c'"),
    (dict(sensitivity=("B", "b")), "named twice"),        # names in any case, as integrators'
])
def test_misuse_is_refused_in_one_line(bad, words):
    with pytest.raises(ValueError, match=words):
        solve(paper_example(law="slip", t_end=1.0), Rodas5P(rtol=1e-6, atol=1e-6), **bad)


def test_a_method_without_sensitivities_and_the_quasi_static_limit_are_refused():
    with pytest.raises(ValueError, match="Exprb43 has no forward sensitivities"):
        solve(paper_example(t_end=1.0), Exprb43(rtol=1e-6, atol=1e-6), sensitivity="b")
    with pytest.raises(ValueError, match="Exprb43 has no forward sensitivities"):
        solve(paper_example(t_end=1.0), Exprb43(rtol=1e-6, atol=1e-6), sensitivity="zz")
    with pytest.raises(ValueError, match="quasi-static"):
        solve(variant(paper_example(t_end=1.0), mass=0.0), Rodas5P(rtol=1e-6, atol=1e-6),
              sensitivity="b")


def test_simulate_prints_and_saves_the_gradients(tmp_path, capsys):
    from benchmarks.cli.main import main
    out = tmp_path / "run.csv"
    code = main(["simulate", "--preset", "W4", "--law", "slip", "--t-end", "12",
                 "--integrator", "Rodas5P", "--rtol", "1e-8", "--atol", "1e-8",
                 "--sensitivity", "b,lc,k", "--save", str(out), "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0
    grads = summary["sensitivity"]
    assert grads["parameters"] == ["b", "lc", "stiffness"]
    assert set(grads["limit_cycle"]) == {"recurrence_s", "friction_drop", "slip_m",
                                         "peak_velocity_m_s"}
    import pandas as pd
    table = pd.read_csv(tmp_path / "run.sensitivity.csv")
    assert "d_recurrence_s/d_lc" in table and len(table) == summary["n_events"]
    assert main(["simulate", "--preset", "W4", "--integrator", "Exprb43", "--rtol", "1e-6",
                 "--atol", "1e-6", "--sensitivity", "b"]) == 2
    assert "has no forward sensitivities" in capsys.readouterr().err


def _w2_observations(problem, rel=0.01):
    from benchmarks.inversion.observations import Observations
    from benchmarks.physics.metrics import summarize
    cycle = summarize(solve(problem, Rodas5P(rtol=1e-10, atol=1e-10), max_points=2))
    return Observations(recurrence_s=cycle.recurrence_s,
                        sigma_recurrence_s=rel * cycle.recurrence_s,
                        friction_drop=cycle.friction_drop,
                        sigma_friction_drop=rel * cycle.friction_drop)


def test_least_squares_with_exact_jacobians_fits_as_differences_do_with_fewer_solves():
    """From one start on W2/slip's own noise-free cycle: the same (b, Lc) and covariance as
    forward differences, in at most half their solves (13 against 39 when this test was
    written)."""
    from benchmarks.inversion.least_squares import fit
    from benchmarks.inversion.misfit import Misfit
    problem = window("W2", law="slip")
    obs = _w2_observations(problem)
    fits = {how: fit(Misfit(problem, obs, Rodas5P(rtol=1e-8, atol=1e-8)),
                     b_range=(0.008, 0.012), lc_range=(1e-7, 1e-6), start=(0.0105, 5e-7),
                     jacobian=how)
            for how in ("differences", "exact")}
    d, e = fits["differences"], fits["exact"]
    assert abs(d.b - e.b) < 0.05 * d.sigma_b and abs(np.log10(d.lc / e.lc)) < 0.05
    assert abs(e.sigma_b / d.sigma_b - 1) < 0.05
    assert 2 * e.n_solves <= d.n_solves


def test_nuisance_fit_recovers_noise_free_truth_and_refuses_misuse():
    """(b, Lc, k, vLs) from W2/slip's own cycle with the priors' means at the truth: back at
    the truth within a tenth of its sd, in few solves; bad priors refused in one line."""
    from benchmarks.inversion.misfit import Misfit
    from benchmarks.inversion.nuisance import fit_with_nuisance
    problem = window("W2", law="slip")
    misfit = Misfit(problem, _w2_observations(problem), Rodas5P(rtol=1e-8, atol=1e-8))
    priors = {"stiffness": (problem.stiffness, 0.03 * problem.stiffness),
              "vls": (problem.loading.vls, 0.02 * problem.loading.vls)}
    f = fit_with_nuisance(misfit, priors, (0.008, 0.012), (1e-7, 1e-6), start=(0.0096, 3.3e-7))
    assert f.success and f.n_solves <= 60
    truth = [problem.law.b, np.log10(problem.law.lc), problem.stiffness, problem.loading.vls]
    assert np.all(np.abs(f.x - truth) <= 0.1 * f.sd), (f.x, truth, f.sd)
    with pytest.raises(ValueError, match="cannot be freed"):
        fit_with_nuisance(misfit, {"df": (0.04, 0.01)}, (0.008, 0.012), (1e-7, 1e-6))
    with pytest.raises(ValueError, match="positive mean and σ"):
        fit_with_nuisance(misfit, {"stiffness": (1.48e8, -1.0)}, (0.008, 0.012), (1e-7, 1e-6))


@pytest.mark.parametrize("method", sorted(SENSITIVE))
def test_an_arrest_leaves_the_solve_as_it_is_and_says_the_gradients_are_unknown(method):
    """A deep lock the engine crosses by its arrest (no derivative there): the solve with
    sensitivities succeeds as the plain one does (it once failed, every later step rejected on
    a NaN error); the sensitivities say why they are NaN, and are NaN at the run's end (they
    once took the last differentiated trial's, stale, a hostile probe found: dv/db 8 orders
    off), the cycle's gradient is empty."""
    from benchmarks.physics.metrics import cycle_gradient
    problem = variant(window("W4", law="slip"), b=0.02, lc=1e-8, t_end=3.0)
    alg = SENSITIVE[method](rtol=1e-7, atol=1e-7)
    plain = solve(problem, alg, max_points=2)
    sens = solve(problem, alg, max_points=2, sensitivity=("b", "lc"))
    assert plain.success and plain.meta["arrests"] >= 1
    assert sens.success and sens.meta["arrests"] >= 1
    assert "arrest" in sens.sensitivity.message
    assert np.isnan(sens.sensitivity.y[-1]).all()
    assert cycle_gradient(sens) == {}


def test_more_misuse_is_refused_before_any_work():
    p = paper_example(t_end=1.0)
    alg = Rodas5P(rtol=1e-6, atol=1e-6)
    for bad in (5, True, b"b", ("b", 3), np.array([b"b"]), np.array([1.0])):
        with pytest.raises(ValueError, match="parameter names"):
            solve(p, alg, sensitivity=bad)
    with pytest.raises(ValueError, match="sensitivity_error"):
        solve(p, alg, sensitivity="b", sensitivity_error="no")
    none = window("W2", law="slip", t_end=1.0)
    none = dataclasses.replace(none, loading=TwoSpeedLoading(none.loading.vls, 1e-3, 0.0))
    with pytest.raises(ValueError, match="no parameter 'vlf'"):   # no overshoot runs
        solve(none, alg, sensitivity="vlf")
    with pytest.warns(UserWarning, match="far off"):
        solve(p, Rodas5P(rtol=1e-3, atol=1e-3), sensitivity="b", max_points=2)
    stuck = dataclasses.replace(variant(p, b=0.0), initial=InitialState(1e-5, 0.0, 6e5))
    with pytest.raises(ValueError, match="^sensitivity: .* along 'initial_theta': slip law"):
        solve(stuck, alg, sensitivity="initial_theta")      # θ = 0 is the only θ at b = 0
    by_array = solve(p, alg, sensitivity=np.array(["b", "lc"]))
    assert by_array.sensitivity.names == ("b", "lc")


def test_an_overshoot_at_the_slow_speed_is_differentiated_as_two_speeds():
    """vlf = vls with df > 0: the overshoot changes nothing, but ∂/∂vls holds vlf (as
    :func:`variant` does), so the overshoot after each event keeps its speed, and ∂/∂vlf is not
    0. Both against central differences (relative step 1e-4) of variants' event starts: the
    gradient along vls was 1.6 % off when such a loading was solved as one speed."""
    p = window("W2", law="slip", t_end=7.0)
    p = variant(p, vlf=p.loading.vls)
    alg = Rodas5P(rtol=1e-9, atol=1e-9)
    sol = solve(p, alg, sensitivity=("vls", "vlf"))
    assert sol.success and len(sol.events) == 3
    exact = np.asarray(sol.sensitivity.events)[:, 0, :]          # ∂t_start/∂(vls, vlf)
    for n, name in enumerate(("vls", "vlf")):
        h = 1e-4 * getattr(p.loading, name)
        up, down = (solve(variant(p, **{name: getattr(p.loading, name) + s * h}), alg)
                    for s in (1, -1))
        fd = (up.events["t_start"].to_numpy() - down.events["t_start"].to_numpy()) / (2 * h)
        np.testing.assert_allclose(exact[1:, n], fd[1:], rtol=1e-4)
    assert exact[0, 1] == 0.0 and abs(exact[2, 1]) > 100.0       # before any overshoot; not 0


def test_the_initial_states_derivative_along_a_damping_of_zero():
    """h0 of a balanced start is linear in the damping: the derivative at ηr = 0 is the chord
    to ηr = 1e3 N s/m (it was 16 % off with a step of 1e-6 N s/m, lost in rounding)."""
    from problems.directions import direction
    from problems.formulations import to_ode_state
    p = paper_example(law="slip")

    def z0(q):
        nd = q.nondimensional()
        return to_ode_state(nd.law_code, nd.beta, nd.x0)

    chord = (z0(variant(p, radiation_damping=1e3)) - z0(p)) / 1e3
    got = direction(p, "radiation_damping").dz0
    assert np.allclose(got, chord, rtol=1e-6, atol=1e-9 * np.abs(chord).max())


def test_the_initial_states_derivative_along_a_damping_on_a_laboratory_apparatus():
    """A balanced start's spring force is friction + ηr v, so ∂h0/∂ηr = v/(k Lc) exactly; on a
    velocity step with a 1 g slider a step of m v0/Lc moved Fs (~6 kN) by less than its
    rounding and the derivative came out 0 (the hostile probe's case)."""
    from problems.directions import direction
    from problems.presets import velocity_step_test
    for mass in (1e-3, 1.0):
        p = velocity_step_test(law="aging", mass=mass)
        ini = p.initial_state
        exact = ini.v / (p.stiffness * p.law.lc)
        got = direction(p, "radiation_damping").dz0
        assert got[0] == pytest.approx(exact, rel=1e-9), mass
        assert got[1] == 0.0 and got[2] == 0.0


def test_the_initial_states_derivative_along_b_at_zero_is_its_neighbours():
    """A slip law's balanced start at b = 0: Ψ0 is 0 there alone (θ = 0) and the same constant
    for every b ≠ 0, so a one-sided difference from b = 0 would make ∂s0/∂b ~ 1e4; b may go
    below 0, so the difference is central and s0's derivative is the neighbours' (0 at
    b = ±1e-3: the derivative of a constant)."""
    from problems.directions import direction
    p = paper_example(law="slip", t_end=0.5)
    at_zero = direction(p.with_law(b=0.0), "b").dz0
    for b in (-1e-3, 1e-3):
        near = direction(p.with_law(b=b), "b").dz0
        assert abs(near[2]) < 1e-6 and abs(at_zero[2]) < 1e-6
        assert np.allclose(at_zero[0], near[0], rtol=1e-6)


def test_stick_slip_design_errors_hold_for_a_precise_plan_and_rank_alternatives():
    """A precise W2/slip plan (240 s, 1 %/2 % scatter): the Fisher errors of (b, log10 Lc)
    within 40 % of the spread of 30 exact-Jacobian fits (1.06 and 1.03 with 40 fits when this
    test was written); a stiffer machine resolves Lc better than the plan."""
    from benchmarks.inversion.design import StickSlipPlan, check_stick_slip, compare_stick_slip
    plan = StickSlipPlan(window("W2", law="slip"), 240.0, 0.01, 0.02)
    table = check_stick_slip(plan, n=30)
    assert (table.fits == 30).all()
    assert np.all(np.abs(table.ratio - 1.0) < 0.4), table       # 30 fits: the spread ±13 %
    ranked = compare_stick_slip(plan, {"stiffer": {"stiffness": 2.5e8}})
    assert ranked.plan.iloc[0] == "stiffer"
    with pytest.raises(ValueError, match="duration"):
        StickSlipPlan(window("W2", law="slip"), 0.0, 0.01, 0.02)


def test_a_repeat_at_other_times_is_the_same_run_with_its_sensitivities():
    """The sensitivities in the step control change the steps: a repeat at other times
    (``resolved``, ``sol(t)``) solves with them again, so it is the same run, and carries them
    at its times (before, it repeated the plain solve and dropped them)."""
    problem = window("W4", law="slip", t_end=3.0)
    alg = Rodas5P(rtol=1e-8, atol=1e-8)
    sol = solve(problem, alg, sensitivity=("b", "lc"), max_points=2)
    times = np.linspace(0.5, 2.5, 7)
    again = sol._at(times)
    direct = solve(problem, alg, sensitivity=("b", "lc"), save_at=times)
    assert again.sensitivity is not None and again.sensitivity.y.shape == (7, 3, 2)
    assert np.array_equal(again.sensitivity.y, direct.sensitivity.y)
    assert np.array_equal(again.v, direct.v)
    plain = solve(problem, alg, save_at=times)
    assert not np.array_equal(plain.v, direct.v)        # the steps differ without them
