"""Parameter sweeps over (b, Lc) for an inversion (Urata et al. 2017, Sect. 4; SPEC §6).

A sweep is an ensemble (:mod:`benchmarks.ensemble`) of one problem — a preset or any
:class:`~problems.SpringSlider` — over the grid b × Lc, scored against observations. The
ensemble engine runs it: the own compiled methods in compiled batches on numba's threads, any
other backend point by point on a pool of processes, or chunks on a Dask cluster; finished chunks
are kept in a Parquet store under ``DIR/chunks`` (``benchmarks.ensemble.read_store(DIR/"chunks")``
reads the simulations back: the chunks its identity file lists, each checked by its hash), so a sweep restarted with the same arguments runs only what is missing, and
changing only the observations (ΔT̄, σ) re-scores the stored simulations without running them
again. Slip-weakening curves (J2) come from a second solve of each point over its last event, in
the batch for the own methods, point by point for the others.

Everything is checked before the first point runs: the grid (finite, non-empty, at most
``max_points`` points), every point's problem, the observations, the budget, the workers and the
Dask scheduler.

The table (``DIR/sweep.csv``, one row per grid point, b outer and Lc inner) holds the limit-cycle
metrics, the classification (:data:`benchmarks.physics.metrics.CLASSIFICATIONS`: the paper's Fig. 8
classes, and what a run that shows no limit cycle is), J1, and J2, J when slip-weakening curves
are given (see :mod:`benchmarks.inversion.objectives`). Only a point with a limit cycle
(:data:`benchmarks.physics.metrics.CYCLES`) has metrics and scores; any other point has NaN there and
the reason in its classification and message.
"""

from __future__ import annotations

import importlib.util
import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.ensemble import ensemble, grid
from benchmarks.ensemble.executors import CONNECT_TIMEOUT_S, WORKER_TIMEOUT_S
from benchmarks.inversion.objectives import (
    CHI2_95_2DOF,
    event_samples,
    j2_per_event,
    joint_fit,
    scores,
)
from benchmarks.inversion.observations import Observations
from benchmarks.physics.metrics import CYCLES
from benchmarks.records.files import remove_stale_temporaries, write_output
from benchmarks.records.provenance import provenance as machine, version_line
from benchmarks.records.report import jsonable
from problems import SpringSlider
from problems._validate import check_count, check_positive, units_checked_already, warn_implausible

__all__ = ["parse_b", "parse_lc", "check_grid", "sweep", "SweepResult", "score",
           "summarize_sweep", "MAX_GRID_POINTS"]

#: the most grid points a sweep runs unless ``max_points`` allows more: a typo in a step must
#: not start a sweep of 10⁸ points (at ~1 ms a point, 10⁴ points take seconds to minutes)
MAX_GRID_POINTS = 10_000
POINT_COLUMNS = ("b", "lc_m", "kappa", "classification", "period", "n_events", "recurrence_s",
                 "friction_drop", "slip_m", "peak_velocity_m_s", "retcode", "message", "nfev",
                 "steps", "wall_s", "integrator")
_METRIC_COLUMNS = ("period", "recurrence_s", "friction_drop", "slip_m", "peak_velocity_m_s")


def parse_b(spec: str, max_points: int = MAX_GRID_POINTS) -> np.ndarray:
    """``START:STOP:STEP`` → b values from START to STOP inclusive (STOP kept if on the grid)."""
    start, stop, step = _fields("--b", spec, 3)
    if not step > 0 or stop < start:
        raise ValueError(f"--b must be START:STOP:STEP with STEP > 0 and STOP ≥ START, got {spec!r}")
    if start < 0:
        raise ValueError(f"--b must start at b ≥ 0, got {spec!r}")
    span = (stop - start) / step                 # inf for a STEP that underflows the span
    if not span + 1 <= max_points:
        raise ValueError(f"--b {spec!r} has {span + 1:.3g} values, more than the limit of "
                         f"{max_points} grid points (a typo in STEP?); raise the limit with "
                         "--max-points")
    n = math.floor(span + 1e-9) + 1
    return np.round(start + step * np.arange(n), 12)


def parse_lc(spec: str, max_points: int = MAX_GRID_POINTS) -> np.ndarray:
    """``START:STOP:N`` (linear) or ``START:STOP:Nlog`` (log-spaced) → N values of Lc in metres."""
    head, _, count = spec.rpartition(":")
    log = count.endswith("log")
    try:
        n = int(count[:-3] if log else count)
    except ValueError:
        raise ValueError(f"--lc must be START:STOP:N or START:STOP:Nlog, got {spec!r}") from None
    start, stop = _fields("--lc", head, 2)
    if n < 1 or not 0 < start <= stop:
        raise ValueError(f"--lc needs 0 < START ≤ STOP and N ≥ 1, got {spec!r}")
    if n > 1 and start == stop:
        raise ValueError(f"--lc {spec!r} repeats one value {n} times: give N = 1, or STOP > START")
    if n > max_points:
        raise ValueError(f"--lc {spec!r} has {n} values, more than the limit of {max_points} "
                         "grid points; raise the limit with --max-points")
    return np.geomspace(start, stop, n) if log else np.linspace(start, stop, n)


def _fields(flag: str, spec: str, n: int) -> list[float]:
    parts = spec.split(":")
    try:
        values = [float(x) for x in parts]
    except ValueError:
        values = []
    if len(values) != n:
        raise ValueError(f"{flag} needs {n} numbers separated by ':', got {spec!r}")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{flag} needs finite numbers, got {spec!r}")
    return values


def check_grid(b_values, lc_values, max_points: int = MAX_GRID_POINTS):
    """The grid as float arrays, or ``ValueError``: both axes non-empty, finite, b ≥ 0, Lc > 0,
    no value repeated, at most ``max_points`` points in all. An axis whose ends are outside the
    plausible range (b dimensionless, Lc in metres) warns once (:class:`~problems._validate.UnitWarning`), not once a point."""
    axes = []
    for name, values in (("b", b_values), ("lc", lc_values)):
        try:
            x = np.asarray(values, dtype=float).ravel()
        except (TypeError, ValueError):
            raise ValueError(f"{name} values must be numbers, got {values!r}") from None
        if x.size == 0:
            raise ValueError(f"the {name} axis of the grid is empty")
        if not np.isfinite(x).all():
            raise ValueError(f"{name} values must be finite, got {x[~np.isfinite(x)][:3].tolist()}")
        if np.unique(x).size != x.size:
            raise ValueError(f"{name} values repeat: {x.tolist()[:10]}")
        axes.append(x)
    b, lc = axes
    if (b < 0).any():
        raise ValueError(f"b must be ≥ 0, got {b[b < 0][:3].tolist()}")
    if (lc <= 0).any():
        raise ValueError(f"lc must be positive (metres), got {lc[lc <= 0][:3].tolist()}")
    limit = check_count("max_points", max_points)
    if b.size * lc.size > limit:
        raise ValueError(f"the grid has {b.size} × {lc.size} = {b.size * lc.size} points, more "
                         f"than max_points = {limit}: raise it if you mean it")
    for name, axis in (("b", b), ("lc", lc)):
        for value in {axis.min(), axis.max()}:
            warn_implausible(name, value, stacklevel=3)
    return b, lc


@dataclass
class SweepResult:
    table: pd.DataFrame
    summary: dict


def sweep(problem, b_values, lc_values, algorithm, obs: Observations, out,
          workers: int | None = None, scheduler: str | None = None, backend: str | None = None,
          curve_dt: float = 5e-5, wall_budget: float | None = None, progress: bool = True,
          max_points: int = MAX_GRID_POINTS, connect_timeout: float = CONNECT_TIMEOUT_S,
          worker_timeout: float = WORKER_TIMEOUT_S, chunk_size: int | None = None,
          reclaim_store: bool = False, provenance: dict | None = None,
          sensitivity=None, settle: float | None = None) -> SweepResult:
    """Run (or resume) the sweep of ``problem`` (a SpringSlider: its t_end is each point's) over
    ``b_values`` × ``lc_values`` and score it against ``obs``.

    Finished chunks are read back from ``out/chunks`` and not run again. Returns the table (also
    written to ``out/sweep.csv``) and a summary (also ``out/summary.json``). Every argument is
    checked before the first point runs (``ValueError``); ``max_points`` bounds the grid.
    ``curve_dt`` (s) resolves the slip-weakening curves when ``obs`` has some. ``provenance``:
    what else the summary records of the run (the command line, why this integrator), beside
    the tool's version, the machine and the packages.
    ``reclaim_store``: stored chunks of another sweep in ``out`` are cleared, not refused (for
    the harness's own caches). ``sensitivity``: parameter names; the table then has the
    gradients of each point's limit-cycle metrics (:func:`benchmarks.ensemble.ensemble`'s).
    ``settle``: each point stops on its settled cycle (:func:`integrators.solve`'s; default
    None: every point runs to t_end).
    """
    if not isinstance(problem, SpringSlider):
        raise ValueError(f"problem must be a SpringSlider, got {type(problem).__name__}")
    if not isinstance(obs, Observations):
        raise ValueError(f"obs must be Observations, got {obs!r}")
    if workers is not None:
        check_count("workers", workers)
    check_positive("curve_dt", curve_dt)
    b_values, lc_values = check_grid(b_values, lc_values, max_points)
    out = Path(out)
    store = out / "chunks"
    if importlib.util.find_spec("pyarrow") is None:    # the core install: no Parquet store
        warnings.warn("pyarrow is not installed: this sweep keeps no chunks and cannot resume "
                      "(pip install 'rsfbench[ensemble]')", stacklevel=2)
        store = None
    with units_checked_already():            # check_grid warned once for the Lc axis
        table = ensemble(problem, algorithm, grid(b=b_values, lc=lc_values), store=store,
                         chunk_size=chunk_size, workers=workers, backend=backend,
                         scheduler=scheduler, wall_budget=wall_budget,
                         curve_dt=curve_dt if obs.curves is not None else None,
                         progress=progress, max_points=max_points,
                         connect_timeout=connect_timeout, worker_timeout=worker_timeout,
                         label=f"sweep {problem.name or 'problem'}",
                         reclaim_store=reclaim_store, sensitivity=sensitivity, settle=settle)
    run = table.attrs
    table = score(table.rename(columns={"lc": "lc_m"}), obs)
    summary = summarize_sweep(table, obs, algorithm, wall_s=run["wall_s"], n_run=run["n_run"],
                              n_resumed=run["n_resumed"], n_bad_files=len(run["bad_chunks"]),
                              bad_files=run["bad_chunks"], stray_files=run["stray_files"],
                              workers=run["workers"],
                              scheduler=scheduler, backend=run["backend"],
                              batched=run["batched"], chunks=run["chunks"],
                              store=None if store is None else str(store))
    summary["gradient_columns"] = [c for c in table.columns if c.startswith("d_")]
    summary["settle"] = settle
    summary["provenance"] = {"tool": version_line(), **machine(), **(provenance or {})}
    out.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(out)
    write_output(out / "sweep.csv", table.to_csv(index=False))
    write_output(out / "summary.json", json.dumps(jsonable(summary), indent=2))
    return SweepResult(table, summary)


def score(points: pd.DataFrame, obs: Observations) -> pd.DataFrame:
    """Add J1 (and J2, J) and the regions to a table of simulated points. A point scores only
    with a limit cycle: metrics of any other point are NaN, so it is in no region."""
    for c in POINT_COLUMNS:
        if c not in points:
            points[c] = np.nan
    table = points[list(POINT_COLUMNS)].copy()
    no_cycle = ~table.classification.isin(CYCLES)
    table.loc[no_cycle, list(_METRIC_COLUMNS)] = np.nan
    table["J1"] = scores(table.recurrence_s, table.friction_drop, ~no_cycle, obs).j1
    if obs.curves is None:
        fit = joint_fit(table.J1.to_numpy())
    else:
        observed = event_samples(obs.curves)
        per_event = [j2_per_event(_curve(s), _curve(f), observed)
                     for s, f in zip(points.get("curve_slip", [None] * len(points)),
                                     points.get("curve_friction", [None] * len(points)))]
        table["J2"] = [np.mean(x) if len(x) else np.nan for x in per_event]
        table["J2_std"] = [np.std(x) if len(x) else np.nan for x in per_event]
        table.loc[no_cycle, ["J2", "J2_std"]] = np.nan
        fit = joint_fit(table.J1.to_numpy(), table.J2.to_numpy(), table.J2_std.to_numpy())
        table["J"] = fit["J"]
        table["possible"] = fit["possible"]
    table["in_region"] = fit["in_region"]
    for c in points.columns:            # the gradients, when the sweep asked for them
        if c.startswith("d_"):          # (per metre of Lc: named as the table's lc_m)
            table[c + "_m" if c.endswith("/d_lc") else c] = points[c].to_numpy(dtype=float)
    table.attrs.update({k: v for k, v in fit.items() if np.ndim(v) == 0})
    return table


def _curve(x) -> np.ndarray:
    """A stored curve as an array (empty for a point without one)."""
    return np.asarray(x, dtype=float) if isinstance(x, (list, np.ndarray)) else np.empty(0)


def summarize_sweep(table: pd.DataFrame, obs: Observations, algorithm, **run) -> dict:
    """The summary printed by ``rsfbench sweep --json``."""
    objective = "J" if "J" in table and table.J.notna().any() else "J1"
    finite = table[objective].notna()
    best = table[finite].loc[table[finite][objective].idxmin()] if finite.any() else None
    s = {
        "best_b": None if best is None else best.b,
        "best_lc_m": None if best is None else best.lc_m,
        "best_J1": None if best is None else best.J1,
        "best_by": objective,
        "n_points": len(table),
        "n_failed": int((table.retcode != "Success").sum()),
        "n_scored": int(table.classification.isin(CYCLES).sum()),
        "n_in_region": int(table.in_region.sum()),
        "region": f"J1 <= {CHI2_95_2DOF}",
        "classification": table.classification.value_counts().to_dict(),
        "alpha1": table.attrs.get("alpha1"),
        "integrator": algorithm.name, "options": algorithm.options(),
        "observations": {"recurrence_s": obs.recurrence_s,
                         "sigma_recurrence_s": obs.sigma_recurrence_s,
                         "friction_drop": obs.friction_drop,
                         "sigma_friction_drop": obs.sigma_friction_drop,
                         "sigma_assumed_10_percent": obs.assumed_sigma,
                         "slip_weakening_events": None if obs.curves is None
                         else int(obs.curves.event_id.nunique())},
        "sim_wall_s_total": float(table.wall_s.sum()),
        "sim_wall_s_median": float(table.wall_s.median()),
        **run,
    }
    if objective == "J":
        s.update(best_J=best.J, alpha2=table.attrs.get("alpha2"),
                 n_possible=int(table.possible.sum()), possible_range="J <= 2 alpha1")
    return s
