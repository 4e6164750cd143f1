"""The speed target, read off a work-precision study: at each recurrence-error level from 1e−3
to 1e−7 and on each problem, is the fastest of the project's own integrators at least 2× faster
than every compiled peer: LSODA (numbalsoda, CyRK), the best SUNDIALS backend, and CyRK's BDF and
Radau?

Everything comes from one study CSV (so the times were measured in one run, side by side) and
uses the reliable error of :func:`benchmarks.devtools.work_precision.reliable_error`: a setting counts for
a level only if it and every tighter setting of its method reach it. All right-hand-side tiers
count (the fastest is usually the compiled one). A competitor that reaches the level nowhere on
the ladder makes the comparison one-sided; the table says so rather than calling it a win.

Two studies: ``target`` reads the quick work-precision study; ``target-full`` runs its own,
of the stiff adaptive integrators on every study problem (:func:`full_target`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.devtools.work_precision import (
    FULL,
    read_study,
    reliable_error,
    study_problems,
    work_precision,
)
from benchmarks.devtools.wp_files import write_work_precision
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import fmt, markdown_table
from benchmarks.studies.study import Study
from integrators import REGISTRY

__all__ = ["STUDIES", "TARGET_LEVELS", "TARGET_FACTOR", "TARGET_WALL_BUDGET", "groups", "target_integrators",
           "target_table", "write_target", "full_target"]

TARGET_LEVELS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
TARGET_FACTOR = 2.0
TARGET_WALL_BUDGET = 10.0       # s per run of the full study, as in the quick one


def groups() -> dict[str, list[str]]:
    """The sides of the comparison, by registry name, selected by tag: the own integrators;
    every way of calling LSODA that is compiled (numbalsoda's block adapter and plain grid call,
    CyRK's C++ port); every way of calling SUNDIALS (from C with cfunc callbacks, and the three
    Python bindings); CyRK's other stiff methods (BDF and Radau)."""
    return {"own": REGISTRY.select("own"),
            "lsoda": REGISTRY.select("lsoda", "compiled"),
            "sundials": REGISTRY.select("sundials"),
            "cyrk": REGISTRY.select("cyrk", "stiff", exclude=("lsoda",))}


def target_integrators() -> list[str]:
    """The integrators of the full study behind the target: the stiff adaptive ones of the three
    sides. Left out: the ETD family and CashKarp45 (own), never the fastest at any level of the
    quick study (``wp_quick_pareto.md``: always Rosenbrock23, Rodas5P or Exprb43), and CVODE's
    Adams mode (SUNDIALS side), not a stiff method and 20× slower than CVODE's BDF mode there at
    its fastest on W2 (1.2 s against 63 ms)."""
    g = groups()
    return [n for side in ("own", "lsoda", "sundials", "cyrk") for n in g[side]
            if REGISTRY[n].adaptive and REGISTRY[n].stiff]


def _fastest(df: pd.DataFrame, names, level: float):
    hit = df[df.integrator.isin(names) & (df.reliable <= level)]
    return None if hit.empty else hit.loc[hit.wall_s.idxmin()]


def target_table(df: pd.DataFrame, error: str = "err_recurrence", levels=TARGET_LEVELS,
                 factor: float = TARGET_FACTOR) -> pd.DataFrame:
    """One row per (problem, level): the fastest own, LSODA and SUNDIALS runs and the ratios."""
    df = df.assign(reliable=reliable_error(df, error))
    df = df[df.retcode == "Success"]
    g = groups()
    rows = []
    for problem, p in df.groupby("problem", sort=False):
        for level in levels:
            row = {"problem": problem, "level": level}
            best = {side: _fastest(p, names, level) for side, names in g.items()}
            for side, r in best.items():
                row[f"{side}"] = None if r is None else r.integrator
                row[f"{side}_setting"] = np.nan if r is None else r.setting
                row[f"{side}_wall_s"] = np.nan if r is None else r.wall_s
            own = row["own_wall_s"]
            for side in ("lsoda", "sundials", "cyrk"):
                row[f"ratio_{side}"] = row[f"{side}_wall_s"] / own
            ratios = [row["ratio_lsoda"], row["ratio_sundials"], row["ratio_cyrk"]]
            peers = [row[f"{side}_wall_s"] for side in ("lsoda", "sundials", "cyrk")]
            row["ratio_peer"] = (np.nanmin(peers) / own if not all(np.isnan(peers))
                                 else np.nan)
            if not np.isfinite(own):
                row["met"] = "no (own: none)"
            elif all(np.isnan(r) for r in ratios):
                row["met"] = "one-sided (no competitor reaches it)"
            else:
                row["met"] = "yes" if all(np.isnan(r) or r >= factor for r in ratios) else "no"
            rows.append(row)
    return pd.DataFrame(rows)


def target_markdown(t: pd.DataFrame, factor: float = TARGET_FACTOR) -> str:
    def who(side):
        return [f"{n} {fmt(s, 'g')}: {fmt(w * 1e3, '.3g')} ms" if isinstance(n, str) else "none"
                for n, s, w in zip(t[side], t[f"{side}_setting"], t[f"{side}_wall_s"])]
    md = pd.DataFrame({"problem": t.problem, "level": t.level.map("{:g}".format),
                       "fastest own": who("own"), "fastest LSODA": who("lsoda"),
                       "fastest SUNDIALS": who("sundials"),
                       "× vs LSODA": t.ratio_lsoda.map(lambda x: fmt(x, ".3g")),
                       "× vs SUNDIALS": t.ratio_sundials.map(lambda x: fmt(x, ".3g")),
                       "fastest CyRK BDF/Radau": who("cyrk"),
                       "× vs CyRK": t.ratio_cyrk.map(lambda x: fmt(x, ".3g")),
                       "× vs the fastest peer": t.ratio_peer.map(lambda x: fmt(x, ".3g")),
                       f"≥ {factor:g}× every peer": t.met})
    n = (t.met == "yes").sum()
    return (f"Target met at {n} of {len(t)} (problem, level) pairs; a ratio is the competitor's "
            f"time over the fastest own integrator's at the same reliable recurrence error. "
            f"Each side is the fastest way of calling its library in this run (compiled or "
            f"Python-bound, whichever was faster); every compiled peer counts.\n\n"
            + markdown_table(md))


def write_target(csv, out, name: str | None = None) -> pd.DataFrame:
    """``target_<name>.csv`` and ``.md`` in ``out`` from the study at ``csv``."""
    csv, out = Path(csv), Path(out)
    name = name or csv.stem.removeprefix("wp_")
    t = target_table(read_study(csv))
    out.mkdir(parents=True, exist_ok=True)
    write_table(t, out / f"target_{name}.csv")
    write_output(out / f"target_{name}.md", target_markdown(t))
    return t


def full_target(out, progress: bool = True) -> pd.DataFrame:
    """The target on every problem of the full study (the paper example and W1–W4 under both
    laws), from a work-precision study of :func:`target_integrators` on the full ladder with a
    10 s budget per run (compiled right-hand sides): ``wp_full*`` and ``target_full.*`` in
    ``out``. About half an hour on a 2-core machine."""
    ladder = dataclasses.replace(FULL, wall_budget=TARGET_WALL_BUDGET)
    df = work_precision(study_problems("full"), ladder, names=target_integrators(),
                        tiers=("numba",), progress=progress)
    paths = write_work_precision(df, Path(out), "full")
    return write_target(paths["csv"], out)


def run_quick(out: Path) -> None:
    write_target(out / "wp_quick.csv", out)


def report_quick(out: Path) -> str:
    return ("On the quick study's two problems (`target_quick.*`, from `wp_quick.csv`):\n\n"
            + (out / "target_quick.md").read_text())


def run_full(out: Path) -> None:
    print(target_markdown(full_target(out)))


def report_full(out: Path) -> str:
    return ("On every study problem (`target_full.*`, from `wp_full.csv`: the stiff adaptive "
            "integrators of\nthe three sides on the full ladder, 10 s per run):\n\n"
            + (out / "target_full.md").read_text())


STUDIES = (
    Study("target", "The 2× target on the quick study: own integrators against compiled "
          "LSODA and SUNDIALS", 90, run_quick, report=report_quick, reads=("wp_quick.csv",),
          writes=("target_quick.csv", "target_quick.md"), minutes=0.05),
    Study("target-full", "The 2× target on every study problem", 100, run_full,
          report=report_full, plan="full", timed=True,
          writes=("target_full.csv", "target_full.md", "wp_full.csv", "wp_full_*.png",
                  "wp_full_pareto.*"), minutes=26),
)
