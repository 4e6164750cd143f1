"""Compiling is never part of a run: the warm-up runs a short piece of the user's own problem
(every kernel it needs, whatever its load history), and a wall budget counts the run only."""

import dataclasses
import json
import os
import subprocess
import sys

import pytest

from integrators import Rodas5P, solve
from integrators.core.solve import compile_ahead, short_piece
from problems import LoadHistory, preset, slide_hold_slide_test, velocity_step_test


def test_a_short_piece_keeps_the_switches_before_its_end_and_the_event_thresholds():
    p = velocity_step_test(t_step=10.0, t_end=20.0)         # one switch at 10 s
    short = short_piece(p, 1e-3)                            # ends at 0.02 s: before the step
    assert short.t_end == pytest.approx(0.02)
    assert short.loading.history.switch_times == ()
    assert short.loading.history.velocities == p.loading.history.velocities[:1]
    assert short.loading.v_slow == p.loading.v_slow
    assert short.initial_state == p.initial_state
    assert short_piece(p, 0.9).loading.history.switch_times == (10.0,)


def test_a_short_piece_of_a_history_that_opens_with_a_hold_slides_at_its_reference_speed():
    p = slide_hold_slide_test(holds=(100.0,), first_slide=10.0, slide=100.0)
    hist = p.loading.history
    opened = dataclasses.replace(p, loading=LoadHistory((0.0,) + hist.velocities[1:],
                                                        hist.switch_times))
    short = short_piece(opened, 1e-4)
    assert short.loading.history.velocities == (hist.v_slow,)
    assert solve(short, Rodas5P(rtol=1e-6, atol=1e-6)).success


def test_the_warm_up_runs_problems_whose_loading_switches():
    # was refused: "the loading switches at t = 10 s, at or after t_end = 0.02 s"
    compile_ahead(velocity_step_test(t_step=10.0, t_end=20.0), Rodas5P(rtol=1e-6, atol=1e-6))
    compile_ahead(preset("W2", law="slip"), Rodas5P(rtol=1e-6, atol=1e-6))


def test_simulate_takes_a_problem_file_whose_loading_switches(tmp_path):
    from probe.harness import cli
    f = tmp_path / "step.toml"
    f.write_text("mass = 0.0\nstiffness = 1e9\nnormal_force = 1e6\nt_end = 800.0\n"
                 "[law]\nname = \"aging\"\na = 0.005\nb = 0.01\nlc = 1e-5\nv0 = 1e-6\n"
                 "[loading]\nvelocities = [1e-6, 1e-5, 0.0, 1e-6]\n"
                 "switch_times = [500.0, 600.0, 700.0]\n")
    run = cli("simulate", "--problem", f, "--json")
    assert run.status == 0, run.err
    assert json.loads(run.out)["retcode"] == "Success"


@pytest.mark.slow
def test_a_wall_budget_excludes_compiling_on_a_cold_cache(tmp_path):
    """A fresh process with an empty numba cache: compiling the engine takes ~20 s here, the
    budget is 0.2 s; the run must stop by its budget (checked every few steps), not after the
    compile."""
    code = ("from integrators import CashKarp45, solve\nfrom problems import preset\n"
            "s = solve(preset('W2', law='slip', t_end=40.0), CashKarp45(rtol=1e-10, atol=1e-10),"
            " wall_budget=0.2)\nprint(s.retcode.name, s.stats.wall_s)")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=600, check=True).stdout.split()
    assert out[0] == "WALL_TIME"
    assert float(out[1]) < 0.2 + 0.1        # the budget, plus the check's granularity


def test_a_setting_that_crawls_cannot_hang_the_warm_up_of_a_budgeted_solve():
    # a step rule of 1e-300 would take minutes to reach the step budget: the warm-up piece is
    # bounded by the same wall budget, then the run by its own
    from integrators import ETD2
    sol = solve(preset("W2", law="slip"), ETD2(dtau_cnst=1e-300), wall_budget=0.5)
    assert sol.retcode.name == "WALL_TIME"
    assert sol.stats.wall_s < 0.5 + 1.0          # the budget, plus the check's granularity
