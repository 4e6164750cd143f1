"""The speed target, read off a work-precision study: at each recurrence-error level from 1e−3
to 1e−7 and on each problem, is the fastest of the project's own integrators at least 2× faster
than every compiled peer: LSODA (numbalsoda, CyRK), the best SUNDIALS backend, and CyRK's BDF and
Radau?

Everything comes from one study CSV (so the times were measured in one run, side by side) and
uses the reliable error of :func:`benchmarks.devtools.work_precision.reliable_error`: a setting counts for
a level only if it and every tighter setting of its method reach it. All right-hand-side tiers
count (the fastest is usually the compiled one). A competitor that reaches the level nowhere on
the ladder makes the comparison one-sided; the table says so rather than calling it a win.

CyRK is also called plainly, as its numba users call it (:func:`plain_cyrk`): the own fastest,
the adapter and the plain call timed in turn, and the ratio published against the faster CyRK
call.

Two studies: ``target`` reads the quick work-precision study; ``target-full`` runs its own,
of the stiff adaptive integrators on every study problem (:func:`full_target`).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.devtools.work_precision import (
    FULL,
    algorithm_at,
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

__all__ = ["STUDIES", "TARGET_LEVELS", "TARGET_FACTOR", "TARGET_WALL_BUDGET", "groups",
           "target_integrators", "target_table", "write_target", "full_target", "plain_cyrk"]

TARGET_LEVELS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
TARGET_FACTOR = 2.0
TARGET_WALL_BUDGET = 10.0       # s per run of the full study, as in the quick one
#: the own fastest, the CyRK adapter and CyRK called plainly are timed in turn this often
PLAIN_REPEATS = 9


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
                row[f"{side}_tier"] = None if r is None else r.rhs_tier
            own = row["own_wall_s"]
            for side in ("lsoda", "sundials", "cyrk"):
                row[f"ratio_{side}"] = row[f"{side}_wall_s"] / own
            ratios = [row["ratio_lsoda"], row["ratio_sundials"], row["ratio_cyrk"]]
            peers = [row[f"{side}_wall_s"] for side in ("lsoda", "sundials", "cyrk")]
            row["ratio_peer"] = (np.nanmin(peers) / own if not all(np.isnan(peers))
                                 else np.nan)
            row["met"] = _verdict(ratios, own, factor)
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
                       **_plain_columns(t),
                       "× vs the fastest peer": t.ratio_peer.map(lambda x: fmt(x, ".3g")),
                       f"≥ {factor:g}× every peer": t.met})
    n = (t.met == "yes").sum()
    return (f"Target met at {n} of {len(t)} (problem, level) pairs; a ratio is the competitor's "
            f"time over the fastest own integrator's at the same reliable recurrence error. "
            f"Each side is the fastest way of calling its library in this run (compiled or "
            f"Python-bound, whichever was faster); every compiled peer counts."
            + (" CyRK is also called plainly (a cfunc, `nbsolve2_ivp` from numba, event starts "
               "bisected on its dense output; the adapter's steps to the one): `again` times "
               "the own fastest, the adapter and the plain call in turn, and the CyRK ratio, "
               "the fastest peer's and the verdict take the faster CyRK call of that run."
               if "cyrk_plain_wall_s" in t else "") + "\n\n"
            + markdown_table(md))


def _plain_columns(t: pd.DataFrame) -> dict:
    """The table's columns of CyRK called plainly, where :func:`plain_cyrk` added them."""
    if "cyrk_plain_wall_s" not in t:
        return {}
    def ms(x):
        return fmt(x * 1e3, ".3g") + " ms" if np.isfinite(x) else "—"
    return {"again: own, CyRK adapter, CyRK plain": [
                f"{ms(a)}, {ms(b)}, {ms(c)}" if np.isfinite(a) else note
                for a, b, c, note in zip(t.own_again_wall_s, t.cyrk_again_wall_s,
                                         t.cyrk_plain_wall_s, t.cyrk_plain_note)],
            "× vs the faster CyRK call": t.ratio_cyrk_faster.map(lambda x: fmt(x, ".3g"))}


def plain_cyrk(t: pd.DataFrame, problems, repeats: int = PLAIN_REPEATS,
               factor: float = TARGET_FACTOR) -> pd.DataFrame:
    """``t`` (:func:`target_table`) with CyRK at its fastest: the setting of the fastest CyRK
    run of each (problem, level) is also called plainly, as CyRK's numba users call it
    (:func:`integrators.external.cyrk_backend.plain_starts`: no counters, event starts only,
    the adapter's steps to the one, which is checked), and timed in turn with the fastest own
    setting and the adapter (``solve(..., max_points=2)``, as the study runs them), each call
    timed whole (its Python included), the minimum over ``repeats`` after a warm-up.
    ``ratio_cyrk_faster`` is the faster CyRK call over the own one of that run; the verdict
    and ``ratio_peer`` take it in place of ``ratio_cyrk`` (each ratio is one run's: the
    LSODA and SUNDIALS ones the study's). A row it cannot re-time says why in
    ``cyrk_plain_note``. ``t`` unchanged where CyRK is not installed. ``problems``: the
    study's problems (matched by name)."""
    if importlib.util.find_spec("CyRK") is None:
        return t
    t = t.copy()
    by_name = {p.name: p for p in problems}
    cols = ("own_again_wall_s", "cyrk_again_wall_s", "cyrk_plain_wall_s", "ratio_cyrk_faster")
    for c in cols:
        t[c] = np.nan
    t["cyrk_plain_note"] = ""
    for i, row in t.iterrows():
        why, times = _plain_times(row, by_name.get(row.problem), repeats)
        t.at[i, "cyrk_plain_note"] = why
        if times is not None:
            own, adapter, plain = times
            t.loc[i, list(cols)] = own, adapter, plain, min(adapter, plain) / own
            ratios = [row.ratio_lsoda, row.ratio_sundials, t.at[i, "ratio_cyrk_faster"]]
            t.at[i, "ratio_peer"] = np.nanmin(ratios)
            t.at[i, "met"] = _verdict(ratios, row.own_wall_s, factor)
    return t


def _plain_times(row, problem, repeats: int):
    """(why not, None) or ("", (own, adapter, plain) wall times in s) for one row."""
    from integrators.core.solve import solve
    from integrators.external.cyrk_backend import plain_starts
    if problem is None or not isinstance(row.cyrk, str) or not isinstance(row.own, str):
        return "no CyRK or own run reaches the level", None
    tol, method = float(row.cyrk_setting), REGISTRY[row.cyrk].method
    own = algorithm_at(row.own, row.own_tier, row.own_setting)
    peer = algorithm_at(row.cyrk, row.cyrk_tier, tol)
    calls = (lambda: solve(problem, own, max_points=2),
             lambda: solve(problem, peer, max_points=2),
             lambda: plain_starts(problem, method, tol, tol))
    try:
        first = [call() for call in calls]          # compiles and warms up
    except Exception as exc:                        # a note in the table, not a crash
        return f"the re-timing raised {type(exc).__name__}: {exc}", None
    if not (first[0].success and first[1].success) or first[2] is None:
        return "a re-timed run failed", None
    if first[2][0] != first[1].stats.steps:
        return (f"the plain call took {first[2][0]} steps, the adapter "
                f"{first[1].stats.steps}: not compared"), None
    times = ([], [], [])
    for _ in range(repeats):
        for call, kept in zip(calls, times):
            start = time.perf_counter()
            call()
            kept.append(time.perf_counter() - start)
    return "", tuple(min(x) for x in times)


def _verdict(ratios, own: float, factor: float = TARGET_FACTOR) -> str:
    """Whether the fastest own run is ``factor``× faster than every peer reaching the level."""
    if not np.isfinite(own):
        return "no (own: none)"
    if all(np.isnan(r) for r in ratios):
        return "one-sided (no competitor reaches it)"
    return "yes" if all(np.isnan(r) or r >= factor for r in ratios) else "no"


def write_target(csv, out, name: str | None = None, problems=()) -> pd.DataFrame:
    """``target_<name>.csv`` and ``.md`` in ``out`` from the study at ``csv``; with
    ``problems`` (the study's), CyRK is also called plainly (:func:`plain_cyrk`)."""
    csv, out = Path(csv), Path(out)
    name = name or csv.stem.removeprefix("wp_")
    t = target_table(read_study(csv))
    if problems:
        t = plain_cyrk(t, problems)
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
    return write_target(paths["csv"], out, problems=study_problems("full"))


def run_quick(out: Path) -> None:
    print(target_markdown(write_target(out / "wp_quick.csv", out,
                                       problems=study_problems("quick"))))


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
          writes=("target_quick.csv", "target_quick.md"), timed=True, minutes=0.5),
    Study("target-full", "The 2× target on every study problem", 100, run_full,
          report=report_full, plan="full", timed=True,
          writes=("target_full.csv", "target_full.md", "wp_full.csv", "wp_full_*.png",
                  "wp_full_pareto.*"), minutes=26),
)
