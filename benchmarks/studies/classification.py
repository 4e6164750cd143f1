"""Where the classification's locking rule comes from, measured: ``rsfbench study classification``.

A run is stick–slip only if the fault locks between events. The trajectory says so directly —
the slip rate falls below vLs/10 between events — but :func:`benchmarks.physics.metrics.limit_cycle`
sees only the events table, which every backend produces identically. Its form of the rule is
the mean slip rate between one event's end and the next one's start, over vLs
(:func:`benchmarks.physics.metrics.interevent_slip_rate`), at most
:data:`benchmarks.physics.metrics.LOCKED_SLIP_RATE`.

This study runs both on the same problems — the paper example and W1–W4 at their best fits
under both laws, a 3 × 3 subsample of each Section 4 sweep grid, and slip-rate oscillations
that never lock (b close to a, or k close to kcr, where the two-speed loading's fast phase
keeps the fault sliding) — with Rodas5P at 1e−6 and the trajectory saved densely enough to
find the minimum slip rate between events, and counts where the two rules disagree.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from benchmarks.inversion.published import GRID, T_END, best_fit, grid_around
from benchmarks.physics.metrics import LOCKED_SLIP_RATE, interevent_slip_rate, summarize
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import fmt, markdown_table
from benchmarks.studies.study import Study, markdown_file
from integrators import Rodas5P, solve
from problems import preset

__all__ = ["STUDY", "classification_study", "write_classification", "OSCILLATIONS"]

#: runs found to oscillate about vL without locking: (preset, law, b, Lc m, t_end s)
OSCILLATIONS = (
    ("W2", "aging", 0.00813, 0.316e-6, 40.0), ("W2", "aging", 0.0081, 0.607e-6, 40.0),
    ("W2", "aging", 0.00813, 0.1e-6, 40.0), ("W1", "slip", 0.0081, 0.09e-6, 40.0),
    ("W1", "slip", 0.0081, 0.285e-6, 40.0), ("W1", "aging", 0.00836, 0.191e-6, 40.0),
    ("W1", "aging", 0.00796, 0.00605e-6, 40.0), ("W2", "slip", 0.0086, 0.3e-6, 40.0),
    ("W3", "aging", 0.00841, 0.602e-6, 40.0), ("W4", "aging", 0.0084, 2.16e-6, 15.0),
    ("paper-example", "slip", 0.0081, 0.64e-6, 100.0),
    ("paper-example", "aging", 0.0081, 0.64e-6, 100.0),
    ("paper-example", "slip", 0.0092, 7.28e-6, 200.0),
)
#: the trajectory rule: the fault locks when v falls below this multiple of vLs between events
LOCKED_V = 0.1
_SAVED_POINTS = 200_001


def _runs():
    runs = [("paper example", "paper-example", law, None, None, 20.0) for law in ("slip", "aging")]
    for law in ("slip", "aging"):
        for name in ("W1", "W2", "W3", "W4"):
            runs.append(("best fit", name, law, None, None, T_END[name]))
            b0, lc0 = best_fit(name, law)
            b, lc = grid_around(b0, lc0, **GRID[law])
            for bi in b[[0, len(b) // 2, -1]]:
                for li in lc[[0, len(lc) // 2, -1]]:
                    runs.append(("sweep grid", name, law, float(bi), float(li), T_END[name]))
    runs += [("oscillation", *case) for case in OSCILLATIONS]
    return runs


def _gap_minima(sol) -> np.ndarray:
    """The smallest saved slip rate between each event's start and the end of the one before."""
    t, v, ev = sol.t, sol.v, sol.events
    out = np.full(len(ev), np.nan)
    for i in range(1, len(ev)):
        lo = np.searchsorted(t, ev.t_end.iloc[i - 1], "right")
        hi = np.searchsorted(t, ev.t_start.iloc[i], "left")
        if hi > lo:
            out[i] = v[lo:hi].min()
    return out


def classification_study(progress: bool = True) -> pd.DataFrame:
    """One row per run: its classification, and over the gaps of its last period (its last 10
    gaps if it has no cycle) the largest mean slip rate and the smallest slip rate, over vLs."""
    algorithm = Rodas5P(rtol=1e-6, atol=1e-6)
    rows = []
    runs = tqdm(_runs(), desc="classification", disable=not progress)
    for group, name, law, b, lc, t_end in runs:
        p = preset(name, law=law, b=b, lc=lc, t_end=t_end)
        sol = solve(p, algorithm, max_points=_SAVED_POINTS, wall_budget=60)
        cycle = summarize(sol)
        vls = p.loading.v_slow
        k = cycle.period or min(10, max(len(sol.events) - 1, 0))
        rate = interevent_slip_rate(sol.events)[-k:] / vls if k else np.array([np.nan])
        vmin = _gap_minima(sol)[-k:] / vls if k else np.array([np.nan])
        rows.append({"group": group, "problem": p.name, "b": p.law.b, "lc_um": p.law.lc * 1e6,
                     "t_end_s": t_end, "retcode": sol.retcode.value,
                     "classification": cycle.classification, "period": cycle.period,
                     "n_events": len(sol.events),
                     "mean_rate_over_vls": float(np.nanmax(rate)) if np.isfinite(rate).any()
                     else np.nan,
                     "min_v_over_vls": float(np.nanmin(vmin)) if np.isfinite(vmin).any()
                     else np.nan})
    return pd.DataFrame(rows)


def write_classification(table: pd.DataFrame, out: Path) -> str:
    """``classification.csv`` and ``.md`` in ``out``; returns the Markdown."""
    out.mkdir(parents=True, exist_ok=True)
    write_table(table, out / "classification.csv")
    # a cycle of events: an oscillation about vL without events (a small limit cycle, or the
    # neutral oscillation at k = kcr) has no gaps between events to compare
    has_cycle = table.period.fillna(0) > 0
    periodic = table[has_cycle]
    by_rule = periodic.mean_rate_over_vls <= LOCKED_SLIP_RATE
    by_trajectory = periodic.min_v_over_vls < LOCKED_V
    summary = (table.groupby("group", sort=False)
               .agg(runs=("problem", "size"),
                    periodic=("period", lambda p: int((p.fillna(0) > 0).sum())),
                    rate_min=("mean_rate_over_vls", "min"), rate_max=("mean_rate_over_vls", "max"),
                    vmin_min=("min_v_over_vls", "min"), vmin_max=("min_v_over_vls", "max"))
               .reset_index())
    summary["classifications"] = [
        ", ".join(f"{n} {c}" for c, n in g.classification.value_counts().items())
        for _, g in table.groupby("group", sort=False)]
    md = summary.assign(**{c: summary[c].map(fmt) for c in
                           ("rate_min", "rate_max", "vmin_min", "vmin_max")}).rename(columns={
        "rate_min": "mean rate / vLs: min", "rate_max": "max",
        "vmin_min": "min v / vLs: min", "vmin_max": "max"})
    text = (f"Rodas5P at 1e−6, {len(table)} runs. Over the gaps of each run's last period: the "
            "largest mean slip rate between events (the events-table rule) and the smallest slip "
            "rate (the trajectory), both over vLs.\n\n" + markdown_table(md) +
            f"\nOf {len(periodic)} periodic runs, the rule 'mean rate ≤ {LOCKED_SLIP_RATE:g} vLs' "
            f"and the trajectory's 'v < {LOCKED_V:g} vLs' agree on "
            f"{int((by_rule == by_trajectory).sum())}; the rule calls "
            f"{int((by_rule & ~by_trajectory).sum())} runs locked whose slip rate stayed above "
            f"{LOCKED_V:g} vLs, and {int((~by_rule & by_trajectory).sum())} runs not locked whose "
            f"slip rate fell below it.\n")
    write_output(out / "classification.md", text)
    return text


def run(out: Path) -> None:
    print(write_classification(classification_study(), out))


STUDY = Study("classification", "Stick–slip needs the fault to lock (`classification.*`)", 150,
              run, report=markdown_file("classification.md"),
              writes=("classification.csv", "classification.md"), minutes=0.05)
