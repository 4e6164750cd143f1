"""What ``make reproduce`` runs: every generated file in ``results/``, from scratch, and
``results/REPORT.md`` assembling them.

Steps (about 35 minutes on a 2-core machine, ten of them scipy's RK45 in its wall budget):
integrator table; W1–W4 simulated under both laws (``simulate_<window>_<law>.json`` and the
windows table); the paper example; the reference solutions and their agreement; the speed-up
claim; the convergence study; the quick work-precision study; every backend side by side; the
Section 4 sweeps; the sweep's speed on 1 and 2 workers; last, when ``out`` is the project's
``results/``, the README's generated blocks (:mod:`benchmarks.readme`).
"""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.cli import simulate_summary
from benchmarks.compare import compare_integrators
from benchmarks.plots import plot_solution
from benchmarks.timing import warm_up
from benchmarks.windows import windows_table, write_windows
from integrators import ETD2, solve
from problems import WINDOWS, paper_example, window

__all__ = ["reproduce"]

COMPARE_RTOL = 1e-8          # the side-by-side comparison of every backend (issue 3)
COMPARE_WALL_BUDGET = 60.0   # s per solve: explicit methods crawl through the stick phase


def _section(title: str) -> None:
    print(f"\n== {title} ==", flush=True)


def reproduce(out: Path, scipy_budget: float | None = None) -> None:
    """Regenerate ``out`` (see the module docstring)."""
    from benchmarks.convergence import convergence_study, write_convergence
    from benchmarks.reference import agreement_table, reference
    from benchmarks.report import markdown_table, write_work_precision
    from benchmarks.speedup import DEFAULT_SCIPY_BUDGET, speedup, write_speedup
    from benchmarks.work_precision import QUICK, study_problems, work_precision

    out.mkdir(parents=True, exist_ok=True)
    report = {}
    _section("integrators")
    (out / "integrators.md").write_text(_integrators_markdown())
    report["integrators"] = (out / "integrators.md").read_text()

    _section("W1–W4 limit cycles (ETD2, both laws)")
    algorithm = ETD2()
    for name in WINDOWS:
        for law in ("slip", "aging"):
            problem = window(name, law)
            warm_up(problem, algorithm)
            summary = simulate_summary(solve(problem, algorithm))
            (out / f"simulate_{name}_{law}.json").write_text(json.dumps(summary, indent=2) + "\n")
    table = windows_table()
    write_windows(table, out)
    report["windows"] = (out / "windows.md").read_text()

    _section("paper example (Appendix 1.4)")
    problem = paper_example()
    warm_up(problem, algorithm)
    sol = solve(problem, algorithm, max_points=200_000)
    summary = simulate_summary(sol)
    (out / "paper_example.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot_solution(sol, out / "paper_example.png")
    plot_solution(solve(window("W2"), algorithm, max_points=200_000), out / "W2_slip.png")
    print(json.dumps(summary["limit_cycle"], indent=2))

    _section("reference solutions (two independent solvers, checked)")
    problems = study_problems("full")
    refs = [(p, reference(p, progress=False)) for p in problems]
    agreement = agreement_table(refs)
    agreement.to_csv(out / "references.csv", index=False)
    report["references"] = markdown_table(
        agreement.groupby(["problem"], sort=False).agg(
            solvers=("name", " & ".join), tol=("tol", "first"),
            recurrence_s=("recurrence_s", "first"), event=("event_index", "first"),
            max_disagreement=("max_disagreement", "first")).reset_index()
        .assign(max_disagreement=lambda d: d.max_disagreement.map("{:.2g}".format),
                recurrence_s=lambda d: d.recurrence_s.map("{:.10f}".format)))
    print(report["references"])

    _section("the paper's speed-up claim")
    budget = DEFAULT_SCIPY_BUDGET if scipy_budget is None else scipy_budget
    report["speedup"] = write_speedup(*speedup(problem, scipy_budget=budget), out)
    print(report["speedup"])

    _section("convergence of the fixed-step methods")
    c_summary = write_convergence(problem, *convergence_study(problem), out)
    report["convergence"] = "\n".join(
        f"* {n}: observed order {o:.2f}; error at the finest step "
        f"{c_summary['finest_error'][n]:.2g}" for n, o in c_summary["orders"].items()) + "\n"
    print(report["convergence"])

    _section("quick work-precision study")
    wp = work_precision(study_problems("quick"), QUICK)
    paths = write_work_precision(wp, out, "quick")
    report["work_precision"] = paths["pareto_md"].read_text()
    report["wp_figures"] = [p.name for k, p in paths.items() if k.startswith("png_")]
    print(report["work_precision"])
    from benchmarks.target import write_target
    write_target(paths["csv"], out)
    report["target"] = (out / "target_quick.md").read_text()

    _section(f"every integrator on the paper example, rtol = atol = {COMPARE_RTOL:g}")
    table = compare_integrators(paper_example(), COMPARE_RTOL, COMPARE_RTOL,
                                wall_budget=COMPARE_WALL_BUDGET)
    table.to_csv(out / "compare_paper_example.csv", index=False)
    (out / "compare_paper_example.md").write_text(_compare_markdown(table))
    report["compare"] = (out / "compare_paper_example.md").read_text()

    _section("Section 4: (b, Lc) sweeps around the published best fits")
    from benchmarks.paper_sweeps import paper_sweeps, sweep_scaling
    paper_sweeps(out, study_csv=out / "wp_quick.csv")
    report["sweeps"] = (out / "sweeps.md").read_text()
    print(report["sweeps"])

    _section("sweep speed: 21 x 21 on W2, serial and on 2 workers")
    sweep_scaling(out, study_csv=out / "wp_quick.csv")
    report["sweep_scaling"] = (out / "sweep_scaling.md").read_text()
    print(report["sweep_scaling"])

    (out / "REPORT.md").write_text(_report_markdown(report))
    print(f"\nwritten: {out / 'REPORT.md'}")
    from benchmarks.readme import ROOT, refresh
    if out.resolve() == (ROOT / "results").resolve():    # the README quotes these files
        stale = refresh()
        print(f"README blocks refilled: {', '.join(stale) or 'none changed'}")


def _report_markdown(r: dict) -> str:
    from benchmarks.provenance import provenance
    meta = provenance()
    figures = "\n".join(f"![{f}]({f})" for f in r["wp_figures"])
    return f"""# rsfbench report

Generated by `make reproduce` (`rsfbench reproduce --out results`) on {meta['date']}, commit
`{meta['git_commit']}`, {meta['cpu']} ({meta['n_cpus']} CPUs), Python {meta['python']},
numpy {meta['v_numpy']}, scipy {meta['v_scipy']}, numba {meta['v_numba']}. Every number below
is in a file of this directory, written by that command.

## Reference solutions (`references.csv`)

Each study problem is solved by two independent solvers at rtol = atol = 1e−12; their limit-cycle
metrics on the last complete event must agree to 1e−7 before either is used. Largest relative
disagreement per problem:

{r['references']}
## The paper's speed-up claim (`speedup.json`, `speedup.csv`)

{r['speedup']}
## Convergence of the fixed-step methods (`convergence_paper-example_slip.*`)

Relative error of the recurrence interval against the reference, least-squares slope over the
finest points above the reference's uncertainty:

{r['convergence']}
![convergence](convergence_paper-example_slip.png)

## Quick work-precision study (`wp_quick.csv`, `wp_quick_pareto.*`)

{r['work_precision']}
{figures}

## Issue 6's target: own integrators against compiled LSODA and SUNDIALS (`target_quick.*`)

{r['target']}
## Every integrator on the paper example at rtol = atol = 1e−8 (`compare_paper_example.*`)

{r['compare']}
## Section 4: (b, Lc) sweeps around the published best fits (`sweeps.*`, `sweeps/`)

{r['sweeps']}
Maps: `sweeps/<window>_<law>/maps.png`.

## Sweep speed (`sweep_scaling.*`)

{r['sweep_scaling']}
## W1–W4 limit cycles, ETD2 at the paper's settings (`windows.*`, `simulate_*.json`)

{r['windows']}
## The registry (`integrators.md`)

{r['integrators']}"""


def _integrators_markdown() -> str:
    import io
    from contextlib import redirect_stdout

    from benchmarks.cli import main
    buf = io.StringIO()
    with redirect_stdout(buf):
        main(["integrators", "--markdown"])
    return buf.getvalue()


def _compare_markdown(table) -> str:
    from benchmarks.report import fmt, markdown_table
    shown = table.assign(
        rtol=[fmt(x, "g") for x in table.rtol],
        wall_s=[fmt(x, ".3g") for x in table.wall_s],
        t_reached_s=[fmt(x, ".4g") for x in table.t_reached_s],
        recurrence_s=[fmt(x, ".8f") for x in table.recurrence_s],
        friction_drop=[fmt(x, ".7f") for x in table.friction_drop],
    )[["integrator", "version", "rtol", "retcode", "t_reached_s", "wall_s", "nfev", "njev",
       "steps", "n_events", "recurrence_s", "friction_drop"]]
    return markdown_table(shown)
