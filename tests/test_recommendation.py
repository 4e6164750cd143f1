"""The commands' default integrator is a constant in code (benchmarks/devtools/recommendation.py), written
from the committed work-precision studies (the quick one and the external problems') and
checked against them here."""

import hashlib
import math
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.devtools import recommendation
from benchmarks.devtools.work_precision import (ADVICE_FILES, STUDY_CSV, advice_study,
                                                front_source, pareto_front, recommend)


def test_the_constant_is_the_committed_studies():
    """Fails when results/wp_quick.csv or wp_external.csv changed without the front being
    rewritten (`rsfbench study work-precision` and `rsfbench study external` do both)."""
    results = STUDY_CSV.parent
    assert recommendation.STUDY["files"] == ADVICE_FILES
    assert recommendation.STUDY["sha256"] == tuple(
        hashlib.sha256((results / f).read_bytes()).hexdigest() for f in ADVICE_FILES)
    front = pareto_front(advice_study(results))
    assert list(recommendation.FRONT) == [tuple(r) for r in front.itertuples(index=False)]
    text = Path(recommendation.__file__).read_text(encoding="utf-8")
    assert front_source(results) in text
    assert recommendation.STUDY["problems"] == 4


@pytest.mark.parametrize("level", [1e-1, 1e-2, 3e-3, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10])
def test_the_front_recommends_what_the_study_does(level):
    advice = recommend(advice_study(STUDY_CSV.parent), [level]).iloc[0]
    algorithm, why = recommendation.recommended(level)
    if pd.isna(advice.get("integrator")):       # beyond the front: its most accurate setting
        worst, _w, name, tier, setting = min(recommendation.FRONT, key=lambda row: row[0])
        assert (algorithm.name, algorithm.rhs, algorithm.rtol) == (name, tier, setting)
        assert "recommend nothing" in why and "most accurate" in why
    else:
        assert (algorithm.name, algorithm.rhs, algorithm.rtol) == (
            advice.integrator, advice.rhs_tier, advice.setting)


def test_pareto_front_keeps_only_rows_no_faster_row_beats():
    # two problems; C is slower and less accurate than B, D only ran on one problem
    rows = [("A", 1e-3, 1.0, 1e-2), ("B", 1e-3, 2.0, 1e-4), ("C", 1e-3, 3.0, 1e-3),
            ("D", 1e-3, 0.1, 1e-9)]
    df = pd.DataFrame([{"problem": p, "integrator": i, "rhs_tier": "numba", "setting": s,
                        "wall_s": w, "retcode": "Success", "err_recurrence": e}
                       for p in ("p1", "p2") for i, s, w, e in rows
                       if not (i == "D" and p == "p2")])
    front = pareto_front(df)
    assert list(front.integrator) == ["A", "B"]
    assert front.total_wall_s.tolist() == [2.0, 4.0] and math.isclose(front.worst_error[1], 1e-4)


def test_the_commands_do_not_read_the_study_at_run_time(monkeypatch, tmp_path):
    from argparse import Namespace

    import benchmarks.devtools.work_precision as wp
    from benchmarks.cli.args import integrator_from_args
    monkeypatch.setattr(wp, "STUDY_CSV", tmp_path / "missing.csv")
    algorithm, why = integrator_from_args(Namespace(integrator=None, rtol=None, atol=None,
                                                    rhs=None, accuracy=1e-3))
    assert algorithm == recommendation.recommended(1e-3)[0] and "work-precision studies" in why


def _worst(algorithm) -> float:
    """The front's worst error of ``algorithm`` (its place on the front)."""
    return next(worst for worst, _w, name, tier, value in recommendation.FRONT
                if name == algorithm.name and tier == algorithm.rhs and value == algorithm.rtol)


def test_tightening_along_the_front_gains_a_factor_each_step_and_then_stops():
    """From the default recommendation, each step is a front setting at least TIGHTER times as
    accurate (its worst error) and the fastest such; the walk ends in None."""
    algorithm, _ = recommendation.recommended(1e-3)
    seen = 0
    while (nxt := recommendation.tighter_on_front(algorithm)) is not None:
        assert _worst(nxt) <= _worst(algorithm) / recommendation.TIGHTER
        # no faster setting of the front is that accurate
        faster = [w for w, wall, *_ in recommendation.FRONT
                  if wall < next(r[1] for r in recommendation.FRONT if r[2:] == (
                      nxt.name, nxt.rhs, nxt.rtol))]
        assert all(w > _worst(algorithm) / recommendation.TIGHTER for w in faster)
        algorithm, seen = nxt, seen + 1
    assert seen >= 3


def test_a_setting_off_the_front_is_not_tightened_along_it():
    from integrators import make_algorithm
    assert recommendation.tighter_on_front(make_algorithm("Exprb43", rtol=2e-3, atol=2e-3)) is None


@pytest.mark.parametrize("level", [1e-3, 1e-5, 1e-7])
def test_the_sensitive_advice_reaches_the_level_at_a_gradients_tolerance(level):
    """--sensitivity's choice: the front's fastest setting with forward sensitivities at
    rtol ≤ 1e-6 within the level (not Rodas5P at 1e-6 whatever the level: its worst over the
    four problems is ~1e-5)."""
    algorithm, why = recommendation.recommended(level, sensitive=True)
    assert getattr(algorithm, "sensitive", False) and algorithm.rtol <= 1e-6
    assert _worst(algorithm) <= level and "with forward sensitivities" in why


def test_a_level_beyond_the_front_warns_and_takes_its_most_accurate_setting():
    with pytest.warns(UserWarning, match="beyond what they vouch for"):
        algorithm, _ = recommendation.recommended(1e-12)
    assert _worst(algorithm) == min(row[0] for row in recommendation.FRONT)


@pytest.mark.parametrize("level", [1e-2, 1e-3, 1e-4, 1e-6, 1e-12])
def test_the_contenders_reach_the_level_at_nearly_the_recommendations_cost(level):
    """The settings a command races on the user's box: the recommendation first, then the
    front's others within the level whose studies' wall is within CONTENDERS_SPAN of it;
    none beyond the front."""
    rivals = recommendation.contenders(level)
    within = [row for row in recommendation.FRONT if row[0] <= level]
    if not within:
        assert rivals == []
        return
    assert rivals[0][0] == recommendation.recommended(level)[0]
    assert all(worst <= level for _a, worst, _w in rivals)
    assert all(wall <= recommendation.CONTENDERS_SPAN * rivals[0][2] for _a, _w, wall in rivals)
    assert len(rivals) == sum(row[1] <= recommendation.CONTENDERS_SPAN * within[0][1]
                              for row in within)
