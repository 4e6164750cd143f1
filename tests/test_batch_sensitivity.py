"""Batches with forward sensitivities (integrators/own/batch_sensitivity.py): each point's
limit-cycle gradient is the single solve's (benchmarks.physics.metrics.cycle_gradient), on
numba's threads and serially; the ensemble's and the sweep's gradient columns, stored and read
back; misuse refused before any work."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from benchmarks.ensemble import ensemble
from benchmarks.ensemble.rows import columns_of, gradient_columns
from benchmarks.physics.metrics import CYCLES, METRICS, cycle_gradient
from integrators import solve
from integrators.own.exprb43 import Exprb43
from integrators.own.radau5 import RadauIIA5
from integrators.own.rodas5p import Rodas5P
from problems.presets import window
from problems.slider import variant

NAMES = ("b", "lc")
DATA = Path(__file__).parent / "data"


def _points():
    base = window("W2", law="slip")          # 40 s: a cycle at each point
    return base, [variant(base, b=base.law.b * f) for f in (0.99, 1.0, 1.01)]


@pytest.mark.parametrize("cls", [Rodas5P, RadauIIA5])
def test_batch_gradients_are_the_single_solves(cls):
    """A batch takes each point's steps as the single solve does (save grid (0, t_end), the
    sensitivities in the step control), so the gradients agree to rounding; threads and one
    thread give the same numbers."""
    alg = cls(rtol=1e-8, atol=1e-8)
    _, points = _points()
    R, grad = alg.solve_batch(points, sensitivity=NAMES)
    _, again = alg.solve_batch(points, sensitivity=NAMES, parallel=False)
    assert np.array_equal(grad, again, equal_nan=True)
    assert grad.shape == (3, 4, 2)
    for i, problem in enumerate(points):
        want = cycle_gradient(solve(problem, alg, sensitivity=NAMES, max_points=2))
        assert want, f"point {i} has no cycle gradient"
        ref = np.array([[want[m][n] for n in NAMES] for m in METRICS])
        assert np.allclose(grad[i], ref, rtol=1e-9, atol=0.0), (i, grad[i], ref)


def test_ensemble_gradient_columns_stored_and_read_back(tmp_path):
    """The ensemble's table has d_<metric>/d_<parameter> after the results, finite for each
    limit cycle (the single solve's), NaN for a point without one (a run too short for a
    cycle); a rerun with a store reads them back."""
    base, points = _points()
    alg = Rodas5P(rtol=1e-8, atol=1e-8)
    params = {"b": [points[0].law.b, points[1].law.b], "t_end": [40.0, 0.05]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = ensemble(base, alg, params, sensitivity=NAMES, progress=False,
                         store=tmp_path / "store")
        again = ensemble(base, alg, params, sensitivity=NAMES, progress=False,
                         store=tmp_path / "store")
        other_steps = r"differing: sensitivity_error \(held True, asked False\)\)"
        with pytest.raises(ValueError, match=other_steps):
            ensemble(base, alg, params, sensitivity=NAMES, sensitivity_error=False,
                     progress=False, store=tmp_path / "store")
        # without sensitivities, the store differs in them only (their error control is
        # recorded only with them)
        none = r"differing: sensitivity \(held \['b', 'lc'\], asked None\)\)"
        with pytest.raises(ValueError, match=none):
            ensemble(base, alg, params, progress=False, store=tmp_path / "store")
    assert list(first.columns) == columns_of(["b", "t_end"], False, NAMES)
    assert again.attrs["n_resumed"] == 2
    cols = gradient_columns(NAMES)
    assert first.classification[0] in CYCLES and first.classification[1] not in CYCLES
    assert np.isfinite(first.loc[0, cols].to_numpy(float)).all()
    assert np.isnan(first.loc[1, cols].to_numpy(float)).all()
    assert np.array_equal(first[cols].to_numpy(float), again[cols].to_numpy(float),
                          equal_nan=True)
    want = cycle_gradient(solve(points[0], alg, sensitivity=NAMES, max_points=2))
    assert first.loc[0, "d_recurrence_s/d_lc"] == pytest.approx(want["recurrence_s"]["lc"],
                                                                rel=1e-9)


@pytest.mark.parametrize("bad, match", [
    (dict(algorithm=Exprb43(rtol=1e-6, atol=1e-6)), "Exprb43 has no forward sensitivities"),
    (dict(curve_dt=5e-5), "has no sensitivities; ask for one or the other"),
    (dict(sensitivity=("b", "zz")), "^sensitivity: .*has no parameter 'zz'"),   # not a point's
    (dict(algorithm=Exprb43(rtol=1e-6, atol=1e-6), curve_dt=5e-5, sensitivity=("zz",)),
     "Exprb43 has no forward sensitivities"),           # the method first, then the rest
    (dict(sensitivity_error="yes"), "sensitivity_error must be True or False"),
    (dict(params={"mass": [1.0, 0.0]}), r"point 1 \(mass = 0\): .*quasi-static limit"),
])
def test_misuse_is_refused_before_any_work(bad, match, monkeypatch):
    import benchmarks.ensemble.run as run
    monkeypatch.setattr(run, "_solve_chunks", lambda *a, **k: pytest.fail("work started"))
    base, _ = _points()
    args = {**dict(algorithm=Rodas5P(rtol=1e-8, atol=1e-8), sensitivity=NAMES,
                   params={"b": [base.law.b]}), **bad}
    alg, params = args.pop("algorithm"), args.pop("params")
    with pytest.raises(ValueError, match=match):
        ensemble(base, alg, params, progress=False, **args)


@pytest.mark.needs("pyarrow")
def test_sweep_writes_gradient_columns(tmp_path, capsys):
    """``rsfbench sweep --sensitivity b,lc`` (no --integrator: a method with sensitivities)
    writes the gradients into sweep.csv; with slip-weakening curves it is refused."""
    import pandas as pd

    from benchmarks.cli.main import main
    assert main(["sweep", "--preset", "W2", "--law", "slip",
                 "--b", "0.0093:0.0094:0.0001", "--lc", "5e-7:6e-7:2", "--sensitivity", "b,lc",
                 "--no-solver-check", "--no-plot", "--no-progress", "--workers", "1",
                 "--out", str(tmp_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    columns = [c + "_m" if c.endswith("/d_lc") else c for c in gradient_columns(NAMES)]
    assert summary["gradient_columns"] == columns         # per metre, as the table's lc_m
    # the front's fastest setting with sensitivities at rtol <= 1e-6 within 1e-3
    assert "RadauIIA5 [numba] at 1e-06" in summary["integrator_choice"]
    table = pd.read_csv(tmp_path / "sweep.csv")
    cycle = table.classification.isin(CYCLES)
    assert cycle.any()
    assert np.isfinite(table.loc[cycle, columns].to_numpy(float)).all()
    assert main(["sweep", "--preset", "W2", "--law", "slip", "--b", "0.0093:0.0093:0.0001",
                 "--lc", "5e-7:5e-7:1", "--slip-weakening", str(DATA / "W2_slip_weakening.csv"),
                 "--sensitivity", "b", "--out", str(tmp_path / "no")]) == 2
    assert "not with slip-weakening curves" in capsys.readouterr().err
    assert not (tmp_path / "no").exists()


def test_a_numpy_bool_is_a_flag():
    """``sensitivity_error=np.True_`` (a flag read from an array or a table) is True, for a
    single solve and an ensemble alike; 1 is refused."""
    base, _ = _points()
    short = variant(base, t_end=0.05)
    alg = Rodas5P(rtol=1e-8, atol=1e-8)
    assert solve(short, alg, sensitivity=("b",), sensitivity_error=np.True_).success
    table = ensemble(short, alg, {"b": [base.law.b]}, sensitivity=("b",),
                     sensitivity_error=np.False_, progress=False)
    assert table.retcode[0] == "Success"
    with pytest.raises(ValueError, match="sensitivity_error must be True or False, got 1"):
        solve(short, alg, sensitivity=("b",), sensitivity_error=1)
