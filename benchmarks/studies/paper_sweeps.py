"""Urata et al. (2017) Section 4 as far as its published numbers allow, and the sweep's speed:
the studies ``sweeps`` and ``sweep-scaling``.

:func:`paper_sweeps`: for W1–W4 and both laws, a (b, Lc) sweep centred on the published best fit
(slip law: Sect. 4.1; aging law: solved from Table 3 and the nucleation lengths, see
:func:`problems.aging_best_fit`), scored with J1 against the observed means of SPEC §5 and
σ = 10 % of each mean. That σ is an assumption (the paper's standard deviations are not
published); the tables say so. The aging-law grid is wider because its best fit is derived.

:func:`sweep_scaling`: the sweep's performance target — a 21 × 21 grid on W2 with 40 s of
simulated time per point — run serially, with 2 processes and with 2 threads, beside one
stand-alone run of the same integrator, so that the overhead per point is measured, not assumed.
"""

from __future__ import annotations

import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.devtools.timing import warm_up
from benchmarks.devtools.recommendation import recommended
from benchmarks.inversion.objectives import CHI2_95_2DOF
from benchmarks.inversion.maps import plot_sweep
from benchmarks.inversion.published import B_STEP, GRID, T_END, best_fit, grid_around
from benchmarks.inversion.observations import observations
from benchmarks.inversion.sweep import sweep
from benchmarks.records.files import write_output, write_table
from benchmarks.records.provenance import provenance
from benchmarks.records.report import fmt, jsonable, markdown_table
from benchmarks.studies.ensemble_scaling import SETTLE
from benchmarks.studies.study import Study, markdown_file
from integrators import solve
from problems import preset, window

__all__ = ["STUDIES", "paper_sweeps", "sweep_scaling"]

#: s per point: a point that takes longer is recorded as failed (WallTime) and the sweep goes on
POINT_BUDGET = 5.0


def paper_sweeps(out, cache=None, windows=("W1", "W2", "W3", "W4"), laws=("slip", "aging"),
                 workers=None, progress: bool = True, accuracy: float = 1e-3) -> pd.DataFrame:
    """Run the sweeps; write ``out/sweeps/<W>_<law>/{sweep.csv,summary.json,maps.png}`` and
    ``out/sweeps.csv``/``.md`` (one row per window and law). Points are kept under ``cache``
    (default ``out/cache/sweeps``), so a rerun only scores."""
    out = Path(out)
    cache = Path(cache) if cache else out / "cache" / "sweeps"
    algorithm, why = recommended(accuracy)
    rows = []
    for law in laws:
        for name in windows:
            b0, lc0 = best_fit(name, law)
            b, lc = grid_around(b0, lc0, **GRID[law])
            res = sweep(preset(name, law=law, t_end=T_END[name]), b, lc, algorithm,
                        observations(name), cache / f"{name}_{law}", workers=workers,
                        progress=progress, wall_budget=POINT_BUDGET, reclaim_store=True)
            dest = out / "sweeps" / f"{name}_{law}"
            dest.mkdir(parents=True, exist_ok=True)
            for f in ("sweep.csv", "summary.json"):
                shutil.copyfile(cache / f"{name}_{law}" / f, dest / f)
            s, t = res.summary, res.table
            plot_sweep(t, dest / "maps.png", title=f"{name}/{law}: J1 with σ = 10 % of the "
                       "observed means (assumed)", mark=(b0, lc0), best=(s["best_b"], s["best_lc_m"]))
            at = t[np.isclose(t.b, b0) & np.isclose(t.lc_m, lc0)].iloc[0]
            region = t[t.in_region]
            rows.append({
                "window": name, "law": law, "published_b": b0, "published_lc_um": lc0 * 1e6,
                "best_b": s["best_b"], "best_lc_um": s["best_lc_m"] * 1e6, "best_J1": s["best_J1"],
                "published_J1": at.J1, "published_in_region": bool(at.in_region),
                "region_b_min": region.b.min(), "region_b_max": region.b.max(),
                "region_lc_um_min": region.lc_m.min() * 1e6,
                "region_lc_um_max": region.lc_m.max() * 1e6,
                "n_points": s["n_points"], "n_in_region": s["n_in_region"],
                "n_failed": s["n_failed"], **{f"n_{k.replace(' ', '_')}": v
                                               for k, v in s["classification"].items()},
                "t_end_s": T_END[name], "grid_b": f"{b.min():.4f}:{b.max():.4f}:{B_STEP:g}",
                "grid_lc_um": f"{lc.min() * 1e6:.3g}..{lc.max() * 1e6:.3g} ({len(lc)} log)",
                "integrator": algorithm.name, "sim_wall_s_total": s["sim_wall_s_total"]})
    table = pd.DataFrame(rows)
    write_table(table, out / "sweeps.csv")
    write_output(out / "sweeps.md", sweeps_markdown(table, why))
    return table


def sweeps_markdown(table: pd.DataFrame, why: str) -> str:
    md = pd.DataFrame({
        "window": table.window, "law": table.law,
        "published (b, Lc µm)": [f"({b:.5f}, {lc:.3g})" for b, lc in
                                 zip(table.published_b, table.published_lc_um)],
        "J1 there": table.published_J1.map(fmt),
        "in 95 % region": table.published_in_region.map({True: "yes", False: "**no**"}),
        "min J1 at (b, Lc µm)": [f"({b:.4f}, {lc:.3g})" for b, lc in
                                 zip(table.best_b, table.best_lc_um)],
        "min J1": table.best_J1.map(fmt),
        "region: b": [f"{lo:.4f}–{hi:.4f}" for lo, hi in zip(table.region_b_min, table.region_b_max)],
        "region: Lc (µm)": [f"{lo:.3g}–{hi:.3g}" for lo, hi in
                            zip(table.region_lc_um_min, table.region_lc_um_max)],
        "points in region": [f"{a} / {n}" for a, n in zip(table.n_in_region, table.n_points)],
    })
    return (f"J1 (Eq. 10) against the observed means of SPEC §5 with σ = 10 % of each mean — an "
            f"assumption: the paper does not publish its standard deviations. Region: J1 ≤ "
            f"{CHI2_95_2DOF}. Integrator: {why}.\n\n" + markdown_table(md))


def sweep_scaling(out, n: int = 21, t_end: float = 40.0, progress: bool = True,
                  accuracy: float = 1e-3) -> dict:
    """Time the 21 × 21 W2 sweep serially, on 2 processes and on 2 threads (fresh each time),
    on 2 threads with each point stopped on its settled cycle (``settle`` =
    :data:`benchmarks.studies.ensemble_scaling.SETTLE`, whose accuracy on these points that
    study measures), and one stand-alone run; write ``out/sweep_scaling.json`` and ``.md``."""
    algorithm, why = recommended(accuracy)
    b0, lc0 = best_fit("W2", "slip")
    b = np.round(b0 + B_STEP * np.arange(-(n // 2), n - n // 2), 12)
    lc = np.geomspace(lc0 / 10, lc0 * 10, n)
    obs = observations("W2")
    runs = {}
    for label, kw in (("serial", dict(workers=1)),
                      ("2 processes", dict(workers=2, backend="processes")),
                      ("2 threads", dict(workers=2, backend="threads")),
                      (f"2 threads, settle = {SETTLE:g}",
                       dict(workers=2, backend="threads", settle=SETTLE))):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            res = sweep(preset("W2", law="slip", t_end=t_end), b, lc, algorithm, obs, tmp,
                        progress=progress, wall_budget=POINT_BUDGET, **kw)
            wall = time.perf_counter() - start
        s = res.summary
        runs[label] = {"wall_s": wall, "sim_wall_s_total": s["sim_wall_s_total"],
                       "sim_wall_s_median": s["sim_wall_s_median"], "n_failed": s["n_failed"],
                       "overhead_per_point_s": (wall * kw["workers"] - s["sim_wall_s_total"])
                       / s["n_points"]}
    problem = window("W2", "slip", t_end=t_end)
    warm_up(problem, algorithm)
    single = min(solve(problem, algorithm, max_points=2).stats.wall_s for _ in range(3))
    serial = runs["serial"]
    summary = {
        "grid": f"{len(b)} x {len(lc)} on W2/slip, b {b.min():.4f}..{b.max():.4f}, "
                f"Lc {lc.min() * 1e6:.3g}..{lc.max() * 1e6:.3g} µm (log), {t_end:g} s per point",
        "n_points": len(b) * len(lc), "integrator": algorithm.name, "integrator_choice": why,
        "runs": runs,
        "speedup_2_processes": serial["wall_s"] / runs["2 processes"]["wall_s"],
        "speedup_2_threads": serial["wall_s"] / runs["2 threads"]["wall_s"],
        "single_run_at_best_fit_s": single,
        "sweep_median_point_s": serial["sim_wall_s_median"],
        "provenance": provenance(),
    }
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_output(out / "sweep_scaling.json", json.dumps(jsonable(summary), indent=2))
    md = pd.DataFrame([{"run": k, "wall (s)": fmt(v["wall_s"]),
                        "Σ per-point solve (s)": fmt(v["sim_wall_s_total"]),
                        "median point (s)": fmt(v["sim_wall_s_median"]),
                        "overhead per point (ms)": fmt(1e3 * v["overhead_per_point_s"]),
                        "speed-up": fmt(serial["wall_s"] / v["wall_s"])} for k, v in runs.items()])
    write_output(out / "sweep_scaling.md",
        f"{summary['grid']}; integrator {why}. One stand-alone run at the best fit: "
        f"{single * 1e3:.1f} ms (min of 3, warm).\n\n" + markdown_table(md))
    return summary


def run_sweeps(out: Path) -> None:
    paper_sweeps(out)


def report_sweeps(out: Path) -> str:
    return (out / "sweeps.md").read_text() + "Maps: `sweeps/<window>_<law>/maps.png`.\n"


def run_scaling(out: Path, n: int, t_end: float) -> None:
    sweep_scaling(out, n=n, t_end=t_end)


STUDIES = (
    Study("sweeps", "Section 4: (b, Lc) sweeps around the published best fits (`sweeps.*`, "
          "`sweeps/`)", 120, run_sweeps, report=report_sweeps,
          writes=("sweeps.csv", "sweeps.md", "sweeps/*/maps.png", "sweeps/*/summary.json",
                  "sweeps/*/sweep.csv"), minutes=0.2),
    Study("sweep-scaling", "Sweep speed (`sweep_scaling.*`)", 130, run_scaling,
          report=markdown_file("sweep_scaling.md"), timed=True,
          settings={"n": 21, "t_end": 40.0}, limits={"n": (2, 101), "t_end": (1.0, 1e4)},
          writes=("sweep_scaling.json", "sweep_scaling.md"), minutes=0.1),
)
