"""One run and the registry as data: the summary ``rsfbench simulate --json`` prints and the
table ``rsfbench integrators`` prints, shared by the command line and
:mod:`benchmarks.pipeline.reproduce`.
"""

from __future__ import annotations

import pandas as pd

from benchmarks.physics import metrics
from benchmarks.records.report import jsonable, markdown_table
from integrators import REGISTRY

__all__ = ["simulate_summary", "integrator_rows", "integrators_markdown"]


def simulate_summary(sol) -> dict:
    """The JSON summary of one run (the keys ``rsfbench simulate --json`` promises).

    Parameters
    ----------
    sol : Solution
        The run.

    Returns
    -------
    dict
        JSON-ready: the problem, method, retcode, counters, limit cycle and last event (SI).
    """
    lc = metrics.summarize(sol)
    p = sol.problem
    per_event = metrics.event_metrics(sol.events, p.normal_force)
    # the last event of a run that reached its end (a failed run's events are not physics)
    last = per_event.iloc[-1].to_dict() if len(per_event) and sol.reached_end else {}
    return jsonable({
        "problem": p.name, "law": p.law.name, "b": p.law.b, "lc_m": p.law.lc, "t_end": p.t_end,
        "integrator": sol.algorithm.name, "options": sol.algorithm.options(),
        "retcode": sol.retcode.value, "message": sol.message,
        "wall_s": sol.stats.wall_s, "steps": sol.stats.steps, "nfev": sol.stats.nfev,
        "njev": sol.stats.njev, "n_events": len(sol.events),
        "limit_cycle": lc.as_dict(),
        "last_event": {k: float(v) for k, v in last.items()},
    })


def integrator_rows() -> list[dict]:
    """One row per registry entry, by name (case-insensitive): family, orders, library."""
    return [{"name": name, "family": cls.family, "order": cls.order,
             "stiff_order": cls.order if cls.stiff_order is None else cls.stiff_order,
             "adaptive": cls.adaptive, "stiff": cls.stiff, "library": cls.library,
             "version": cls.library_version()}
            for name, cls in sorted(REGISTRY.items(), key=lambda kv: kv[0].lower())]


def integrators_markdown() -> str:
    """The registry as a Markdown table (``results/integrators.md``)."""
    return markdown_table(pd.DataFrame(integrator_rows()))
