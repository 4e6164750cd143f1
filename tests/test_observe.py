"""``rsfbench observe``: from a laboratory recording to the observations of an inversion.

Round trips: recordings made by the forward model (benchmarks/lab/synthetic.py:
sampled at 10 kHz, an anti-alias filter, white noise and a slow drift as fractions of what one
event changes) from which the analysis must recover the model's own per-event metrics — those
of its event table, which its integrator located by root finding — and the apparatus it was made
with, within tolerances that shrink with the noise. Misuse: each a clear line naming the column
and the row."""

import json
import math
from unittest import mock

import numpy as np
import pandas as pd
import pytest

from benchmarks.inversion.observations import read_observations, write_observations
from benchmarks.lab.observe_recording import observe, read_column_file
from benchmarks.lab.events import analyse
from benchmarks.lab.channels import column_spec, read_recording, recording_from
from benchmarks.lab.synthetic import synthetic_recording
from problems import preset

ALL = ("time", "shear_force", "acceleration", "slip", "table")
W2 = preset("W2", law="slip", t_end=40.0)


@pytest.fixture(scope="module")
def records():
    """W2, slip law, 40 s at 10 kHz from t = 10 s (8 complete events): clean and noisy."""
    return {noise: synthetic_recording(W2, t_skip=10.0, noise=noise, drift=noise, seed=3)
            for noise in (0.0, 0.003, 0.01)}


def _measure(table, channels=ALL, problem=W2, **kw):
    rec = recording_from(table, {c: c for c in channels}, normal_force=problem.normal_force)
    return analyse(rec, mass=problem.mass, **kw)


def _rel(measured, truth):
    return abs(measured / truth - 1.0)


# tolerances (relative) at noise n: the targets at n = 1 % are ΔT and Δμ 0.5 %, slip
# 2 %, k 1 %; with no noise what is left is the sampling (0.1 ms) and the fits' shapes
TOL = {"recurrence_s": lambda n: 1e-5 + 0.05 * n, "friction_drop": lambda n: 1e-3 + 0.4 * n,
       "slip_m": lambda n: 2e-3 + 1.8 * n, "peak_velocity_m_s": lambda n: 5e-3 + 1.0 * n}


@pytest.mark.parametrize("noise", [0.0, 0.003, 0.01])
@pytest.mark.parametrize("channels", [ALL, ("time", "shear_force", "acceleration", "table"),
                                      ("time", "shear_force", "slip", "table")],
                         ids=["all", "accelerations", "slip column"])
def test_the_model_s_own_metrics_come_back(records, noise, channels):
    table, truth = records[noise]
    found = _measure(table, channels)
    model = truth.events.iloc[1:]                 # the first recorded event's stick is cut
    assert len(found.events) == len(model) == 8
    # event by event: the same events, in order
    assert np.allclose(found.events.t_start, model.t_start, atol=0.02)
    for metric, tol in TOL.items():
        assert _rel(found.events[metric].mean(), model[metric].mean()) <= tol(noise), metric
    k_tol = 1e-3 + 0.9 * noise if "slip" in channels else 5e-3 + 0.9 * noise   # creep, see k's how
    assert _rel(found.apparatus["stiffness"], truth.stiffness) <= k_tol
    assert _rel(found.apparatus["vls"], truth.vls) <= 1e-3 + 0.2 * noise
    assert _rel(found.apparatus["vlf"], truth.vlf) <= 2e-3 + 1.0 * noise
    assert _rel(found.apparatus["df"], truth.df) <= 2e-3 + 1.5 * noise


def test_the_force_alone_gives_the_recurrence_and_the_drop(records):
    table, truth = records[0.01]
    found = _measure(table, ("time", "shear_force", "table"))
    model = truth.events.iloc[1:]
    assert _rel(found.events.recurrence_s.mean(), model.recurrence_s.mean()) <= 1e-3
    assert _rel(found.events.friction_drop.mean(), model.friction_drop.mean()) <= 5e-3
    assert found.events.peak_velocity_m_s.isna().all() and found.curves is None
    assert any("force alone" in n for n in found.notes)


def test_curves_are_the_fault_s_friction_on_the_model_s_convention(records):
    """The observed curve of an event against the model's (event_curve: Ft/Fn against the slip
    since the start, from the event's start to its end), on the clean record."""
    from benchmarks.physics.curves import event_curve
    from integrators import Rodas5P, solve
    table, truth = records[0.0]
    found = _measure(table)
    sol = solve(W2, Rodas5P(rtol=1e-10, atol=1e-10), save_every=1e-4, max_points=400_002)
    slip, mu = event_curve(sol, -2)                  # the last complete event
    last = found.curves[found.curves.event_id == found.curves.event_id.max()]
    inside = (last.slip_m > 0.05 * slip[-1]) & (last.slip_m < 0.95 * slip[-1])
    model = np.interp(last.slip_m[inside], slip, mu)
    assert np.max(np.abs(last.friction[inside] - model)) < 2e-3       # Ft/Fn; the drop is 0.045
    # the load cell's force is not the fault's friction: it would be off by far more
    fs = np.interp(last.slip_m[inside], *_spring_curve(sol))
    assert np.max(np.abs(fs - model)) > 5e-3


def test_a_vibrating_lower_specimen_is_in_the_friction_not_the_slip(records):
    """a2 ≠ 0 (synthetic_recording's ``shake``: the upper specimen carried along): the slip is
    integrated from a1 − a2 and is the model's, but the fault's friction is Fs − m·a1 (Eq. 3),
    the model's less m·a2. m·a2/Fn is 0.01 rms, a fifth of the drop: a reading with a1 − a2
    in Eq. 3 would give the model's curve, off by that."""
    shake = 0.01 * W2.normal_force / W2.mass
    table, truth = synthetic_recording(W2, t_skip=10.0, shake=shake, seed=3)
    assert np.std(table.acceleration_lower) == pytest.approx(shake, rel=0.01)
    found = _measure(table, (*ALL, "acceleration_lower"))
    still = _measure(records[0.0][0])
    model = truth.events.iloc[1:]
    assert len(found.events) == len(model) == 8
    for metric, tol in TOL.items():
        assert _rel(found.events[metric].mean(), model[metric].mean()) <= tol(0.0), metric
    t, a2 = table.time.to_numpy(), table.acceleration_lower.to_numpy()
    for k, ev in found.events.reset_index(drop=True).iterrows():
        shaken = found.curves[found.curves.event_id == k + 1]
        calm = still.curves[still.curves.event_id == k + 1]
        assert np.allclose(shaken.slip_m, calm.slip_m, rtol=0, atol=1e-3 * ev.slip_m)
        i0 = int(np.searchsorted(t, ev.t_start))          # the curve's first sample
        expected = calm.friction.to_numpy() - W2.mass * a2[i0:i0 + len(calm)] / W2.normal_force
        assert np.max(np.abs(shaken.friction.to_numpy() - expected)) < 1e-3


def _spring_curve(sol):
    from benchmarks.physics.curves import event_window
    t, slip, fs = event_window(sol, -2)
    return slip, fs / sol.problem.normal_force


@pytest.mark.parametrize("name, law, t_end", [("W4", "slip", 8.0), ("W3", "aging", 40.0)])
def test_other_windows_and_the_aging_law(name, law, t_end):
    problem = preset(name, law=law, t_end=t_end)
    table, truth = synthetic_recording(problem, t_skip=t_end / 4, noise=0.01, drift=0.01, seed=5)
    found = _measure(table, problem=problem)
    model = truth.events.iloc[1:]
    assert len(found.events) == len(model) >= 3
    for metric in ("recurrence_s", "friction_drop", "slip_m"):
        assert _rel(found.events[metric].mean(), model[metric].mean()) <= TOL[metric](0.01)


# --- the observations file --------------------------------------------------------------------

def test_the_file_reads_back_with_either_sigma(records, tmp_path):
    table, _ = records[0.01]
    found = _measure(table)
    path = tmp_path / "observations.json"
    doc = write_observations(path, found.events, found.curves, found.apparatus, found.how,
                             found.notes)
    ev = found.events
    assert doc["metrics"]["recurrence_s"]["std"] == pytest.approx(ev.recurrence_s.std())
    assert doc["metrics"]["friction_drop"]["sem"] == pytest.approx(
        ev.friction_drop.std() / math.sqrt(len(ev)))
    with pytest.warns(UserWarning):                # the model's cycle hardly scatters
        obs = read_observations(path)
        sem = read_observations(path, sigma="sem")
    assert obs.recurrence_s == pytest.approx(ev.recurrence_s.mean())
    assert obs.sigma_friction_drop == pytest.approx(ev.friction_drop.std())
    assert sem.sigma_friction_drop == pytest.approx(ev.friction_drop.std() / math.sqrt(len(ev)))
    assert len(obs.curves) == len(found.curves)
    back = pd.read_csv(path.with_name("events.csv")) if path.with_name("events.csv").exists() \
        else None
    assert back is None                            # write_observations writes the JSON only
    doc["version"] = 99
    path.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="version 1"):
        read_observations(path)


def test_observe_writes_its_files_and_reads_units(records, tmp_path):
    table, truth = records[0.003]
    lab = table.assign(shear_force=table.shear_force / 1e3, slip=table.slip * 1e3,
                       table=table.table * 1e3)
    lab.columns = ["Time(s)", "Load", "a1", "LDT", "Table"]
    lab.to_csv(tmp_path / "rec.csv", index=False)
    (tmp_path / "columns.toml").write_text(
        '[columns]\ntime = "Time(s)"\nshear_force = {column = "Load", unit = "kN"}\n'
        'acceleration = "a1"\nslip = {column = "LDT", unit = "mm"}\n'
        'table = {column = "Table", unit = "mm"}\n\n[apparatus]\nnormal_force = 997500.0\n'
        'mass = 1100.0\n')
    columns, constants = read_column_file(tmp_path / "columns.toml")
    doc = observe(tmp_path / "rec.csv", columns, tmp_path / "out", **constants)
    files = doc["files"]
    assert set(files) == {"observations", "events", "curves", "apparatus", "figure"}
    events = pd.read_csv(files["events"])
    assert len(events) == 8 and list(events.columns)[:2] == ["t_start", "t_end"]
    assert _rel(doc["apparatus"]["stiffness"], truth.stiffness) < 5e-3
    from problems import load_problem
    problem = load_problem(files["apparatus"])               # simulate runs it
    assert problem.loading.two_speed and _rel(problem.stiffness, truth.stiffness) < 5e-3
    assert doc["recording"]["columns"]["shear_force"] == {"column": "Load", "unit": "kN"}


# --- misuse: one line, naming the column and the row ---------------------------------------------

def _table(n=2000, rate=1000.0, fall=0.008):
    """A sawtooth: a rise of 0.04 in μ over 0.3 s − ``fall``, then a drop over ``fall`` s."""
    t = np.arange(n) / rate
    phase = t % 0.3
    rise = 0.3 - fall
    saw = 0.6 + 0.04 * np.where(phase < rise, phase / rise, 1.0 - (phase - rise) / fall)
    return pd.DataFrame({"t": t, "Fs": saw * 1e6})


@pytest.mark.parametrize("change, match", [
    (lambda d: d.assign(t=d.t.where(d.index != 100, d.t[98])), "column 't' row 102 goes back"),
    (lambda d: d.assign(t=d.t.where(d.index != 100, d.t[99])), "column 't' row 102 repeats"),
    (lambda d: d.assign(t=d.t + (d.index >= 500) * 0.5), "a gap of 0.501 s after row 501"),
    (lambda d: d.assign(Fs=d.Fs.where((d.index < 50) | (d.index > 59))),
     "column 'Fs' has no value from row 52 \\(10 samples missing\\)"),
    (lambda d: d.assign(Fs=d.Fs.astype(object).where(d.index != 7, "x")),
     "column 'Fs' row 9 is not a number \\('x'\\)"),
    (lambda d: d.assign(Fs=np.minimum(d.Fs, 6.3e5)), "column 'Fs' \\(shear_force\\) is stuck at "
                                                      "its maximum 630000 from row"),
    (lambda d: d.assign(Fs=d.Fs / 1e3), "column 'Fs' \\(shear_force\\) over the normal force is "
                                        "0.000"),
    (lambda d: d.assign(t=d.t - 0.0006 * (d.index >= 1000)), "row 1002: samples 0.0004 s apart"),
])
def test_bad_recordings_are_refused_in_one_line(change, match):
    with pytest.raises(ValueError, match=match) as err:
        rec = recording_from(change(_table()), {"time": "t", "shear_force": "Fs"},
                             normal_force=1e6)
        analyse(rec)
    assert "\n" not in str(err.value)


def test_a_record_without_events_or_with_one_is_refused():
    flat = pd.DataFrame({"t": np.arange(3000) / 1e3,
                         "Fs": 6e5 + np.random.default_rng(0).normal(0, 10, 3000)})
    with pytest.raises(ValueError, match="no stick–slip event in column 'Fs'"):
        analyse(recording_from(flat, {"time": "t", "shear_force": "Fs"}, normal_force=1e6))
    t = np.arange(4000) / 1e3
    one = pd.DataFrame({"t": t, "Fs": np.where(t < 2.0, 6.4e5 + 1e4 * t, 6.0e5 + 1e4 * t)})
    with pytest.raises(ValueError, match="0 complete stick–slip events"):
        analyse(recording_from(one, {"time": "t", "shear_force": "Fs"}, normal_force=1e6))


def test_a_unit_slip_between_columns_is_named(records):
    table, _ = records[0.0]
    wrong = table.assign(slip=table.slip * 1e3)        # mm read as m
    thousand = "(9\\d\\d|1e\\+03)"                      # 934 over this record's span
    with pytest.raises(ValueError, match=f"column 'slip' \\(slip\\) advances {thousand} times "
                                         "as far as column 'table' \\(table\\)"):
        _measure(wrong)
    with pytest.raises(ValueError, match="integrated from column 'acceleration' \\(acceleration"
                                         f"\\) is {thousand} times the travel"):
        _measure(table.assign(acceleration=table.acceleration * 1e3),
                 ("time", "shear_force", "acceleration", "table"))


@pytest.mark.parametrize("spec, match", [
    ("force=Fs", "unknown channel 'force'"), ("shear_force", "expected CHANNEL=COLUMN"),
    ("slip=LDT:kN", "kN is not a unit of slip"),
])
def test_column_specs_are_checked(spec, match):
    with pytest.raises(ValueError, match=match):
        column_spec(spec)


def test_a_column_s_own_colon_is_kept():
    assert column_spec("time=Time:s") == ("time", "Time", "s")
    assert column_spec("time=t:raw") == ("time", "t:raw", "s")
    assert column_spec("slip=LDT:mm") == ("slip", "LDT", "mm")


def test_a_missing_file_and_column_are_named(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        read_recording(tmp_path / "none.csv", ["time=t", "shear_force=Fs"], normal_force=1e6)
    _table().to_csv(tmp_path / "r.csv", index=False)
    with pytest.raises(ValueError, match="has no column 'Load'; its columns: t, Fs"):
        read_recording(tmp_path / "r.csv", ["time=t", "shear_force=Load"], normal_force=1e6)


def test_what_is_no_saturation_is_not_refused():
    """A held normal force, a slip at its extremes at the record's ends, and one flat peak of a
    quantised force: none is a clipped sensor (two flat runs at the extreme inside the record
    are)."""
    d = _table()
    d["Fn"] = 1e6                                         # a column of the held value
    d["u"] = np.round(np.arange(len(d)) * 1e-6, 9)        # advances: its extremes at the ends
    peak = int(d.Fs.idxmax())
    d.loc[peak - 30:peak, "Fs"] = d.Fs[peak]              # one flat top, 31 samples
    rec = recording_from(d, {"time": "t", "shear_force": "Fs", "normal_force": "Fn",
                             "slip": "u"})
    assert rec.has("normal_force") and rec.has("slip")


def test_files_as_other_programs_write_them(tmp_path):
    import csv
    _table().to_csv(tmp_path / "q.csv", index=False, quoting=csv.QUOTE_ALL)   # R's write.csv
    rec = read_recording(tmp_path / "q.csv", ["time=t", "shear_force=Fs"], normal_force=1e6)
    assert len(rec.t) == 2000
    with pytest.raises(ValueError, match="'kgf' in 'Fs:kgf' is not a known unit"):
        read_recording(tmp_path / "q.csv", ["time=t", "shear_force=Fs:kgf"], normal_force=1e6)
    durations = _table().assign(t=pd.to_timedelta(_table().t, unit="s"))
    with pytest.raises(ValueError, match="column 't' holds timedelta64.* give it as numbers"):
        recording_from(durations, {"time": "t", "shear_force": "Fs"}, normal_force=1e6)


@pytest.mark.parametrize("text, match", [
    ('columns = ["t"]\n', "columns must be a table"),
    ('[columns]\ntime = "t"\nshear_force = {column = "Fs", unit = "kgf"}\n',
     "column 'Fs' \\(shear_force\\): 'kgf' is not a known unit"),
])
def test_column_files_are_checked(tmp_path, text, match):
    (tmp_path / "c.toml").write_text(text)
    with pytest.raises(ValueError, match=match):
        read_column_file(tmp_path / "c.toml")


def test_observe_prints_a_record_of_the_force_alone(tmp_path, capsys):
    """The text output of a record whose slip and peak slip rate are not measured (null in the
    file): a dash, not a crash; a channel given twice is refused."""
    from benchmarks.cli import main
    _table(n=6000).to_csv(tmp_path / "r.csv", index=False)
    args = ["observe", str(tmp_path / "r.csv"), "--column", "time=t", "--column",
            "shear_force=Fs", "--normal-force", "1e6", "--out", str(tmp_path / "o"), "--no-plot"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "peak slip rate       – " in out and "complete events" in out
    doc = json.loads((tmp_path / "o" / "observations.json").read_text())
    assert doc["provenance"]["command"].startswith("rsfbench observe ")
    assert main([*args, "--column", "time=t"]) == 2
    assert "channel time is mapped twice" in capsys.readouterr().err


# --- a recording made by an independent implementation ----------------------------------------

def _independent_recording(t_end=30.0, rate=10_000.0):
    """The W2 spring-slider (slip law, two-speed loading; Urata et al. 2017, Tables 2 and 4)
    written here with scipy alone — its own equations, state (s = l − u, ln v, θ), integrator
    (LSODA) and event rules — and its events measured on its dense output at 100 kHz, not by
    the project's code. Returns the recording from t = 8 s and the per-event truth."""
    from scipy.integrate import solve_ivp
    m, k, fn, a, b, lc, v0 = 1100.0, 1.48e8, 997500.0, 0.008, 0.0094, 3e-7, 1e-5
    vls, vlf, df = 7.5e-5, 1.9717e-3, 0.042

    def rhs(t, y, vl):
        s, lnv, th = y
        v = math.exp(lnv)
        ft_minus_f0 = a * fn * (lnv - math.log(v0)) + th        # Ft − F0
        return [vl - v, (k * s - ft_minus_f0) / (m * v),
                -v / lc * (th + b * fn * (lnv - math.log(v0)))]

    def crossing(level, direction):
        def g(t, y, vl):
            return y[1] - math.log(level)
        g.terminal, g.direction = True, direction
        return g

    v = vls / 1.1                                  # steady sliding 1.1× slower, Fs = Ft
    th = -b * fn * math.log(v / v0)
    y = [(a * fn * math.log(v / v0) + th) / k, math.log(v), th]
    t, pieces, starts, ends = 0.0, [], [], []
    while t < t_end:
        # slow loading until an event starts and ends; then the fast loading for df
        for vl, ev, until in ((vls, crossing(10 * vls, 1), t_end), (vls, crossing(vls, -1), t_end),
                              (vlf, None, None)):
            stop = t_end if until is not None else min(t + df, t_end)
            sol = solve_ivp(rhs, (t, stop), y, method="LSODA", rtol=1e-10, atol=1e-12,
                            dense_output=True, events=ev, args=(vl,))
            pieces.append((t, sol.t[-1], vl, sol.sol))
            if ev is not None and sol.t_events[0].size:
                (starts if ev.direction > 0 else ends).append(sol.t_events[0][0])
            t, y = sol.t[-1], sol.y[:, -1]
            if t >= t_end:
                break
    # the trajectory: s, v and the load point's travel l (exact: piecewise constant vL)
    fine = np.arange(0.0, t, 1e-5)
    s_f, lnv_f, l_f = np.empty_like(fine), np.empty_like(fine), np.empty_like(fine)
    travel = 0.0
    for t0, t1, vl, dense in pieces:
        inside = (fine >= t0) & (fine <= t1)
        yy = dense(fine[inside])
        s_f[inside], lnv_f[inside] = yy[0], yy[1]
        l_f[inside] = travel + vl * (fine[inside] - t0)
        travel += vl * (t1 - t0)
    fs = k * s_f                                    # Fs − F0
    u = l_f - s_f
    rows = []
    for i in range(1, len(ends)):
        ts, te, prev_end = starts[i], ends[i], ends[i - 1]
        before = (fine > prev_end) & (fine < ts)
        during = (fine >= ts) & (fine <= te + 0.01)
        rows.append({"t_start": ts, "recurrence_s": ts - starts[i - 1],
                     "friction_drop": (fs[before].max() - fs[during].min()) / fn,
                     "slip_m": np.interp(te, fine, u) - np.interp(ts, fine, u),
                     "peak_velocity_m_s": float(np.exp(lnv_f[during].max()))})
    step = int(round(1e5 / rate))
    keep = slice(int(8.0 * 1e5), None, step)
    fs_k, v_k = fs[keep], np.exp(lnv_f[keep])
    acc = np.gradient(v_k, 1.0 / rate)
    record = pd.DataFrame({"time": fine[keep], "shear_force": fs_k + 0.6 * fn,
                           "acceleration": acc, "slip": u[keep], "table": l_f[keep]})
    truth = pd.DataFrame(rows)
    return record, truth[truth.t_start > 8.0 + 3.5].reset_index(drop=True)


@pytest.mark.slow
def test_an_independent_implementation_s_events_come_back():
    """A recording made without the project's model or integrators (scipy's LSODA on the
    equations written in this test), 1 % noise added here: the analysis recovers that model's
    metrics, measured on its own dense output, to the targets (~15 s)."""
    record, truth = _independent_recording()
    rng = np.random.default_rng(11)
    scale = {"shear_force": truth.friction_drop.mean() * 997500.0,
             "acceleration": float(np.abs(record.acceleration).max()),
             "slip": truth.slip_m.mean(), "table": 7.5e-5 * truth.recurrence_s.mean()}
    noisy = record.assign(**{c: record[c] + 0.01 * s * rng.standard_normal(len(record))
                             for c, s in scale.items()})
    found = analyse(recording_from(noisy, {c: c for c in ALL}, normal_force=997500.0),
                    mass=1100.0)
    ev = found.events
    matched = ev[ev.t_start > truth.t_start.iloc[0] - 0.5].reset_index(drop=True)
    n = min(len(matched), len(truth))
    assert n >= 5
    for metric, tol in TOL.items():
        assert _rel(matched[metric][:n].mean(), truth[metric][:n].mean()) <= tol(0.01), metric
    assert _rel(found.apparatus["stiffness"], 1.48e8) <= 0.01


@pytest.mark.needs("pyarrow")
@pytest.mark.parametrize("suffix, sep", [(".parquet", None), (".tsv", "\t"), (".csv", ";")])
def test_parquet_and_other_separators_read_the_same(records, tmp_path, suffix, sep):
    table, _ = records[0.0]
    part = table.iloc[:50_000]
    path = tmp_path / f"rec{suffix}"
    if sep is None:
        part.to_parquet(path)
    else:
        part.to_csv(path, sep=sep, index=False)
    rec = read_recording(path, [f"{c}={c}" for c in ALL], normal_force=W2.normal_force)
    assert np.array_equal(rec.t, part.time.to_numpy())
    assert np.allclose(rec["slip"], part.slip.to_numpy(), rtol=1e-12, atol=1e-18)


# --- the drop at the rates labs record: no overshoot, unresolved events refused ----------------

@pytest.fixture(scope="module")
def apparatus_run():
    """docs/examples/apparatus.toml (the README's route), 40 s, Rodas5P at 1e-8: its events'
    Δμ are the truth (fs_max_before and fs_min located on the dense output by root finding)."""
    import integrators as I
    from problems import load_problem
    problem = load_problem("docs/examples/apparatus.toml")
    return I.solve(problem, I.Rodas5P(rtol=1e-8, atol=1e-8))


def _sampled(sol, rate):
    df = sol(np.arange(0.0, sol.problem.t_end, 1.0 / rate))
    return recording_from(pd.DataFrame({"t": df.t, "Fs": df.fs}), {"time": "t", "shear_force": "Fs"},
                          normal_force=sol.problem.normal_force)


@pytest.mark.parametrize("rate", [10_000.0, 1_000.0, 500.0])
def test_the_drop_of_a_saved_run_is_the_run_s_at_the_rates_labs_record(apparatus_run, rate):
    """The issue's target: Δμ within 0.5 % of the run's. Before the samples bounded the fit,
    the quartic around the peak's corner overshot: +0.38 % at 1 kHz, +2.8 % at 500 Hz (the
    README's `simulate --save`), every event high."""
    sol = apparatus_run
    found = analyse(_sampled(sol, rate))
    ev = sol.events
    truth = ((ev.fs_max_before - ev.fs_min) / sol.problem.normal_force).to_numpy()
    nearest = [int(np.argmin(np.abs(ev.t_start.to_numpy() - t))) for t in found.events.t_start]
    assert len(found.events) >= 8
    measured = found.events.friction_drop.to_numpy()
    assert abs(measured.mean() / truth[nearest].mean() - 1.0) <= 5e-3
    assert np.all(np.abs(measured / truth[nearest] - 1.0) <= 8e-3)        # and event by event
    assert np.all(found.events.drop_samples >= 4)
    assert not any("differs from the raw samples" in n for n in found.notes)


@pytest.mark.parametrize("rate", [100.0, 10.0])
def test_events_the_sampling_cannot_resolve_are_refused_with_the_rate_needed(apparatus_run, rate):
    """At 100 Hz a 10–12 ms event spans one or two samples (Δμ off by up to 3.3 %); at 10 Hz by
    24 %: refused, naming the rate it would need."""
    with pytest.raises(ValueError, match=r"the drops are not resolved.*record (at|faster "
                                         r"than) [0-9.e+]+ Hz") as err:
        analyse(_sampled(apparatus_run, rate))
    assert "\n" not in str(err.value)
    # the rate it names is one that resolves these 10–12 ms drops (4 intervals: 400 Hz), or a
    # lower bound said to be one
    need = float(str(err.value).split(" Hz")[-2].split()[-1])
    assert need >= 400.0 or "at the least" in str(err.value)


def test_a_resolved_sawtooth_gives_its_exact_drop():
    """A clean sawtooth of exact 0.04 drops, each over 8 ms, at 1 kHz: the quartic made it
    +21 % when its drops were instantaneous; the extremes now come from the samples."""
    rec = recording_from(_table(n=6000), {"time": "t", "shear_force": "Fs"}, normal_force=1e6)
    found = analyse(rec)
    assert np.allclose(found.events.friction_drop, 0.04, rtol=2e-3)


def test_a_foreshock_that_the_fit_does_not_see_is_said(records):
    """The raw samples' max − min is compared with the fitted drop: a glitch of 3 % of the
    drop, 40 ms before an event's peak, is above the fitted maximum and is said."""
    table, truth = records[0.0]
    table = table.copy()
    found = _measure(table, ("time", "shear_force", "table"))
    i = int(np.searchsorted(table.time, found.events.t_start.iloc[3] - 0.04))
    drop = found.events.friction_drop.iloc[3] * W2.normal_force
    table.loc[i:i + 2, "shear_force"] += 0.03 * drop
    glitched = _measure(table, ("time", "shear_force", "table"))
    assert any("differs from the raw samples" in n for n in glitched.notes)
    assert not any("differs from the raw samples" in n for n in found.notes)


# --- absurd constants and units: refused, naming what is wrong --------------------------------

def test_an_absurd_mass_is_refused_not_turned_into_curves(records):
    """--mass 1e300 wrote friction curves of ±1e295 and exit 0."""
    table, _ = records[0.0]
    rec = recording_from(table, {c: c for c in ALL}, normal_force=W2.normal_force)
    with pytest.raises(ValueError, match=r"m·a reaches .* times the force's drop"):
        analyse(rec, mass=1e300)
    with pytest.raises(ValueError, match=r"m·a reaches"):
        analyse(rec, mass=W2.mass * 1000)                    # grams typed as kilograms
    assert analyse(rec, mass=W2.mass).curves is not None


def test_a_slow_speed_no_event_could_start_at_is_refused(records):
    """--vls 10 gave "slip per event 0 mm" and exit 0."""
    table, _ = records[0.0]
    rec = recording_from(table, {c: c for c in ("time", "shear_force", "slip")},
                         normal_force=W2.normal_force)
    with pytest.warns(UserWarning, match="not mm/s"), \
            pytest.raises(ValueError, match=r"below the rate that starts an event \(10·vLs = 100"):
        analyse(rec, vls=10.0)


def test_an_acceleration_in_g_read_as_m_s2_is_refused(records):
    """The slip column's change over each event against the accelerations integrated twice."""
    table, _ = records[0.003]
    in_g = table.assign(acceleration=table.acceleration / 9.80665)
    rec = recording_from(in_g, {c: c for c in ALL}, normal_force=W2.normal_force)
    with pytest.raises(ValueError, match=r"integrated from .* is 0.10\d times the change of"):
        analyse(rec, mass=W2.mass)


def test_the_noise_lift_of_a_fitted_peak_is_taken_off():
    """A smooth lopsided peak (a slower rise than fall) under white noise of σ = 1, where the
    quartic fits the shape exactly: the fitted extreme is lifted by the noise alone, and taking
    the lift off leaves it unbiased. Over 400 draws (seeds 0–399), measured: +0.066 ± 0.015 σ
    with the lift left on, −0.023 ± 0.016 σ taken off."""
    from benchmarks.lab import events
    rate, true = 5000.0, 100.0
    t = np.arange(-0.02, 0.006, 1.0 / rate)
    clean = true - 2e5 * t ** 2 - 1e7 * t ** 3                    # the peak at t = 0
    i = int(np.argmin(np.abs(t)))
    found = {True: [], False: []}
    for seed in range(400):
        x = clean + np.random.default_rng(seed).standard_normal(len(t))
        for lifted in found:
            with mock.patch.object(events, "_noise_lift",
                                   events._noise_lift if lifted else lambda *a: 0.0):
                found[lifted].append(events._extremum(t, x, i, 30.0, 1.0, 0, len(t), rate,
                                                      1.0)[0] - true)
    assert abs(np.mean(found[True])) < 0.05 < np.mean(found[False])


def test_noise_at_a_coarse_rate_is_said_with_the_bias_it_gives(apparatus_run):
    """White noise of 1 % of the drop at 500 Hz: Δμ comes out 2.7 % high (each extreme at the
    drop's corner has few samples to average); not removed, but said with its size."""
    sol = apparatus_run
    t = np.arange(0.0, sol.problem.t_end, 1.0 / 500.0)
    drop = 0.0462 * sol.problem.normal_force
    fs = sol(t).fs.to_numpy() + 0.01 * drop * np.random.default_rng(1).standard_normal(len(t))
    rec = recording_from(pd.DataFrame({"t": t, "Fs": fs}), {"time": "t", "shear_force": "Fs"},
                         normal_force=sol.problem.normal_force)
    found = analyse(rec)
    said = [n for n in found.notes if "biases the friction drop high" in n]
    assert len(said) == 1 and "500 Hz" in said[0]
    bias = found.events.friction_drop.mean() / 0.0462 - 1.0
    assert 0.005 < bias < 0.06                      # what the note is about: not hidden
