"""A user's own apparatus from a TOML or JSON file (issue 16): read back exactly, every bad key
refused with the file and the key named, and swept from the command line."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks.cli.main import main
from problems import (InitialState, LoadHistory, load_problem, paper_example,
                      slide_hold_slide_test, variant, velocity_step_test, window)
from problems.files import problem_dict

EXAMPLE = Path(__file__).parents[1] / "docs" / "examples" / "apparatus.toml"


@pytest.mark.parametrize("problem", [
    window("W2", "slip"), window("W3", "aging"), paper_example(),
    dataclasses.replace(window("W1"), initial=InitialState(v=1e-4, theta=2e3, fs=6e5)),
    slide_hold_slide_test("nagata", c=1.5, radiation_damping=2.0),
    velocity_step_test("slip", mass=3.0),
    dataclasses.replace(window("W2"), loading=LoadHistory(
        (1e-4, 2e-4), (5.0,), overshoot_velocity=1e-3, overshoot_duration=0.04,
        reference_velocity=1e-4)),
], ids=["W2-slip", "W3-aging", "paper-example", "initial-state", "shs-nagata-quasi-dynamic",
        "velocity-step-mass", "history-overshoot"])
def test_a_problem_written_as_json_reads_back_equal(problem, tmp_path):
    path = tmp_path / "p.json"
    path.write_text(json.dumps(problem_dict(problem)))
    assert load_problem(path) == problem


def test_the_documented_example_is_w2_with_a_softer_spring():
    p = load_problem(EXAMPLE)
    assert p == dataclasses.replace(variant(window("W2", "slip"), stiffness=1.184e8),
                                    name="W2, softer spring")


TOML = EXAMPLE.read_text()


@pytest.mark.parametrize("text, match", [
    (TOML.replace("mass = 1100.0", "masse = 1100.0"), "unknown key 'masse' in the file"),
    (TOML.replace("stiffness = 1.184e8", ""), "lacks the key 'stiffness'"),
    (TOML.replace("a = 0.008", 'a = "0.008"'), "a in \\[law\\] must be a finite number"),
    (TOML.replace('name = "slip"', 'name = "ruina"'), "law must be one of"),
    (TOML.replace("lc = 3e-7", "lc = -3e-7"), "lc must be positive"),
    (TOML.replace("df = 0.042", "dff = 0.042"), "unknown key 'dff' in \\[loading\\]"),
    (TOML.replace("slowdown = 1.1", "v = 1e-4"), "\\[initial\\] .*lacks the key 'theta'"),
    (TOML.replace("[law]", "[law"), "not valid TOML"),
    (TOML.replace("t_end = 40.0", "t_end = nan"), "t_end in the file must be a finite number"),
])
def test_bad_files_are_refused_naming_file_and_key(text, match, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as caught:
        load_problem(path)
    assert str(path) in str(caught.value)


def test_wrong_suffix_and_missing_file_are_refused(tmp_path):
    with pytest.raises(ValueError, match="must end in .toml or .json"):
        load_problem(tmp_path / "p.yaml")
    with pytest.raises(ValueError, match="cannot read the problem file"):
        load_problem(tmp_path / "none.toml")


@pytest.mark.needs("pyarrow")
def test_cli_sweeps_a_problem_file_and_marks_a_given_point(tmp_path, capsys):
    from benchmarks.cli.main import main
    out = tmp_path / "s"
    assert main(["sweep", "--problem", str(EXAMPLE), "--b", "0.0093:0.0094:0.0001", "--lc",
                 "3e-7:3e-7:1", "--t-end", "10", "--obs-recurrence", "0.3", "--obs-drop",
                 "0.04", "--mark", "0.0094,3e-7", "--out", str(out), "--json",
                 "--no-progress"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["n_points"] == 2 and s["batched"] and (out / "maps.png").stat().st_size > 0
    from benchmarks.ensemble.store import read_store      # the store's one reader
    assert len(read_store(out / "chunks")) == 2


def test_cli_refuses_law_with_a_problem_file(tmp_path, capsys):
    from benchmarks.cli.main import main
    status = main(["sweep", "--problem", str(EXAMPLE), "--law", "aging", "--b",
                   "0.0093:0.0094:0.0001", "--lc", "3e-7:3e-7:1", "--obs-recurrence", "0.3",
                   "--obs-drop", "0.04", "--out", str(tmp_path / "s"), "--json"])
    assert status == 2
    assert "--law applies to --preset" in json.loads(capsys.readouterr().out)["error"]


def test_cli_simulates_a_problem_file_with_b_replaced(capsys):
    from benchmarks.cli.main import main
    assert main(["simulate", "--problem", str(EXAMPLE), "--b", "0.0095", "--t-end", "2",
                 "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["problem"] == "W2, softer spring" and s["b"] == 0.0095 and s["lc_m"] == 3e-7


# --- issue 29: files that hung, raised or were silently misread ----------------------------------

BASE = problem_dict(window("W2", "slip", t_end=2.0))


def _json(tmp_path, text, name="p.json"):
    path = tmp_path / name
    path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)
    return path


@pytest.mark.parametrize("text, match", [
    (json.dumps(BASE).replace('"mass": 1100.0', '"mass": 1' + "0" * 400),
     "mass in the file must be a finite number, got an integer of 401 digits"),
    (json.dumps(BASE).replace('"mass": 1100.0', '"mass": 1100.0, "mass": 1.0'),
     "the key 'mass' appears twice"),
    ("[" * 100_000 + "]" * 100_000, "nests deeper than any problem"),
    (json.dumps([BASE] * 50), r"must be a table of keys, got \[.{0,60}$"),
    (json.dumps({**BASE, "loading": {"velocity": 1e-4}}), "a history\\); got the keys velocity"),
    (json.dumps({**BASE, "initial": {"slowdown": 1.1, "v": 1e-4}}), "not both"),
    (json.dumps({**BASE, "initial": {"slowdown": 1.1, "slowdwn": 1.0}}), "unknown key 'slowdwn'"),
    (json.dumps({**BASE, "loading": {"velocities": [1e-4, 2e-4], "switch_times": [1.0],
                                     "overshoot_velocity": 1e-3}}),
     "overshoot_velocity without overshoot_duration"),
    (json.dumps({**BASE, "mu0": 60.0}), "mu0 = 60 is impossible"),
    (json.dumps({**BASE, "law": {**BASE["law"], "b": 0.0}, "initial": {
        "v": 1e-4, "theta": 1.0, "fs": 6e5}}), "b = 0 needs theta = 0"),
])
def test_bad_json_is_refused_in_one_line(text, match, tmp_path):
    path = _json(tmp_path, text)
    with pytest.raises(ValueError, match=match) as caught:
        load_problem(path)
    assert "\n" not in str(caught.value) and str(path) in str(caught.value)


def test_a_byte_order_mark_is_no_error(tmp_path):
    path = _json(tmp_path, b"\xef\xbb\xbf" + json.dumps(BASE).encode())
    assert load_problem(path) == window("W2", "slip", t_end=2.0)


def test_a_fifo_a_directory_and_a_huge_file_are_refused_without_reading(tmp_path, monkeypatch):
    import os
    import problems.files as F
    os.mkfifo(tmp_path / "pipe.toml")          # reading it would wait for a writer forever
    (tmp_path / "dir.json").mkdir()
    for name in ("pipe.toml", "dir.json"):
        with pytest.raises(ValueError, match="is not a regular file"):
            load_problem(tmp_path / name)
    monkeypatch.setattr(F, "MAX_FILE_BYTES", 100)
    with pytest.raises(ValueError, match="more than any problem file"):
        load_problem(_json(tmp_path, json.dumps(BASE)))


def test_a_unit_slip_in_a_file_warns_in_the_problems_words(tmp_path):
    import warnings
    from problems._validate import UnitWarning
    path = _json(tmp_path, json.dumps({**BASE, "normal_force": 1.33}))
    with pytest.warns(UnitWarning, match="normal_force = 1.33 N is implausibly small") as seen:
        load_problem(path)
    assert len([w for w in seen if issubclass(w.category, UnitWarning)]) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        load_problem(EXAMPLE)


def test_every_valid_kind_of_file_reads_back_in_toml_and_json(tmp_path):
    """The probe's valid files (tests/probe/families/problem_files.py), written by its TOML
    writer and as JSON, read back equal, with the loading switches each has."""
    from probe.families.problem_files import _valid_problems, toml_text
    for name, (make, switches) in _valid_problems().items():
        problem = make()
        for suffix, text in ((".toml", toml_text(problem_dict(problem))),
                             (".json", json.dumps(problem_dict(problem)))):
            path = tmp_path / f"p{suffix}"
            path.write_text(text)
            got = load_problem(path)
            assert got == problem, name
            assert len(got.loading.history.switch_times) == switches, name


def test_compare_runs_every_named_integrator_on_a_problem_file(capsys, tmp_path):
    """With an observations file, each integrator's error against the tight reference in
    units of σ (σ of ΔT 0.0057 s, 0.13 % of it, here): at rtol = atol = 1e-3 Rosenbrock23 is
    2.3 σ off in ΔT and Exprb43 0.006 σ (measured when the test was written)."""
    import pandas as pd

    from benchmarks.inversion.observations import write_observations
    events = pd.DataFrame({"t_start": [0.0, 4.2, 8.4], "t_end": [0.01, 4.21, 8.41],
                           "recurrence_s": [np.nan, 4.232, 4.240],
                           "friction_drop": [0.0469, 0.0470, 0.0468],
                           "slip_m": [4e-4] * 3, "peak_velocity_m_s": [0.06] * 3})
    write_observations(tmp_path / "obs.json", events)
    assert main(["compare", "--problem", str(EXAMPLE), "--t-end", "10", "--rtol", "1e-3",
                 "--atol", "1e-3", "--integrators", "Exprb43", "Rosenbrock23",
                 "--observations", str(tmp_path / "obs.json"), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["integrator"] for r in rows] == ["Exprb43", "Rosenbrock23"]
    assert all(r["problem"] == "W2, softer spring" for r in rows)
    assert [r["within_a_tenth_of_sigma"] for r in rows] == [True, False]
    assert rows[1]["err_recurrence_sigma"] > 1
    assert main(["compare", "--problem", str(EXAMPLE), "--law", "aging", "--rtol", "1e-6",
                 "--atol", "1e-6"]) == 2
    assert "names its own law" in capsys.readouterr().err


@pytest.mark.slow
def test_work_precision_names_the_fastest_setting_within_your_sigma(tmp_path, capsys):
    """A problem file and an observations file: the settings whose ΔT and Δμ errors are within
    σ/10 of the observed means on the problem, fastest first (the file: 5 events of the example
    apparatus with 1 % scatter)."""
    import pandas as pd

    from benchmarks.inversion.observations import write_observations
    events = pd.DataFrame({"t_start": [0.0, 4.2, 8.4, 12.6, 16.9],
                           "t_end": [0.01, 4.21, 8.41, 12.61, 16.91],
                           "recurrence_s": [np.nan, 4.20, 4.25, 4.22, 4.27],
                           "friction_drop": [0.0469, 0.0470, 0.0465, 0.0472, 0.0468],
                           "slip_m": [4e-4] * 5, "peak_velocity_m_s": [0.06] * 5})
    write_observations(tmp_path / "obs.json", events)
    assert main(["work-precision", "--problem", str(EXAMPLE), "--t-end", "20",
                 "--integrators", "Rodas5P", "Rosenbrock23", "--tiers", "numba",
                 "--observations", str(tmp_path / "obs.json"), "--out", str(tmp_path),
                 "--json", "--no-progress"]) == 0
    out = json.loads(capsys.readouterr().out)
    yours = out["for_your_sigma"]
    assert yours["limits"]["err_recurrence"] == pytest.approx(0.1 * np.std(
        [4.20, 4.25, 4.22, 4.27], ddof=1) / np.mean([4.20, 4.25, 4.22, 4.27]))
    assert yours["choice"]["integrator"] in ("Rodas5P", "Rosenbrock23")
    table = pd.read_csv(tmp_path / "wp_quick_for_sigma.csv")
    assert (table.worst_err_recurrence <= yours["limits"]["err_recurrence"]).all()
    assert table.total_wall_s.is_monotonic_increasing and out["problems"] == ["W2, softer spring"]


@pytest.mark.slow
def test_solver_effect_ranks_the_settings_on_a_problem_file(tmp_path, capsys):
    import pandas as pd

    from benchmarks.inversion.observations import write_observations
    events = pd.DataFrame({"t_start": [0.0, 4.2, 8.4, 12.6], "t_end": [0.01, 4.21, 8.41, 12.61],
                           "recurrence_s": [np.nan, 4.20, 4.25, 4.22],
                           "friction_drop": [0.0469, 0.0470, 0.0465, 0.0472],
                           "slip_m": [4e-4] * 4, "peak_velocity_m_s": [0.06] * 4})
    write_observations(tmp_path / "obs.json", events)
    assert main(["solver-effect", "--problem", str(EXAMPLE), "--observations",
                 str(tmp_path / "obs.json"), "--b-range", "0.0086,0.0102", "--lc-range",
                 "3e-8,3e-6", "--n", "5", "--out", str(tmp_path / "se"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    table = pd.read_csv(tmp_path / "se" / "solver_effect.csv")
    assert set(table.window) == {"apparatus"} and set(table.data) == {"yours"}
    assert {"reference", "floor", "own", "ETD"} <= set(table.family)
    assert out["provenance"]["mode"] == "quick" and out["recommendation"]
    assert "your observations" in (tmp_path / "se" / "solver_effect.md").read_text()
    assert main(["solver-effect", "--problem", str(EXAMPLE), "--observations",
                 str(tmp_path / "obs.json"), "--b-range", "0.0086,0.0102", "--lc-range",
                 "3e-8,3e-6", "--study", str(tmp_path / "obs.json")]) == 2
    assert "add --full" in capsys.readouterr().err
