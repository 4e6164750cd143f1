"""The accuracy-and-cost harness on small problems: references (agreement, cache), error
measures, the work-precision bookkeeping, convergence fits and the study CLIs."""

import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pytest

import integrators as I
import problems as P
from benchmarks.devtools import reference as R
from benchmarks.cli.main import main
from benchmarks.devtools.convergence import observed_order
from benchmarks.devtools.errors import ERROR_COLUMNS, HEADLINE_ERRORS, errors
from benchmarks.physics.metrics import event_metrics
from benchmarks.devtools.work_precision import (WP_COLUMNS, Ladder, best_at_levels, recommend,
                                       work_precision)


def small_problem():
    """W4 (slip law) for 1.5 s: three events, ~0.3 s per reference solver."""
    return P.window("W4", "slip", t_end=1.5)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("references")


@pytest.fixture(scope="module")
def small_ref(cache):
    return R.reference(small_problem(), cache=cache)


def test_reference_solvers_agree_and_the_agreement_is_recorded(small_ref):
    assert [s["name"] for s in small_ref.solvers] == [n for n, _ in R._solver_pair()]
    assert small_ref.agreement["max"] <= R.AGREEMENT_RTOL
    assert set(small_ref.agreement) >= {"recurrence_s", "friction_drop", "slip_m",
                                        "peak_velocity_m_s", "t_start", "max"}
    assert small_ref.event_index == len(small_ref.events) - 1 >= 1
    assert len(small_ref.grid_t) == R.GRID_POINTS and small_ref.grid_t[-1] == 1.5


def test_reference_is_cached_by_problem(small_ref, cache):
    files = list(cache.glob("*.json"))
    assert len(files) == 1
    again = R.reference(small_problem(), cache=cache)          # from disk
    assert again.key == small_ref.key
    pd.testing.assert_frame_equal(again.events, small_ref.events)
    np.testing.assert_array_equal(again.grid_mu, small_ref.grid_mu)
    changed = small_problem().with_law(b=small_problem().law.b * 1.001)
    assert R._key(changed, R._solver_pair()) != small_ref.key


def test_disagreeing_references_are_refused(tmp_path, monkeypatch):
    # a loose solver against a tight one: they differ by far more than AGREEMENT_RTOL
    monkeypatch.setattr(R, "REFERENCE_SOLVERS", ((("scipy-BDF", 1e-4), ("scipy-Radau", 1e-10)),))
    with pytest.raises(R.ReferenceDisagreement, match="disagree"):
        R.reference(small_problem(), cache=tmp_path)
    assert not list(tmp_path.glob("*.json"))


def test_errors_of_a_run_against_the_reference(small_ref):
    p = small_problem()
    sol = I.solve(p, I.ETD2(), save_every=p.t_end / 2000)
    e = errors(sol, small_ref)
    assert set(e) == set(ERROR_COLUMNS)
    got = event_metrics(sol.events, p.normal_force).iloc[small_ref.event_index]
    want = small_ref.metrics
    assert e["err_recurrence"] == pytest.approx(abs(got.recurrence_s / want.recurrence_s - 1))
    assert e["err_slip"] == pytest.approx(abs(got.slip_m / want.slip_m - 1))
    assert e["err_event_time"] == pytest.approx(abs(got.t_start - want.t_start) / want.recurrence_s)
    # ETD2 at the paper's steps: ~1e-4–1e-3 on the cycle (its documented first-order error)
    assert all(1e-7 < e[k] < 1e-2 for k in HEADLINE_ERRORS)


def test_error_of_the_reference_itself_is_zero_and_of_a_shifted_copy_is_the_shift(small_ref):
    p = small_problem()
    first = small_ref.solvers[0]                     # the reference's own solver and tolerance
    sol = I.solve(p, I.algorithm_class(first["name"])(rtol=first["tol"], atol=first["tol"]),
                  save_every=p.t_end / 2000)
    e = errors(sol, small_ref)
    assert all(e[k] == 0.0 for k in HEADLINE_ERRORS + ("err_event_time",))
    assert e["err_trajectory"] < 1e-12
    # delay every event by 1 ms: the event-time error is exactly that in cycles, the metrics keep
    shift = 1e-3
    late = dataclasses.replace(sol, t=sol.t + shift,
                               event_array=sol.event_array + np.eye(8)[0] * shift)
    e = errors(late, small_ref)
    assert e["err_event_time"] == pytest.approx(shift / small_ref.metrics.recurrence_s, rel=1e-9)
    assert e["err_recurrence"] == pytest.approx(0.0, abs=1e-12)
    assert e["err_trajectory"] > 0.01


def test_a_failed_or_short_run_has_nan_errors(small_ref):
    p = small_problem()
    failed = I.solve(p, I.ETD2(max_steps=10))
    assert not failed.success and all(math.isnan(v) for v in errors(failed, small_ref).values())
    short = I.solve(dataclasses.replace(p, t_end=0.3), I.ETD2())    # one event only
    e = errors(short, small_ref)
    assert all(math.isnan(e[k]) for k in HEADLINE_ERRORS)


def test_work_precision_rows_columns_and_skips(small_ref, cache, monkeypatch):
    monkeypatch.setenv("RSFBENCH_CACHE", str(cache))
    ladder = Ladder(tolerances=(1e-4, 1e-7), etd_factors=(1.0, 0.5), wall_budget=1.0, repeats=2)
    df = work_precision([small_problem()], ladder, names=["ETD2", "scipy-RK45"],
                        tiers=("numba", "python"), progress=False)
    assert set(WP_COLUMNS) <= set(df.columns) and {"cpu", "git_commit", "v_numpy"} <= set(df.columns)
    # ETD2: numba only, 2 rungs; RK45: 2 tiers × 2 rungs
    assert len(df) == 6 and set(df[df.integrator == "ETD2"].rhs_tier) == {"numba"}
    etd = df[df.integrator == "ETD2"]
    assert (etd.retcode == "Success").all() and etd.err_recurrence.iloc[1] < etd.err_recurrence.iloc[0]
    # explicit RK45 crawls through the stick phase (~1 min here): a WallTime row after 1 s,
    # then the tighter rung is not run
    for tier in ("numba", "python"):
        rk = df[(df.integrator == "scipy-RK45") & (df.rhs_tier == tier)]
        assert rk.retcode.tolist() == ["WallTime", "Skipped"]
        assert rk.err_recurrence.isna().all() and rk.t_reached_s.iloc[0] < 1.5
    assert list(df.setting[df.integrator == "ETD2"]) == [1e-5, 5e-6]


def test_pareto_and_recommendation_pick_the_cheapest_that_reaches_each_level():
    rows = []
    for problem, scale in (("p1", 1.0), ("p2", 2.0)):
        for name, setting, err, wall in (("A", 1e-3, 1e-3, 1.0), ("A", 1e-6, 1e-6, 3.0),
                                         ("B", 1e-3, 1e-4, 2.0), ("B", 1e-6, 1e-7, 10.0)):
            rows.append({"problem": problem, "integrator": name, "rhs_tier": "numba",
                         "setting": setting, "retcode": "Success", "err_recurrence": err,
                         "wall_s": wall * scale})
    df = pd.DataFrame(rows)
    pareto = best_at_levels(df, (1e-2, 1e-4, 1e-6), "err_recurrence")
    p1 = pareto[pareto.problem == "p1"].set_index("level")
    assert p1.loc[1e-2, "fastest"] == "A" and p1.loc[1e-2, "runner_up_ratio"] == 2.0
    assert p1.loc[1e-4, "fastest"] == "B" and p1.loc[1e-4, "fastest_setting"] == 1e-3
    assert p1.loc[1e-6, "fastest"] == "A" and p1.loc[1e-6, "fastest_wall_s"] == 3.0
    advice = recommend(df, (1e-2, 1e-6, 1e-8)).set_index("level")
    assert advice.loc[1e-2, "integrator"] == "A" and advice.loc[1e-2, "total_wall_s"] == 3.0
    assert advice.loc[1e-6, "integrator"] == "A" and advice.loc[1e-6, "next_integrator"] == "B"
    assert pd.isna(advice.loc[1e-8, "integrator"])
    # a lucky loose setting (error 1e-7 at 1e-3, but 1e-5 at 1e-6) is not recommended for 1e-6
    lucky = [{"problem": p, "integrator": "C", "rhs_tier": "numba", "setting": s,
              "retcode": "Success", "err_recurrence": e, "wall_s": 0.1}
             for p in ("p1", "p2") for s, e in ((1e-3, 1e-7), (1e-6, 1e-5))]
    advice = recommend(pd.concat([df, pd.DataFrame(lucky)]), (1e-6,)).set_index("level")
    assert advice.loc[1e-6, "integrator"] == "A"


def test_observed_order_of_an_exact_power_law():
    h = np.array([1.0, 0.5, 0.25, 0.125])
    assert observed_order(h, 3.0 * h ** 2) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="positive"):
        observed_order(h, h * 0)


def test_convergence_cli_json(cache, monkeypatch, capsys):
    monkeypatch.setenv("RSFBENCH_CACHE", str(cache))
    assert main(["convergence", "--problem", "W4", "--t-end", "1.5", "--integrators", "ETD1",
                 "ETD2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["orders"]) == {"ETD1", "ETD2"}
    # both first order on the stick–slip problem (ETD2 by order reduction, see etd.py)
    assert out["orders"]["ETD1"] == pytest.approx(1.0, abs=0.2)
    assert out["orders"]["ETD2"] == pytest.approx(1.0, abs=0.2)


@pytest.mark.slow          # 15 s on 2 cores (pytest --durations, 2026-11-26)
def test_fixed_step_order_cli_measures_the_declared_orders(tmp_path, capsys):
    # the compiled stiff methods with error control off on the paper example's stick phase;
    # measured 2.01, 4.91 (Rodas5P: 8–24 steps; finer ones reach the reference's ~3e-13)
    assert main(["convergence", "--fixed-steps", "--integrators", "Rosenbrock23", "Rodas5P",
                 "--out", str(tmp_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["orders"]) == {f"{n}/{law}" for n in ("Rosenbrock23", "Rodas5P")
                                  for law in ("slip", "aging")}
    for key, order in out["orders"].items():
        assert order == pytest.approx(out["declared"][key.split("/")[0]], abs=0.15), key
    table = pd.read_csv(tmp_path / "convergence_fixed_steps.csv")
    assert table.fitted.sum() == 16 and (table[table.fitted].error > 1e-10).all()
    assert (tmp_path / "convergence_fixed_steps.png").exists()
    assert main(["convergence", "--fixed-steps", "--integrators", "ETD2"]) == 2
    assert "ETD2 has no fixed-step mode" in capsys.readouterr().err


@pytest.mark.slow                        # 10 s
@pytest.mark.needs("scikits.odes")
def test_work_precision_cli_writes_the_study(cache, monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("RSFBENCH_CACHE", str(cache))
    assert main(["work-precision", "--problems", "W4", "--t-end", "1.5", "--integrators", "ETD2",
                 "odes-CVODE-BDF", "--tiers", "numba", "--out", str(tmp_path), "--name", "t",
                 "--json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    df = pd.read_csv(out["csv"])
    assert set(WP_COLUMNS) <= set(df.columns)
    assert set(df.integrator) == {"ETD2", "odes-CVODE-BDF"}
    assert (tmp_path / "wp_t_pareto.md").exists() and list(tmp_path.glob("wp_t_*.png"))
    assert out["recommendation"] and out["pareto"]


@pytest.mark.needs("scikits.odes")
def test_speedup_keys_and_a_budget_stop_is_a_lower_bound(cache, monkeypatch):
    """Paper example for 2 s (two events). scipy's RK45 gets 2 s of wall time, far too little
    (it needs ~70 s for this interval): its ratio must be flagged as a lower bound, with the
    simulated time it reached."""
    from benchmarks.records.report import jsonable
    from benchmarks.studies.speedup import speedup
    monkeypatch.setenv("RSFBENCH_CACHE", str(cache))
    out, _ = speedup(P.preset("paper-example", t_end=2.0), scipy_budget=2.0,
                     implicit=["odes-CVODE-BDF"], progress=False)
    out = json.loads(json.dumps(jsonable(out)))
    for key in ("ratio_vs_scipy_rk45", "ratio_vs_compiled_rk45", "ratio_vs_best_implicit",
                "cycles_agree"):
        assert key in out
    assert out["ratio_vs_scipy_rk45_is_lower_bound"] is True
    assert 0 < out["scipy_rk45_t_reached_s"] < 2.0 and out["scipy_rk45_retcode"] == "WallTime"
    assert out["ratio_vs_scipy_rk45"] >= 2.0 / out["etd2_wall_s"] * 0.99
    assert out["compiled_rk45_retcode"] == "Success" and out["ratio_vs_compiled_rk45"] > 1
    assert out["best_implicit"] == "odes-CVODE-BDF"
    # the compiled RK45 and ETD2 agree on both events; scipy completed fewer
    assert out["events_compared"]["CashKarp45"] == 2
    assert out["cycle_disagreement"]["CashKarp45_vs_ETD2"] < 1e-3


@pytest.mark.needs("numbalsoda", "scikits.odes", "CyRK")
def test_target_table_compares_the_fastest_own_run_with_every_compiled_peer():
    from benchmarks.studies.target import target_table
    rows = [("Rodas5P", 1e-6, 1e-5, 1.0), ("Rodas5P", 1e-8, 1e-7, 3.0),
            ("numbalsoda-LSODA", 1e-6, 1e-5, 2.5), ("numbalsoda-LSODA", 1e-8, 1e-7, 5.0),
            ("odes-CVODE-BDF", 1e-8, 1e-7, 4.0), ("CyRK-Radau", 1e-4, 1e-3, 1.5)]
    df = pd.DataFrame([{"problem": "p", "integrator": n, "rhs_tier": "numba", "setting": s,
                        "retcode": "Success", "err_recurrence": e, "wall_s": w}
                       for n, s, e, w in rows])
    t = target_table(df, levels=(1e-3, 1e-5, 1e-7, 1e-9)).set_index("level")
    # 1e-3: own 1.0 s, CyRK 1.5 s → 1.5×: missed, though LSODA (2.5×) and SUNDIALS (4×) are beaten
    assert t.loc[1e-3, "ratio_cyrk"] == 1.5 and t.loc[1e-3, "ratio_peer"] == 1.5
    assert t.loc[1e-3, "met"] == "no"
    # 1e-5: own 1.0 s, LSODA 2.5 s, SUNDIALS only at 1e-8 (4.0 s), CyRK not there → met
    assert t.loc[1e-5, "ratio_lsoda"] == 2.5 and t.loc[1e-5, "ratio_sundials"] == 4.0
    assert t.loc[1e-5, "ratio_peer"] == 2.5 and t.loc[1e-5, "met"] == "yes"
    # 1e-7: own 3.0 s, LSODA 5.0 s → 1.67×: missed
    assert t.loc[1e-7, "met"] == "no" and t.loc[1e-7, "own"] == "Rodas5P"
    assert t.loc[1e-9, "met"].startswith("no (own: none)")


@pytest.mark.needs("numbalsoda", "scikits.odes", "assimulo")
def test_target_study_runs_every_stiff_adaptive_integrator_of_the_sides():
    from benchmarks.studies.target import groups, target_integrators
    names, g = target_integrators(), groups()
    assert {"Rosenbrock23", "Rodas5P", "Exprb32", "Exprb43", "numbalsoda-LSODA", "odes-CVODE-BDF",
            "odes-IDA", "assimulo-CVode", "assimulo-IDA"} <= set(names)
    # every way of calling each library: the compiled tiers are on their side
    assert {"sundials-CVODE-BDF", "sundials-IDA"} <= set(g["sundials"]) & set(names)
    assert {"numbalsoda-LSODA-grid", "CyRK-LSODA"} <= set(g["lsoda"]) & set(names)
    assert {"CyRK-BDF", "CyRK-Radau"} <= set(names)
    assert not {"ETD2", "CashKarp45", "odes-CVODE-Adams", "sundials-CVODE-Adams",
                "CyRK-RK45"} & set(names)
    assert all(any(n in g[side] for n in names) for side in ("own", "lsoda", "sundials", "cyrk"))


def test_a_speedup_below_one_says_which_method_is_faster():
    from benchmarks.studies.speedup import _ratio
    assert _ratio(43683.2) == "43,683" and _ratio(3.456) == "3.5"
    # ETD2 13.7 ms against Rodas5P 0.55 ms (results/speedup.json) printed as "0.0" before
    assert _ratio(0.0405) == "0.041 (the other method is 24.7× faster)"
    assert _ratio(None) == ""


def test_the_engine_speed_verdict_is_read_from_the_table():
    import pandas as pd
    from benchmarks.studies.engine_speed import _verdict
    goals = pd.DataFrame({"target": ["a", "b", "c", "d", "e"],
                          "target_ms": [1.0, 1.0, 0.4, 1.0, 0.4],
                          "fastest": ["Rodas5P 1e-08", "Exprb43 1e-02", "Rodas5P", "none",
                                      "Rodas5P"],
                          "wall_ms": [1.8, 0.5, 0.44, float("nan"), 0.401],
                          "attempts": [4662, 400, 0, 0, 0],
                          "us_per_attempt": [0.39, 0.7, float("nan"), float("nan"), float("nan")],
                          "met": [False, True, False, False, False]})
    # a miss by a quarter of a per cent reads as one, not as "1×"
    assert _verdict(goals) == ("1 of the 5 speed targets are met. a: missed by 1.8×; Rodas5P "
                               "1e-08 takes 4,662 step attempts at 0.39 µs each. c: missed by "
                               "1.1×. d: no own setting reaches it. e: missed by 1.0025×.")


@pytest.mark.slow
def test_the_engine_speed_start_up_times_run_the_checkout():
    """The start-up timings run this checkout's packages (warm) and a copy without numba's cache
    (cold: it compiles), and the simulate command; each is a positive time and the cold first
    solve pays the compiling the warm one does not (~1 min: make test-slow)."""
    from benchmarks.studies.engine_speed import startup
    t = startup(warm_repeats=1)
    assert set(t) == {"import_warm", "first_solve_warm", "import_cold", "first_solve_cold",
                      "simulate_warm"}
    assert all(0 < v < 600 for v in t.values())
    assert t["first_solve_cold"] > t["first_solve_warm"]
