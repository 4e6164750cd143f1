"""Classifying runs at the edges of stability (issue 29): k = kcr, σ = 0 or unknown, masses and
stiffnesses toward the float limits, settled small oscillations about vL, promised lengths."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pandas as pd
import pytest

from benchmarks.physics.metrics import EndState, limit_cycle, summarize
from integrators import Rodas5P, solve
from integrators.core import cycles
from integrators.core.solution import EVENT_COLUMNS
from problems import critical_stiffness, paper_example

FN = 1e6
NO_EVENTS = pd.DataFrame(columns=list(EVENT_COLUMNS), dtype=float)
#: the longest run of the paper example (τ = 1e12 at Lc = 0.5 µm, v0 = 10 µm/s), s
LONGEST = 5e10
PROMISE = re.compile(r"run to t_end ≥ ([0-9.e+]+) s")


def _end(growth, offset=0.2, longest=LONGEST):
    return EndState(log_v=offset, state_offset=offset, force_offset=offset, growth_rate=growth,
                    longest_run=longest)


@pytest.mark.parametrize("growth", [0.0, -0.0, math.nan, 1e-300, -1e-300, 2.0, -2.0])
def test_describe_never_divides_by_the_growth_rate(growth):
    # σ = 0 raised ZeroDivisionError here (k = kcr, or a mass/stiffness near the float limit)
    text = _end(growth).describe()
    assert "steady sliding is" in text
    if growth == 0.0:
        assert "neutrally stable" in text
    if math.isnan(growth):
        assert "unknown" in text


def test_settle_time_from_the_linear_stability():
    tol = cycles.STEADY_LOG_TOLERANCE
    # decaying: ln(offset/tol) e-folds plus the margin
    assert cycles.settle_time(-0.5, 0.2, 3.0) == pytest.approx(
        (math.log(0.2 / tol) + cycles.DECAY_MARGIN_EFOLDS) / 0.5)
    assert cycles.settle_time(-0.5, 0.01, 3.0) == 0.0
    # growing: SETTLE_EFOLDS e-folds since the last event
    assert cycles.settle_time(0.5, 0.2, 3.0) == pytest.approx(cycles.SETTLE_EFOLDS / 0.5 - 3.0)
    assert cycles.settle_time(0.5, 0.2, 1e3) == 0.0
    assert cycles.settle_time(0.0, 0.2, 3.0) == math.inf
    assert math.isnan(cycles.settle_time(math.nan, 0.2, 3.0))


def test_no_events_at_neutral_stability_is_a_steady_oscillation():
    lc = limit_cycle(NO_EVENTS, FN, 10.0, end=_end(0.0))
    assert lc.classification == "oscillation about vL" and "neutral" in lc.reason
    assert np.isnan(lc.recurrence_s)
    # without the longest run known, the rule before it: too short
    lc = limit_cycle(NO_EVENTS, FN, 10.0, end=_end(0.0, longest=math.nan))
    assert lc.classification == "too short to classify"


def test_a_too_short_run_promises_a_length_it_can_have():
    lc = limit_cycle(NO_EVENTS, FN, 10.0, end=_end(-0.5))
    assert lc.classification == "too short to classify"
    promised = float(PROMISE.search(lc.reason).group(1))
    assert promised >= 10.0 + cycles.settle_time(-0.5, 0.2, 10.0)
    lc = limit_cycle(NO_EVENTS, FN, 10.0, end=_end(0.5))
    assert float(PROMISE.search(lc.reason).group(1)) >= cycles.SETTLE_EFOLDS / 0.5
    # unknown stability: no promise, and no crash
    lc = limit_cycle(NO_EVENTS, FN, 10.0, end=_end(math.nan))
    assert lc.classification == "too short to classify" and "unknown" in lc.reason


def test_a_locked_end_is_never_an_oscillation():
    # far from steady sliding (locked, healed): the linear analysis does not apply
    locked = EndState(log_v=-6.0, state_offset=8.0, force_offset=5.0, growth_rate=0.5,
                      longest_run=LONGEST)
    lc = limit_cycle(NO_EVENTS, FN, 1e4, end=locked)
    assert lc.classification == "too short to classify" and "run longer" in lc.reason


def _run(law, factor, t_end):
    p = paper_example(law=law, t_end=t_end)
    p = dataclasses.replace(p, stiffness=critical_stiffness(p) * factor)
    sol = solve(p, Rodas5P(rtol=1e-8, atol=1e-8), max_points=4001)
    return p, sol, summarize(sol)


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_k_equal_to_kcr_is_classified_at_once(law):
    _, sol, lc = _run(law, 1.0, 5.0)
    assert sol.success and len(sol.events) == 0
    assert lc.classification == "oscillation about vL" and "neutral" in lc.reason


def test_a_settled_small_limit_cycle_after_the_promised_length():
    # slip law, k = 0.99 kcr: steady sliding grows e-fold in 6.7 s, and the slip rate settles
    # on a limit cycle between 0.29 and 7.6 vL that never reaches an event (Rodas5P at 1e-8
    # for 2000 s: the same range in each eighth of the run, no event)
    _, _, lc = _run("slip", 0.99, 5.0)
    assert lc.classification == "too short to classify"
    promised = float(PROMISE.search(lc.reason).group(1))
    _, sol, lc = _run("slip", 0.99, promised)
    assert lc.classification == "oscillation about vL" and "small limit cycle" in lc.reason
    # the trajectory says the same: no event, and the last two quarters span the same range
    v = sol.v / sol.problem.loading.v_slow
    n = len(v)
    q3, q4 = v[n // 2:3 * n // 4], v[3 * n // 4:]
    assert len(sol.events) == 0 and v[n // 2:].max() < 10.0
    assert q3.max() == pytest.approx(q4.max(), rel=0.02)
    assert q3.min() == pytest.approx(q4.min(), rel=0.02)


@pytest.mark.parametrize("law", ["slip", "aging"])
def test_a_decaying_oscillation_is_stable_sliding_at_the_promised_length(law):
    _, _, lc = _run(law, 1.01, 5.0)
    assert lc.classification == "too short to classify"
    promised = float(PROMISE.search(lc.reason).group(1))
    _, _, lc = _run(law, 1.01, promised)
    assert lc.classification == "stable sliding"


@pytest.mark.filterwarnings("ignore:.*implausibly large")
@pytest.mark.parametrize("field,value", [("mass", 1e300), ("stiffness", 1e300),
                                         ("mass", 1.7e308)])
def test_float_limit_parameters_are_classified_not_raised(field, value):
    p = dataclasses.replace(paper_example(t_end=0.5), **{field: value})
    sol = solve(p, Rodas5P(rtol=1e-8, atol=1e-8), max_points=101)
    lc = summarize(sol)          # raised ZeroDivisionError (σ rounded to 0.0)
    assert lc.classification in ("stable sliding", "too short to classify",
                                 "oscillation about vL", "failed")
    assert lc.reason


def test_a_growth_rate_that_cannot_be_computed_is_a_reason(monkeypatch):
    import problems.stability

    def singular(problem, v=None):
        raise np.linalg.LinAlgError("Array must not contain infs or NaNs")

    monkeypatch.setattr(problems.stability, "growth_rate", singular)
    sol = solve(paper_example(t_end=0.5), Rodas5P(rtol=1e-8, atol=1e-8), max_points=101)
    lc = summarize(sol)
    assert lc.classification == "too short to classify" and "unknown" in lc.reason


def test_the_locking_study_compares_only_runs_with_a_cycle_of_events(tmp_path):
    from benchmarks.studies.classification import write_classification
    row = dict(group="g", problem="p", b=0.01, lc_um=0.3, t_end_s=1.0, retcode="Success")
    table = pd.DataFrame([
        {**row, "classification": "stick-slip", "period": 1, "n_events": 10,
         "mean_rate_over_vls": 0.01, "min_v_over_vls": 0.01},
        # a small limit cycle without events: no gaps between events, nothing to compare
        {**row, "classification": "oscillation about vL", "period": 0, "n_events": 0,
         "mean_rate_over_vls": np.nan, "min_v_over_vls": np.nan}])
    text = write_classification(table, tmp_path)
    assert "Of 1 periodic runs" in text and "| g | 2 | 1 |" in text


def test_an_uneven_cycle_is_not_stopped_by_where_the_run_ends():
    """A period-2 cycle whose intervals alternate ~0.06 s and ~0.45 s (W2/slip at b =
    0.00868718, Lc = 6.46e-7, found by a hostile probe) was called "too short to classify" when
    t_end fell in its long gap: the quiet-end test read only the last interval. It reads the
    longest of the last max_period now, so the class does not depend on the end's phase."""
    from integrators import RadauIIA5
    from problems import window
    classes = {summarize(solve(window("W2", "slip", b=0.00868718, lc=6.46e-7, t_end=t_end),
                               RadauIIA5(rtol=1e-4, atol=1e-4))).classification
               for t_end in (149.3, 149.6, 150.0)}
    assert classes == {"oscillation about vL"}, classes
