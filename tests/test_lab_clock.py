"""The load point's displacement as a record's clock (benchmarks/lab/clock.py, ``rsfbench lab
fit --clock displacement``) and the speeds given by hand (``--velocities``), on records of the
independent model (scipy's Radau) whose time stamps wander: a clock that runs ahead and behind
by 0.3 s over a 40 s period, the friction and displacement sampled at the true times."""

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pandas as pd
import pytest

from benchmarks.lab.clock import displacement_clock
from benchmarks.lab.fit import LabFitWarning, fit_lab
from benchmarks.lab.independent_model import synthetic_record
from benchmarks.lab.model import LabModel
from benchmarks.lab.step_data import lab_record_from
from benchmarks.lab.switches import refine_switches, with_velocities

COLUMNS = ["time=time_s", "load_point=load_point_um:um", "friction=friction"]
TRUTH = dict(a=0.006, b=0.009, dc=10e-6, k=3e3)
T = np.linspace(0.0, 60.0, 1500)
VELOCITIES, SWITCHES = (1e-6, 1e-5), (20.0,)


def _table(seed: int, wander: float):
    df = synthetic_record(T, VELOCITIES, SWITCHES, **TRUTH, noise=2e-4,
                          displacement_noise=0.002e-6, drift=0.0, seed=seed)
    df["time_s"] = T + wander * np.sin(2 * np.pi * T / 40.0)
    return df


def _z(fit) -> dict:
    """Each parameter's error in its standard errors (ln Dc, ln k′)."""
    return {k: (math.log(fit.values[k] / TRUTH[k]) if k in ("dc", "k")
                else fit.values[k] - TRUTH[k]) / fit.se(k) for k in ("a", "b", "dc", "k")}


def _fit(record):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LabFitWarning)
        return refine_switches(fit_lab(LabModel(record, "aging")))[0]


def test_a_wandering_clock_biases_the_time_fit_and_not_the_displacement_one():
    """On the record's own time Dc is off by 10–17 se (measured on seeds 0–2 when written);
    on the displacement's clock, with the commanded speeds (the speeds a wandering clock gives
    are 1.4 % low), a, b, Dc and k′ are within 1.1 se of the truth (within 3 asserted)."""
    rec = lab_record_from(_table(0, 0.3), COLUMNS)
    assert abs(_z(_fit(rec))["dc"]) > 5
    on_displacement, notes = displacement_clock(with_velocities(rec, VELOCITIES))
    assert "the clock is the load point's displacement" in notes[0]
    z = _z(_fit(on_displacement))
    assert all(abs(v) < 3 for v in z.values()), z


def test_a_true_clock_gives_the_displacement_clock_the_same_fit():
    """Time stamps that do not wander: the displacement's clock differs from them by its noise
    (2 nm at 1 µm/s is 2 ms) and the fit is the time fit's, within 0.3 se (0.1 when written)."""
    rec = lab_record_from(_table(1, 0.0), COLUMNS)
    on_time, on_displacement = _fit(rec), _fit(displacement_clock(rec)[0])
    for name in ("a", "b", "dc", "k"):
        scale = on_time.values[name] if name in ("dc", "k") else 1.0
        assert abs(on_displacement.values[name] - on_time.values[name]) <= \
            0.3 * on_time.se(name) * scale, name


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "benchmarks.cli", "lab", "fit",
                           *map(str, args)], capture_output=True, text=True, timeout=300)


def test_the_command_takes_the_clock_and_the_speeds(tmp_path):
    path = tmp_path / "step.csv"
    _table(2, 0.3).to_csv(path, index=False)
    columns = [f"--column={c}" for c in COLUMNS]
    out = _cli(path, *columns, "--clock", "displacement", "--velocities", "1,10",
               "--no-profiles", "--no-solver-check", "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["clock"] == "displacement"
    assert doc["history"]["velocities_m_s"] == pytest.approx([1e-6, 1e-5])
    assert any("the clock is the load point's displacement" in n for n in doc["notes"])
    bad = _cli(path, *columns, "--velocities", "1,10,3", "--json")
    assert bad.returncode == 2 and "3 velocities given, but the history has 2 pieces" in \
        bad.stderr and len(bad.stderr.strip().splitlines()) == 1, bad.stderr


def test_a_quantised_spiky_displacement_still_makes_a_clock():
    """A displacement rounded to 0.01 µm with 15 spikes of ±50 µm (found by a hostile probe:
    the first clock refused quantised records, ties, and let one spike shift it all): the
    clock follows the true time within 20 ms and the fit on it holds a, b, Dc and k′ within
    3 se (its own noise is the clock's error here)."""
    df = _table(3, 0.3)
    rng = np.random.default_rng(3)
    df["load_point_um"] = np.round(df["load_point_um"], 2)
    spikes = rng.choice(len(df), 15, replace=False)
    df.loc[spikes, "load_point_um"] += rng.choice([-50.0, 50.0], 15)
    rec = lab_record_from(df, COLUMNS)
    on_displacement, _ = displacement_clock(with_velocities(rec, VELOCITIES))
    keep = np.setdiff1d(np.arange(len(T)), spikes)
    true = np.interp(on_displacement.file_t, df["time_s"], T)
    assert np.max(np.abs(on_displacement.t + on_displacement.t_offset - true)[keep]) < 0.02
    z = _z(_fit(on_displacement))
    assert all(abs(v) < 3 for v in z.values()), z


@pytest.mark.parametrize("speeds, match", [
    ((1e-6, 0.0), "velocity 2 given as 0 µm/s, where the displacement moves at 10"),
    ((1e-6, 1e-4), "velocity 2 given as 100 µm/s"),
    ((1e-6, 1e-5, 1e-5), "3 velocities given, but the history has 2 pieces")])
def test_a_hand_speed_the_displacement_denies_is_refused(speeds, match):
    rec = lab_record_from(_table(0, 0.0), COLUMNS)
    with pytest.raises(ValueError, match=match):
        with_velocities(rec, speeds)


def test_the_clock_reports_file_times_and_keeps_a_short_piece():
    """Found in review: the switch was reported in the model's time as if it were the file's
    (0.3 s off under the wander), and a piece shorter than the corner's window (60 samples
    between two switches) had both corners pulled 10 samples, the clock 0.8 s off. The switch
    of the wandering record is reported at its file time (20 s) within 20 ms; the short piece
    keeps its clock within 10 ms of the file's (1.3 ms when written)."""
    rec = lab_record_from(_table(0, 0.3), COLUMNS)
    on_displacement, _ = displacement_clock(with_velocities(rec, VELOCITIES))
    assert on_displacement.file_time(on_displacement.switch_times[0]) == pytest.approx(20.0,
                                                                                     abs=0.02)
    t = np.arange(0.0, 40.0, 0.04)
    v = np.where(t < 20.0, 1e-6, np.where(t < 22.4, 1e-5, 1e-6))
    x = np.concatenate(([0.0], np.cumsum(v[:-1] * 0.04)))
    x += np.random.default_rng(0).standard_normal(len(t)) * 2e-9
    short = lab_record_from(pd.DataFrame({"time_s": t, "load_point_um": x * 1e6,
                                          "friction": 0.6 + 0.0 * t}), COLUMNS)
    clocked, _ = displacement_clock(short)
    assert np.max(np.abs(clocked.t + clocked.t_offset - clocked.file_t)) < 0.01


def test_a_unit_warning_reaches_the_json_notes(tmp_path):
    """A load point in µm read as nm (0.5 and 5 nm/s): the unit warning goes to the standard
    error as before and now also into lab_fit.json's notes (found by a hostile probe: with
    --json it reached the standard error only)."""
    df = synthetic_record(T, (0.5e-6, 5e-6), SWITCHES, **TRUTH, noise=2e-4, seed=0)
    path = tmp_path / "nm.csv"
    df.to_csv(path, index=False)
    out = _cli(path, "--column=time=time_s", "--column=load_point=load_point_um:nm",
               "--column=friction=friction", "--no-profiles", "--no-solver-check",
               "--switches-from", "displacement", "--json")
    doc = json.loads(out.stdout)
    assert "is its unit right?" in out.stderr
    assert any("is its unit right?" in n for n in doc["notes"])
