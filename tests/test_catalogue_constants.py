"""The apparatus constants a catalogue does not state, estimated from it
(:mod:`benchmarks.lab.catalogue_constants`): on synthetic catalogues of known stiffness and
load-point speed, the estimates lie within their stated standard errors as often as those
errors say; the problem file ``observe --catalogue`` writes from them is one the problem
loader and ``rsfbench simulate --problem`` read; impossible input is refused."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmarks.cli.main import main
from benchmarks.lab.catalogue import read_catalogue
from benchmarks.lab.catalogue_constants import (PAPER_A, PAPER_MASS, catalogue_apparatus_toml,
                                                estimate_constants)
from problems import load_problem

NIED = Path(__file__).parent / "data" / "nied-4m-stick-slip" / "Macroscopic_stats_FB03_087.csv"
NIED_ARGS = ["--catalogue", str(NIED), "--column", "onset=event_starttime[s]",
             "--column", "shear_stress_before=macroshearstress_beforeevent[MPa]:MPa",
             "--column", "shear_stress_after=macroshearstress_afterevent[MPa]:MPa",
             "--column", "slip=slip_mean[mm]:mm", "--area", "0.4", "--normal-stress", "2e6"]
#: the synthetic apparatus: k/Fn (1/m) and vL (m/s), about the NIED catalogue's
KAPPA, VL = 300.0, 8.4e-6


def synthetic_catalogue(seed: int, n: int = 56, scatter: float = 0.03,
                        rate_scatter: float = 0.1) -> pd.DataFrame:
    """A catalogue of known k/Fn = KAPPA and vL = VL: intervals of 1.5–7 s over which the
    friction rises at KAPPA·VL (each interval's rate off by ``rate_scatter``, Gaussian), levels
    after the events scattered by 0.0003, slips = drop/KAPPA with ``scatter`` (Gaussian)."""
    rng = np.random.default_rng(seed)
    dt = rng.uniform(1.5, 7.0, n - 1)
    after = 0.32 + 0.0003 * rng.standard_normal(n)
    before = np.empty(n)
    before[0] = after[0] + 0.02
    before[1:] = after[:-1] + KAPPA * VL * dt * (1 + rate_scatter * rng.standard_normal(n - 1))
    drop = before - after
    return pd.DataFrame({"t_start": np.concatenate(([30.0], 30.0 + np.cumsum(dt))),
                         "friction_drop": drop, "friction_before": before,
                         "friction_after": after,
                         "slip_m": drop / KAPPA * (1 + scatter * rng.standard_normal(n))})


def test_the_estimates_fall_within_their_standard_errors_as_often_as_they_say():
    # 400 synthetic catalogues of known k and vL, noise added: |estimate − truth| ≤ 2 se in
    # about 95 % of them (the binomial range of 400 draws at 95 %: 367–393 at 3 σ); a se too
    # small by half (or an estimate biased by one se) would put it near 70 %
    inside = {"k": 0, "vl": 0}
    for seed in range(400):
        c = estimate_constants(synthetic_catalogue(seed), normal_force=8e5, area=0.4)
        inside["k"] += abs(c.stiffness_per_fn.value - KAPPA) <= 2 * c.stiffness_per_fn.se
        inside["vl"] += abs(c.vl.value - VL) <= 2 * c.vl.se
    assert 360 <= inside["k"] <= 396 and 360 <= inside["vl"] <= 396, inside


def test_one_synthetic_catalogue_in_force_per_area_and_its_assumptions():
    c = estimate_constants(synthetic_catalogue(1), normal_force=8e5, area=0.4)
    assert c.stiffness.value == pytest.approx(KAPPA * 8e5, abs=3 * c.stiffness.se)
    assert c.stiffness_per_area.value == pytest.approx(c.stiffness.value / 0.4)
    assert c.stiffness.unit == "N/m" and c.stiffness_per_area.unit == "Pa/m"
    assert c.vl.value == pytest.approx(VL, abs=3 * c.vl.se)
    # the standard errors are a few per cent here, not zero nor the whole value
    assert 0.001 < c.stiffness.se / c.stiffness.value < 0.02 and 0.005 < c.vl.se / VL < 0.1
    assert c.n_events == 56 and c.n_intervals == 55 and c.vl.how == "measured"
    assert "creeps" in c.vl.assumption and "median" in c.stiffness_per_fn.assumption
    assert "not estimable" in c.as_dict()["mass"]
    # without the normal force: k/Fn and vL only (vL does not need Fn)
    bare = estimate_constants(synthetic_catalogue(1))
    assert bare.stiffness is None and bare.stiffness_per_area is None
    assert bare.vl.value == c.vl.value


def test_a_catalogue_of_drops_loads_from_the_next_drop():
    # without the levels before and after: the stress regained is the next event's drop, the
    # same as the levels' gain but for the drift of the level after (Gaussian, no trend here)
    table = synthetic_catalogue(3).drop(columns=["friction_before", "friction_after"])
    c = estimate_constants(table)
    assert c.vl.value == pytest.approx(VL, abs=3 * c.vl.se)
    assert any("next event's drop" in n for n in c.notes)


def test_a_start_up_event_moves_the_regression_not_the_median():
    # one event with three times the slip and a 20 % stiffer ratio: the median hardly moves,
    # the regression through the origin (slip² weights) moves by several of its se
    table = synthetic_catalogue(5)
    plain = estimate_constants(table)
    table.loc[0, "slip_m"] *= 3.0
    table.loc[0, "friction_drop"] = table.slip_m[0] * KAPPA * 1.2
    odd = estimate_constants(table)
    assert abs(odd.stiffness_per_fn.value - plain.stiffness_per_fn.value) \
        < plain.stiffness_per_fn.se
    assert odd.stiffness_regression - plain.stiffness_regression > 2 * plain.stiffness_per_fn.se


def test_the_after_delay_bias_is_stated_not_corrected():
    table = synthetic_catalogue(2)
    plain = estimate_constants(table)
    c = estimate_constants(table, after_delay=0.17)
    assert c.vl.value == plain.vl.value
    # rate low by d/ΔT̄; k low by at most d·rate/median(Δμ): about equal, as rate·ΔT̄ ≈ Δμ
    assert c.after_bias["rate_low_by"] == pytest.approx(0.17 / np.diff(table.t_start).mean())
    assert c.after_bias["stiffness_low_by_at_most"] == pytest.approx(
        c.after_bias["rate_low_by"], rel=0.2)
    assert any("0.17 s after its onset" in n for n in c.notes)


@pytest.mark.parametrize("change, kw, said", [
    (lambda t: t.drop(columns="slip_m"), {}, "no column 'slip_m'"),
    (lambda t: t.assign(slip_m=math.nan), {}, "0 events have a slip"),
    (lambda t: t.assign(slip_m=np.where(t.index == 4, -1e-5, t.slip_m)), {},
     "event 5: slip_m = -1e-05 m is not positive"),
    (lambda t: t.assign(friction_drop=np.where(t.index == 2, 0.0, t.friction_drop)), {},
     "event 3: friction_drop = 0 is not positive"),
    (lambda t: t.assign(t_start=np.where(t.index == 6, t.t_start[5], t.t_start)), {},
     "event 7: onset"),
    (lambda t: t.iloc[:2], {}, "2 events with an onset: the constants need at least 3"),
    (lambda t: t, {"normal_force": -8e5}, "normal_force"),
    (lambda t: t, {"after_delay": 2.0}, "after_delay = 2 s must be from 0 to below"),
], ids=["no slip column", "no slips", "negative slip", "zero drop", "onsets repeat",
        "two events", "negative normal force", "delay past an interval"])
def test_impossible_input_is_refused(change, kw, said):
    with pytest.raises(ValueError, match=said.replace("(", r"\(")):
        estimate_constants(change(synthetic_catalogue(0)), **kw)


def test_the_problem_file_needs_the_stiffness_in_newtons_per_metre():
    with pytest.raises(ValueError, match="needs the stiffness in N/m"):
        catalogue_apparatus_toml(estimate_constants(synthetic_catalogue(0)), 4.0, "x", 8e5)


# --- observe --catalogue ------------------------------------------------------------------------

def test_observe_writes_an_apparatus_file_the_loader_and_simulate_read(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["observe", *NIED_ARGS, "--after-delay", "0.17", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "observations.json").read_text())
    events, info = read_catalogue(NIED, NIED_ARGS[3::2][:4], area=0.4, normal_stress=2e6)
    c = estimate_constants(events, info["normal_force"], 0.4, after_delay=0.17)
    problem = load_problem(out / "apparatus.toml")
    # k and vL as the module estimates them from the catalogue; Fn = 2 MPa × 0.4 m²; the mass
    # and a the paper's, assumed; t_end 25 mean recurrence intervals of the events used
    assert problem.stiffness == pytest.approx(c.stiffness.value, rel=1e-5)
    assert problem.loading.vl == pytest.approx(c.vl.value, rel=1e-5)
    assert problem.normal_force == pytest.approx(8e5) and problem.mass == PAPER_MASS
    assert problem.law.a == PAPER_A and problem.law.b > problem.law.a
    assert problem.t_end == pytest.approx(25 * doc["metrics"]["recurrence_s"]["mean"], rel=1e-5)
    toml = (out / "apparatus.toml").read_text()
    assert "measured ±" in toml and "assumed: the paper's slider" in toml
    assert "--b-range 0.008,0.01 --lc-range 1e-08,1e-05" in toml
    assert doc["apparatus"]["stiffness"] == pytest.approx(c.stiffness.value)
    assert doc["how"]["mass"].startswith("assumed")
    assert "stiffness k" in text and "load-point speed vL" in text and "moving mass" in text
    # the placeholders b, lc make stick–slip: the file runs as it is, to a limit cycle
    assert main(["simulate", "--problem", str(out / "apparatus.toml"), "--json"]) == 0
    cycle = json.loads(capsys.readouterr().out)["limit_cycle"]
    assert cycle["classification"] == "stick-slip", cycle


def test_observe_json_carries_the_estimates_and_a_given_mass(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["observe", *NIED_ARGS, "--mass", "380", "--out", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["constants"]["vl"]["unit"] == "m/s" and doc["constants"]["after_bias"] is None
    assert doc["apparatus"]["mass"] == 380 and doc["how"]["mass"] == "given"
    assert load_problem(out / "apparatus.toml").mass == 380


def test_a_catalogue_of_friction_without_loads_writes_no_apparatus_file(tmp_path, capsys):
    table = synthetic_catalogue(0)
    path = tmp_path / "cat.csv"
    table.to_csv(path, index=False)
    args = ["observe", "--catalogue", str(path), "--column", "onset=t_start",
            "--column", "friction_before=friction_before", "--column",
            "friction_after=friction_after", "--column", "slip=slip_m:m", "--out",
            str(tmp_path / "o")]
    assert main(args) == 0
    assert not (tmp_path / "o" / "apparatus.toml").exists()
    assert "load-point speed vL" in capsys.readouterr().out


@pytest.mark.parametrize("args, said", [
    (["--after-delay", "0.17"], "--after-delay is for a catalogue"),
    (["--catalogue-free"], None),
], ids=["a recording's delay", "unknown option"])
def test_the_delay_belongs_to_a_catalogue(tmp_path, capsys, args, said):
    recording = tmp_path / "r.csv"
    recording.write_text("t,Fs\n0,1\n1,2\n")
    code = main(["observe", str(recording), "--column", "time=t", "--column",
                 "shear_force=Fs", *args, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and (said is None or said in err) and "\n" not in err, err
    assert not (tmp_path / "o").exists()


def test_a_delay_without_slips_and_a_delay_past_an_interval_are_refused(tmp_path, capsys):
    base = ["observe", "--catalogue", str(NIED), "--column", "onset=event_starttime[s]",
            "--column", "drop=macroshearstress_drop[MPa]:MPa", "--area", "0.4",
            "--normal-stress", "2e6", "--out", str(tmp_path / "o")]
    assert main([*base, "--after-delay", "0.17"]) == 2
    assert "need the slip per event" in capsys.readouterr().err
    assert main([*NIED_ARGS[:0], *base, "--column", "slip=slip_mean[mm]:mm",
                 "--after-delay", "5"]) == 2
    assert "after_delay = 5 s must be from 0 to below" in capsys.readouterr().err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())
