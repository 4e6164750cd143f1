"""The settled cycle (issue 47): the events of a record that differ from its settled cycle — the
start-up, the outliers — are found and named with their distance; the start-up is left out of
the means unless kept; ``--window`` measures part of a record; a small σ of a regular cycle is
said to be that, not a unit slip.

The end-to-end check is on a recording made outside the project's model code
(``benchmarks/lab/independent_stick_slip.py``: scipy's Radau on the paper's W2 equations from
near steady sliding, 1 % sensor noise)."""

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from benchmarks.lab import independent_stick_slip as independent_radau
from benchmarks.cli.main import main
from benchmarks.inversion.observations import Observations, read_observations
from benchmarks.lab.observe_recording import observe
from benchmarks.lab.settled import Z_DIFFERS, judge
from problems._validate import RegularCycleWarning, UnitWarning


def _cycle(n=20, scatter=1e-6, seed=0, startup=(), tails=None):
    """A per-event table about W2's cycle (ΔT 3.044 s, Δμ 0.0452, slip 0.305 mm) with relative
    scatter ``scatter`` (normal, or Student-t of ``tails`` degrees of freedom); the leading
    rows scaled by the factors ``startup``."""
    rng = np.random.default_rng(seed)
    e = rng.standard_normal((n, 3)) if tails is None else rng.standard_t(tails, (n, 3))
    ev = pd.DataFrame({"recurrence_s": 3.044 * (1 + scatter * e[:, 0]),
                       "friction_drop": 0.0452 * (1 + scatter * e[:, 1]),
                       "slip_m": 3.05e-4 * (1 + scatter * e[:, 2])})
    for i, factor in enumerate(startup):
        ev.iloc[i] *= np.broadcast_to(factor, 3)
    return ev


# --- the verdict on a per-event table ------------------------------------------------------------

def test_the_start_up_of_a_regular_cycle_is_found_and_left_out():
    # the transient decays as the independent Radau run's (ΔT 1.03, 2.43, 2.96, 3.036 s …)
    ev = _cycle(startup=(0.34, 0.80, 0.97, 0.997, 0.9997))
    verdict = judge(ev, when=np.arange(20.0))
    assert verdict.startup == [0, 1, 2, 3, 4] and verdict.outliers == []
    marked = verdict.mark(ev)
    assert list(marked.kept) == [False] * 5 + [True] * 15
    assert list(marked.reason[:6]) == ["start-up"] * 5 + [""]
    # by how many σ: event 5 is 3e-4 off a cycle that repeats to 1e-6, ~300 σ
    assert 100 < marked.z_max[4] < 1000 and marked.z_max[5:].max() < Z_DIFFERS
    (note,) = verdict.notes
    assert "the first 5 events differ" in note and "event 1 (t = 0 s)" in note
    assert "left out of the means" in note


def test_keep_startup_keeps_it_and_still_names_it():
    verdict = judge(_cycle(startup=(0.5, 0.9)), keep_startup=True)
    assert verdict.startup == [0, 1] and verdict.dropped == []
    assert verdict.mark(_cycle()).kept.all()
    assert "kept in the means (--keep-startup)" in verdict.notes[0]


def test_an_irregular_record_keeps_its_ordinary_events():
    # 20 % scatter with heavy tails (Student-t, 3 degrees of freedom), 30 events, no start-up:
    # none of 100 records loses its first events (measured: none of 300; settled.STANDS_OUT)
    dropped = [seed for seed in range(100)
               if judge(_cycle(30, 0.2, seed, tails=3)).startup]
    assert dropped == []


def test_a_start_up_stands_out_of_a_record_with_20_percent_scatter():
    # as NIED's catalogue: the first drop and slip three times the others'
    ev = _cycle(30, 0.2, seed=4, startup=((1.0, 3.0, 3.0),))
    verdict = judge(ev)
    assert verdict.startup == [0]
    assert verdict.z.iloc[0].drop("recurrence_s").min() > Z_DIFFERS     # ~10 σ: 2/0.2


def test_an_isolated_outlier_is_named_and_kept():
    ev = _cycle(scatter=1e-3)
    ev.loc[9, "slip_m"] *= 1.05                      # 50 σ
    verdict = judge(ev)
    assert verdict.startup == [] and verdict.outliers == [9]
    marked = verdict.mark(ev)
    assert marked.kept.all() and marked.reason[9] == "outlier"
    assert "event 10: slip by +" in verdict.notes[0] and "kept in the means" in verdict.notes[0]


def test_an_odd_first_event_no_odder_than_a_later_one_is_not_a_start_up():
    ev = _cycle(scatter=1e-3)
    ev.loc[0, "recurrence_s"] *= 1.012               # ~12 σ
    ev.loc[12, "recurrence_s"] *= 0.98               # ~20 σ
    verdict = judge(ev)
    assert verdict.startup == [] and verdict.outliers == [0, 12]
    assert any("irregular throughout" in n for n in verdict.notes)


def test_a_record_that_has_not_settled_drops_nothing():
    verdict = judge(_cycle(3, startup=(0.5,)))
    assert verdict.startup == [] and any("too few are left" in n for n in verdict.notes)


def test_a_catalogue_s_first_event_without_recurrence_is_judged_on_the_rest():
    ev = _cycle(12, 1e-2, startup=((1.0, 3.0, 3.0),))
    ev.loc[0, "recurrence_s"] = np.nan
    assert judge(ev).startup == [0]


# --- σ of a regular cycle ------------------------------------------------------------------------

def _warned(make):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        make()
    return [w for w in seen if issubclass(w.category, UnitWarning)]


def test_a_small_sigma_of_a_regular_cycle_is_said_as_such():
    # the settled Radau cycle as observe measures it at 5 kHz: σ(ΔT)/ΔT ~ 1e-4, σ(Δμ)/Δμ ~ 3e-3;
    # a model's record repeats to 1e-6
    seen = _warned(lambda: Observations(3.044, 3.0e-6, 0.0452, 4.5e-6))
    assert [w.category for w in seen] == [RegularCycleWarning] * 2
    text = str(seen[0].message)
    assert text.startswith("sigma_recurrence_s = 3e-06 is 9.9e-07 × recurrence_s")
    assert "very regular cycle" in text and "not a unit slip" in text and "±0.00024 %" in text
    assert "hours" not in text and "implausibly" not in text


def test_unit_slips_of_sigma_and_mean_are_still_called_so():
    slips = {"sigma in ms": (3.1, 310.0, "is 100 × recurrence_s"),
             "mean in hours": (0.3 / 3600, 0.03 / 3600, "not hours")}
    for what, (mean, sigma, said) in slips.items():
        seen = _warned(lambda: Observations(mean, sigma, 0.046, 0.0046))
        assert seen and all(w.category is UnitWarning for w in seen), what
        assert any(said in str(w.message) for w in seen), what


# --- a recording from an independent Radau run, start-up kept in the file ---------------------------

@pytest.fixture(scope="module")
def radau_recording(tmp_path_factory):
    """40 s at 5 kHz (200,000 rows), 1 % noise: 13 events, the first four before the cycle
    settles (ΔT 1.03, 2.43, 2.96, 3.036 s against 3.04410 s). Made once (~8 s of CPU)."""
    table, truth = independent_radau.recording(t_end=40.0, rate=5000.0)
    path = tmp_path_factory.mktemp("radau") / "radau_w2.csv"
    table.to_csv(path, index=False)
    return path, truth


COLUMNS = {c: c for c in ("time", "shear_force", "acceleration", "slip", "table")}
W2 = dict(normal_force=independent_radau.FN, mass=independent_radau.M)


def _means(doc):
    return {k: doc["metrics"][k]["mean"] for k in ("recurrence_s", "friction_drop", "slip_m")}


@pytest.mark.slow
def test_a_kept_start_up_leaves_the_means_within_0_1_percent_of_the_settled_cycle(
        radau_recording, tmp_path):
    """The issue's target. Against the same record cropped to its settled part by hand
    (--window), every mean within 0.1 %; against the run's own cycle too (measured at the
    commit that took the fit's noise lift off: ΔT −2.9e−5, Δμ +9.2e−4, slip +5.2e−4; Δμ was
    +2.75e−3 with the lift left on)."""
    path, truth = radau_recording
    whole = observe(path, COLUMNS, tmp_path / "whole", plot=False, **W2)
    settled = truth.t_start > 10.0                    # by the run's own ΔT: within 3e-4
    cropped = observe(path, COLUMNS, tmp_path / "cropped", plot=False,
                      window=(truth.t_start[settled].iloc[0] - 1.0, 39.9), **W2)
    assert 1 <= len(whole["settled"]["startup_events"]) <= 6
    assert whole["settled"]["startup_events"][0] == 1
    for k, v in _means(whole).items():
        assert abs(v / _means(cropped)[k] - 1) < 1e-3, k
    cycle = truth.iloc[-1]
    for k, v in _means(whole).items():
        assert abs(v / cycle[k] - 1) < 1e-3, k
    # σ with and without the start-up: the transient's size against the cycle's scatter
    every, kept = whole["metrics_all_events"], whole["metrics"]
    assert every["recurrence_s"]["std"] > 100 * kept["recurrence_s"]["std"]
    events = pd.read_csv(tmp_path / "whole" / "events.csv")
    assert list(events.reason[events.reason.notna()].unique()) == ["start-up"]
    assert (~events.kept).sum() == len(whole["settled"]["startup_events"])
    obs = read_observations(tmp_path / "whole" / "observations.json")
    assert obs.recurrence_s == pytest.approx(kept["recurrence_s"]["mean"])


@pytest.mark.slow
def test_keep_startup_puts_the_transient_back_in_the_means(radau_recording, tmp_path, capsys):
    path, truth = radau_recording
    assert main(["observe", str(path), *[f"--column={c}={c}" for c in COLUMNS],
                 "--normal-force", "997500", "--mass", "1100", "--no-plot", "--keep-startup",
                 "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "kept in the means (--keep-startup)" in out
    doc = json.loads((tmp_path / "o" / "observations.json").read_text())
    assert doc["settled"]["startup_kept"] and doc["settled"]["dropped_events"] == []
    # the start-up's bias on the mean ΔT: several per cent short
    assert doc["metrics"]["recurrence_s"]["mean"] / truth.iloc[-1].recurrence_s - 1 < -0.02


@pytest.fixture
def short_record(tmp_path):
    """A 2 s record at 1 kHz (no events needed: a window is checked before any measure)."""
    t = np.arange(0.0, 2.0, 1e-3)
    path = tmp_path / "short.csv"
    pd.DataFrame({"time": t, "Fs": 6e5 + 1e3 * np.sin(t)}).to_csv(path, index=False)
    return path


@pytest.mark.parametrize("window, said", [(("1", "5"), "reaches outside the record"),
                                          (("1.5", "0.5"), "must be before END"),
                                          (("-1", "1"), "reaches outside the record"),
                                          (("nan", "1"), "two finite times")])
def test_a_window_outside_the_record_is_refused_in_one_line(short_record, tmp_path, capsys,
                                                            window, said):
    out = tmp_path / "o"
    assert main(["observe", str(short_record), "--column=time=time", "--column=shear_force=Fs",
                 "--normal-force", "1e6", "--window", *window, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert said in err and "\n" not in err
    assert not out.exists() or not any(out.iterdir())
