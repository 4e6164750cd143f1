"""The nuisance inversion on hard data: settled, precise recordings made outside the project's
model code, through ``observe`` and ``invert --nuisance`` as a user runs them, with an apparatus
whose stiffness and load speed are known only to their calibration.

Each recording is :mod:`benchmarks.studies.settled_coverage`'s (W2 by scipy's Radau from near
steady sliding, the start-up in the file, white sensor noise, seed 0, 1, …), read by
``observe``. The problem file the user hands ``invert`` has the calibrated constants, not the
truth: k and vLs drawn about the truth with the calibration's σ (3 % and 2 %, a seeded draw per
recording), and the box of :func:`~benchmarks.studies.settled_coverage.prior_box`. Then

* ``invert --nuisance k=3% --nuisance vls=2% --curve-noise none`` (its nested sampler,
  ``steps`` draws): do its Laplace intervals (±1.96 sd) and its sampler's 95 % intervals hold
  the truth's b, log10 Lc, k and vLs, and how narrow are they?
* with ``held=1``, ``invert --curve-noise none`` with the constants held at the calibrated
  values (what a user does without ``--nuisance``): does its region hold b and log10 Lc?

The means are precise (σ(ΔT)/ΔT ≈ 4e−5): a 3 % error in k moves the cycle by far more than
that, so the held inversion's region, a few σ wide, is expected to miss, and the nuisance
inversion is expected to hold. The target: 17–20 of 20 (Binomial(20, 0.95)'s central 95 %).
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.inversion.calibration import binomial_check
from benchmarks.lab import independent_stick_slip as radau
from benchmarks.lab.self_check import verdict
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.settled_coverage import COLUMNS, _command, prior_box, problem_file
from benchmarks.studies.study import Study, markdown_file

__all__ = ["STUDY", "nuisance_settled"]

#: the calibration's relative σ of each freed constant (the prior's, and the draw's)
CALIBRATION = {"stiffness": 0.03, "vls": 0.02}
TRUTH = {"b": radau.B_LAW, "log10_lc": math.log10(radau.LC), "stiffness": radau.K,
         "vls": radau.VLS}


def calibrated(seed: int) -> dict:
    """Recording ``seed``'s calibrated k and vLs: the truth × (1 + σ z), z ~ N(0, 1)."""
    z = np.random.default_rng([53, seed]).standard_normal(2)
    return {"stiffness": float(radau.K * (1 + CALIBRATION["stiffness"] * z[0])),
            "vls": float(radau.VLS * (1 + CALIBRATION["vls"] * z[1]))}


def _problem(values: dict) -> str:
    text = problem_file()
    return (text.replace(f"stiffness = {radau.K!r}", f"stiffness = {values['stiffness']!r}")
            .replace(f"vls = {radau.VLS!r}", f"vls = {values['vls']!r}"))


def _one(seed: int, work: Path, settings: dict) -> dict:
    table, _ = radau.recording(t_end=settings["duration_s"], rate=settings["rate_hz"],
                               noise=settings["noise"], seed=seed)
    table.to_csv(work / "recording.csv", index=False)
    code, took = _command(["observe", str(work / "recording.csv"),
                           *[f"--column={c}={c}" for c in COLUMNS], "--normal-force",
                           repr(radau.FN), "--mass", repr(radau.M), "--no-plot", "--out",
                           str(work / "obs")], work / "observe.log")
    row = {"seed": seed, "observe_exit": code}
    if code != 0:
        return row
    values = calibrated(seed)
    row.update({f"calibrated_{k}_error": v / TRUTH[k] - 1 for k, v in values.items()})
    (work / "cal.toml").write_text(_problem(values))
    (b_lo, b_hi), (lc_lo, lc_hi) = prior_box(seed)
    common = ["--problem", str(work / "cal.toml"), "--observations",
              str(work / "obs" / "observations.json"), "--b-range", f"{b_lo!r},{b_hi!r}",
              "--lc-range", f"{lc_lo!r},{lc_hi!r}", "--curve-noise", "none", "--no-progress"]
    code, took = _command(["invert", *common, "--nuisance", "k=3%", "--nuisance", "vls=2%",
                           "--steps", str(settings["steps"]), "--out", str(work / "nuisance")],
                          work / "nuisance.log")
    row.update(nuisance_exit=code, nuisance_s=took)
    summary = work / "nuisance" / "nuisance.json"
    if code in (0, 1) and summary.exists():
        row.update(_nuisance_row(json.loads(summary.read_text()), b_hi - b_lo,
                                 math.log10(lc_hi / lc_lo)))
    if settings["held"]:
        code, took = _command(["invert", *common, "--out", str(work / "held")],
                              work / "held.log")
        row.update(held_exit=code, held_s=took)
        if code in (0, 1) and (work / "held" / "inversion.json").exists():
            v = verdict(json.loads((work / "held" / "inversion.json").read_text()),
                        {"b": TRUTH["b"], "log10_lc": TRUTH["log10_lc"]})
            row.update(held_covered=v["covered"], held_from=v["from"],
                       held_width_b_box=np.diff(v["intervals_95"]["b"])[0] / (b_hi - b_lo),
                       held_width_log10_lc_box=np.diff(v["intervals_95"]["log10_lc"])[0]
                       / math.log10(lc_hi / lc_lo),
                       held_b_low=v["intervals_95"]["b"][0],
                       held_b_high=v["intervals_95"]["b"][1],
                       held_log10_lc_low=v["intervals_95"]["log10_lc"][0],
                       held_log10_lc_high=v["intervals_95"]["log10_lc"][1])
    return row


def _nuisance_row(doc: dict, box_b: float, box_decades: float) -> dict:
    """Whether the Laplace and the sampler's intervals hold each truth, the z-scores, and the
    sampler's 95 % widths of b and log10 Lc as fractions of the box's."""
    row = {"converged": doc["success"], "solves": doc["solves"], "chi2": doc["chi2"],
           "laplace_check": doc["laplace_check"]}
    widths = (doc.get("sampler") or {}).get("interval_95") or {}
    for name, box in (("b", box_b), ("log10_lc", box_decades)):
        if name in widths:
            row[f"sampler_width_{name}_box"] = (widths[name][1] - widths[name][0]) / box
    for p in doc["parameters"]:
        name, est, sd = p["parameter"], p["estimate"], p["sd"]
        row[f"z_{name}"] = (TRUTH[name] - est) / sd if sd else math.nan
        row[f"laplace_covers_{name}"] = bool(abs(TRUTH[name] - est) <= 1.96 * sd)
    sampler = doc.get("sampler") or {}
    for name, (lo, hi) in (sampler.get("interval_95") or {}).items():
        row[f"sampler_covers_{name}"] = bool(lo <= TRUTH[name] <= hi)
    row["effective_draws"] = sampler.get("effective_draws", math.nan)
    return row


def nuisance_settled(recordings: int = 20, rate_hz: float = 10_000.0, noise: float = 0.01,
                     duration_s: float = 60.0, steps: int = 200, held: int = 1,
                     progress: bool = False) -> pd.DataFrame:
    """One row per recording (module docstring)."""
    settings = dict(rate_hz=rate_hz, noise=noise, duration_s=duration_s, steps=steps,
                    held=held)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(recordings):
            work = Path(tmp) / f"seed{seed}"
            work.mkdir()
            rows.append(_one(seed, work, settings))
            if progress:
                r = rows[-1]
                print(f"recording {seed + 1}/{recordings}: nuisance exit "
                      f"{r.get('nuisance_exit')} ({r.get('nuisance_s', math.nan):.0f} s), "
                      f"held covered {r.get('held_covered')}", flush=True)
    return pd.DataFrame(rows)


def _markdown(rows: pd.DataFrame, settings: dict) -> str:
    n = len(rows)
    cover = []
    for label, column in [*((f"nuisance, Laplace: {k}", f"laplace_covers_{k}") for k in TRUTH),
                          *((f"nuisance, sampler: {k}", f"sampler_covers_{k}") for k in TRUTH),
                          ("held constants: b and log10 Lc", "held_covered")]:
        if column not in rows:
            continue
        k = int(rows[column].fillna(False).astype(bool).sum())
        check = binomial_check(k, n)
        cover.append({"region": label, "holds the truth": f"{k} / {n}",
                      "binomial 95 % range": f"{check['binomial_low']}–{check['binomial_high']}",
                      "met": "yes" if check["consistent"] else "**no**"})
    rows = rows.reindex(columns=list(dict.fromkeys([
        *rows.columns, "nuisance_s", "effective_draws", "laplace_check", "converged",
        "calibrated_stiffness_error", "calibrated_vls_error",
        "sampler_width_b_box", "sampler_width_log10_lc_box", "held_width_b_box",
        "held_width_log10_lc_box"])))
    times = rows.nuisance_s
    lines = ["# The nuisance inversion on settled, precise recordings", "",
             __doc__.split("\n\n")[0].replace("\n", " "), "",
             f"{n} recordings, {settings['duration_s']:g} s at {settings['rate_hz']:g} Hz, "
             f"sensor noise {settings['noise']:.0%}; the calibrated k and vLs off the truth by "
             f"{rows.calibrated_stiffness_error.abs().median():.1%} and "
             f"{rows.calibrated_vls_error.abs().median():.1%} (median |error|); "
             f"{settings['steps']} draws of the nested sampler.", "",
             markdown_table(pd.DataFrame(cover)), "",
             f"`invert --nuisance`: median {times.median():.0f} s, worst {times.max():.0f} s; "
             f"the nested sampler's effective draws median {rows.effective_draws.median():.0f} "
             f"of {settings['steps']}; Laplace check "
             "(worst |Δχ²/k² − 1| at ±1, ±2 sd; empty: a step left the box or the cycles) "
             f"median {rows.laplace_check.median():.3g}; the optimiser converged on "
             f"{int(rows.converged.fillna(False).astype(bool).sum())} / {n} (else it stopped "
             "at its budget on a cycle, where the sampler starts).", "",
             "How much the regions say, as the median 95 % width over the box's (b; log10 "
             "Lc): the nuisance sampler's "
             f"{rows.sampler_width_b_box.median():.2f}; "
             f"{rows.sampler_width_log10_lc_box.median():.2f}, the held inversion's "
             f"{rows.held_width_b_box.median():.2g}; "
             f"{rows.held_width_log10_lc_box.median():.2g}. A width near 1 is the box: "
             "the means and the priors do not resolve the parameter.", ""]
    shown = rows.reindex(columns=["seed", "calibrated_stiffness_error", "calibrated_vls_error",
                                  "converged", "z_b", "z_log10_lc", "z_stiffness", "z_vls",
                                  "effective_draws", "sampler_width_b_box",
                                  "sampler_width_log10_lc_box", "nuisance_s", "held_covered"])
    lines += ["Per recording (z: (truth − estimate)/Laplace sd; every interval in "
              "`nuisance_settled.csv`):", "", markdown_table(shown, floatfmt=".3g"), ""]
    return "\n".join(lines)


SETTINGS = {"recordings": 20, "rate_hz": 10_000.0, "noise": 0.01, "duration_s": 60.0,
            "steps": 200, "held": 1}


def run(out: Path, recordings: int = 20, rate_hz: float = 10_000.0, noise: float = 0.01,
        duration_s: float = 60.0, steps: int = 200, held: int = 1) -> None:
    settings = dict(recordings=recordings, rate_hz=rate_hz, noise=noise,
                    duration_s=duration_s, steps=steps, held=held)
    rows = nuisance_settled(**settings, progress=True)
    write_table(rows, out / "nuisance_settled.csv")
    text = _markdown(rows, settings)
    write_output(out / "nuisance_settled.md", text + "\nCommand: `rsfbench study "
                 "nuisance-settled" + "".join(f" --set {k}={v}" for k, v in settings.items()
                                              if v != SETTINGS[k]) + "`.\n")
    print(text)


STUDY = Study("nuisance-settled", "The nuisance inversion on settled, precise recordings made "
              "outside the model code, with miscalibrated constants (`nuisance_settled.*`)",
              213, run, report=markdown_file("nuisance_settled.md"), plan="full", minutes=40,
              timed=True, settings=SETTINGS,
              limits={"recordings": (1, 200), "rate_hz": (500.0, 1e5), "noise": (0.0, 0.1),
                      "duration_s": (20.0, 600.0), "steps": (0, 100_000), "held": (0, 1)},
              modules=("benchmarks.cli",),
              writes=("nuisance_settled.csv", "nuisance_settled.md"))
