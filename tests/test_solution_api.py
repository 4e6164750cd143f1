"""What a user does with a Solution: ``sol(t)`` from the method's dense output, the run with its
events resolved, ``to_dataframe()``, ``plot()``; ``rsfbench simulate --save``; the one line a
first compile prints."""

import dataclasses
import json
import types

import numpy as np
import pandas as pd
import pytest

from benchmarks.cli import main
from integrators import ETD2, RadauIIA5, Rodas5P, Stats, algorithm_class, solve
from integrators.core import cache
from problems import paper_example, window


@pytest.fixture(scope="module")
def problem():
    return paper_example(t_end=6.0)


@pytest.fixture(scope="module")
def sol(problem):
    return solve(problem, Rodas5P(rtol=1e-8, atol=1e-8), max_points=300)


def test_sol_at_the_saved_times_is_the_saved_trajectory_to_the_bit(sol):
    # the repeated solve takes the same steps, and its dense output at the same times gives
    # the same numbers: nothing is interpolated from the saved points
    again = sol(sol.t[::7])
    saved = sol.to_dataframe().iloc[::7].reset_index(drop=True)
    assert again.equals(saved) and again.attrs == saved.attrs


def test_sol_between_the_saved_points_is_the_dense_output_of_the_run(problem, sol):
    # times inside the events, where the 300 saved points say nothing (the slip rate varies by
    # 1e4 across an event): against an independent method at a tight tolerance. The
    # differences (measured: 4.3e-4 in v, 2.3e-6 in Fs) are Rodas5P's own at 1e-8, its third
    # event ~3e-7 s off where Fs falls at ~4e6 N/s, not the interpolant's
    t = np.sort(np.concatenate([np.linspace(a, b, 9) for a, b in sol.event_array[:, :2]]))
    ours = sol(t)
    ref = solve(problem, RadauIIA5(rtol=1e-11, atol=1e-11), save_at=t)
    assert np.array_equal(ours.t, t)
    assert np.allclose(ours.v, ref.v, rtol=2e-3) and np.allclose(ours.fs, ref.fs, rtol=1e-5)
    scalar = sol(float(t[3]))
    assert len(scalar) == 1 and scalar.v[0] == ours.v[3]


def test_a_peer_interpolates_with_its_own_dense_output(problem):
    peer = solve(problem, algorithm_class("scipy-Radau")(rtol=1e-7, atol=1e-7), max_points=50)
    # the same steps; scipy evaluates its interpolant over another batch of times, which moves
    # the last bits (measured: 2e-14 at one of ten points)
    assert np.allclose(peer(peer.t[10:20]).v, peer.v[10:20], rtol=1e-12, atol=0.0)


def test_sol_refuses_a_method_without_dense_output_and_a_failed_run(problem, sol):
    etd = solve(problem, ETD2(), max_points=10)
    with pytest.raises(ValueError, match="sol\\(t\\) needs a method with dense output; ETD2"):
        etd(1.0)
    short = solve(problem, Rodas5P(rtol=1e-8, atol=1e-8, max_steps=20), max_points=10)
    assert not short.success
    with pytest.raises(ValueError, match="needs a successful run; this one ended MaxSteps"):
        short(0.1)
    with pytest.raises(ValueError, match="outside the run"):
        sol(np.array([-1.0]))
    with pytest.raises(ValueError, match="t must be a time or an array of times in s"):
        sol("abc")


def test_resolved_draws_each_event_from_the_dense_output(sol):
    # 300 points over 6 s are 20 ms apart: the events (~10 ms) fall between them
    assert sol.v.max() < 0.5 * sol.event_array[:, 4].max()
    fine = sol.resolved(per_event=400)
    assert set(sol.t) <= set(fine.t) and len(fine.t) >= len(sol.t) + 400 * len(sol.event_array) - 10
    # the exact peaks (root-found, in the events table) are reached within the dense output's
    # resolution of 1/400 of an event
    assert fine.v.max() == pytest.approx(sol.event_array[:, 4].max(), rel=1e-3)
    with pytest.raises(ValueError, match="per_event"):
        sol.resolved(per_event=0)


def test_to_dataframe_has_the_columns_and_units_and_parquet_keeps_them(sol, tmp_path):
    df = sol.to_dataframe()
    assert list(df.columns) == ["t", "v", "fs", "ft", "mu", "theta"] and len(df) == len(sol.t)
    assert df.attrs["units"]["theta"] == "N" and df.attrs["integrator"] == "Rodas5P"
    assert np.array_equal(df.mu, sol.fs / sol.problem.normal_force)
    aging = solve(window("W2", "aging", t_end=2.0), Rodas5P(rtol=1e-6, atol=1e-6), max_points=5)
    assert aging.to_dataframe().attrs["units"]["theta"] == "s"
    pytest.importorskip("pyarrow")
    df.to_parquet(tmp_path / "t.parquet")
    back = pd.read_parquet(tmp_path / "t.parquet")
    assert back.equals(df) and back.attrs["units"] == df.attrs["units"]


def test_plot_writes_a_figure(sol, tmp_path):
    fig = sol.plot(tmp_path / "run.png")
    assert (tmp_path / "run.png").stat().st_size > 10_000
    assert len(fig.axes) == 2


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_simulate_save_writes_a_trajectory_pandas_reads_and_what_it_is(tmp_path, capsys, suffix):
    if suffix == ".parquet":
        pytest.importorskip("pyarrow")
    path = tmp_path / f"traj{suffix}"
    rc = main(["simulate", "--preset", "W2", "--t-end", "3", "--save", str(path), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["trajectory"]["file"] == str(path)
    df = pd.read_csv(path) if suffix == ".csv" else pd.read_parquet(path)
    assert list(df.columns) == ["t", "v", "fs", "ft", "mu", "theta"] and len(df) == 20_000
    about = json.loads(path.with_name(path.name + ".json").read_text())
    assert about["columns"]["v"] == "m/s" and about["command"].startswith("rsfbench simulate")
    assert about["run"]["n_events"] == out["n_events"] and about["git_commit"]


def test_simulate_save_and_plot_create_their_directories(tmp_path, capsys):
    path, figure = tmp_path / "new" / "traj.csv", tmp_path / "other" / "run.png"
    rc = main(["simulate", "--preset", "W2", "--t-end", "2", "--save", str(path), "--plot",
               str(figure)])
    assert rc == 0 and path.exists() and figure.exists(), capsys.readouterr().err


def test_simulate_save_refuses_another_suffix_in_one_line(tmp_path, capsys):
    rc = main(["simulate", "--preset", "W2", "--save", str(tmp_path / "t.txt")])
    err = capsys.readouterr().err
    assert rc == 2 and "must end in .csv or .parquet" in err and "Traceback" not in err


def _dispatcher(tmp_path, signatures=(), index_exists=False):
    index = tmp_path / "k.nbi"
    if index_exists:
        index.write_text("")
    file = types.SimpleNamespace(_index_path=str(index))
    return types.SimpleNamespace(signatures=list(signatures),
                                 _cache=types.SimpleNamespace(_cache_file=file))


def test_a_first_compile_says_so_once_and_a_cached_or_built_kernel_says_nothing(tmp_path, capsys):
    fresh = _dispatcher(tmp_path)
    assert cache.announce_compile(fresh, "the X kernel")
    assert "rsfbench: compiling the X kernel for its first use (about" in capsys.readouterr().err
    assert not cache.announce_compile(fresh, "the X kernel")           # once a process
    assert not cache.announce_compile(_dispatcher(tmp_path, index_exists=True), "Y")
    assert not cache.announce_compile(_dispatcher(tmp_path, signatures=["sig"]), "Z")
    assert cache.announce_compile(_dispatcher(tmp_path, index_exists=True), "W", cached=False)
    assert "cannot be cached" in capsys.readouterr().err
    assert not cache.announce_compile(object(), "broken")               # never raises


def test_a_solution_pickles_and_interpolates_after(sol):
    import pickle
    back = pickle.loads(pickle.dumps(sol))
    assert back(sol.t[:3]).equals(sol(sol.t[:3]))


def test_stats_is_a_frozen_value_whose_sum_adds_every_counter(sol):
    with pytest.raises(dataclasses.FrozenInstanceError):
        sol.stats.nfev = 0
    a = Stats(nfev=1, njev=2, steps=3, rejected=4, wall_s=0.5)
    b = Stats(nfev=10, njev=20, steps=30, rejected=40, wall_s=0.25)
    assert (a + b).as_dict() == {"nfev": 11, "njev": 22, "steps": 33, "rejected": 44,
                                 "wall_s": 0.75}
    assert sum([a, b, a], Stats()) == Stats(nfev=12, njev=24, steps=36, rejected=48, wall_s=1.25)
