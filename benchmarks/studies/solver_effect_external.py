"""Does the choice of solver change what is inferred on problems nobody here chose?

The rule of :mod:`benchmarks.inversion.solver_effect` on the external problems
(:mod:`problems.external`: Im et al.'s stick-slip slider, run for :data:`IM_T_END` s — their
2 s hold 4 events, too few for a cycle's means — and NIED's 4-m apparatus), beside the paper's
windows of ``rsfbench study solver-effect``. The data of each: the reference's (Rodas5P
at rtol = atol = 1e−9) mean recurrence interval ΔT̄ and friction drop Δμ̄ at the problem's own
(b, Lc), plus Gaussian noise of σ = ``sigma`` of each (seed 0): 1 % by default, ten times as
precise as the windows' assumed 10 % (a precise record moves the posterior most per solver
error). The prior is uniform in (b, log10 Lc) on b ± (b − a)/2 and Lc ÷ 10 to × 10 about the
problem's values. The candidates are the quick ones (the own methods' front settings and ETD2
at the paper's Δτ rule, :data:`~benchmarks.inversion.solver_effect.QUICK_LADDERS`) on ``n`` ×
``n`` grids. The question: is the setting the windows recommend indistinguishable here too?
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import pandas as pd

from benchmarks.inversion.misfit import synthetic
from benchmarks.inversion.solver_effect import (MIN_OVERLAP, QUICK_LADDERS, SHIFT_SD,
                                                candidates, recommendation, solver_effect)
from benchmarks.physics.metrics import CYCLES, summarize
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import fmt, markdown_table
from benchmarks.studies.study import Study
from integrators import Exprb43, Rodas5P, solve
from problems.external import im_spring_slider, nied_4m

__all__ = ["STUDY", "external_data"]

#: s of Im et al.'s slider simulated: 20 events of a settled cycle (ΔT ≈ 0.5 s)
IM_T_END = 10.0
#: the reference and the floor of the comparison (as the windows' study)
REFERENCE, FLOOR = Rodas5P(rtol=1e-9, atol=1e-9), Exprb43(rtol=1e-9, atol=1e-9)


def external_data(problem, sigma: float, seed: int = 0):
    """``(observations, box)``: the reference's ΔT̄ and Δμ̄ of ``problem`` with noise of
    ``sigma`` (a fraction of each) and the prior box about its (b, Lc) (module docstring);
    ValueError when the reference finds no limit cycle."""
    cycle = summarize(solve(problem, REFERENCE, max_points=2))
    if cycle.classification not in CYCLES:
        raise ValueError(f"{problem.name}: the reference finds {cycle.classification}, no "
                         "limit cycle to observe")
    law = problem.law
    half = (law.b - law.a) / 2
    box = ((law.b - half, law.b + half), (law.lc / 10, law.lc * 10))
    return synthetic(cycle.recurrence_s, cycle.friction_drop, sigma, seed), box


def run(out: Path, n: int, sigma: float) -> None:
    started, tables, notes = time.perf_counter(), [], []
    chosen = candidates(None, QUICK_LADDERS, etd_factors=(1,))
    for label, problem in (("im/stick-slip", im_spring_slider("stick-slip", IM_T_END)),
                           ("nied/fb03-087", nied_4m())):
        obs, box = external_data(problem, sigma)
        print(f"{label}: ΔT̄ = {obs.recurrence_s:.6g} s, Δμ̄ = {obs.friction_drop:.5g} "
              f"(σ {sigma:.0%}); b {box[0][0]:.5g}..{box[0][1]:.5g}, "
              f"Lc {box[1][0]:.3g}..{box[1][1]:.3g} m", flush=True)
        tables.append(solver_effect(
            chosen, REFERENCE, FLOOR, windows=(), laws=(), n=n,
            progress=lambda text: print(f"  {text}", flush=True), yours=obs,
            own=(label, problem, box)))
        notes += _refusals(label, problem, chosen, tables[-1])
    table = pd.concat(tables, ignore_index=True)
    advice = recommendation(table)
    write_table(table, out / "solver_effect_external.csv")
    write_output(out / "solver_effect_external.md",
                 _markdown(table, advice, n, sigma, time.perf_counter() - started)
                 + "".join(f"\n{line}\n" for line in notes))
    print(report(out))


def _refusals(label: str, problem, chosen, table) -> list[str]:
    """A line for each candidate that failed at every node it solved, with why: one solve of
    the problem itself says (a method that refuses the problem, say)."""
    lines = []
    for c in chosen:
        row = table[table.setting == c.label]
        if len(row) and row.n_cycle_nodes.iloc[0] == 0 and row.n_failed.iloc[0] > 0:
            try:
                sol = solve(problem, c.algorithm, max_points=2, wall_budget=5.0)
                why = sol.message or sol.retcode.value
            except ValueError as exc:          # ProblemNotSupported is one
                why = str(exc)
            lines.append(f"{c.label} failed at every node of {label}: {why}")
    return lines


def _markdown(table, advice, n: int, sigma: float, wall: float) -> str:
    rows = table[["window", "setting", "family", "wall_per_solve_ms", "mean_shift_b_sd",
                  "mean_shift_log10_lc_sd", "overlap", "overlap_box", "n_failed",
                  "indistinguishable", "resolved"]].rename(columns={"window": "problem"})
    rows = rows.assign(**{c: [fmt(x, ".3g") for x in rows[c]] for c in (
        "wall_per_solve_ms", "mean_shift_b_sd", "mean_shift_log10_lc_sd", "overlap",
        "overlap_box")})
    best = advice.rename(columns={"window": "problem"}).drop(columns=["law", "data"])
    return ("# The solver's effect on the inferred (b, Lc): the external problems\n\n"
            + _plain(__doc__.split("\n\n")[1]) + "\n\n"
            f"Data: σ = {sigma:.0%} of each mean; grids {n}×{n} over the zoom where the "
            f"reference's posterior lives and {max(n // 2, 5)}×{max(n // 2, 5)} over the whole "
            f"box. **Indistinguishable**: both posterior means within {SHIFT_SD:g} reference sd "
            f"and overlap ≥ {MIN_OVERLAP:g} on the zoom and on the box; **resolved**: the floor "
            f"(Exprb43 at 1e−9) is indistinguishable. Wall time of the study: {wall / 60:.1f} "
            "min.\n\n## The cheapest indistinguishable setting\n\n"
            + markdown_table(best, floatfmt=".3g")
            + "\n\n## Every setting\n\n" + markdown_table(rows) + "\n")


def _plain(text: str) -> str:
    """A docstring's paragraph as Markdown: one line, the roles' targets as code."""
    text = re.sub(r":\w+:`~?([\w.]+)`", lambda m: f"`{m.group(1).split('.')[-1]}`", text)
    return " ".join(text.replace("``", "`").split())


def report(out: Path) -> str:
    text = (out / "solver_effect_external.md").read_text(encoding="utf-8")
    return text.split("\n## ", 1)[1].split("\n", 1)[1].split("\n## ")[0]


STUDY = Study("solver-effect-external", "The solver's effect on the inferred (b, Lc) on the "
              "external problems (`solver_effect_external.*`)", 225, run, report=report,
              plan="full", timed=True, settings={"n": 31, "sigma": 0.01},
              limits={"n": (5, 101), "sigma": (1e-4, 0.5)},
              writes=("solver_effect_external.csv", "solver_effect_external.md"), minutes=8)
