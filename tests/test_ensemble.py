"""Ensembles (issue 16): compiled batches equal single solves, failures are rows, the Parquet
store resumes, distrusts bad chunk files and refuses a second run or another ensemble. What the
store reads back, against every kind of stray and damaged file, is tests/test_store.py."""

import dataclasses
import shutil
import warnings

import numpy as np
import pandas as pd
import pytest

from benchmarks.ensemble import (BadChunkWarning, ChunkStore, StoreBusy, ensemble, grid,
                                 point_problems, point_rows, read_store)
from benchmarks.ensemble import run as ensemble_run
from benchmarks.ensemble.rows import METRIC_COLUMNS, RESULT_COLUMNS
from integrators import ETD2, Rodas5P, Rosenbrock23
from problems import variant, window

# a 4 × 3 grid around the W2 slip-law fit, 10 s a point: stick–slip, oscillations about vL and
# points too short to classify among its 12 points (checked below, so the grid keeps covering
# more than one class)
B_AXIS = [0.0084, 0.0090, 0.0094, 0.0100]
LC_AXIS = [5e-8, 3e-7, 2e-6]


@pytest.fixture(scope="module")
def base():
    return window("W2", "slip", t_end=10.0)


@pytest.fixture(scope="module")
def points():
    return grid(b=B_AXIS, lc=LC_AXIS)


def _same(a: pd.DataFrame, b: pd.DataFrame, rtol: float = 1e-12) -> None:
    """Every column equal (text and counters exactly, metrics to rtol), wall time aside."""
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        if c == "wall_s":
            continue
        x, y = a[c].to_numpy(), b[c].to_numpy()
        if c in METRIC_COLUMNS or c == "kappa":
            np.testing.assert_allclose(x.astype(float), y.astype(float), rtol=rtol, atol=0,
                                       equal_nan=True, err_msg=c)
        else:
            assert (x == y).all(), (c, x, y)


def test_grid_is_the_outer_product_first_axis_outermost():
    g = grid(b=[1.0, 2.0], lc=[3.0, 4.0, 5.0])
    assert g["b"].tolist() == [1, 1, 1, 2, 2, 2]
    assert g["lc"].tolist() == [3, 4, 5, 3, 4, 5]


@pytest.mark.parametrize("method", [Rodas5P, Rosenbrock23])
def test_batched_rows_equal_single_solves(base, points, method):
    algorithm = method(rtol=1e-4, atol=1e-4)
    table = ensemble(base, algorithm, points, progress=False, workers=2)
    assert table.attrs["batched"] and len(table) == 12
    assert list(table.columns) == ["b", "lc", *RESULT_COLUMNS]
    names, values = ("b", "lc"), np.column_stack([points["b"], points["lc"]])
    single = point_rows(point_problems(base, names, values), algorithm, names, values)
    _same(table, single)
    assert table.classification.nunique() >= 2, table.classification.value_counts()
    assert (table.retcode == "Success").all()


def test_batched_curves_are_the_dense_output_of_the_same_steps():
    """A compiled batch's slip-weakening curves (a second solve of each point, saved at 257
    times over its last event) are the single solve's curves from a trajectory saved every
    10 µs (W2's events last ~9 ms): the friction at the batch's slips within 3e-4 (the
    reference's linear interpolation between its samples, measured at 1.3e-4; a curve of
    another event or time would be off by up to the drop, ~0.04); the other columns are the
    batch's without curves, the counters doubled (two solves of every point with a cycle)."""
    base = window("W2", "slip")                   # 40 s: three limit cycles, one oscillation
    points = {"b": np.array([0.0094, 0.0096, 0.0094, 0.0088]),
              "lc": np.array([3e-7, 3e-7, 6e-7, 3e-7])}
    algorithm = Rodas5P(rtol=1e-6, atol=1e-6)
    plain = ensemble(base, algorithm, points, progress=False, workers=2)
    table = ensemble(base, algorithm, points, progress=False, workers=2, curve_dt=1e-5)
    names, values = ("b", "lc"), np.column_stack([points["b"], points["lc"]])
    single = point_rows(point_problems(base, names, values), algorithm, names, values,
                        curve_dt=1e-5)
    cycle = table.classification.isin(["stick-slip", "multiple recurrence"]).to_numpy()
    assert cycle.tolist() == [True, True, True, False]
    counters = ["nfev", "njev", "steps", "rejected"]
    _same(table[plain.columns].drop(columns=counters), plain.drop(columns=counters))
    np.testing.assert_array_equal(table.nfev, np.where(cycle, 2, 1) * plain.nfev)
    for i in np.flatnonzero(cycle):
        s, f = table.curve_slip[i], table.curve_friction[i]
        ref_s, ref_f = single.curve_slip[i], single.curve_friction[i]
        assert len(s) == 257 and s[0] == 0 and (np.diff(s) > 0).all()
        assert s[-1] == pytest.approx(ref_s[-1], rel=1e-4)
        np.testing.assert_allclose(f, np.interp(s, ref_s, ref_f), atol=3e-4, rtol=0)
    assert len(table.curve_slip[3]) == 0


def test_failures_are_rows_with_their_retcode(base, points):
    """A step budget that runs out is a row (retcode MaxSteps, its message, no metrics), in a
    batch as in a single solve; the batch goes on."""
    algorithm = Rodas5P(rtol=1e-4, atol=1e-4, max_steps=50)
    table = ensemble(base, algorithm, points, progress=False)
    assert (table.retcode == "MaxSteps").all() and (table.classification == "failed").all()
    assert table.message.str.startswith("step budget of 50 used up at t = ").all()
    assert table[list(METRIC_COLUMNS)].isna().all().all()
    names, values = ("b", "lc"), np.column_stack([points["b"], points["lc"]])
    _same(table, point_rows(point_problems(base, names, values), algorithm, names, values))


def test_a_wall_budget_stops_each_point_not_the_batch(base):
    table = ensemble(variant(base, t_end=200.0), Rodas5P(rtol=1e-6, atol=1e-6),
                     {"b": [0.0094, 0.0095]}, wall_budget=1e-6, progress=False)
    assert (table.retcode == "WallTime").all(), table.message.tolist()
    assert table.message.str.contains("wall-time budget of 1e-06 s used up").all()


def test_methods_without_batches_run_point_by_point(base):
    """ETD2 is not on the compiled engine: the same table, solved through solve()."""
    params = {"b": [0.0094], "lc": [3e-7]}
    table = ensemble(variant(base, t_end=2.0), ETD2(), params, progress=False)
    assert not table.attrs["batched"] and table.integrator.tolist() == ["ETD2"]
    assert table.retcode.tolist() == ["Success"]


def test_any_scalar_field_can_vary(base):
    table = ensemble(base, Rodas5P(rtol=1e-4, atol=1e-4),
                     {"stiffness": [1.2e8, 1.48e8], "vls": [5e-5, 7.5e-5]}, progress=False)
    assert list(table.columns[:2]) == ["stiffness", "vls"]
    assert table.kappa.iloc[0] != table.kappa.iloc[1]


@pytest.mark.parametrize("params, match", [
    ({"foo": [1.0]}, "'foo' is not a field"),
    ({"b": [0.009, 0.01], "lc": [3e-7]}, "differ in length"),
    ({"b": [0.009, np.nan]}, "must be finite"),
    ({"b": [0.009, 1.5]}, r"point 1 \(b = 1.5\): b = 1.5 is impossible"),
    # the growth rates of all points come from one call: a bad one is still named
    ({"mass": [1.0, 1e-10], "stiffness": [1.2e8, 1e305]},
     r"point 1 \(mass = 1e-10, stiffness = 1e\+305\): the linear stability .* overflows"),
    ({"a": [0.008, 1e-200], "normal_force": [1e6, 1e-200]},
     r"point 1 \(a = 1e-200, normal_force = 1e-200\): a \* normal_force = "),
    ({}, "non-empty mapping"),
])
def test_misuse_is_refused_before_any_work(base, params, match, tmp_path):
    with pytest.raises(ValueError, match=match):
        ensemble(base, Rodas5P(rtol=1e-4, atol=1e-4), params, store=tmp_path / "s",
                 progress=False)
    assert not (tmp_path / "s").exists()


def test_max_points_bounds_the_ensemble(base):
    with pytest.raises(ValueError, match="more than max_points = 3"):
        ensemble(base, Rodas5P(rtol=1e-4, atol=1e-4), grid(b=[0.009, 0.01], lc=[1e-7, 2e-7]),
                 max_points=3)


# --- the store ------------------------------------------------------------------------------
def _run(base, points, store, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BadChunkWarning)
        return ensemble(base, Rodas5P(rtol=1e-4, atol=1e-4), points, store=store, chunk_size=3,
                        progress=False, **kw)


def test_the_store_reads_back_and_resumes(base, points, tmp_path):
    first = _run(base, points, tmp_path)
    assert len(list(tmp_path.glob("*.parquet"))) == 4
    _same(read_store(tmp_path), first)
    again = _run(base, points, tmp_path)
    assert again.attrs["n_resumed"] == 12 and again.attrs["n_run"] == 0
    _same(again, first)
    assert (again.wall_s == first.wall_s).all()          # read back, not solved again


def test_a_stopped_run_loses_no_finished_chunk(base, points, tmp_path, monkeypatch):
    """A run stopped between chunks (Ctrl-C after the second chunk) keeps the two finished
    chunks; the rerun solves only the other two, and the table is the uninterrupted one."""
    whole = _run(base, points, tmp_path / "whole")
    real = ensemble_run.run_chunk

    def stop_after_two(chunk):
        if chunk.first == 6:                      # the third chunk of 3 points
            raise KeyboardInterrupt
        return real(chunk)
    monkeypatch.setattr(ensemble_run, "run_chunk", stop_after_two)
    with pytest.raises(KeyboardInterrupt):
        _run(base, points, tmp_path / "s")
    monkeypatch.setattr(ensemble_run, "run_chunk", real)
    assert len(list((tmp_path / "s").glob("*.parquet"))) == 2
    resumed = _run(base, points, tmp_path / "s")
    assert resumed.attrs["n_resumed"] == 6 and resumed.attrs["n_run"] == 6
    _same(resumed, whole)
    assert len(read_store(tmp_path / "s")) == 12     # nothing lost, nothing twice


def test_bad_chunk_files_are_recomputed_not_trusted(base, points, tmp_path):
    first = _run(base, points, tmp_path)
    files = sorted(tmp_path.glob("*.parquet"))
    data = files[0].read_bytes()
    files[0].write_bytes(data[: len(data) // 2])                  # truncated
    files[1].write_bytes(b"garbage")                              # not Parquet
    shutil.copyfile(files[3], files[2])                           # another chunk's file
    with pytest.warns(BadChunkWarning) as caught:
        again = ensemble(base, Rodas5P(rtol=1e-4, atol=1e-4), points, store=tmp_path,
                         chunk_size=3, progress=False)
    named = " ".join(str(w.message) for w in caught)
    assert all(f.name in named for f in files[:3]) and files[3].name not in named
    assert again.attrs["n_run"] == 9 and len(again.attrs["bad_chunks"]) == 3
    _same(again, first)
    _same(read_store(tmp_path), first)


def test_a_second_run_on_a_busy_store_is_refused(base, points, tmp_path):
    _run(base, points, tmp_path)
    import json
    identity = json.loads((tmp_path / "_ensemble.json").read_text())
    del identity["chunks"]                                # the listing, not the identity
    with ChunkStore(tmp_path, identity):
        with pytest.raises(StoreBusy, match="in use by another run"):
            _run(base, points, tmp_path)


def test_a_store_of_another_ensemble_is_refused(base, points, tmp_path):
    _run(base, points, tmp_path)
    with pytest.raises(ValueError, match="holds another ensemble .*points_sha256"):
        _run(base, grid(b=B_AXIS, lc=[1e-7]), tmp_path)
    with pytest.raises(ValueError, match="holds another ensemble .*algorithm"):
        ensemble(base, Rodas5P(rtol=1e-5, atol=1e-5), points, store=tmp_path, chunk_size=3,
                 progress=False)


def test_a_pool_of_processes_after_threads_and_serial_batches_agree(base, points):
    """A threaded batch starts OpenMP in this process; a pool forked from it must not (GNU
    OpenMP aborts such a child): its chunks run single-threaded. Same rows all three ways."""
    algorithm = Rodas5P(rtol=1e-4, atol=1e-4)
    threads = ensemble(base, algorithm, points, workers=2, progress=False)
    one = ensemble(base, algorithm, points, workers=1, progress=False)
    pool = ensemble(base, algorithm, points, workers=2, backend="processes", chunk_size=4,
                    progress=False)
    _same(one, threads)
    _same(pool, threads)


def test_a_point_that_cannot_start_is_refused_before_any_work(base, tmp_path):
    """b = 0 under the slip law with a given θ ≠ 0: Ψ = θ/B is undefined. The problem is built,
    but its nondimensional form fails; that is found before the first solve."""
    from problems import InitialState
    given = dataclasses.replace(base, initial=InitialState(v=7.5e-5, theta=1e3, fs=6e5))
    with pytest.raises(ValueError, match=r"point 1 \(b = 0\)"):
        ensemble(given, Rodas5P(rtol=1e-4, atol=1e-4), {"b": [0.0094, 0.0]},
                 store=tmp_path / "s", progress=False)
    assert not (tmp_path / "s").exists()


def test_a_bad_chunk_is_moved_aside_so_readers_never_see_it(base, points, tmp_path):
    _run(base, points, tmp_path)
    target = sorted(tmp_path.glob("*.parquet"))[0]
    target.write_bytes(b"garbage")
    again = _run(base, points, tmp_path)
    assert (tmp_path / f".bad-{target.name}").read_bytes() == b"garbage"
    _same(read_store(tmp_path), again)          # the recomputed chunk, once


def test_a_store_written_by_other_code_is_refused_or_reclaimed(base, points, tmp_path):
    import json
    _run(base, points, tmp_path)
    identity = json.loads((tmp_path / "_ensemble.json").read_text())
    (tmp_path / "_ensemble.json").write_text(json.dumps({**identity, "code": "0" * 16}))
    with pytest.raises(ValueError, match="holds another ensemble .*code"):
        _run(base, points, tmp_path)
    again = _run(base, points, tmp_path, reclaim_store=True)     # a cache of the harness
    assert again.attrs["n_run"] == 12 and len(read_store(tmp_path)) == 12


def test_grid_errors_count_a_missing_or_failed_dt_as_infinite_and_skip_points_left_out():
    """The ensemble study's accuracy on the grid's points: relative ΔT error against the
    reference over the points that count (values made up here, errors worked by hand)."""
    from benchmarks.studies.ensemble_scaling import grid_errors
    ref = pd.DataFrame({"recurrence_s": [10.0, 20.0, 5.0, np.nan],
                        "classification": ["stick-slip"] * 3 + ["not converged"]})
    counts = pd.Series([True, True, False, False])
    good = ref.assign(recurrence_s=[10.01, 19.99, 99.0, np.nan], retcode="Success")
    e = grid_errors(good, ref, counts)
    assert e["worst_dt_error"] == pytest.approx(1e-3)          # |10.01 − 10|/10; point 2 left out
    assert e["points_compared"] == 2 and e["same_class"] == 1.0
    missing = good.assign(recurrence_s=[10.0, np.nan, 5.0, np.nan],
                          classification=["stick-slip", "not converged", "stick-slip",
                                          "not converged"])
    e = grid_errors(missing, ref, counts)
    assert e["worst_dt_error"] == np.inf and e["same_class"] == 0.75
    failed = good.assign(retcode=["Success", "MaxSteps", "Success", "Success"])
    assert grid_errors(failed, ref, counts)["worst_dt_error"] == np.inf


def test_the_ensemble_report_judges_the_fastest_setting_within_the_level():
    from benchmarks.studies.ensemble_scaling import TARGETS, scaling_markdown
    errs = dict(p95_dt_error=1e-4, points_compared=3, same_class=1.0)
    grid = {"n_points": 4, "wall_1_thread_s": 0.8, "wall_2_threads_s": 0.45,
            "thread_speedup": 1.8, "per_point_ratio": 1.0, "sum_standalone_solve_s": 0.8,
            "sum_batch_solve_s": 0.8,
            "accuracy": {"references": "A and B at 1e-10", "references_agree": 1e-9,
                         "points_left_out": 1, "recommended": dict(errs, worst_dt_error=2e-3),
                         "settings": [], "fastest_within_level": None}}
    text = scaling_markdown({"integrator_choice": "X", "targets": TARGETS, "grid": grid})
    assert "none within the level | **missed**" in text
    fast = {"integrator": "Rodas5P", "rtol": 1e-4, "wall_2_threads_s": 0.4,
            "worst_dt_error": 5e-4, **errs}
    grid["accuracy"].update(settings=[fast], fastest_within_level=fast)
    text = scaling_markdown({"integrator_choice": "X", "targets": TARGETS, "grid": grid})
    assert "0.4 s (Rodas5P at 0.0001, worst 0.0005) | met" in text
    assert "| Rodas5P | 0.0001 | 0.4 | 0.0005 | 0.0001 | 100.0% |" in text
