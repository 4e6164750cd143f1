"""The self-check of an inversion (``rsfbench self-check``): a recording of the user's own
apparatus made by the model at a truth of their choosing (usually their fit), measured by
``observe`` and inverted as theirs was — does the 95 % region hold the truth?

:func:`self_check` reads the observations file that ``observe`` wrote of the user's recording: the
recording's rate, duration, channels and noise (``recording``), the mean friction drop and the
normal force. It makes a synthetic recording of ``problem`` at the truth (b, Lc)
(:func:`benchmarks.lab.synthetic.synthetic_recording`) with:

* the same sampling rate and duration, after :data:`SKIP_CYCLES` mean recurrence intervals of
  start-up that are not recorded (the settled cycle, as a cropped record);
* the same channels (those of time, shear_force, acceleration, acceleration_lower, slip and table
  that the user's recording has; the normal force given as a constant);
* white noise of the user's recording's level: the load cell's noise σ over the mean force drop
  (Δμ̄·Fn), the fraction :func:`synthetic_recording` applies to every channel's per-event scale
  (an assumption: the other channels' noise is not matched one by one), and its anti-alias
  filter and no drift.

It is measured by :func:`benchmarks.lab.observe_recording.observe` and inverted with the means
alone and with the curves (when the user's file has curves; noise model ``scatter``) by
:func:`benchmarks.inversion.invert.invert`, each with the same prior box and integrator, and says
for each whether the posterior's 95 % marginal intervals of b and log10 Lc (or, without a
posterior, the profiles') hold the truth.

Files under ``out``: ``recording.csv`` (SI units, the channels' names as columns),
``observations/`` (observe's files), ``means/`` and ``curves/`` (invert's), ``self_check.json``.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.inversion import Misfit
from benchmarks.inversion.invert import check_box, invert, inversion_files, write_inversion
from benchmarks.inversion.observations import OBSERVATIONS_FORMAT, read_observations
from benchmarks.lab.observe_recording import observe, observe_files
from benchmarks.lab.synthetic import synthetic_recording
from benchmarks.records.files import (BadResultsFile, claim_outputs, read_json_record,
                                      write_output, write_table)
from benchmarks.records.report import jsonable
from problems import variant

__all__ = ["self_check", "self_check_files", "recording_plan", "covered_text", "verdict",
           "SKIP_CYCLES", "CHANNELS_MADE"]

#: mean recurrence intervals of start-up simulated before the recording starts
SKIP_CYCLES = 5.0
#: the channels a synthetic recording has, which the user's may name
CHANNELS_MADE = ("time", "shear_force", "acceleration", "acceleration_lower", "slip", "table")


def self_check_files(out) -> list[Path]:
    """Every file :func:`self_check` may write under ``out``."""
    out = Path(out)
    return [out / "recording.csv", out / "self_check.json",
            *observe_files(out / "observations"), *inversion_files(out / "means"),
            *inversion_files(out / "curves")]


def recording_plan(path, problem) -> dict:
    """What the synthetic recording copies of the user's (module docstring), read from the
    observations file ``path``: ``rate_hz``, ``duration_s``, ``channels``, ``noise`` (fraction),
    ``skip_s``, ``curves`` (whether the file has curves) and ``given`` (the constants observe
    was given); ``ValueError`` naming the file and what it lacks."""
    try:
        doc = read_json_record(Path(path), ("format", "version", "metrics"),
                               what="observations file")
    except BadResultsFile as exc:
        raise ValueError(str(exc)) from None
    if (doc.get("format"), doc.get("version")) != OBSERVATIONS_FORMAT:
        raise ValueError(f"observations file {path}: not an rsfbench observations file")
    rec = doc.get("recording") or {}
    if not all(k in rec for k in ("rate_hz", "duration_s", "columns", "noise")):
        raise ValueError(f"observations file {path}: no recording record (rate, duration, "
                         "channels, noise): the self-check copies a recording that `rsfbench "
                         "observe` measured")
    m = doc["metrics"]
    drop, recurrence = m["friction_drop"]["mean"], m["recurrence_s"]["mean"]
    sigma_force = rec["noise"].get("shear_force")
    if not all(isinstance(x, (int, float)) and x > 0 for x in (drop, recurrence)):
        raise ValueError(f"observations file {path}: no mean ΔT and Δμ to scale the check by")
    noise = (sigma_force / (drop * problem.normal_force)
             if isinstance(sigma_force, (int, float)) and sigma_force > 0 else 0.0)
    channels = [c for c in CHANNELS_MADE if c in rec["columns"]]
    if "acceleration" not in channels:
        channels.append("acceleration")          # its curves need a1, and so do the means' Fs
    return {"rate_hz": float(rec["rate_hz"]), "duration_s": float(rec["duration_s"]),
            "channels": channels, "noise": float(noise), "skip_s": SKIP_CYCLES * recurrence,
            "curves": bool(doc.get("curves")),
            "given": [k for k, how in (doc.get("how") or {}).items() if how == "given"]}


def self_check(observations, problem, b: float, lc: float, out, b_range, lc_range, algorithm,
               grid: int = 33, profile_points: int = 21, seed: int = 0,
               walkers: int = 32, steps: int = 2000, workers: int | None = None, wall_budget: float | None = None,
               say=None) -> dict:
    """Make, measure and invert a recording of ``problem`` at (``b``, ``lc``) like the user's
    (module docstring); returns the document written to ``out/self_check.json``.

    Parameters
    ----------
    observations : str or pathlib.Path
        The observations file ``observe`` wrote of the user's recording.
    problem : SpringSlider
        The user's apparatus (with its mass); b and Lc replaced by the truth.
    b, lc : float
        The truth: b (dimensionless) and Lc (m).
    out : str or pathlib.Path
        The directory written into.
    b_range, lc_range : tuple of float
        The prior box (Lc in m), the user's inversion's.
    algorithm : Algorithm
        The forward solver of the inversions.
    grid, profile_points, seed, walkers, steps : int
        As :func:`benchmarks.inversion.invert.invert` (``steps`` = 0: no posterior, the
        profiles' intervals are judged); ``seed`` also the recording's noise.
    workers : int, optional
        Threads of a batch of solves.
    wall_budget : float, optional
        s per forward solve.
    say : callable, optional
        Given a line of text as each stage starts.

    Returns
    -------
    dict
        ``truth``, ``recording`` (what was copied), ``means`` and ``curves`` (each: the fit,
        the 95 % intervals, ``holds_truth``), ``wall_s``, ``files``.

    Raises
    ------
    ValueError
        For a file without a recording record, a problem without mass, a bad box or truth.
    """
    say = say or (lambda text: None)
    if not problem.mass > 0:
        raise ValueError("the self-check records accelerations: the problem needs its mass "
                         "(mass > 0 kg)")
    plan = recording_plan(observations, problem)
    truth = variant(problem, b=b, lc=lc, t_end=plan["skip_s"] + plan["duration_s"])
    check_box(problem, b_range, lc_range)
    out = Path(out)
    claim_outputs(self_check_files(out))
    start = time.perf_counter()
    say(f"a recording of the truth b = {b:g}, Lc = {lc:g} m: {plan['duration_s']:g} s at "
        f"{plan['rate_hz']:g} Hz, noise {plan['noise']:.2g} of an event's change")
    path = _record(truth, plan, seed, out)
    say("observe")
    constants = {"vls": problem.loading.v_slow, "stiffness": problem.stiffness}
    observe(path, {c: c for c in plan["channels"]}, out / "observations",
            normal_force=problem.normal_force, mass=problem.mass, plot=False,
            **{k: v for k, v in constants.items() if k in plan["given"]})
    found = out / "observations" / "observations.json"
    result = {"truth": {"b": b, "lc_m": lc, "log10_lc": math.log10(lc)},
              "recording": {**plan, "seed": seed, "file": str(path)},
              "box": {"b": list(b_range), "lc_m": list(lc_range)}}
    for label, noise in (("means", "none"), ("curves", "scatter")):
        if label == "curves" and not plan["curves"]:
            result[label] = None
            continue
        say(f"invert ({'the means alone' if noise == 'none' else 'the means and the curves'})")
        misfit = Misfit(problem, read_observations(found, curve_noise=noise), algorithm,
                        wall_budget=wall_budget, workers=workers)
        inv = invert(misfit, b_range, lc_range, profile_points=profile_points, seed=seed,
                     grid=grid, walkers=walkers, steps=steps)
        result[label] = verdict(write_inversion(inv, out / label, {"self_check": True}),
                                 result["truth"])
    result["wall_s"] = time.perf_counter() - start
    write_output(out / "self_check.json", json.dumps(jsonable(result), indent=2) + "\n")
    return result


def _record(truth, plan: dict, seed: int, out: Path) -> Path:
    """The synthetic recording of ``truth`` with the user's rate, channels and noise."""
    table, _ = synthetic_recording(truth, rate=plan["rate_hz"], t_skip=plan["skip_s"],
                                   noise=plan["noise"], seed=seed)
    dt = np.diff(table.time.to_numpy()[-2:])
    if len(dt) and abs(dt[0] * plan["rate_hz"] - 1.0) > 1e-6:
        table = table.iloc[:-1]             # the run's end, off the sampling grid
    path = out / "recording.csv"
    out.mkdir(parents=True, exist_ok=True)
    write_table(table[[c for c in plan["channels"] if c in table]], path)
    return path


def verdict(summary: dict, truth: dict) -> dict:
    """The fit, the 95 % intervals and whether they hold the truth, of one inversion."""
    post = summary["posterior"]
    if post is not None:
        intervals, source = post["interval_95"], f"posterior ({post['method']})"
    else:
        intervals = {k: [p["low"], p["high"]] for k, p in summary["profiles"].items()}
        source = f"profiles (no posterior: {summary.get('no_posterior') or 'none'})"
    holds = {k: bool(intervals[k][0] <= truth[k] <= intervals[k][1]) for k in ("b", "log10_lc")}
    f = summary["fit"]
    return {"fit": {"b": f["b"], "log10_lc": f["log10_lc"], "misfit": f["misfit"]},
            "intervals_95": intervals, "from": source,
            "profiles": {k: [p["low"], p["high"]] for k, p in summary["profiles"].items()},
            "holds_truth": holds, "covered": all(holds.values()),
            "likelihood": summary["likelihood"], "out": str(Path(summary["files"]["summary"])
                                                            .parent)}


def covered_text(label: str, found: dict | None, truth: dict) -> str:
    """One line saying whether the region of ``found`` (a :func:`verdict`) holds the truth."""
    if found is None:
        return f"{label}: no curves in the observations file"
    i = found["intervals_95"]
    parts = [f"{k} {'inside' if found['holds_truth'][k] else 'OUTSIDE'} [{i[k][0]:.5g}, "
             f"{i[k][1]:.5g}] (truth {truth[k]:.5g})" for k in ("b", "log10_lc")]
    return (f"{label}: the 95 % region {'holds' if found['covered'] else 'MISSES'} the truth "
            f"— {'; '.join(parts)}; from the {found['from']}")

