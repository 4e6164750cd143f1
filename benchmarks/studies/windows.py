"""Windows W1–W4: simulated limit cycles at the best fits beside the observed means (SPEC §5)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
from tqdm.auto import tqdm

from benchmarks.devtools.timing import warm_up
from benchmarks.physics.metrics import summarize
from benchmarks.physics.summary import simulate_summary
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study, markdown_file
from integrators import ETD2, solve
from problems import WINDOWS, window

__all__ = ["STUDY", "windows_table", "write_windows"]


def windows_table(laws=("slip", "aging"), integrator=None, t_end: float | None = None,
                  progress: bool = True, names=tuple(WINDOWS),
                  wall_budget: float | None = None) -> pd.DataFrame:
    """One row per (window, law): parameters, simulated limit-cycle metrics, observed means.
    ``integrator`` defaults to ETD2 at the paper's settings (the paper's own method)."""
    integrator = integrator or ETD2()
    jobs = [(name, law) for law in laws for name in names]
    rows = []
    for name, law in tqdm(jobs, desc="windows", disable=not progress):
        problem = window(name, law=law, **({} if t_end is None else {"t_end": t_end}))
        warm_up(problem, integrator)
        sol = solve(problem, integrator, wall_budget=wall_budget)
        lc = summarize(sol)
        w = WINDOWS[name]
        rows.append({
            "window": name, "law": law, "b": problem.law.b, "lc_um": problem.law.lc * 1e6,
            "kappa": problem.kappa, "t_end_s": problem.t_end,
            "classification": lc.classification, "n_events": lc.n_events,
            "recurrence_s": lc.recurrence_s, "obs_recurrence_s": w.observed_recurrence,
            "friction_drop": lc.friction_drop, "obs_friction_drop": w.observed_drop,
            "slip_mm": lc.slip_m * 1e3, "obs_slip_mm": w.observed_slip * 1e3,
            "peak_velocity_m_s": lc.peak_velocity_m_s,
            "obs_peak_velocity_m_s": w.observed_peak_velocity,
            "integrator": integrator.name, "retcode": sol.retcode.value,
            "steps": sol.stats.steps, "wall_s": sol.stats.wall_s,
        })
    return pd.DataFrame(rows)


def write_windows(table: pd.DataFrame, out: Path) -> None:
    """``windows.csv`` (all columns) and ``windows.md`` (the comparison, rounded) in ``out``."""
    write_table(table, out / "windows.csv")
    md = table.assign(
        b=table.b.map("{:.5f}".format), lc_um=table.lc_um.map("{:.3f}".format),
        kappa=table.kappa.map("{:.3g}".format),
        **{"ΔT sim / obs (s)": [f"{a:.3f} / {b:g}" for a, b in zip(table.recurrence_s, table.obs_recurrence_s)],
           "Δμ sim / obs": [f"{a:.4f} / {b:g}" for a, b in zip(table.friction_drop, table.obs_friction_drop)],
           "slip sim / obs (mm)": [f"{a:.3f} / {b:g}" for a, b in zip(table.slip_mm, table.obs_slip_mm)],
           "peak v sim / obs (m/s)": [f"{a:.3f} / {b:g}" for a, b in
                                      zip(table.peak_velocity_m_s, table.obs_peak_velocity_m_s)],
           "wall (s)": table.wall_s.map("{:.3f}".format)},
    )[["window", "law", "b", "lc_um", "kappa", "classification", "ΔT sim / obs (s)", "Δμ sim / obs",
       "slip sim / obs (mm)", "peak v sim / obs (m/s)", "integrator", "steps", "wall (s)"]]
    write_output(out / "windows.md", markdown_table(md))


def run(out: Path) -> None:
    """``simulate_<window>_<law>.json`` for W1–W4 and both laws (ETD2 at the paper's settings),
    and the table of :func:`windows_table` beside the observed means."""
    algorithm = ETD2()
    for name in WINDOWS:
        for law in ("slip", "aging"):
            problem = window(name, law)
            warm_up(problem, algorithm)
            summary = simulate_summary(solve(problem, algorithm))
            write_output(out / f"simulate_{name}_{law}.json", json.dumps(summary, indent=2) + "\n")
    write_windows(windows_table(), out)


STUDY = Study("windows", "W1–W4 limit cycles, ETD2 at the paper's settings (`windows.*`, "
              "`simulate_*.json`)", 20, run, report=markdown_file("windows.md"),
              writes=("windows.csv", "windows.md", "simulate_W*_*.json"), minutes=0.15)
