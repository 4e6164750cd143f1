"""Observed order of convergence of the fixed-step methods on a stick–slip limit cycle.

Every non-adaptive registry entry (the ETD family) runs over a ladder of step factors f applied
to the paper's Δτcnst = 1e−5 and Δτmax = 0.01 together; its errors against the reference
(:mod:`benchmarks.errors`) are fitted by least squares, log(error) against log(Δτcnst). Only
points whose error is well above the reference's own uncertainty (``FLOOR_FACTOR`` × the two
reference solvers' disagreement) enter the fit, and of those the finest ``fit_points``: the
coarsest steps can be pre-asymptotic.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from benchmarks.errors import errors
from benchmarks.reference import reference
from benchmarks.timing import warm_up
from integrators import REGISTRY, solve

__all__ = ["observed_order", "convergence_study", "convergence_summary", "write_convergence",
           "CONVERGENCE_FACTORS", "FLOOR_FACTOR"]

CONVERGENCE_FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25, 0.125, 1 / 16, 1 / 32)
FLOOR_FACTOR = 100.0


def observed_order(steps, errors) -> float:
    """Least-squares slope of log(error) against log(step)."""
    steps, errors = np.asarray(steps, float), np.asarray(errors, float)
    if len(steps) < 2 or np.any(errors <= 0) or np.any(steps <= 0):
        raise ValueError(f"need >= 2 positive steps and errors, got {steps!r}, {errors!r}")
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def convergence_study(problem, names=None, factors=CONVERGENCE_FACTORS, fit_points: int = 4,
                      error: str = "err_recurrence", progress: bool = True):
    """Run the ladder; return ``(table, orders)``: one row per (method, factor) with a ``fitted``
    flag, and the observed order of each method (NaN if fewer than two points are usable)."""
    names = [n for n in REGISTRY if not REGISTRY[n].adaptive] if names is None else list(names)
    ref = reference(problem)
    floor = FLOOR_FACTOR * ref.agreement["max"]
    rows = []
    jobs = [(n, f) for n in names for f in sorted(factors, reverse=True)]
    for name, f in tqdm(jobs, desc="convergence", unit="run", disable=not progress):
        cls = REGISTRY[name]
        if cls.adaptive:
            raise ValueError(f"{name} is adaptive: its convergence is a work-precision question")
        d = cls()
        algorithm = cls(dtau_cnst=d.dtau_cnst * f, dtau_max=d.dtau_max * f)
        warm_up(problem, algorithm)
        sol = solve(problem, algorithm, save_every=problem.t_end / (len(ref.grid_t) - 1))
        rows.append({"problem": problem.name, "integrator": name, "factor": f,
                     "dtau_cnst": algorithm.dtau_cnst, "dtau_max": algorithm.dtau_max,
                     "retcode": sol.retcode.value, "wall_s": sol.stats.wall_s,
                     "nfev": sol.stats.nfev, "steps": sol.stats.steps, **errors(sol, ref),
                     "reference_agreement": ref.agreement["max"]})
    table = pd.DataFrame(rows)
    table["fitted"] = False
    orders = {}
    for name, g in table.groupby("integrator", sort=False):
        usable = g[(g.retcode == "Success") & (g[error] > floor)].sort_values("dtau_cnst")
        chosen = usable.head(fit_points)
        table.loc[chosen.index, "fitted"] = True
        orders[name] = (observed_order(chosen.dtau_cnst, chosen[error]) if len(chosen) >= 2
                        else float("nan"))
    return table, orders


def convergence_summary(problem, table: pd.DataFrame, orders: dict) -> dict:
    """What ``rsfbench convergence --json`` prints: observed and declared orders, the error at
    the finest step of each method, and the reference's own uncertainty."""
    finest = table.sort_values("dtau_cnst").groupby("integrator", sort=False).first()
    return {"problem": problem.name, "error": "err_recurrence", "orders": orders,
            "finest_error": finest["err_recurrence"].to_dict(),
            "declared": {n: {"order": REGISTRY[n].order, "stiff_order": REGISTRY[n].stiff_order}
                         for n in orders},
            "reference_agreement": float(table.reference_agreement.max())}


def write_convergence(problem, table: pd.DataFrame, orders: dict, out) -> dict:
    """Write ``convergence_<problem>.csv/.json/.png`` to ``out``; return the summary."""
    import json
    from pathlib import Path

    from benchmarks.report import jsonable as _jsonable
    from benchmarks.plots import plot_convergence
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = convergence_summary(problem, table, orders)
    stem = out / f"convergence_{problem.name.replace('/', '_')}"
    table.to_csv(stem.with_suffix(".csv"), index=False)
    stem.with_suffix(".json").write_text(json.dumps(_jsonable(summary), indent=2) + "\n")
    plot_convergence(table, orders, stem.with_suffix(".png"))
    return summary
