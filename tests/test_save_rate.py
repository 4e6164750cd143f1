"""``rsfbench simulate --save-rate HZ`` and the event zoom of its figure: the samples are 1/HZ
apart, from the dense output, and the run summarised is the run without the rate (its steps and
events), also for a method whose steps move with its output times; a rate that is not positive,
or would save more than SAVE_LIMIT samples, is refused in one line before any work."""

import json

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from benchmarks.cli.main import main
from benchmarks.physics.plots import draw_event_zoom, event_zoom_window, plot_solution
from integrators import Rodas5P, solve
from integrators.core.solution import SAVE_LIMIT
from problems import window

#: W2 (slip law) over 4 s: a start-up event and two more, each ~9 ms long
RUN = ["simulate", "--preset", "W2", "--t-end", "4", "--integrator", "Rodas5P", "--rtol", "1e-6",
       "--atol", "1e-6", "--json"]


def _simulate(capsys, *extra, run=RUN) -> dict:
    assert main(run + list(extra)) == 0
    return json.loads(capsys.readouterr().out)


def test_save_rate_saves_every_1_over_hz_and_keeps_the_steps(capsys, tmp_path):
    plain = _simulate(capsys, "--save", str(tmp_path / "a.csv"))
    rated = _simulate(capsys, "--save-rate", "25000", "--save", str(tmp_path / "b.csv"))
    for counter in ("steps", "nfev", "n_events"):
        assert rated[counter] == plain[counter], counter
    assert rated["limit_cycle"] == plain["limit_cycle"]
    t = pd.read_csv(tmp_path / "b.csv").t.to_numpy()
    assert len(t) == 4 * 25000 + 1 and t[0] == 0 and t[-1] == 4.0
    np.testing.assert_allclose(np.diff(t), 4e-5, rtol=1e-6)      # CSV keeps ~15 digits
    assert rated["trajectory"]["rows"] == len(t)
    assert rated["trajectory"]["rate_hz"] == pytest.approx(25000)
    # the default is the behaviour before --save-rate: 20,000 samples over the run
    assert plain["trajectory"]["rows"] == 20_000
    assert plain["trajectory"]["rate_hz"] == pytest.approx(19_999 / 4)
    # the samples are those of a solve saving every 4e-5 s: Rodas5P takes the same steps
    # whatever it saves, and reads the same dense output
    direct = solve(window("W2", "slip", t_end=4.0), Rodas5P(rtol=1e-6, atol=1e-6),
                   save_every=4e-5)
    assert direct.stats.steps == plain["steps"]
    np.testing.assert_allclose(pd.read_csv(tmp_path / "b.csv").v, direct.v, rtol=1e-12)


@pytest.mark.slow                      # ~30 s: numbalsoda compiles its driver at first use
@pytest.mark.needs("numbalsoda")
def test_a_method_whose_steps_follow_its_output_times_is_still_the_run_summarised(capsys,
                                                                                  tmp_path):
    # numbalsoda's LSODA steps through its output times (measured on this run at rtol 1e-6:
    # 2,717 steps saving 20,000 points, 2,507 saving at 25 kHz): the summary is the run at
    # the default save grid, and the samples come from a repeat checked to be the same run
    run = [a.replace("Rodas5P", "numbalsoda-LSODA") for a in RUN]
    plain = _simulate(capsys, "--save", str(tmp_path / "a.csv"), run=run)
    rated = _simulate(capsys, "--save-rate", "25000", "--save", str(tmp_path / "b.csv"),
                      run=run)
    assert rated["steps"] == plain["steps"] and rated["nfev"] == plain["nfev"]
    assert rated["limit_cycle"] == plain["limit_cycle"]
    t = pd.read_csv(tmp_path / "b.csv").t.to_numpy()
    assert len(t) == 100_001
    np.testing.assert_allclose(np.diff(t), 4e-5, rtol=1e-6)


@pytest.mark.parametrize("rate, match", [
    ("0", "--save-rate: must be positive"),
    ("-100", "--save-rate: must be positive"),
    ("nan", "--save-rate: must be a finite positive number"),
    ("inf", "--save-rate: must be a finite positive number"),
    ("1e7", f"more than {SAVE_LIMIT:,}"),            # 4e7 samples over 4 s
])
def test_a_bad_save_rate_is_refused_in_one_line_before_any_work(rate, match, capsys, tmp_path):
    assert main(RUN + ["--save-rate", rate, "--save", str(tmp_path / "x.csv")]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert match in err and "Traceback" not in err and len(err.splitlines()) == 1, err
    assert json.loads(captured.out)["exit_status"] == 2      # --json: one document, the error
    assert list(tmp_path.iterdir()) == []


def test_the_limit_is_in_samples_over_the_run_and_says_the_highest_rate(capsys, tmp_path):
    # 2.5e6 Hz over 4 s is 1e7 + 1 samples: one over the limit; the message names 2.5e6 Hz
    assert main(RUN + ["--save-rate", "2.5e6", "--save", str(tmp_path / "x.csv")]) == 2
    assert "at most 2.5e+06 Hz" in capsys.readouterr().err


def test_a_save_rate_without_a_file_or_figure_is_refused(capsys):
    assert main(RUN + ["--save-rate", "1000"]) == 2
    err = capsys.readouterr().err
    assert "--save-rate 1000 Hz" in err and "--save and --plot" in err


def test_the_zoom_draws_the_last_event_from_the_dense_output_with_the_saved_samples():
    p = window("W2", "slip", t_end=4.0)
    saved = solve(p, Rodas5P(rtol=1e-6, atol=1e-6), save_every=1e-3)
    dense = saved.resolved()
    fig = Figure()
    ax_v, ax_mu = fig.subplots(2, 1)
    draw_event_zoom(dense, ax_v, ax_mu, saved.to_dataframe())
    i, t0, t1 = event_zoom_window(dense)
    start, end = saved.event_array[-1, :2]
    assert i == len(saved.event_array) - 1
    assert (t0, t1) == pytest.approx((2 * start - end, 2 * end - start))   # its duration each side
    line, dots = ax_v.get_lines()
    inside = (dense.t >= t0) & (dense.t <= t1)
    np.testing.assert_allclose(line.get_xdata(), (dense.t[inside] - start) * 1e3)
    np.testing.assert_array_equal(line.get_ydata(), dense.v[inside])
    kept = (saved.t >= t0) & (saved.t <= t1)
    assert len(dots.get_xdata()) == kept.sum() and len(line.get_xdata()) > 5 * kept.sum()
    assert len(ax_mu.get_lines()) == 4          # Fs/Fn and Ft/Fn, lines and saved samples


def test_simulate_s_figure_has_the_zoom_panels(tmp_path):
    p = window("W2", "slip", t_end=4.0)
    saved = solve(p, Rodas5P(rtol=1e-6, atol=1e-6))
    plot_solution(saved.resolved(), tmp_path / "run.png", saved=saved.to_dataframe())
    data = (tmp_path / "run.png").read_bytes()
    size = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert size == (15 * 110, round(6.5 * 110))      # figsize (15, 6.5) in at 110 dpi
