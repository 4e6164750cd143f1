"""Parameter sweeps over (b, Lc) for an inversion (Urata et al. 2017, Sect. 4; SPEC §6).

Every grid point is one simulation of a preset with (b, Lc) replaced. Points run in parallel
(local processes by default, threads or a Dask cluster on request: :mod:`benchmarks.sweep_exec`)
and each finished point is written at once to ``DIR/points/<key>.json`` (write to a temporary
file, then rename: a killed sweep never leaves half a file). The key hashes everything the
simulation depends on (problem, algorithm and its options, curve resolution, budget), so a sweep
restarted with the same arguments skips the points it has, and changing only the observations
(ΔT̄, σ, curves) re-scores the stored simulations without running them again. A stored point is
trusted only if it parses and holds its own key and grid point; any other file under that name
(empty, truncated, copied from another point, garbage) is reported by name and recomputed.

Everything is checked before the first point runs: the grid (finite, non-empty, at most
``max_points`` points), every point's problem, the observations, the budget, the workers and the
Dask scheduler.

The table (``DIR/sweep.csv``, one row per grid point, b outer and Lc inner) holds the limit-cycle
metrics, the classification (:data:`benchmarks.metrics.CLASSIFICATIONS`: the paper's Fig. 8
classes, and what a run that shows no limit cycle is), J1, and J2, J when slip-weakening curves
are given (see :mod:`benchmarks.fitting`). Only a point with a limit cycle
(:data:`benchmarks.metrics.CYCLES`) has metrics and scores; any other point has NaN there and
the reason in its classification and message.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from benchmarks.files import (BadResultsFile, atomic_write, read_json_record,
                              remove_stale_temporaries)
from benchmarks.fitting import (CHI2_95_2DOF, check_curves, event_curve, j1, j2_per_event,
                                joint_fit)
from benchmarks.metrics import CLASSIFICATIONS, CYCLES, summarize
from benchmarks.report import jsonable
from benchmarks.sweep_exec import CONNECT_TIMEOUT_S, WORKER_TIMEOUT_S, connect, execute
from benchmarks.timing import warm_up
from integrators import ReturnCode, solve
from problems import preset
from problems._validate import (check_count, check_positive, units_checked_already,
                                warn_implausible)

__all__ = ["parse_b", "parse_lc", "check_grid", "PointTask", "run_point", "PointStore",
           "Observations", "observations", "ASSUMED_SIGMA", "sweep", "SweepResult", "BACKENDS",
           "MAX_GRID_POINTS", "BadPointWarning"]

BACKENDS = ("processes", "threads")
#: the most grid points a sweep runs unless ``max_points`` allows more: a typo in a step must
#: not start a sweep of 10⁸ points (at ~10 ms a point, 10⁴ points take minutes)
MAX_GRID_POINTS = 10_000
POINT_COLUMNS = ("b", "lc_m", "kappa", "classification", "period", "n_events", "recurrence_s",
                 "friction_drop", "slip_m", "peak_velocity_m_s", "retcode", "message", "nfev",
                 "steps", "wall_s", "integrator")
#: what a stored point must hold to be trusted
POINT_REQUIRED = ("key", "b", "lc_m", "classification", "retcode", "message", "integrator")
_METRIC_COLUMNS = ("period", "recurrence_s", "friction_drop", "slip_m", "peak_velocity_m_s")
RETCODES = {r.value for r in ReturnCode}


class BadPointWarning(UserWarning):
    """A stored point that cannot be trusted; it is recomputed (the message names the file)."""


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
    no value repeated, at most ``max_points`` points in all. An Lc axis outside the plausible
    range in metres warns once (:class:`~problems._validate.UnitWarning`), not once a point."""
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
    for value in {lc.min(), lc.max()}:
        warn_implausible("lc", value, stacklevel=3)
    return b, lc


@dataclass(frozen=True)
class PointTask:
    """One grid point: the preset with (b, Lc) replaced, and how to solve it."""

    preset: str
    law: str
    b: float
    lc: float
    t_end: float | None
    algorithm: object
    curve_dt: float | None = None     # s: save the trajectory this finely, for J2
    wall_budget: float | None = None

    def problem(self):
        with units_checked_already():        # check_grid warned once for the whole Lc axis
            return preset(self.preset, law=self.law, b=self.b, lc=self.lc, t_end=self.t_end)

    def key(self) -> str:
        """Hash of the full problem (so a changed preset is a new point) and the solve options."""
        text = repr((repr(self.problem()), self.algorithm, self.curve_dt, self.wall_budget))
        return hashlib.sha256(text.encode()).hexdigest()[:24]


def run_point(task: PointTask) -> dict:
    """Simulate one point and summarise it (never raises: a failure is a row with its retcode).
    The parent adds the point's key (computed once, there) before storing the row.
    Limit-cycle metrics are filled in only for a limit cycle (:data:`benchmarks.metrics.CYCLES`):
    a failed, truncated or unclassifiable run is never read as physics."""
    try:
        problem = task.problem()
        save = (dict(save_every=task.curve_dt) if task.curve_dt else dict(max_points=2))
        sol = solve(problem, task.algorithm, wall_budget=task.wall_budget, **save)
    except Exception as exc:            # checked before the sweep started: a bug if it happens
        return failed_row(task, f"{type(exc).__name__}: {exc}")
    cycle = summarize(sol)
    row = {"b": task.b, "lc_m": task.lc, "integrator": task.algorithm.name,
           "kappa": problem.kappa, "classification": cycle.classification,
           "n_events": len(sol.events), "retcode": sol.retcode.value,
           "message": sol.message or cycle.reason, "nfev": sol.stats.nfev,
           "steps": sol.stats.steps, "wall_s": sol.stats.wall_s}
    if cycle.classification in CYCLES:
        row.update({c: getattr(cycle, c) for c in _METRIC_COLUMNS})
        if task.curve_dt:
            slip, mu = event_curve(sol)
            row.update(curve_slip=slip.tolist(), curve_friction=mu.tolist())
    return row


def failed_row(task: PointTask, message: str) -> dict:
    """The row of a point that could not be simulated at all (its worker crashed): in this
    sweep's table, but ``transient``, never stored, so that a rerun tries the point again."""
    return {"b": task.b, "lc_m": task.lc, "integrator": task.algorithm.name,
            "classification": "failed", "retcode": "Failure", "message": message,
            "transient": True}


def _check_row(row: dict, task: PointTask, key: str, path: Path) -> None:
    """``BadResultsFile`` unless ``row`` is a whole row of ``task``: its own key and grid point,
    a known classification and retcode, finite metrics for a cycle and none otherwise, and its
    slip-weakening curve when the sweep needs one."""
    def bad(why):
        raise BadResultsFile(f"sweep point {path} {why}")

    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool)

    if row["key"] != key:
        bad(f"holds the point {row['key']!r} (a copied file?)")
    if (row["b"], row["lc_m"]) != (task.b, task.lc):
        bad(f"holds (b, Lc) = ({row['b']!r}, {row['lc_m']!r}), not ({task.b!r}, {task.lc!r})")
    if row["classification"] not in CLASSIFICATIONS or row["retcode"] not in RETCODES:
        bad(f"holds an unknown classification or retcode ({row['classification']!r}, "
            f"{row['retcode']!r})")
    if row.get("transient") or row["integrator"] != task.algorithm.name:
        bad("is not a finished point of this sweep's integrator")
    if row["classification"] in CYCLES:
        if not all(number(row.get(c)) and math.isfinite(row[c]) for c in _METRIC_COLUMNS):
            bad("lacks a finite limit-cycle metric")
        if task.curve_dt:
            curve = [row.get("curve_slip"), row.get("curve_friction")]
            if not (all(isinstance(x, list) and len(x) >= 2 for x in curve)
                    and len(curve[0]) == len(curve[1])
                    and all(number(v) and math.isfinite(v) for x in curve for v in x)):
                bad("lacks its slip-weakening curve")
    elif any(row.get(c) is not None and not (number(row[c]) and math.isnan(row[c]))
             for c in _METRIC_COLUMNS):
        bad(f"holds limit-cycle metrics for a point classified {row['classification']!r}")


class PointStore:
    """Finished points as one JSON file each under ``root/points``, written atomically and
    checked when read (module docstring); ``bad`` lists the files found untrustworthy."""

    def __init__(self, root) -> None:
        self.dir = Path(root) / "points"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.bad: list[str] = []
        remove_stale_temporaries(self.dir)

    def load(self, task: PointTask, key: str) -> dict | None:
        """The stored row of ``task`` (whose key is ``key``), or None: not stored, or stored
        but not trustworthy (then reported with :class:`BadPointWarning`, to be recomputed)."""
        path = self.dir / f"{key}.json"
        if not path.exists():
            return None
        try:
            row = read_json_record(path, POINT_REQUIRED, what="sweep point")
            _check_row(row, task, key, path)
        except BadResultsFile as exc:
            self.bad.append(str(exc))
            warnings.warn(f"{exc}: recomputing it", BadPointWarning, stacklevel=2)
            return None
        return row

    def save(self, key: str, row: dict) -> None:
        atomic_write(self.dir / f"{key}.json", json.dumps(jsonable(row)))


@dataclass(frozen=True)
class Observations:
    """What a point is scored against: observed means and standard deviations (Eq. 10), and
    optionally the observed slip-weakening curves (Eq. 11). The four numbers must be positive
    and finite (ΔT̄ and its σ in s, Δμ̄ and its σ dimensionless)."""

    recurrence_s: float
    sigma_recurrence_s: float
    friction_drop: float
    sigma_friction_drop: float
    curves: pd.DataFrame | None = None
    assumed_sigma: bool = False        # σ not measured: 10 % of the mean, say so in the output

    def __post_init__(self) -> None:
        for name in ("recurrence_s", "sigma_recurrence_s", "friction_drop",
                     "sigma_friction_drop"):
            check_positive(name, getattr(self, name))
        if self.curves is not None:
            object.__setattr__(self, "curves", check_curves(self.curves, "obs.curves"))


#: σ assumed when none is given: 10 % of the observed mean (flagged in the output)
ASSUMED_SIGMA = 0.10


def observations(preset_name: str, obs_recurrence=None, sigma_recurrence=None, obs_drop=None,
                 sigma_drop=None, curves=None) -> Observations:
    """Observations of a preset: a window's published means fill what is not given, and a
    missing σ is 10 % of its mean (``assumed_sigma`` says so)."""
    from problems import WINDOWS
    w = WINDOWS.get(preset_name.upper())
    obs_recurrence = obs_recurrence if obs_recurrence is not None else (w and w.observed_recurrence)
    obs_drop = obs_drop if obs_drop is not None else (w and w.observed_drop)
    for name, value in (("obs_recurrence", obs_recurrence), ("obs_drop", obs_drop)):
        if value is None:
            raise ValueError(f"{name} is required for {preset_name!r} (it has no observed means)")
    assumed = sigma_recurrence is None or sigma_drop is None
    return Observations(
        recurrence_s=obs_recurrence,
        sigma_recurrence_s=(sigma_recurrence if sigma_recurrence is not None
                            else ASSUMED_SIGMA * obs_recurrence),
        friction_drop=obs_drop,
        sigma_friction_drop=sigma_drop if sigma_drop is not None else ASSUMED_SIGMA * obs_drop,
        curves=curves, assumed_sigma=assumed)


@dataclass
class SweepResult:
    table: pd.DataFrame
    summary: dict


def _warm(task: PointTask) -> None:
    """Compile (or load from numba's cache) what ``task`` needs, so no point pays for it."""
    try:
        warm_up(task.problem(), task.algorithm)
    except Exception:         # a failing point is reported by run_point, not here
        pass


def sweep(preset_name: str, law: str, b_values, lc_values, algorithm, obs: Observations,
          out, t_end: float | None = None, workers: int | None = None,
          scheduler: str | None = None, backend: str = "processes",
          curve_dt: float = 5e-5, wall_budget: float | None = None,
          progress: bool = True, max_points: int = MAX_GRID_POINTS,
          connect_timeout: float = CONNECT_TIMEOUT_S,
          worker_timeout: float = WORKER_TIMEOUT_S) -> SweepResult:
    """Run (or resume) the sweep over ``b_values`` × ``lc_values`` and score it against ``obs``.

    Finished points are read back from ``out`` and not run again. Returns the table (also
    written to ``out/sweep.csv``) and a summary (also ``out/summary.json``). Every argument is
    checked before the first point runs (``ValueError``); ``max_points`` bounds the grid.
    """
    tasks = _tasks(preset_name, law, b_values, lc_values, algorithm, obs, t_end, workers,
                   backend, curve_dt, wall_budget, max_points)
    workers = os.cpu_count() or 1 if workers is None else workers
    client = connect(scheduler, connect_timeout) if scheduler else None   # before any work
    try:
        rows, n_run, n_resumed, wall, bad = _run(tasks, out, client, workers, backend,
                                                 worker_timeout, f"{preset_name}/{law}", progress)
    finally:
        if client is not None:
            client.close()
    table = score(rows, obs)
    summary = summarize_sweep(table, obs, algorithm, wall_s=wall, n_run=n_run,
                              n_resumed=n_resumed, n_bad_files=len(bad), bad_files=bad,
                              workers=1 if scheduler else workers, scheduler=scheduler,
                              backend=backend)
    out = Path(out)
    remove_stale_temporaries(out)
    atomic_write(out / "sweep.csv", table.to_csv(index=False))
    atomic_write(out / "summary.json", json.dumps(jsonable(summary), indent=2))
    return SweepResult(table, summary)


def _run(tasks, out, client, workers, backend, worker_timeout, name, progress):
    """Load the stored points, run the others: (their rows in grid order, how many were run and
    resumed, the wall time, the bad files found)."""
    store = PointStore(out)
    keys = [t.key() for t in tasks]
    key_of = dict(zip(tasks, keys))       # the parent's keys: a worker's repr may differ
    rows = {k: store.load(t, k) for t, k in zip(tasks, keys)}
    todo = [t for t, k in zip(tasks, keys) if rows[k] is None]
    n_resumed = len(tasks) - len(todo)
    start = time.perf_counter()
    bar = tqdm(total=len(tasks), initial=n_resumed, desc=f"sweep {name}", unit="point",
               disable=not progress)
    with bar:
        for task, row in execute(run_point, _warm, failed_row, todo, workers, backend, client,
                                 worker_timeout):
            key = key_of[task]
            row["key"] = key
            if not row.get("transient"):
                store.save(key, row)
            rows[key] = row
            bar.update(1)
    wall = time.perf_counter() - start
    return pd.DataFrame([rows[k] for k in keys]), len(todo), n_resumed, wall, store.bad


def _tasks(preset_name, law, b_values, lc_values, algorithm, obs, t_end, workers, backend,
           curve_dt, wall_budget, max_points) -> list[PointTask]:
    """The points of a sweep, every argument checked (``ValueError`` before any work)."""
    from integrators import Algorithm
    from integrators import Output
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if workers is not None:
        check_count("workers", workers)
    if not isinstance(algorithm, Algorithm):
        raise ValueError(f"algorithm must be an Algorithm instance, got {algorithm!r}")
    if not isinstance(obs, Observations):
        raise ValueError(f"obs must be Observations, got {obs!r}")
    for name, value in (("wall_budget", wall_budget), ("t_end", t_end), ("curve_dt", curve_dt)):
        if value is not None:
            check_positive(name, value)
    b_values, lc_values = check_grid(b_values, lc_values, max_points)
    need_curves = obs.curves is not None
    tasks = [PointTask(preset_name, law, float(b), float(lc), t_end, algorithm,
                       curve_dt if need_curves else None, wall_budget)
             for b in b_values for lc in lc_values]
    for task in tasks:                           # every point a valid problem, or say which
        try:
            problem = task.problem()
        except ValueError as exc:
            raise ValueError(f"grid point (b = {task.b:g}, Lc = {task.lc:g} m): {exc}") from None
    if need_curves:                              # the saved trajectory of a point fits memory
        Output(save_every=curve_dt).interval(problem.t_end)
    return tasks


def score(points: pd.DataFrame, obs: Observations) -> pd.DataFrame:
    """Add J1 (and J2, J) and the regions to a table of simulated points. A point scores only
    with a limit cycle: metrics of any other point are NaN, so it is in no region."""
    for c in POINT_COLUMNS:
        if c not in points:
            points[c] = np.nan
    table = points[list(POINT_COLUMNS)].copy()
    no_cycle = ~table.classification.isin(CYCLES)
    table.loc[no_cycle, list(_METRIC_COLUMNS)] = np.nan
    table["J1"] = j1(table.recurrence_s, table.friction_drop, obs.recurrence_s,
                     obs.sigma_recurrence_s, obs.friction_drop, obs.sigma_friction_drop)
    if obs.curves is None:
        fit = joint_fit(table.J1.to_numpy())
    else:
        per_event = [j2_per_event(np.asarray(s if isinstance(s, list) else []),
                                  np.asarray(f if isinstance(f, list) else []), obs.curves)
                     for s, f in zip(points.get("curve_slip", [None] * len(points)),
                                     points.get("curve_friction", [None] * len(points)))]
        table["J2"] = [np.mean(x) if len(x) else np.nan for x in per_event]
        table["J2_std"] = [np.std(x) if len(x) else np.nan for x in per_event]
        table.loc[no_cycle, ["J2", "J2_std"]] = np.nan
        fit = joint_fit(table.J1.to_numpy(), table.J2.to_numpy(), table.J2_std.to_numpy())
        table["J"] = fit["J"]
        table["possible"] = fit["possible"]
    table["in_region"] = fit["in_region"]
    table.attrs.update({k: v for k, v in fit.items() if np.ndim(v) == 0})
    return table


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
