"""What a binding adds: the same solver called from Python and from compiled code.

For each SUNDIALS solver, the project's Python-bound backends (scikits-odes, scikit-sundae,
assimulo; each with the compiled and with the plain-Python right-hand side) against the backend
that calls the system SUNDIALS from C with numba ``cfunc`` callbacks (:mod:`integrators.external.
sundials_c`); for LSODA, numbalsoda's compiled call with events located to the last bit against
its plain call over an output grid and against ODEPACK's Fortran LSODA(R) stepped from Python
(scipy, assimulo: the same algorithm, another code). On the paper example and W2 under the aging
law, at the same tolerances, in one run: the minimum wall time over ``repeats`` solves after a
warm-up (``max_points=2``), the steps each took and the ratio of its time to the compiled
reference's. A ratio is a binding's overhead only when both runs succeeded and took about the
same steps (different SUNDIALS versions and root-finding details make them differ by a few per
cent; CVODE's error-test failures on W2 end runs at different times); otherwise it is left out
and the table says why.

``write_binding_overhead(out)`` writes ``binding_overhead.csv`` (every run) and
``binding_overhead.md``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from tqdm.auto import tqdm

from benchmarks.records.files import atomic_write
from benchmarks.studies.study import Study, markdown_file
from integrators import REGISTRY, solve
from problems import paper_example, window

__all__ = ["STUDY", "PAIRS", "TOLERANCES", "binding_overhead", "binding_overhead_markdown",
           "write_binding_overhead"]

#: compiled backend → the Python-bound backends of the same SUNDIALS solver
PAIRS = {
    "sundials-CVODE-BDF": ("odes-CVODE-BDF", "sundae-CVODE", "assimulo-CVode"),
    "sundials-CVODE-Adams": ("odes-CVODE-Adams",),
    "sundials-IDA": ("odes-IDA", "sundae-IDA", "assimulo-IDA"),
    "numbalsoda-LSODA": ("numbalsoda-LSODA-grid", "scipy-LSODA", "assimulo-LSODAR"),
}
#: s per solve: a run that takes longer ends with WallTime
WALL_BUDGET = 30.0
#: a ratio is shown only where the steps differ by less than this factor
STEPS_AGREE = 1.25
TOLERANCES = (1e-6, 1e-8)


def _problems():
    return {"paper-example": paper_example(), "W2/aging": window("W2", "aging")}


def _timed(problem, algorithm, repeats: int):
    """Min wall over ``repeats`` solves after a warm-up; one solve if the warm-up failed."""
    def run():
        return solve(problem, algorithm, max_points=2, wall_budget=WALL_BUDGET)
    first = run()                                            # warm-up: caches, imports
    runs = [run() for _ in range(repeats)] if first.success else [first]
    return min(r.stats.wall_s for r in runs), runs[-1]


def _overhead(sol, wall: float, ref, ref_wall: float) -> float:
    """wall / ref_wall where both succeeded with about the same steps, else NaN."""
    if not (sol.success and ref.success):
        return float("nan")
    steps = sorted((max(sol.stats.steps, 1), max(ref.stats.steps, 1)))
    return wall / ref_wall if steps[1] < STEPS_AGREE * steps[0] else float("nan")


def _why_not(r) -> str:
    if r.retcode != "Success" or r.compiled_retcode != "Success":
        return f"— ({r.retcode} / compiled {r.compiled_retcode})"
    return f"— (steps differ: {r.steps} / {r.compiled_steps})"


def binding_overhead(repeats: int = 3, tolerances=TOLERANCES, progress: bool = True
                     ) -> pd.DataFrame:
    """One row per (problem, tolerance, backend, rhs tier): wall (min), counters, retcode, and
    the compiled reference's wall, steps and retcode at the same setting."""
    jobs = [(pname, problem, tol, compiled, name, tier)
            for pname, problem in _problems().items() for tol in tolerances
            for compiled, others in PAIRS.items() if compiled in REGISTRY
            for name in (compiled, *others) if name in REGISTRY
            for tier in REGISTRY[name].rhs_tiers]
    rows, ref = [], {}
    for pname, problem, tol, compiled, name, tier in tqdm(jobs, desc="binding-overhead",
                                                           unit="run", disable=not progress):
        wall, sol = _timed(problem, REGISTRY[name](rtol=tol, atol=tol, rhs=tier), repeats)
        if name == compiled:
            ref[pname, tol, compiled] = wall, sol
            continue
        c_wall, c_sol = ref[pname, tol, compiled]
        s = sol.stats
        rows.append(dict(problem=pname, tol=tol, solver=compiled, backend=name, rhs=tier,
                         retcode=sol.retcode.value, wall_s=wall, steps=s.steps, nfev=s.nfev,
                         njev=s.njev, compiled_retcode=c_sol.retcode.value,
                         compiled_wall_s=c_wall, compiled_steps=c_sol.stats.steps,
                         overhead=_overhead(sol, wall, c_sol, c_wall)))
    return pd.DataFrame(rows)


def binding_overhead_markdown(table: pd.DataFrame, repeats: int) -> str:
    """The table, and per solver the range of the ratios that mean a binding's cost."""
    lines = ["# What a way of calling costs: the same solver called from Python and compiled", "",
             f"`rsfbench study binding-overhead` (min of {repeats} solves after a warm-up, "
             "`max_points=2`, one run). Ratio = this way's wall time / the compiled reference's, "
             "same solver, problem and tolerance; shown only where both succeeded and took about "
             f"the same steps (within {STEPS_AGREE:g}×). LSODA's references are numbalsoda's "
             "compiled call; scipy and assimulo step ODEPACK's Fortran LSODA(R) from Python (the "
             "same algorithm, another code), the grid call is numbalsoda's own, plain.", ""]
    other = table
    keys = ["solver", "backend", "rhs"]
    summary = (other.dropna(subset=["overhead"]).groupby(keys).overhead
               .agg(["min", "max", "count"]).reset_index())
    order = other[keys].drop_duplicates().reset_index(drop=True).reset_index()
    summary = summary.merge(order, on=keys).sort_values("index")
    lines += ["| compiled reference | other way | rhs | ratio (min–max) | settings |",
              "|---|---|---|---|---|"]
    for r in summary.itertuples():
        lines.append(f"| {r.solver} | {r.backend} | {r.rhs} | {r.min:.3g}–{r.max:.3g} | "
                     f"{r.count} |")
    lines += ["", "| problem | tol | compiled reference | ms | steps | other way | rhs | ms | "
              "steps | ratio |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in other.itertuples():
        ratio = f"{r.overhead:.3g}" if pd.notna(r.overhead) else _why_not(r)
        lines.append(f"| {r.problem} | {r.tol:.0e} | {r.solver} | "
                     f"{r.compiled_wall_s * 1e3:.3g} | {r.compiled_steps} | {r.backend} | "
                     f"{r.rhs} | {r.wall_s * 1e3:.3g} | {r.steps} | {ratio} |")
    return "\n".join(lines) + "\n"


def write_binding_overhead(out: Path | None, repeats: int = 3, progress: bool = True
                           ) -> tuple[pd.DataFrame, str]:
    """Measure; write ``binding_overhead.csv`` and ``.md`` in ``out`` (if given)."""
    table = binding_overhead(repeats, progress=progress)
    text = binding_overhead_markdown(table, repeats)
    if out is not None:
        atomic_write(Path(out) / "binding_overhead.csv", table.to_csv(index=False))
        atomic_write(Path(out) / "binding_overhead.md", text)
    return table, text


def run(out: Path, repeats: int) -> None:
    print(write_binding_overhead(out, repeats, progress=False)[1])


STUDY = Study("binding-overhead", "What a way of calling costs (`binding_overhead.*`)", 190, run,
              report=markdown_file("binding_overhead.md"), plan="full", timed=True,
              settings={"repeats": 3}, limits={"repeats": (1, 100)},
              writes=("binding_overhead.csv", "binding_overhead.md"), minutes=6)
