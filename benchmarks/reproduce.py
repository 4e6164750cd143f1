"""What ``make reproduce`` runs: every generated file in ``results/``, from scratch, and
``results/REPORT.md`` assembling them.

Steps (about an hour and a half on a 2-core machine; ten minutes of it are scipy's RK45 in its wall
budget, half an hour the full study behind issue 6's target): integrator table; W1–W4 simulated
under both laws (``simulate_<window>_<law>.json`` and the windows table); the paper example; the
reference solutions and their agreement; the speed-up claim; the convergence study and the
fixed-step order of the compiled stiff methods; the quick work-precision study and issue 6's
target; the target on every study problem (a full work-precision study of the stiff adaptive
integrators); every backend side by side; the Section 4 sweeps; the sweep's speed on 1 and 2
workers; the locking rule of the classification against the trajectory; the ETD family's
step-rule check on the studied problems; what J2 sees; the reliability probe;
last, when ``out`` is the project's ``results/``, the README's generated blocks
(:mod:`benchmarks.readme`).
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


def _integrators(out: Path, scipy_budget) -> None:
    (out / "integrators.md").write_text(_integrators_markdown())


def _windows(out: Path, scipy_budget) -> None:
    algorithm = ETD2()
    for name in WINDOWS:
        for law in ("slip", "aging"):
            problem = window(name, law)
            warm_up(problem, algorithm)
            summary = simulate_summary(solve(problem, algorithm))
            (out / f"simulate_{name}_{law}.json").write_text(json.dumps(summary, indent=2) + "\n")
    write_windows(windows_table(), out)


def _paper_example(out: Path, scipy_budget) -> None:
    algorithm, problem = ETD2(), paper_example()
    warm_up(problem, algorithm)
    sol = solve(problem, algorithm, max_points=200_000)
    summary = simulate_summary(sol)
    (out / "paper_example.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot_solution(sol, out / "paper_example.png")
    plot_solution(solve(window("W2"), algorithm, max_points=200_000), out / "W2_slip.png")
    print(json.dumps(summary["limit_cycle"], indent=2))


def _references(out: Path, scipy_budget) -> None:
    from benchmarks.reference import agreement_table, reference
    from benchmarks.work_precision import study_problems
    refs = [(p, reference(p, progress=False)) for p in study_problems("full")]
    agreement_table(refs).to_csv(out / "references.csv", index=False)


def _speedup(out: Path, scipy_budget) -> None:
    from benchmarks.speedup import DEFAULT_SCIPY_BUDGET, speedup, write_speedup
    budget = DEFAULT_SCIPY_BUDGET if scipy_budget is None else scipy_budget
    print(write_speedup(*speedup(paper_example(), scipy_budget=budget), out))


def _convergence(out: Path, scipy_budget) -> None:
    from benchmarks.convergence import convergence_study, write_convergence
    problem = paper_example()
    write_convergence(problem, *convergence_study(problem), out)


def _fixed_steps(out: Path, scipy_budget) -> None:
    from benchmarks.convergence import fixed_step_orders, write_fixed_step_orders
    write_fixed_step_orders(*fixed_step_orders(progress=False), out)


def _work_precision(out: Path, scipy_budget) -> None:
    from benchmarks.report import write_work_precision
    from benchmarks.target import write_target
    from benchmarks.work_precision import QUICK, study_problems, work_precision
    paths = write_work_precision(work_precision(study_problems("quick"), QUICK), out, "quick")
    write_target(paths["csv"], out)


def _target_full(out: Path, scipy_budget) -> None:
    from benchmarks.target import full_target, target_markdown
    print(target_markdown(full_target(out)))


def _compare(out: Path, scipy_budget) -> None:
    table = compare_integrators(paper_example(), COMPARE_RTOL, COMPARE_RTOL,
                                wall_budget=COMPARE_WALL_BUDGET)
    table.to_csv(out / "compare_paper_example.csv", index=False)
    (out / "compare_paper_example.md").write_text(_compare_markdown(table))


def _sweeps(out: Path, scipy_budget) -> None:
    from benchmarks.paper_sweeps import paper_sweeps
    paper_sweeps(out, study_csv=out / "wp_quick.csv")


def _sweep_scaling(out: Path, scipy_budget) -> None:
    from benchmarks.paper_sweeps import sweep_scaling
    sweep_scaling(out, study_csv=out / "wp_quick.csv")


def _classification(out: Path, scipy_budget) -> None:
    from benchmarks.classification import classification_study, write_classification
    print(write_classification(classification_study(), out))


def _etd_validity(out: Path, scipy_budget) -> None:
    from benchmarks.etd_validity import etd_validity, write_etd_validity
    print(write_etd_validity(etd_validity(), out))


def _misfit(out: Path, scipy_budget) -> None:
    from benchmarks.misfit import j2_information, write_j2_information
    print(write_j2_information(j2_information(), out))


def _probe(out: Path, scipy_budget) -> None:
    from benchmarks.probe import run_probe, write_probe
    from benchmarks.probe_cases import cases
    print(write_probe(run_probe(cases()), out))


#: the steps in order: (name for --from, title, function(out, scipy_budget))
STEPS = (
    ("integrators", "integrators", _integrators),
    ("windows", "W1–W4 limit cycles (ETD2, both laws)", _windows),
    ("paper-example", "paper example (Appendix 1.4)", _paper_example),
    ("references", "reference solutions (two independent solvers, checked)", _references),
    ("speedup", "the paper's speed-up claim", _speedup),
    ("convergence", "convergence of the fixed-step methods", _convergence),
    ("fixed-steps", "fixed-step order of the compiled stiff methods (stiff segment, control "
                    "off)", _fixed_steps),
    ("work-precision", "quick work-precision study and issue 6's target", _work_precision),
    ("target-full", "issue 6's target on every study problem (full work-precision study of the "
                    "stiff adaptive integrators)", _target_full),
    ("compare", f"every integrator on the paper example, rtol = atol = {COMPARE_RTOL:g}",
     _compare),
    ("sweeps", "Section 4: (b, Lc) sweeps around the published best fits", _sweeps),
    ("sweep-scaling", "sweep speed: 21 x 21 on W2, serial and on 2 workers", _sweep_scaling),
    ("classification", "the locking rule of stick-slip, against the trajectory",
     _classification),
    ("etd-validity", "the ETD family's step-rule check on the studied problems", _etd_validity),
    ("misfit", "what J2 sees: friction against the spring force", _misfit),
    ("probe", "the reliability probe, slow cases included", _probe),
)
STEP_NAMES = tuple(name for name, _, _ in STEPS)


def reproduce(out: Path, scipy_budget: float | None = None, start: str | None = None,
              only: str | None = None) -> None:
    """Regenerate ``out`` (see the module docstring); with ``start``, only that step and the ones
    after it; with ``only``, that step alone (the files of the other steps must be there:
    REPORT.md reads them all)."""
    for what, name in (("start", start), ("only", only)):
        if name is not None and name not in STEP_NAMES:
            raise ValueError(f"unknown step {what}={name!r}: expected one of "
                             f"{', '.join(STEP_NAMES)}")
    out.mkdir(parents=True, exist_ok=True)
    first = STEP_NAMES.index(only or start) if (only or start) else 0
    last = first + 1 if only else len(STEPS)
    for name, title, step in STEPS[first:last]:
        _section(title)
        step(out, scipy_budget)
    (out / "REPORT.md").write_text(_report_markdown(_collect(out)))
    print(f"\nwritten: {out / 'REPORT.md'}")
    from benchmarks.readme import ROOT, refresh
    if out.resolve() == (ROOT / "results").resolve():    # the README quotes these files
        stale = refresh()
        print(f"README blocks refilled: {', '.join(stale) or 'none changed'}")


def _collect(out: Path) -> dict:
    """The pieces of REPORT.md, read from the files the steps wrote."""
    import pandas as pd

    from benchmarks.report import markdown_table

    def read(name: str, step: str) -> str:
        path = out / name
        if not path.exists():
            raise FileNotFoundError(f"{path} is missing: run `rsfbench reproduce --only {step}`")
        return path.read_text()

    read("references.csv", "references")
    agreement = pd.read_csv(out / "references.csv")
    c_summary = json.loads(read("convergence_paper-example_slip.json", "convergence"))
    return {
        "integrators": read("integrators.md", "integrators"),
        "windows": read("windows.md", "windows"),
        "references": markdown_table(
            agreement.groupby(["problem"], sort=False).agg(
                solvers=("name", " & ".join), tol=("tol", "first"),
                recurrence_s=("recurrence_s", "first"), event=("event_index", "first"),
                max_disagreement=("max_disagreement", "first")).reset_index()
            .assign(max_disagreement=lambda d: d.max_disagreement.map("{:.2g}".format),
                    recurrence_s=lambda d: d.recurrence_s.map("{:.10f}".format))),
        "speedup": read("speedup.md", "speedup"),
        "convergence": "\n".join(
            f"* {n}: observed order {o:.2f}; error at the finest step "
            f"{c_summary['finest_error'][n]:.2g}" for n, o in c_summary["orders"].items()) + "\n",
        "fixed_steps": read("convergence_fixed_steps.md", "fixed-steps"),
        "work_precision": read("wp_quick_pareto.md", "work-precision"),
        "wp_figures": sorted(p.name for p in out.glob("wp_quick_*.png")),
        "target": read("target_quick.md", "work-precision"),
        "target_full": read("target_full.md", "target-full"),
        "compare": read("compare_paper_example.md", "compare"),
        "sweeps": read("sweeps.md", "sweeps"),
        "sweep_scaling": read("sweep_scaling.md", "sweep-scaling"),
        "classification": read("classification.md", "classification"),
        "reliability": read("reliability.md", "probe"),
        "misfit": read("j2_information.md", "misfit"),
        "etd_validity": read("etd_validity.md", "etd-validity"),
    }


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

## Order of the compiled stiff methods (`convergence_fixed_steps.*`)

Equal steps with the error control off on the paper example's stick phase, τ ∈ [5, 9] (stiff:
hD/w up to 1e7); the error of the state at the end against scipy Radau at 1e−13:

{r['fixed_steps']}
![fixed-step orders](convergence_fixed_steps.png)

## Quick work-precision study (`wp_quick.csv`, `wp_quick_pareto.*`)

{r['work_precision']}
{figures}

## Issue 6's target: own integrators against compiled LSODA and SUNDIALS

On the quick study's two problems (`target_quick.*`, from `wp_quick.csv`):

{r['target']}
On every study problem (`target_full.*`, from `wp_full.csv`: the stiff adaptive integrators of
the three sides on the full ladder, 10 s per run):

{r['target_full']}
## Every integrator on the paper example at rtol = atol = 1e−8 (`compare_paper_example.*`)

{r['compare']}
## Section 4: (b, Lc) sweeps around the published best fits (`sweeps.*`, `sweeps/`)

{r['sweeps']}
Maps: `sweeps/<window>_<law>/maps.png`.

## Sweep speed (`sweep_scaling.*`)

{r['sweep_scaling']}
## Reliability: the probe (`reliability.*`)

Every case of `benchmarks/probe_cases.py`, by kind and outcome (`rsfbench probe --slow`):

{r['reliability']}
## The ETD family's step-rule check (`etd_validity.*`)

{r['etd_validity']}
## What J2 sees (`j2_information.*`)

{r['misfit']}
## Stick–slip needs the fault to lock (`classification.*`)

{r['classification']}
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
