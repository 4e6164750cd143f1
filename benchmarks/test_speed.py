"""pytest-benchmark suite: every integrator on each benchmark problem at a matched accuracy.

    pytest benchmarks --benchmark-json results/benchmarks.json      (``make bench``)

Matched accuracy: each integrator runs at the loosest rung of its work-precision ladder whose
recurrence-interval error is within ``MATCHED_ERROR`` of the reference, as measured by the
committed quick study (``results/wp_quick.csv``, counted as its Pareto summary does: that setting
and every tighter one reach it; from ``rsfbench work-precision --study quick``);
where that file has no row for a problem, the ladder is climbed here. An integrator that never
reaches the accuracy within its budget is skipped, with the reason. One benchmark per
(integrator, problem), grouped by problem; the achieved errors, rhs evaluations and steps of the
timed run are in ``extra_info``. Not part of ``make test``: timings are not assertions.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.devtools.errors import errors
from benchmarks.devtools.reference import reference
from benchmarks.devtools.work_precision import (
    QUICK,
    measure,
    reliable_error,
    settings,
    study_problems,
)
from integrators import REGISTRY, solve

MATCHED_ERROR = 1e-4
WP_CSV = Path(__file__).resolve().parents[1] / "results" / "wp_quick.csv"
PROBLEMS = {p.name: p for p in study_problems("quick")}


@functools.cache
def _study() -> pd.DataFrame | None:
    """The committed quick study, read once, errors counted as its Pareto summary counts them."""
    if not WP_CSV.exists():
        return None
    df = pd.read_csv(WP_CSV)
    return df.assign(err_recurrence=reliable_error(df))


def _from_study(problem_name: str, name: str):
    """The loosest setting of the committed study that reached the accuracy, or None."""
    df = _study()
    if df is None:
        return None
    rows = df[(df.problem == problem_name) & (df.integrator == name) & (df.rhs_tier == "numba")]
    if not len(rows):
        return None
    hit = rows[(rows.retcode == "Success") & (rows.err_recurrence <= MATCHED_ERROR)]
    return "unreached" if not len(hit) else hit.sort_values("setting", ascending=False).iloc[0].setting


def _matched(problem, name: str):
    """(algorithm, how the setting was chosen), or pytest.skip."""
    cls = REGISTRY[name]
    ladder = settings(cls, QUICK, "numba")
    setting = _from_study(problem.name, name)
    if setting == "unreached":
        pytest.skip(f"{name} did not reach {MATCHED_ERROR:g} on {problem.name} in {WP_CSV.name}")
    if setting is not None:
        for _, value, algorithm in ladder:
            if value == pytest.approx(setting, rel=1e-12):
                return algorithm, WP_CSV.name
    ref = reference(problem)
    for _, value, algorithm in ladder:
        point = measure(problem, algorithm, ref, QUICK)
        if point["retcode"] != "Success":
            break
        if point["err_recurrence"] <= MATCHED_ERROR:
            return algorithm, "ladder climbed in this run"
    pytest.skip(f"{name} did not reach {MATCHED_ERROR:g} on {problem.name} within its ladder")


@pytest.mark.parametrize("problem_name", list(PROBLEMS))
@pytest.mark.parametrize("name", sorted(REGISTRY, key=str.lower))
def test_matched_accuracy(benchmark, name, problem_name):
    problem = PROBLEMS[problem_name]
    algorithm, chosen_by = _matched(problem, name)
    solve(problem, algorithm, max_points=2)               # warm-up: numba compiles here
    probe = solve(problem, algorithm, max_points=2, wall_budget=QUICK.wall_budget)
    rounds = 5 if probe.stats.wall_s < 1.0 else 1
    benchmark.group = problem_name
    sol = benchmark.pedantic(solve, args=(problem, algorithm), kwargs={"max_points": 2},
                             rounds=rounds, iterations=1)
    errs = errors(sol, reference(problem))
    benchmark.extra_info.update({
        "integrator": name, "options": json.dumps(algorithm.options()), "chosen_by": chosen_by,
        "retcode": sol.retcode.value, "nfev": sol.stats.nfev, "steps": sol.stats.steps,
        "njev": sol.stats.njev, **errs})
    assert sol.success, sol.message
