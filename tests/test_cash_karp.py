"""Cash–Karp RK45 with Numerical Recipes step control (integrators/own/cash_karp.py): error scaled by
the tolerance, events against Radau, the cost counters, the wall budget on the stiff run, and
the stick-phase jitter kept out of the event roots."""

import dataclasses

import numpy as np
import pytest

import integrators as I
import problems as P
from integrators.own import engine


def _heavy_slider():
    """Paper example with the mass × 1e4 (D ≈ 3.6, as in test_etd): not stiff, no event in 2 s."""
    base = P.paper_example(t_end=2.0)
    return dataclasses.replace(base, mass=base.mass * 1e4)


def _ln_v_end(problem, algorithm):
    sol = I.solve(problem, algorithm, max_points=2)
    assert sol.success, sol.message
    return float(np.log(sol.v[-1]))


def test_error_scales_with_tolerance():
    """ln v at t_end against scipy Radau at rtol = atol = 1e−12 (its own error is far below the
    smallest error measured here): within 100·rtol, and 1000× less tolerance buys > 100× less
    error (measured: 0.015·rtol at 1e−6, 0.05·rtol at 1e−9)."""
    p = _heavy_slider()
    ref = _ln_v_end(p, I.ScipyRadau(rtol=1e-12, atol=1e-12))
    err = {tol: abs(_ln_v_end(p, I.CashKarp45(rtol=tol, atol=tol)) - ref) for tol in (1e-6, 1e-9)}
    for tol, e in err.items():
        assert e < 100 * tol, f"rtol {tol}: error {e:.3g}"
    assert err[1e-9] < err[1e-6] / 100


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_event_times_match_radau(law):
    """W2, 50 ms: one event with the two-speed restart after it. Its times and peak slip rate
    against scipy Radau at rtol = atol = 1e−10 (measured at rtol 1e−6: 2–3e−7 relative, t_peak
    2e−6). Two saved points: every advance lands on its output time, so a dense save grid
    would shorten the steps below what the tolerance asks for."""
    p = P.window("W2", law, t_end=0.05)
    ref = I.solve(p, I.ScipyRadau(rtol=1e-10, atol=1e-10)).events
    sol = I.solve(p, I.CashKarp45(rtol=1e-6, atol=1e-6), max_points=2)
    assert sol.success, sol.message
    assert len(sol.events) == len(ref) == 1
    for col in ("t_start", "t_end", "t_peak", "v_peak"):
        np.testing.assert_allclose(sol.events[col], ref[col], rtol=5e-5, err_msg=col)


def test_counters():
    """nfev = 6·steps + 5·rejected + 2·starts (module docstring), on a constant-loading run (one
    start) and on W2 with its two-speed restarts (starts counted here)."""
    sol = I.solve(_heavy_slider(), I.CashKarp45(rtol=1e-8, atol=1e-8), max_points=2)
    s = sol.stats
    assert s.steps > 0 and s.rejected > 0 and s.njev == 0
    assert s.nfev == 6 * s.steps + 5 * s.rejected + 2

    sol = I.solve(P.window("W2", "slip", t_end=0.05), I.CashKarp45(rtol=1e-7, atol=1e-7))
    s, starts = sol.stats, sol.meta["starts"]
    assert sol.success and starts >= 2 and len(sol.events) == 1   # the restart at the event's end
    assert s.nfev == 6 * s.steps + 5 * s.rejected + 2 * starts


def test_wall_budget_stops_the_stiff_run():
    """The paper example (20 s) needs 6.3e7 steps (~25 s); a 0.2 s budget stops it with a valid
    state and a message, promptly: the engine reads the clock every 256 steps (0.2 s of wall
    time is ~0.2 s simulated, ~6e5 steps)."""
    p = P.paper_example()
    sol = I.solve(p, I.CashKarp45(rtol=1e-6, atol=1e-6), max_points=100, wall_budget=0.2)
    assert sol.retcode is I.ReturnCode.WALL_TIME
    assert 0.0 < sol.t_reached < 1.0 and "wall-time budget" in sol.message
    assert np.all(np.isfinite(sol.v)) and sol.stats.steps > 0


def test_stick_phase_jitter_is_not_reported():
    """Paper example to 1.5 s (one event and the stick phase after it): at the stability limit
    C h − D η jitters about zero near the minimum of w; those PEAK crossings (w ≤ E_slow, never an
    event's peak) are not reported (~2e4 per cycle otherwise, 3e5 at rtol 1e−8)."""
    sol = I.solve(P.paper_example(t_end=1.5), I.CashKarp45(rtol=1e-8, atol=1e-8), max_points=2)
    assert sol.success and len(sol.events) == 1
    assert sol.meta["roots"]["peak"] == 1


def _initial_step_in_python(p, z, t_span, exponent):
    """Hairer's initial step as the stepper's start computed it in Python before it was
    compiled (numpy's NaN propagation, Python's min/max): the reference of the test below."""
    from problems.formulations import ode_rhs
    from integrators.own.engine import P_ATOL, P_RTOL
    rtol, atol = p[P_RTOL], p[P_ATOL]
    f, f1 = np.empty(3), np.empty(3)
    ode_rhs(p, z, f)
    scale = atol + rtol * np.abs(z)
    d0, d1 = np.max(np.abs(z) / scale), np.max(np.abs(f) / scale)
    h0 = 0.01 * d0 / d1 if min(d0, d1) >= 1e-5 else 1e-6
    ode_rhs(p, z + h0 * f, f1)
    big = max(d1, np.max(np.abs(f1 - f) / scale) / h0)
    h1 = (0.01 / big) ** exponent if big > 1e-15 else max(1e-6, 1e-3 * h0)
    return min(100.0 * h0, h1 if h1 > 0.0 else 1e-3 * h0, t_span)


@pytest.mark.parametrize("z", [(0.3, -12.0, 11.0), (0.0, 0.0, 0.0), (5.0, 40.0, -40.0),
                               (0.3, 700.0, 1.0), (0.3, 800.0, -800.0), (1e-3, -30.0, 29.0)])
def test_compiled_start_takes_the_same_initial_step_as_the_python_one(z):
    """The compiled start (integrators.own.engine.start) against the Python code it replaced, to the
    bit: a steady state (f = 0), a fast slip (e^40), an overflowing trial (e^700), a state whose
    f is NaN in its last entry (e^800 = inf times u + s = 0: numpy's max is NaN), a deep stick. Same step sizes keep every committed result of the compiled methods."""
    nd = P.window("W2", "aging").nondimensional()
    z = np.array(z)
    for e, span, exponent in ((nd.e_slow, 50.0, 0.2), (nd.e_fast, 1e-4, 1 / 3)):
        st, q, Z, G = engine.new_state(nd, 1e-6, 1e-8, {"INIT_EXPONENT": exponent}, 1, 1.0)
        with np.errstate(all="ignore"):
            engine.start(st, q, Z, G, 0.0, z, e, span, np.empty((3, 3)))   # sets E, ln E in q
            expected = _initial_step_in_python(q, z, span, exponent)
        assert st[engine.H] == expected or (np.isnan(st[engine.H]) and np.isnan(expected))
