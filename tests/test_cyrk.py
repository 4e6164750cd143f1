"""CyRK's C++ solvers from numba (``CyRK-*``): counters, budgets and failures come back the way
every backend reports them; CyRK's own status and message are kept."""

import numpy as np
import pytest

import integrators as I
import problems as P
from integrators import REGISTRY

pytest.importorskip("CyRK")


def test_counters_explicit_and_implicit():
    p = P.window("W2", "slip", t_end=0.05)
    rk = I.solve(p, REGISTRY["CyRK-RK45"](rtol=1e-6, atol=1e-6), max_points=2)
    radau = I.solve(p, REGISTRY["CyRK-Radau"](rtol=1e-6, atol=1e-6), max_points=2)
    assert rk.success and radau.success
    # Dormand–Prince: six new evaluations per attempt (FSAL), so at least six per step
    assert rk.stats.nfev >= 6 * rk.stats.steps and rk.stats.njev == 0
    # Radau: finite-difference Jacobians, counted in the cfunc, three calls each at least
    assert 0 < radau.stats.njev and radau.stats.nfev > 3 * radau.stats.njev


def test_the_step_budget_ends_the_run_with_a_retcode():
    sol = I.solve(P.window("W2", "slip", t_end=0.05),
                  REGISTRY["CyRK-Radau"](rtol=1e-8, atol=1e-8, max_steps=50))
    assert sol.retcode is I.ReturnCode.MAX_STEPS and "step budget of 50" in sol.message
    assert sol.stats.steps == 50


class _FailedCall:
    """What nbsolve2_ivp returns when CyRK gives up at once (status −54: step size error)."""

    status, steps_taken, message, _ptr = -54, 0, "Step size is too small (spacing).", 0
    t = np.array([0.0])

    def __init__(self, z0):
        self.y = np.asarray(z0, float)[:, None]

    def free(self):
        pass


def test_a_cyrk_failure_comes_back_with_its_status_and_message(monkeypatch):
    """CyRK gives up at once: the one-call path hands the run to the segment path, whose call
    fails the same way and reports it."""
    from integrators.external import cyrk_backend as cb
    monkeypatch.setattr(cb, "_whole_run", lambda *a: (-54, 0, np.empty((0, 8)), 0.0, a[4]))
    monkeypatch.setattr(cb, "_call", lambda rhs, t0, t1, z0, *a: _FailedCall(z0))
    sol = I.solve(P.paper_example(), REGISTRY["CyRK-BDF"](rtol=1e-6, atol=1e-6))
    assert sol.retcode is I.ReturnCode.STEP_UNDERFLOW
    assert "status -54" in sol.message and "spacing" in sol.message


@pytest.mark.parametrize("name", ["CyRK-Radau", "CyRK-BDF"])
def test_one_call_path_is_the_segment_path_to_the_bit(name):
    """On a run with one loading speed the implicit methods take the one compiled call; its
    events, saved times and states and counters are those of the segment driver over the same
    library (run directly here), on uniform grids (50 and the default 20,000 points) and at
    given times."""
    from integrators.core.segments import run_segments
    from integrators.core.solution import Output
    from integrators.core.solve import Budget
    import dataclasses
    base = P.paper_example()
    # and a history whose reference velocity (the one E is measured in) is not its speed
    other = dataclasses.replace(base, loading=P.LoadHistory(
        (base.loading.v_slow,), reference_velocity=2 * base.loading.v_slow))
    method = REGISTRY[name](rtol=1e-6, atol=1e-6)
    for p, kw in ((base, dict(max_points=50)), (base, dict(save_at=np.linspace(0.5, 19.5, 7))),
                  (base, dict(save_at=np.array([1.0, 1.0 + 1e-12, 2.0, 20.0]))),
                  (base, dict()), (other, dict(max_points=3))):
        sol = I.solve(p, method, **kw)
        raw = run_segments(p, method.make_stepper(p.nondimensional(), None), Output(**kw),
                           Budget(), None)
        assert sol.meta["one_call"] and sol.success and len(sol.events) == 8
        assert np.array_equal(sol.event_array, raw.events)
        assert np.array_equal(sol.t, raw.t)
        assert np.array_equal(np.column_stack([sol.v, sol.fs, sol.theta]), raw.y)
        assert (sol.stats.steps, sol.stats.nfev, sol.stats.njev) == \
            (raw.stats.steps, raw.stats.nfev, raw.stats.njev)


def test_two_speed_loading_takes_the_segment_path():
    sol = I.solve(P.window("W2", "slip", t_end=0.05),
                  REGISTRY["CyRK-Radau"](rtol=1e-6, atol=1e-6), max_points=2)
    assert sol.success and "one_call" not in sol.meta


def test_a_call_that_runs_out_goes_on_chunked_its_steps_counted(monkeypatch):
    """With calls of at most 2000 steps the one call runs out (the paper example takes ~4000
    at 1e−7): the segment path runs it again, chunked from the steps per unit τ just seen; the
    thrown-away steps count, against the step budget too."""
    from integrators.external import cyrk_backend as cb
    monkeypatch.setattr(cb, "CHUNK_STEPS", 1000)
    p = P.paper_example()
    sol = I.solve(p, REGISTRY["CyRK-Radau"](rtol=1e-7, atol=1e-7), max_points=2)
    assert sol.success and sol.meta["one_call"] is False and len(sol.events) == 8
    assert sol.stats.steps > 2000 + 3900
    short = I.solve(p, REGISTRY["CyRK-Radau"](rtol=1e-7, atol=1e-7, max_steps=2500))
    assert short.retcode is I.ReturnCode.MAX_STEPS and short.stats.steps == 2500


@pytest.mark.parametrize("problem, method, tol", [
    (P.variant(P.paper_example(), t_end=10.0), "BDF", 1e-6),   # one call (1e-5: CyRK fails)
    (P.window("W2", "aging", t_end=60.0), "RADAU", 1e-5)])     # two-speed: restarts
def test_the_plain_call_takes_the_adapters_steps_and_finds_its_starts(problem, method, tol):
    """The harness's plain CyRK call (no counters, starts only, its own compiled segment loop)
    takes the adapter's steps and finds its event starts to the bit: so its time is the same
    solve's, called as CyRK's numba users call it."""
    from integrators.external.cyrk_backend import plain_starts
    name = {"RADAU": "CyRK-Radau", "BDF": "CyRK-BDF"}[method]
    sol = I.solve(problem, REGISTRY[name](rtol=tol, atol=tol), max_points=2)
    steps, starts = plain_starts(problem, method, tol, tol)
    assert sol.success and len(sol.events) >= 2
    assert steps == sol.stats.steps
    done = sol.events["t_start"].to_numpy()
    assert len(starts) - len(done) in (0, 1)      # an event running at the end: its start
    np.testing.assert_array_equal(starts[:len(done)], done)


def test_the_target_takes_the_faster_cyrk_call():
    """A (problem, level) row re-timed: the own run, the adapter and the plain call, and the
    CyRK ratio against the faster of the two; a row without a CyRK run says why."""
    import pandas as pd
    from benchmarks.studies.target import plain_cyrk
    problem = P.variant(P.paper_example(), t_end=5.0)
    row = dict(problem=problem.name, level=1e-3, own="Rodas5P", own_setting=1e-3,
               own_tier="numba", own_wall_s=1e-3, cyrk="CyRK-Radau", cyrk_setting=1e-3,
               cyrk_tier="numba", cyrk_wall_s=2e-3, ratio_lsoda=9.0, ratio_sundials=40.0,
               ratio_cyrk=2.0, ratio_peer=2.0, met="yes")
    t = plain_cyrk(pd.DataFrame([row, {**row, "cyrk": None}]), [problem], repeats=2)
    done, skipped = t.iloc[0], t.iloc[1]
    assert done.cyrk_plain_note == "" and done.own_again_wall_s > 0
    assert done.ratio_cyrk_faster == pytest.approx(
        min(done.cyrk_again_wall_s, done.cyrk_plain_wall_s) / done.own_again_wall_s)
    assert done.ratio_peer == min(9.0, 40.0, done.ratio_cyrk_faster)
    assert done.met == ("yes" if done.ratio_cyrk_faster >= 2.0 else "no")
    assert "no CyRK" in skipped.cyrk_plain_note and np.isnan(skipped.ratio_cyrk_faster)


@pytest.mark.slow
def test_the_plain_call_redoes_a_call_that_ran_out_of_steps_as_the_adapter_does():
    """400 s of the paper example at 1e-9 takes ~370,000 steps: the first call of each runs
    out of its 2·CHUNK_STEPS (the adapter falls back to its segment path), is done again over
    less, and the later calls are sized from the steps per unit time seen. The two still take
    the same steps and find the same starts, to the bit."""
    from integrators.external.cyrk_backend import CHUNK_STEPS, plain_starts
    problem = P.variant(P.paper_example(), t_end=400.0)
    sol = I.solve(problem, REGISTRY["CyRK-Radau"](rtol=1e-9, atol=1e-9), max_points=2)
    steps, starts = plain_starts(problem, "RADAU", 1e-9, 1e-9)
    assert sol.success and sol.meta["one_call"] is False and steps > 2 * CHUNK_STEPS
    assert steps == sol.stats.steps
    done = sol.events["t_start"].to_numpy()
    np.testing.assert_array_equal(starts[:len(done)], done)
