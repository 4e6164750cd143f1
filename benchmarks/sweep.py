"""Parameter sweeps over (b, Lc) for an inversion (Urata et al. 2017, Sect. 4; SPEC §6).

Every grid point is one simulation of a preset with (b, Lc) replaced. Points run in parallel
(local processes by default, threads or a Dask cluster on request) and each finished point is
written at once to ``DIR/points/<key>.json`` (write to a temporary file, then rename: a killed
sweep never leaves half a file). The key hashes everything the simulation depends on (problem,
algorithm and its options, curve resolution, budget), so a sweep restarted with the same
arguments skips the points it has, and changing only the observations (ΔT̄, σ, curves) re-scores
the stored simulations without running them again.

The table (``DIR/sweep.csv``, one row per grid point, b outer and Lc inner) holds the limit-cycle
metrics, the classification (the paper's Fig. 8: stick–slip, multiple recurrence, stable
sliding; ``not converged`` or ``failed`` otherwise), J1, and J2, J when slip-weakening curves are
given (see :mod:`benchmarks.fitting`).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from benchmarks.fitting import CHI2_95_2DOF, event_curve, j1, j2_per_event, joint_fit
from benchmarks.metrics import summarize
from benchmarks.report import jsonable
from benchmarks.timing import warm_up
from integrators import solve
from problems import preset

__all__ = ["parse_b", "parse_lc", "PointTask", "run_point", "PointStore", "Observations",
           "sweep", "SweepResult", "BACKENDS"]

BACKENDS = ("processes", "threads")
POINT_COLUMNS = ("b", "lc_m", "kappa", "classification", "period", "n_events", "recurrence_s",
                 "friction_drop", "slip_m", "peak_velocity_m_s", "retcode", "message", "nfev",
                 "steps", "wall_s", "integrator")


def parse_b(spec: str) -> np.ndarray:
    """``START:STOP:STEP`` → b values from START to STOP inclusive (STOP kept if on the grid)."""
    start, stop, step = _fields("--b", spec, 3)
    if not step > 0 or stop < start:
        raise ValueError(f"--b must be START:STOP:STEP with STEP > 0 and STOP ≥ START, got {spec!r}")
    n = int(np.floor((stop - start) / step + 1e-9)) + 1
    return np.round(start + step * np.arange(n), 12)


def parse_lc(spec: str) -> np.ndarray:
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
    return np.geomspace(start, stop, n) if log else np.linspace(start, stop, n)


def _fields(flag: str, spec: str, n: int) -> list[float]:
    parts = spec.split(":")
    try:
        values = [float(x) for x in parts]
    except ValueError:
        values = []
    if len(values) != n:
        raise ValueError(f"{flag} needs {n} numbers separated by ':', got {spec!r}")
    return values


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
        return preset(self.preset, law=self.law, b=self.b, lc=self.lc, t_end=self.t_end)

    def key(self) -> str:
        """Hash of the full problem (so a changed preset is a new point) and the solve options."""
        try:
            problem = repr(self.problem())
        except ValueError as exc:        # an invalid point is still a point: it fails in run_point
            problem = repr((self.preset, self.law, self.b, self.lc, self.t_end, str(exc)))
        text = repr((problem, self.algorithm, self.curve_dt, self.wall_budget))
        return hashlib.sha256(text.encode()).hexdigest()[:24]


def run_point(task: PointTask) -> dict:
    """Simulate one point and summarise it (never raises: a failure is a row with its retcode)."""
    row = {"b": task.b, "lc_m": task.lc, "integrator": task.algorithm.name}
    try:
        problem = task.problem()
        row["kappa"] = problem.kappa
        save = (dict(save_every=task.curve_dt) if task.curve_dt else dict(max_points=2))
        sol = solve(problem, task.algorithm, wall_budget=task.wall_budget, **save)
    except Exception as exc:            # a bad point (e.g. b ≤ 0) must not stop the sweep
        return {**row, "classification": "failed", "retcode": "Failure",
                "message": f"{type(exc).__name__}: {exc}"}
    cycle = summarize(sol)
    row.update(classification=cycle.classification if sol.success else "failed",
               period=cycle.period, n_events=len(sol.events), recurrence_s=cycle.recurrence_s,
               friction_drop=cycle.friction_drop, slip_m=cycle.slip_m,
               peak_velocity_m_s=cycle.peak_velocity_m_s, retcode=sol.retcode.value,
               message=sol.message, nfev=sol.stats.nfev, steps=sol.stats.steps,
               wall_s=sol.stats.wall_s)
    if task.curve_dt:
        slip, mu = event_curve(sol)
        row.update(curve_slip=slip.tolist(), curve_friction=mu.tolist())
    return row


class PointStore:
    """Finished points as one JSON file each under ``root/points``, written atomically."""

    def __init__(self, root) -> None:
        self.dir = Path(root) / "points"
        self.dir.mkdir(parents=True, exist_ok=True)

    def load(self, key: str) -> dict | None:
        path = self.dir / f"{key}.json"
        if not path.exists():
            return None
        try:
            return json.loads(path.read_text())
        except json.JSONDecodeError:     # cannot happen with the atomic write; rerun it if so
            return None

    def save(self, key: str, row: dict) -> None:
        atomic_write(self.dir / f"{key}.json", json.dumps(jsonable(row)))


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` so that readers see the old file or the new one, never half."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@dataclass(frozen=True)
class Observations:
    """What a point is scored against: observed means and standard deviations (Eq. 10), and
    optionally the observed slip-weakening curves (Eq. 11)."""

    recurrence_s: float
    sigma_recurrence_s: float
    friction_drop: float
    sigma_friction_drop: float
    curves: pd.DataFrame | None = None
    assumed_sigma: bool = False        # σ not measured: 10 % of the mean, say so in the output


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


def _execute(tasks: list[PointTask], workers: int, scheduler: str | None, backend: str):
    """Yield ``(task, row)`` as points finish: in this process (1 worker), in a local pool, or
    on the Dask cluster at ``scheduler``. Every worker warms up first."""
    if not tasks:
        return
    if scheduler:
        from distributed import Client, as_completed
        with Client(scheduler) as client:
            client.run(_warm, tasks[0])
            futures = client.map(run_point, tasks, pure=False)
            index = {f.key: t for f, t in zip(futures, tasks)}
            for fut in as_completed(futures):
                yield index[fut.key], fut.result()
        return
    if workers == 1 or backend == "threads":
        _warm(tasks[0])
    if workers == 1:
        for t in tasks:
            yield t, run_point(t)
        return
    from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor, as_completed
    pool = (ProcessPoolExecutor(max_workers=workers, initializer=_warm, initargs=(tasks[0],))
            if backend == "processes" else ThreadPoolExecutor(max_workers=workers))
    with pool:
        futures = {pool.submit(run_point, t): t for t in tasks}
        for fut in as_completed(futures):
            yield futures[fut], fut.result()


def sweep(preset_name: str, law: str, b_values, lc_values, algorithm, obs: Observations,
          out, t_end: float | None = None, workers: int | None = None,
          scheduler: str | None = None, backend: str = "processes",
          curve_dt: float = 5e-5, wall_budget: float | None = None,
          progress: bool = True) -> SweepResult:
    """Run (or resume) the sweep over ``b_values`` × ``lc_values`` and score it against ``obs``.

    Finished points are read back from ``out`` and not run again. Returns the table (also
    written to ``out/sweep.csv``) and a summary (also ``out/summary.json``).
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers!r}")
    store = PointStore(out)
    need_curves = obs.curves is not None
    tasks = [PointTask(preset_name, law, float(b), float(lc), t_end, algorithm,
                       curve_dt if need_curves else None, wall_budget)
             for b in b_values for lc in lc_values]
    keys = [t.key() for t in tasks]
    rows = {k: store.load(k) for k in keys}
    todo = [t for t, k in zip(tasks, keys) if rows[k] is None]
    n_resumed = len(tasks) - len(todo)
    start = time.perf_counter()
    bar = tqdm(total=len(tasks), initial=n_resumed, desc=f"sweep {preset_name}/{law}",
               unit="point", disable=not progress)
    with bar:
        for task, row in _execute(todo, workers, scheduler, backend):
            key = task.key()
            store.save(key, row)
            rows[key] = row
            bar.update(1)
    wall = time.perf_counter() - start
    table = score(pd.DataFrame([rows[k] for k in keys]), obs)
    summary = summarize_sweep(table, obs, algorithm, wall_s=wall, n_run=len(todo),
                              n_resumed=n_resumed, workers=1 if scheduler else workers,
                              scheduler=scheduler, backend=backend)
    out = Path(out)
    atomic_write(out / "sweep.csv", table.to_csv(index=False))
    atomic_write(out / "summary.json", json.dumps(jsonable(summary), indent=2))
    return SweepResult(table, summary)


def score(points: pd.DataFrame, obs: Observations) -> pd.DataFrame:
    """Add J1 (and J2, J) and the regions to a table of simulated points."""
    for c in POINT_COLUMNS:
        if c not in points:
            points[c] = np.nan
    table = points[list(POINT_COLUMNS)].copy()
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
        # J2 only means something for a point that has a stick–slip cycle
        no_cycle = ~table.classification.isin(["stick-slip", "multiple recurrence"])
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
