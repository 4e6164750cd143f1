"""Stresses and catalogues in (issue 47): stress and friction channels beside the force
channels, and ``rsfbench observe --catalogue`` on an event table — the real one of NIED's 4-m
apparatus (``tests/data/nied-4m-stick-slip``, MIT) and small made ones; bad input refused in
one line, exit 2, before anything is written."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmarks.cli.main import main
from benchmarks.inversion.observations import read_observations
from benchmarks.lab.catalogue import CATALOGUE_CHANNELS, read_catalogue
from benchmarks.lab.channels import column_spec, recording_from
from benchmarks.lab.events import analyse
from benchmarks.lab.synthetic import synthetic_recording
from problems import preset

NIED = Path(__file__).parent / "data" / "nied-4m-stick-slip" / "Macroscopic_stats_FB03_087.csv"
NIED_COLUMNS = ["--column", "onset=event_starttime[s]",
                "--column", "shear_stress_before=macroshearstress_beforeevent[MPa]:MPa",
                "--column", "shear_stress_after=macroshearstress_afterevent[MPa]:MPa",
                "--column", "slip=slip_mean[mm]:mm"]
#: the apparatus as the data set's README states it: a 4 m × 0.1 m fault, σn about 2 MPa
NIED_APPARATUS = ["--area", "0.4", "--normal-stress", "2e6"]


def _observe(args, out, capsys):
    code = main(["observe", *args, "--out", str(out)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err.strip()


# --- the real catalogue ----------------------------------------------------------------------------

def test_the_nied_catalogue_reads_into_observations_an_inversion_reads(tmp_path, capsys):
    code, out, err = _observe(["--catalogue", str(NIED), *NIED_COLUMNS, *NIED_APPARATUS],
                              tmp_path / "o", capsys)
    assert code == 0, err
    doc = json.loads((tmp_path / "o" / "observations.json").read_text())
    events = pd.read_csv(tmp_path / "o" / "events.csv")
    raw = pd.read_csv(NIED)
    assert doc["n_events"] == len(events) == 56 and doc["curves"] is None
    # ΔT from consecutive onsets; Δμ = (τ before − τ after)/σn; slip in m — from the file's
    # own columns, computed here with pandas
    onset = raw["event_starttime[s]"]
    assert np.allclose(events.recurrence_s[1:], onset.diff()[1:]) and math.isnan(
        events.recurrence_s[0])
    drop = (raw["macroshearstress_beforeevent[MPa]"] - raw["macroshearstress_afterevent[MPa]"])
    assert np.allclose(events.friction_drop, drop * 1e6 / 2e6)
    assert np.allclose(events.slip_m, raw["slip_mean[mm]"] * 1e-3)
    # the first event (drop and slip ~3× the others') is the start-up, left out of the means
    assert doc["settled"]["startup_events"] == [1] and not events.kept[0] and events.kept[1:].all()
    m, every = doc["metrics"], doc["metrics_all_events"]
    assert m["friction_drop"]["mean"] == pytest.approx(events.friction_drop[1:].mean())
    assert m["recurrence_s"]["mean"] == pytest.approx(onset.diff().mean())   # event 1 has none
    assert every["slip_m"]["std"] > 2 * m["slip_m"]["std"]
    assert doc["apparatus"]["normal_force"] == pytest.approx(0.8e6)        # 2 MPa × 0.4 m²
    assert "start-up: the first event differs" in out and "55 in the means" in out
    obs = read_observations(tmp_path / "o" / "observations.json")
    assert obs.recurrence_s == pytest.approx(3.9342, rel=1e-4)    # the README's "mean 3.9 s"


def test_the_stress_drop_column_gives_the_same_drops(tmp_path, capsys):
    args = ["--catalogue", str(NIED), "--column", "onset=event_starttime[s]",
            "--column", "drop=macroshearstress_drop[MPa]:MPa", "--column",
            "slip=slip_mean[mm]:mm", "--area", "0.4", "--normal-force", "8e5"]
    code, _, err = _observe(args, tmp_path / "o", capsys)
    assert code == 0, err
    events = pd.read_csv(tmp_path / "o" / "events.csv")
    assert np.allclose(events.friction_drop, pd.read_csv(NIED)["macroshearstress_drop[MPa]"] / 2)


def test_keep_startup_and_a_window_on_a_catalogue(tmp_path, capsys):
    code, _, _ = _observe(["--catalogue", str(NIED), *NIED_COLUMNS, *NIED_APPARATUS,
                           "--keep-startup"], tmp_path / "k", capsys)
    doc = json.loads((tmp_path / "k" / "observations.json").read_text())
    assert code == 0 and doc["n_events_used"] == 56 and doc["settled"]["startup_events"] == [1]
    code, _, _ = _observe(["--catalogue", str(NIED), *NIED_COLUMNS, *NIED_APPARATUS,
                           "--window", "100", "200"], tmp_path / "w", capsys)
    events = pd.read_csv(tmp_path / "w" / "events.csv")
    assert code == 0 and events.t_start.between(100, 200).all() and len(events) == 24
    assert events.kept.all()                   # no start-up inside that window


# --- bad input: one line, exit 2, nothing written ---------------------------------------------------

def _catalogue(tmp_path, rows=6, **change):
    t = 10.0 + 3.0 * np.arange(rows)
    table = pd.DataFrame({"t0": t, "tau_b": 0.66 + 0 * t, "tau_a": 0.64 + 0 * t,
                          "slip": 0.032 + 0 * t})
    for column, (row, value) in change.items():
        table[column] = table[column].astype(object)
        table.loc[row, column] = value
    path = tmp_path / "cat.csv"
    table.to_csv(path, index=False)
    return path


CAT = ["--column", "onset=t0", "--column", "shear_stress_before=tau_b:MPa",
       "--column", "shear_stress_after=tau_a:MPa", "--column", "slip=slip:mm"]


@pytest.mark.parametrize("rows, change, args, said", [
    (2, {}, [*CAT, "--area", "0.4", "--normal-stress", "2e6"], "2 events; a mean recurrence"),
    (6, {"t0": (3, 12.0)}, [*CAT, "--area", "0.4", "--normal-stress", "2e6"],
     "column 't0' row 5: onset 12 s is not after the previous one"),
    (6, {"tau_a": (2, 0.7)}, [*CAT, "--area", "0.4", "--normal-stress", "2e6"],
     "row 4: the drop ('tau_b' − 'tau_a') is -0.02 in friction, not positive"),
    (6, {}, [*CAT, "--normal-stress", "2e6"], "column 'tau_b' (shear_stress_before) is a "
     "stress: give the fault's area"),
    (6, {}, ["--column", "onset=t0", "--column", "drop=tau_b:furlongs", "--area", "0.4",
             "--normal-stress", "2e6"], "'furlongs' in 'tau_b:furlongs' is not a known unit"),
    (6, {}, [*CAT, "--area", "0.4"], "give the normal stress (--normal-stress PA)"),
    (6, {}, [*CAT, "--area", "0.4", "--normal-stress", "2"], "gives a friction of 3.3e+05"),
    (6, {}, ["--column", "onset=t0", "--column", "slip=slip:mm"], "map exactly one way of "
     "the drop"),
    (6, {}, [*CAT[:4], "--area", "0.4", "--normal-stress", "2e6"], "map shear_stress_after "
     "too"),
    (6, {"slip": (1, "abc")}, [*CAT, "--area", "0.4", "--normal-stress", "2e6"],
     "column 'slip' row 3 is not a number ('abc')"),
    (6, {}, [*CAT, "--area", "0.4", "--normal-stress", "2e6", "--vls", "1e-5"],
     "--vls is for a recording, not for a catalogue"),
], ids=["few events", "onsets out of order", "negative drop", "stress without area",
        "unknown unit", "stress without normal stress", "stress in another unit", "no drop",
        "half a drop", "not a number", "a recording's option"])
def test_bad_catalogues_are_refused_in_one_line(tmp_path, capsys, rows, change, args, said):
    path = _catalogue(tmp_path, rows, **change)
    out = tmp_path / "out"
    code, stdout, err = _observe(["--catalogue", str(path), *args], out, capsys)
    assert code == 2 and said in err and "\n" not in err, err
    assert stdout == "" and (not out.exists() or not any(out.iterdir()))


def test_a_recording_and_a_catalogue_at_once_or_neither_is_refused(tmp_path, capsys):
    path = _catalogue(tmp_path)
    for args in (["--catalogue", str(path), str(path)], []):
        code, _, err = _observe([*args, *CAT, "--area", "0.4", "--normal-stress", "2e6"],
                                tmp_path / "o", capsys)
        assert code == 2 and "give a recording (RECORDING) or an event catalogue" in err


def test_catalogue_columns_with_brackets_and_colons_keep_their_unit():
    spec = "shear_stress_before=macroshearstress_beforeevent[MPa]:MPa"
    assert column_spec(spec, CATALOGUE_CHANNELS) == (
        "shear_stress_before", "macroshearstress_beforeevent[MPa]", "MPa")
    assert column_spec("onset=a:b[s]", CATALOGUE_CHANNELS) == ("onset", "a:b[s]", "s")
    assert column_spec("drop=d:kPa", CATALOGUE_CHANNELS)[2] == "kPa"
    assert column_spec("drop=d", CATALOGUE_CHANNELS)[2] == "1"          # a friction drop
    with pytest.raises(ValueError, match="mm is not a unit of drop"):
        column_spec("drop=d:mm", CATALOGUE_CHANNELS)


def test_friction_columns_need_no_normal_stress(tmp_path):
    path = _catalogue(tmp_path)
    events, info = read_catalogue(path, ["onset=t0", "friction_before=tau_b",
                                         "friction_after=tau_a", "slip=slip:mm"])
    assert np.allclose(events.friction_drop, 0.02) and info["normal_force"] is None


# --- stress and friction channels of a recording ------------------------------------------------------

@pytest.fixture(scope="module")
def w2_record():
    """W2, slip law, 16 s at 10 kHz from t = 4 s, no noise (the forward model's own)."""
    return synthetic_recording(preset("W2", law="slip", t_end=16.0), t_skip=4.0)


AREA, FN = 0.75, 997500.0      # the paper's fault: 1.5 m × 0.5 m, σn = 1.33 MPa


@pytest.mark.parametrize("channels, kw", [
    ({"shear_stress": ("tau", "MPa"), "normal_force": ("fn", "N")}, dict(area=AREA)),
    ({"shear_stress": ("tau", "kPa"), "normal_stress": ("sn", "kPa")}, dict(area=AREA)),
    ({"friction": ("mu", "1")}, dict(normal_force=FN)),
])
def test_stress_and_friction_channels_measure_as_the_force_does(w2_record, channels, kw):
    table, _ = w2_record
    fs = table.shear_force.to_numpy()
    scale = {"MPa": 1e-6, "kPa": 1e-3}
    data = pd.DataFrame({"time": table.time, "fs": fs, "fn": FN,
                         "tau": fs / AREA * scale[channels.get("shear_stress", ("", "MPa"))[1]],
                         "sn": FN / AREA * 1e-3, "mu": fs / FN})
    force = analyse(recording_from(data, {"time": "time", "shear_force": "fs"},
                                   normal_force=FN)).events
    other = analyse(recording_from(data, {"time": "time", **channels}, **kw)).events
    assert np.allclose(other.friction_drop, force.friction_drop, rtol=1e-9)
    assert np.allclose(other.recurrence_s, force.recurrence_s, rtol=1e-12)


@pytest.mark.parametrize("channels, kw, said", [
    ({"shear_stress": "tau"}, dict(normal_force=FN), "column 'tau' (shear_stress) is a stress: "
     "give the fault's area in m² (--area M2)"),
    ({"shear_force": "fs", "friction": "mu"}, dict(normal_force=FN), "shear_force and friction "
     "are one force"),
    ({"shear_force": "fs", "normal_stress": "sn"}, dict(normal_force=FN, area=AREA),
     "a column (normal_stress) or a constant"),
])
def test_a_stress_without_an_area_and_two_forces_at_once_are_refused(channels, kw, said):
    data = pd.DataFrame({"time": np.arange(10.0), "fs": 6e5, "tau": 0.8, "mu": 0.6, "sn": 1e6})
    with pytest.raises(ValueError, match=said.replace("(", r"\(").replace(")", r"\)")):
        recording_from(data, {"time": "time", **channels}, **kw)


def test_observe_refuses_a_stress_column_without_area_on_the_command_line(tmp_path, capsys):
    path = tmp_path / "rec.csv"
    pd.DataFrame({"t": np.arange(100) * 1e-3, "tau": 0.8}).to_csv(path, index=False)
    code, _, err = _observe([str(path), "--column", "time=t", "--column",
                             "shear_stress=tau:MPa", "--normal-stress", "1.33e6"],
                            tmp_path / "o", capsys)
    assert code == 2 and "is a stress: give the fault's area in m² (--area M2)" in err
