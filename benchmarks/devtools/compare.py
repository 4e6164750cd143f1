"""Every registry entry on one problem, side by side: cost, outcome and limit-cycle metrics.

Adaptive methods run at the given rtol/atol, fixed-step ones at their documented defaults (the
paper's settings for ETD). Each is warmed up first (numba compilation is not timed) and limited
by a wall-time budget: explicit methods crawl through the stiff stick phase, and a budget that
runs out is a recorded result (retcode ``WallTime``, the simulated time reached), not a crash.
"""

from __future__ import annotations

import pandas as pd
from tqdm.auto import tqdm

from benchmarks.devtools.timing import warm_up
from benchmarks.physics.metrics import event_metrics
from benchmarks.records.report import fmt, markdown_table
from integrators import REGISTRY, solve

__all__ = ["compare_integrators", "compare_markdown"]


def compare_integrators(problem, rtol: float, atol: float, names=None,
                        wall_budget: float = 120.0, progress: bool = True) -> pd.DataFrame:
    """One row per integrator: retcode, wall time, counters, the last event's metrics (only for
    a run that reached its end: a failed run's events are not physics).

    Parameters
    ----------
    problem : SpringSlider
        The problem every method solves.
    rtol, atol : float
        The tolerances of the adaptive methods (a fixed-step one runs at its defaults).
    names : list of str, optional
        Registry names; ``None`` takes every registered method.
    wall_budget : float
        Each run's wall-time budget (s).
    progress : bool
        Show a progress bar.

    Returns
    -------
    pandas.DataFrame
        Columns integrator, library, version, rtol, retcode, t_reached_s (s), wall_s (s),
        nfev, njev, steps, n_events, recurrence_s (s), friction_drop (dimensionless), message.

    Raises
    ------
    KeyError
        For a name not in the registry.
    """
    rows = []
    names = sorted(REGISTRY, key=str.lower) if names is None else names
    for name in tqdm(names, desc=problem.name, disable=not progress):
        cls = REGISTRY[name]
        algorithm = cls(rtol=rtol, atol=atol) if cls.adaptive else cls()
        warm_up(problem, algorithm)
        sol = solve(problem, algorithm, max_points=2, wall_budget=wall_budget)
        m = event_metrics(sol.events, problem.normal_force)
        last = m.iloc[-1] if len(m) and sol.success else None     # a failed run is no physics
        rows.append({
            "integrator": name, "library": cls.library, "version": cls.library_version(),
            "rtol": rtol if cls.adaptive else None, "retcode": sol.retcode.value,
            "t_reached_s": sol.t_reached, "wall_s": sol.stats.wall_s, "nfev": sol.stats.nfev,
            "njev": sol.stats.njev, "steps": sol.stats.steps, "n_events": len(sol.events),
            "recurrence_s": None if last is None else last.recurrence_s,
            "friction_drop": None if last is None else last.friction_drop,
            "message": sol.message,
        })
    return pd.DataFrame(rows)


def compare_markdown(table: pd.DataFrame) -> str:
    """The table of :func:`compare_integrators` in Markdown (``compare_<problem>.md``)."""
    shown = table.assign(
        rtol=[fmt(x, "g") for x in table.rtol],
        wall_s=[fmt(x, ".3g") for x in table.wall_s],
        t_reached_s=[fmt(x, ".4g") for x in table.t_reached_s],
        recurrence_s=[fmt(x, ".8f") for x in table.recurrence_s],
        friction_drop=[fmt(x, ".7f") for x in table.friction_drop],
    )[["integrator", "version", "rtol", "retcode", "t_reached_s", "wall_s", "nfev", "njev",
       "steps", "n_events", "recurrence_s", "friction_drop"]]
    return markdown_table(shown)
