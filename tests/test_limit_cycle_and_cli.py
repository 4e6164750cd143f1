"""The paper example's limit cycle, W1–W4 against the observations, and the rsfbench CLI."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import integrators as I
import problems as P
from benchmarks.cli.main import main
from benchmarks.physics.metrics import event_metrics, summarize


@pytest.fixture(scope="module")
def paper_etd2():
    return I.solve(P.paper_example(), I.ETD2(), save_every=2e-5)


def test_paper_example_slip_per_cycle_is_vl_times_period(paper_etd2):
    """Exact invariant of a limit cycle: over one period the slider slips vL·T."""
    sol = paper_etd2
    lc = summarize(sol)
    assert lc.classification == "stick-slip" and lc.n_events >= 6
    ev = sol.events
    t0, t1 = ev.t_start.iloc[-2], ev.t_start.iloc[-1]
    vl = sol.problem.loading.vl
    # from the events table (slip = load-point displacement − spring stretch)
    assert ev.slip_start.iloc[-1] - ev.slip_start.iloc[-2] == pytest.approx(vl * (t1 - t0), rel=1e-5)
    # independently, by integrating the saved slip rate over the cycle (trapezoid, 20 µs grid)
    mask = (sol.t >= t0) & (sol.t <= t1)
    assert np.trapezoid(sol.v[mask], sol.t[mask]) == pytest.approx(vl * (t1 - t0), rel=1e-2)
    # and the event's own slip matches the integral of v over the event
    m = event_metrics(ev, sol.problem.normal_force).iloc[-1]
    during = (sol.t >= ev.t_start.iloc[-1]) & (sol.t <= ev.t_end.iloc[-1])
    assert np.trapezoid(sol.v[during], sol.t[during]) == pytest.approx(m.slip_m, rel=1e-2)


def test_paper_example_mean_friction_equals_mean_spring_force(paper_etd2):
    """m dv/dt = Fs − Ft averaged over a period (v periodic) gives mean Ft = mean Fs."""
    sol = paper_etd2
    t0, t1 = sol.events.t_start.iloc[-2], sol.events.t_start.iloc[-1]
    mask = (sol.t >= t0) & (sol.t <= t1)
    mean_fs = np.trapezoid(sol.fs[mask], sol.t[mask]) / (t1 - t0)
    mean_ft = np.trapezoid(sol.ft[mask], sol.t[mask]) / (t1 - t0)
    assert mean_ft == pytest.approx(mean_fs, rel=1e-5)


@pytest.mark.parametrize("name", ["W1", "W2", "W3", "W4"])
def test_windows_with_slip_law_best_fits_match_observed_means(name):
    """The paper's best fits reproduce the observed mean ΔT and Δμ within the observed
    scatter; we require 15 % (SPEC §5 gives the means, not the scatter)."""
    w = P.WINDOWS[name]
    lc = summarize(I.solve(P.window(name, "slip"), I.ETD2()))
    assert lc.classification == "stick-slip"
    assert lc.recurrence_s == pytest.approx(w.observed_recurrence, rel=0.15)
    assert lc.friction_drop == pytest.approx(w.observed_drop, rel=0.15)
    assert lc.slip_m == pytest.approx(w.observed_slip, rel=0.15)


def test_cli_simulate_json(capsys):
    assert main(["simulate", "--preset", "paper-example", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("integrator", "retcode", "wall_s", "steps", "n_events", "limit_cycle"):
        assert key in out
    lc = out["limit_cycle"]
    assert lc["classification"] == "stick-slip" and out["retcode"] == "Success"
    for key in ("recurrence_s", "friction_drop", "slip_m", "peak_velocity_m_s"):
        assert lc[key] > 0
    assert lc["recurrence_s"] == pytest.approx(2.672, rel=1e-3)   # ETD2 run, checked vs Radau above


def test_cli_overrides_plot_and_text(tmp_path, capsys):
    png = tmp_path / "w2.png"
    assert main(["simulate", "--preset", "W2", "--law", "aging", "--b", "0.009", "--lc", "1e-7",
                 "--t-end", "8", "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "W2/aging" in text and "b = 0.009" in text and "recurrence" in text
    assert "Lc = 0.1 µm" in text and "8 s" in text
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_cli_bad_parameter_is_a_clear_error(capsys):
    assert main(["simulate", "--preset", "W1", "--lc=-1e-6"]) == 2
    assert "argument --lc: must be positive, got '-1e-6'" in capsys.readouterr().err
    assert main(["simulate", "--preset", "W1", "--integrator", "nope"]) == 2


def test_console_script_is_installed():
    exe = Path(sys.executable).parent / "rsfbench"
    out = subprocess.run([str(exe), "integrators", "--json"], capture_output=True, text=True,
                         check=True).stdout
    names = {row["name"] for row in json.loads(out)}
    assert {"ETD1", "ETD2", "ETDIterated", "scipy-Radau"} <= names


@pytest.mark.parametrize("name", sorted(I.REGISTRY))
def test_cli_simulate_every_integrator(name, capsys):
    cls = I.REGISTRY[name]
    args = ["simulate", "--preset", "W2", "--t-end", "0.05", "--integrator", name.lower(), "--json"]
    if cls.adaptive:
        args += ["--rtol", "1e-6", "--atol", "1e-6", "--rhs", cls.rhs_tiers[-1]]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["integrator"] == name and out["retcode"] == "Success"
    assert out["n_events"] == 1 and out["nfev"] > 0
    if cls.adaptive:
        assert out["options"]["rtol"] == 1e-6 and out["options"]["rhs"] == cls.rhs_tiers[-1]


def test_cli_integrators_lists_library_versions(capsys):
    assert main(["integrators", "--json"]) == 0
    rows = [r for r in json.loads(capsys.readouterr().out) if r["available"]]
    assert {r["name"] for r in rows} == set(I.REGISTRY)
    for r in rows:
        assert r["library"] and r["version"] and r["family"] and r["order"] >= 1
