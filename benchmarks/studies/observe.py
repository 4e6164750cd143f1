"""``rsfbench observe`` measured against what it must recover: recordings made by the forward
model (:func:`benchmarks.lab.synthetic.synthetic_recording`: 10 kHz, a causal
anti-alias filter at 4 kHz, white noise and a linear drift, both as fractions of what one event
changes) of W1–W4 under both laws, at three noise levels and with four sets of channels, each
measured by :func:`benchmarks.lab.events.analyse` and compared with the model's own
event table; and the time :func:`benchmarks.lab.observe_recording.observe` takes on a 400 s record
at 10 kHz (4 million rows) in CSV and in Parquet, after one run that warms the caches; and the
mean Δμ's bias from noise by sampling rate (:func:`observe_noise_bias`).

The targets, met or missed row by row: at 1 % noise ΔT and Δμ within 0.5 % of the
model's, the slip per event within 2 %, the stiffness within 1 %; a 4-million-row record in at
most 10 s.
"""

from __future__ import annotations

import importlib.util
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.physics.metrics import METRICS
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study, markdown_file
from problems import preset

__all__ = ["STUDY", "observe_accuracy", "observe_speed"]

#: (window, law, simulated s): long enough for 7 or more complete events
CASES = (("W1", "slip", 30.0), ("W1", "aging", 30.0), ("W2", "slip", 40.0),
         ("W2", "aging", 40.0), ("W3", "slip", 40.0), ("W3", "aging", 40.0),
         ("W4", "slip", 8.0), ("W4", "aging", 8.0))
NOISES = (0.0, 0.01, 0.03)
CHANNELS = {"all": ("time", "shear_force", "acceleration", "slip", "table"),
            "accelerations": ("time", "shear_force", "acceleration", "table"),
            "slip column": ("time", "shear_force", "slip", "table"),
            "force and table": ("time", "shear_force", "table")}
#: at 1 % noise: the largest relative error allowed for each quantity that has a target
TARGETS = {"recurrence_s": 0.005, "friction_drop": 0.005, "slip_m": 0.02, "stiffness": 0.01}
#: the time target for a 400 s record at 10 kHz, s
SPEED_TARGET_S = 10.0


def observe_accuracy(progress: bool = False) -> pd.DataFrame:
    """One row per window, law, noise and channel set: the relative errors of the mean
    metrics and of the apparatus against the model's, and the number of events."""
    from benchmarks.lab.events import analyse
    from benchmarks.lab.channels import recording_from
    from benchmarks.lab.synthetic import synthetic_recording
    rows = []
    for name, law, t_end in CASES:
        problem = preset(name, law=law, t_end=t_end)
        for noise in NOISES:
            table, truth = synthetic_recording(problem, t_skip=t_end / 4, noise=noise,
                                               drift=noise, seed=7)
            model = truth.events.iloc[1:]
            for label, channels in CHANNELS.items():
                rec = recording_from(table, {c: c for c in channels},
                                     normal_force=problem.normal_force)
                found = analyse(rec, mass=problem.mass)
                ap = found.apparatus
                row = {"window": name, "law": law, "noise": noise, "channels": label,
                       "events": len(found.events), "model_events": len(model)}
                for m in METRICS:
                    row[f"err_{m}"] = _err(found.events[m].mean(), model[m].mean())
                for key, true in (("stiffness", truth.stiffness), ("vls", truth.vls),
                                  ("vlf", truth.vlf), ("df", truth.df)):
                    row[f"err_{key}"] = _err(ap[key], true)
                rows.append(row)
            if progress:
                print(f"{name} {law} noise {noise:g}: done", flush=True)
    return pd.DataFrame(rows)


def _err(measured, true) -> float:
    return float("nan") if measured is None or not np.isfinite(measured) else \
        float(abs(measured / true - 1.0))


def observe_speed(repeats: int = 3) -> pd.DataFrame:
    """Wall time of :func:`observe` on a 400 s record at 10 kHz with 1 % noise, as CSV and as
    Parquet, with and without the figure: the fastest of ``repeats`` runs after a warm-up."""
    from benchmarks.lab.observe_recording import observe
    from benchmarks.lab.synthetic import synthetic_recording
    problem = preset("W2", law="slip", t_end=400.0)
    table, _ = synthetic_recording(problem, noise=0.01, drift=0.01, seed=1)
    columns = {c: c for c in table.columns}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        files = {"csv": Path(tmp) / "record.csv"}
        write_table(table, files["csv"])
        if importlib.util.find_spec("pyarrow") is not None:   # the ensemble extra's
            files["parquet"] = Path(tmp) / "record.parquet"
            table.to_parquet(files["parquet"])
        for kind, path in files.items():
            for plot in (False, True):
                times = []
                for _ in range(repeats + 1):               # the first warms the caches
                    start = time.perf_counter()
                    doc = observe(path, columns, Path(tmp) / "out", plot=plot,
                                  normal_force=problem.normal_force, mass=problem.mass)
                    times.append(time.perf_counter() - start)
                rows.append({"file": kind, "figure": plot, "rows": len(table),
                             "events": doc["n_events"], "wall_s": min(times[1:]),
                             "met": min(times[1:]) <= SPEED_TARGET_S})
    return pd.DataFrame(rows)


#: the rates (Hz) and noise draws of :func:`observe_noise_bias`
BIAS_RATES, BIAS_DRAWS = (10_000.0, 1_000.0, 500.0), 8


def observe_noise_bias() -> pd.DataFrame:
    """The mean Δμ's bias from white noise of 1 % of the drop, in σ of the noise, on
    ``docs/examples/apparatus.toml`` sampled from its run's dense output at each of
    :data:`BIAS_RATES`: the mean over :data:`BIAS_DRAWS` draws (seeds 0, 1, …) with its
    standard error, as observe measures it and with the fit's noise lift left on."""
    from unittest import mock

    import integrators as I
    from benchmarks.lab import events
    from benchmarks.lab.channels import recording_from
    from problems import load_problem
    problem = load_problem(Path(__file__).resolve().parents[2] / "docs/examples/apparatus.toml")
    sol = I.solve(problem, I.Rodas5P(rtol=1e-8, atol=1e-8))
    starts = sol.events.t_start.to_numpy()
    truth = ((sol.events.fs_max_before - sol.events.fs_min) / problem.normal_force).to_numpy()
    sigma = 0.01 * float(np.median(truth))                       # in μ
    rows = []
    for rate in BIAS_RATES:
        t = np.arange(0.0, problem.t_end, 1.0 / rate)
        clean = sol(t).fs.to_numpy()
        for lifted in (True, False):
            errors = []
            for seed in range(BIAS_DRAWS):
                noisy = clean + sigma * problem.normal_force * \
                    np.random.default_rng(seed).standard_normal(len(t))
                rec = recording_from(pd.DataFrame({"t": t, "Fs": noisy}),
                                     {"time": "t", "shear_force": "Fs"},
                                     normal_force=problem.normal_force)
                with mock.patch.object(events, "_noise_lift",
                                       events._noise_lift if lifted else lambda *a: 0.0):
                    found = events.analyse(rec)
                near = [int(np.argmin(np.abs(starts - s))) for s in found.events.t_start]
                errors.append(found.events.friction_drop.mean() - truth[near].mean())
            e = np.array(errors) / sigma
            rows.append({"rate_hz": rate, "lift_taken_off": lifted,
                         "bias_sigma": e.mean(), "se_sigma": e.std(ddof=1) / np.sqrt(len(e)),
                         "bias_percent": 100 * e.mean() * sigma / float(np.median(truth)),
                         "draws": len(e)})
    return pd.DataFrame(rows)


def observe_markdown(accuracy: pd.DataFrame, speed: pd.DataFrame,
                     bias: pd.DataFrame | None = None) -> str:
    at1 = accuracy[accuracy.noise == 0.01]
    lines = ["At 1 % noise (and drift), the largest relative error over W1–W4, both laws, by "
             "channel set, against the targets:", ""]
    rows = []
    for label, g in at1.groupby("channels", sort=False):
        row = {"channels": label}
        for key, target in TARGETS.items():
            worst = g[f"err_{key}"].max()
            row[key] = (f"{worst:.2%} ({'met' if worst <= target else '**missed**'}, "
                        f"target {target:.1%})" if np.isfinite(worst) else "–")
        row["peak slip rate"] = (f"{g.err_peak_velocity_m_s.max():.2%}"
                                 if g.err_peak_velocity_m_s.notna().any() else "–")
        rows.append(row)
    lines += [markdown_table(pd.DataFrame(rows)), ""]
    lines += ["Every noise level (largest relative error over the windows and laws):", ""]
    worst = (accuracy.groupby(["noise", "channels"], sort=False)
             [[f"err_{m}" for m in (*METRICS, "stiffness", "vls", "vlf", "df")]].max()
             .reset_index())
    errors = [c for c in worst.columns if c.startswith("err_")]
    worst[errors] = worst[errors].map(lambda x: f"{x:.2%}" if np.isfinite(x) else "–")
    worst["noise"] = worst.noise.map(lambda x: f"{x:.0%}")
    worst.columns = [c.removeprefix("err_") for c in worst.columns]
    lines += [markdown_table(worst), ""]
    missing = accuracy[accuracy.events != accuracy.model_events]
    lines += [f"Events found as the model has them: {len(accuracy) - len(missing)} of "
              f"{len(accuracy)} runs.", ""]
    lines += [f"Speed: `observe` on a 400 s record at 10 kHz ({speed.rows.iloc[0]:,} rows), "
              f"fastest of 3 runs after a warm-up (target ≤ {SPEED_TARGET_S:g} s):", "",
              markdown_table(speed.assign(wall_s=speed.wall_s.map(lambda x: f"{x:.2f}"))), ""]
    if bias is not None:
        shown = bias.assign(**{c: bias[c].map(lambda x: f"{x:+.2f}")
                               for c in ("bias_sigma", "bias_percent")},
                            se_sigma=bias.se_sigma.map(lambda x: f"{x:.2f}"))
        lines += ["The mean Δμ's bias from white noise of 1 % of the drop (σ the noise in μ), "
                  "on `docs/examples/apparatus.toml` sampled from its run, the mean of "
                  f"{BIAS_DRAWS} noise draws; `lift_taken_off`: as observe measures, the lift "
                  "of the fit's extreme by its noise taken off "
                  "(`benchmarks/lab/events.py::_noise_lift`), or not:", "",
                  markdown_table(shown), ""]
    return "\n".join(lines)


def run(out: Path) -> None:
    accuracy = observe_accuracy(progress=True)
    speed = observe_speed()
    bias = observe_noise_bias()
    write_table(accuracy, out / "observe_accuracy.csv")
    write_table(speed, out / "observe_speed.csv")
    write_table(bias, out / "observe_noise_bias.csv")
    text = observe_markdown(accuracy, speed, bias)
    write_output(out / "observe.md", text)
    print(text)


STUDY = Study("observe", "A recording in: what `rsfbench observe` recovers (`observe.md`, "
              "`observe_*.csv`)", 205, run, report=markdown_file("observe.md"), timed=True,
              writes=("observe.md", "observe_accuracy.csv", "observe_speed.csv",
                      "observe_noise_bias.csv"), minutes=5)
