"""What a binding adds to SUNDIALS: the same solver called from Python and from compiled code.

For each SUNDIALS solver, the project's Python-bound backends (scikits-odes, scikit-sundae,
assimulo; each with the compiled and with the plain-Python right-hand side) against the backend
that calls the system SUNDIALS from C with numba ``cfunc`` callbacks (:mod:`integrators.external.
sundials_c`), on the paper example and W2 under the aging law, at the same tolerances, in one
run: the minimum wall time over ``repeats`` solves after a warm-up (``max_points=2``), the steps
each took (the same method should take about the same steps: different SUNDIALS versions and
root-finding details make them differ by a few per cent) and the ratio of the bound call's time
to the compiled one's. A ratio is the binding's overhead only when the steps agree; the table
shows both.

``write_binding_overhead(out)`` writes ``binding_overhead.csv`` (every run) and
``binding_overhead.md``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from benchmarks.files import atomic_write
from integrators import REGISTRY, UNAVAILABLE, solve
from problems import paper_example, window

__all__ = ["PAIRS", "TOLERANCES", "binding_overhead", "binding_overhead_markdown",
           "write_binding_overhead"]

#: compiled backend → the Python-bound backends of the same SUNDIALS solver
PAIRS = {
    "sundials-CVODE-BDF": ("odes-CVODE-BDF", "sundae-CVODE", "assimulo-CVode"),
    "sundials-CVODE-Adams": ("odes-CVODE-Adams",),
    "sundials-IDA": ("odes-IDA", "sundae-IDA", "assimulo-IDA"),
}
TOLERANCES = (1e-6, 1e-8)


def _problems():
    return {"paper-example": paper_example(), "W2/aging": window("W2", "aging")}


def _timed(problem, algorithm, repeats: int):
    solve(problem, algorithm, max_points=2)                  # warm-up: caches, imports
    runs = [solve(problem, algorithm, max_points=2) for _ in range(repeats)]
    return min(r.stats.wall_s for r in runs), runs[-1]


def binding_overhead(repeats: int = 3, tolerances=TOLERANCES) -> pd.DataFrame:
    """One row per (problem, tolerance, backend, rhs tier): wall (min), counters, retcode, and
    the compiled backend's wall and steps at the same setting."""
    rows = []
    for pname, problem in _problems().items():
        for tol in tolerances:
            for compiled, bound in PAIRS.items():
                if compiled in UNAVAILABLE:
                    continue
                c_wall, c_sol = _timed(problem, REGISTRY[compiled](rtol=tol, atol=tol), repeats)
                for name in (compiled, *bound):
                    if name in UNAVAILABLE:
                        continue
                    for tier in REGISTRY[name].rhs_tiers:
                        wall, sol = ((c_wall, c_sol) if name == compiled else
                                     _timed(problem, REGISTRY[name](rtol=tol, atol=tol, rhs=tier),
                                            repeats))
                        s = sol.stats
                        rows.append(dict(problem=pname, tol=tol, solver=compiled, backend=name,
                                         rhs=tier, retcode=sol.retcode.value, wall_s=wall,
                                         steps=s.steps, nfev=s.nfev, njev=s.njev,
                                         compiled_wall_s=c_wall, compiled_steps=c_sol.stats.steps,
                                         overhead=wall / c_wall))
    return pd.DataFrame(rows)


def binding_overhead_markdown(table: pd.DataFrame, repeats: int) -> str:
    lines = ["# Binding overhead: SUNDIALS called from Python against SUNDIALS called from C", "",
             f"`rsfbench binding-overhead` (min of {repeats} after a warm-up, `max_points=2`, one "
             "run). Overhead = the bound backend's wall time / the compiled backend's, same "
             "solver, problem and tolerance; a ratio means the binding's cost only where the "
             "steps agree.", "",
             "| problem | tol | solver (compiled) | backend | rhs | wall (ms) | steps | compiled "
             "(ms) | compiled steps | overhead |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    bound = table[table.backend != table.solver]
    for r in bound.itertuples():
        lines.append(f"| {r.problem} | {r.tol:.0e} | {r.solver} | {r.backend} | {r.rhs} | "
                     f"{r.wall_s * 1e3:.3g} | {r.steps} | {r.compiled_wall_s * 1e3:.3g} | "
                     f"{r.compiled_steps} | {r.overhead:.3g} |")
    return "\n".join(lines) + "\n"


def write_binding_overhead(out: Path | None, repeats: int = 3) -> tuple[pd.DataFrame, str]:
    """Measure; write ``binding_overhead.csv`` and ``.md`` in ``out`` (if given)."""
    table = binding_overhead(repeats)
    text = binding_overhead_markdown(table, repeats)
    if out is not None:
        atomic_write(Path(out) / "binding_overhead.csv", table.to_csv(index=False))
        atomic_write(Path(out) / "binding_overhead.md", text)
    return table, text
