"""What ``make reproduce`` runs: the generated files of ``results/``, ``results/REPORT.md``
assembling them, and the README's generated blocks.

Two plans share one list of steps (:data:`STEPS`). The quick plan (``make reproduce``; about a
quarter of an hour on 2 cores when every quick step runs) runs the quick steps and keeps the
files of the full ones; the full plan (``make reproduce-full``, ``rsfbench reproduce --full``;
about an hour and a half) also runs the long steps: the quick work-precision study, issue 6's
target on every study problem and scipy's RK45 to its budget in the speed-up claim. Either plan
reuses a step whose inputs did not change (:mod:`benchmarks.pipeline.manifest`: ``results/manifest.json``
records what each step read and wrote); ``force`` reruns every step of the plan, ``only`` one
step. A full step the quick plan keeps although its inputs changed is reported as stale, at the
end and in ``REPORT.md``.

When ``out`` is the project's ``results/``, the README's generated blocks are refilled last
(:mod:`benchmarks.pipeline.readme`). ``docs/reproduce.md`` lists the steps and their times.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from benchmarks.pipeline import manifest as M
from benchmarks.records.files import BadResultsFile

__all__ = ["reproduce", "run_steps", "describe", "summary", "Step", "STEPS", "STEP_NAMES",
           "QUICK_STEPS", "FULL_STEPS"]


@dataclass(frozen=True, eq=False)
class Step:
    """One step: ``run(out, **settings)`` writes its files to ``out``. ``full``: only in the
    full plan. ``timed``: its numbers are timings (the machine is an input). ``reads``: results
    files it reads, relative to ``out``; ``data``: project files it reads, relative to the
    project; ``modules``: project modules it runs without importing them (a command line run
    as a program). ``minutes``: the time it takes on 2 cores, as last measured."""

    name: str
    title: str
    run: Callable[..., object]
    full: bool = False
    timed: bool = False
    settings: dict = field(default_factory=dict)
    reads: tuple[str, ...] = ()
    data: tuple[str, ...] = ()
    modules: tuple[str, ...] = ()
    minutes: float = 0.0


def _section(title: str) -> None:
    print(f"\n== {title} ==", flush=True)


# --- the steps: thin calls of the library (their source is one of their inputs) ------------

def _integrators(out: Path) -> None:
    from benchmarks.physics.summary import integrators_markdown
    (out / "integrators.md").write_text(integrators_markdown())


def _windows(out: Path) -> None:
    from benchmarks.devtools.timing import warm_up
    from benchmarks.physics.summary import simulate_summary
    from benchmarks.studies.windows import windows_table, write_windows
    from integrators import ETD2, solve
    from problems import WINDOWS, window
    algorithm = ETD2()
    for name in WINDOWS:
        for law in ("slip", "aging"):
            problem = window(name, law)
            warm_up(problem, algorithm)
            summary = simulate_summary(solve(problem, algorithm))
            (out / f"simulate_{name}_{law}.json").write_text(json.dumps(summary, indent=2) + "\n")
    write_windows(windows_table(), out)


def _paper_example(out: Path) -> None:
    from benchmarks.devtools.timing import warm_up
    from benchmarks.physics.plots import plot_solution
    from benchmarks.physics.summary import simulate_summary
    from integrators import ETD2, solve
    from problems import paper_example, window
    algorithm, problem = ETD2(), paper_example()
    warm_up(problem, algorithm)
    sol = solve(problem, algorithm, max_points=200_000)
    summary = simulate_summary(sol)
    (out / "paper_example.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot_solution(sol, out / "paper_example.png")
    plot_solution(solve(window("W2"), algorithm, max_points=200_000), out / "W2_slip.png")
    print(json.dumps(summary["limit_cycle"], indent=2))


def _references(out: Path) -> None:
    from benchmarks.devtools.reference import agreement_table, reference
    from benchmarks.devtools.work_precision import study_problems
    refs = [(p, reference(p, progress=False)) for p in study_problems("full")]
    agreement_table(refs).to_csv(out / "references.csv", index=False)


def _speedup(out: Path, scipy_budget: float) -> None:
    from benchmarks.studies.speedup import speedup, write_speedup
    from problems import paper_example
    print(write_speedup(*speedup(paper_example(), scipy_budget=scipy_budget), out))


def _convergence(out: Path) -> None:
    from benchmarks.devtools.convergence import convergence_study, write_convergence
    from problems import paper_example
    problem = paper_example()
    write_convergence(problem, *convergence_study(problem), out)


def _fixed_steps(out: Path) -> None:
    from benchmarks.devtools.convergence import (
        fixed_step_orders,
        write_fixed_step_orders,
    )
    write_fixed_step_orders(*fixed_step_orders(progress=False), out)


def _problem_family(out: Path) -> None:
    from benchmarks.studies.family import write_lab_checks
    checks = write_lab_checks(out)
    print(checks["marone"].to_string(index=False))


def _family(out: Path) -> None:
    from benchmarks.studies.family import summary, write_family
    print(summary(write_family(out, progress=False)).to_string(index=False))


def _mass_limit(out: Path) -> None:
    from benchmarks.studies.mass_limit import write_mass_limit
    write_mass_limit(out, progress=False)
    print((out / "mass_limit.md").read_text().split("## ")[1])


def _work_precision(out: Path) -> None:
    from benchmarks.devtools.work_precision import (
        QUICK,
        study_problems,
        work_precision,
        write_recommendation,
    )
    from benchmarks.devtools.wp_files import write_work_precision
    write_work_precision(work_precision(study_problems("quick"), QUICK), out, "quick")
    from benchmarks.pipeline.manifest import ROOT
    if out.resolve() == (ROOT / "results").resolve():    # the commands' default integrator
        print(f"wrote {write_recommendation(out / 'wp_quick.csv')}")


def _target(out: Path) -> None:
    from benchmarks.studies.target import write_target
    write_target(out / "wp_quick.csv", out)


def _target_full(out: Path) -> None:
    from benchmarks.studies.target import full_target, target_markdown
    print(target_markdown(full_target(out)))


def _compare(out: Path, rtol: float, wall_budget: float) -> None:
    from benchmarks.devtools.compare import compare_integrators, compare_markdown
    from problems import paper_example
    table = compare_integrators(paper_example(), rtol, rtol, wall_budget=wall_budget)
    table.to_csv(out / "compare_paper_example.csv", index=False)
    (out / "compare_paper_example.md").write_text(compare_markdown(table))


def _sweeps(out: Path) -> None:
    from benchmarks.studies.paper_sweeps import paper_sweeps
    paper_sweeps(out, study_csv=out / "wp_quick.csv")


def _sweep_scaling(out: Path) -> None:
    from benchmarks.studies.paper_sweeps import sweep_scaling
    sweep_scaling(out, study_csv=out / "wp_quick.csv")


def _ensemble_scaling(out: Path) -> None:
    from benchmarks.studies.ensemble_scaling import ensemble_scaling
    ensemble_scaling(out, study_csv=out / "wp_quick.csv", progress=False)


def _classification(out: Path) -> None:
    from benchmarks.studies.classification import (
        classification_study,
        write_classification,
    )
    print(write_classification(classification_study(), out))


def _etd_validity(out: Path) -> None:
    from benchmarks.studies.etd_validity import etd_validity, write_etd_validity
    print(write_etd_validity(etd_validity(), out))


def _misfit(out: Path) -> None:
    from benchmarks.studies.misfit import j2_information, write_j2_information
    print(write_j2_information(j2_information(), out))


def _engine_speed(out: Path) -> None:
    from benchmarks.studies.engine_speed import write_engine_speed
    print(write_engine_speed(out)[1])


def _binding_overhead(out: Path) -> None:
    from benchmarks.studies.binding_overhead import write_binding_overhead
    print(write_binding_overhead(out, progress=False)[1])


def _probe(out: Path) -> None:
    from benchmarks.probe import run_probe, write_probe
    from benchmarks.probe_cases import cases
    print(write_probe(run_probe(cases()), out))


def _inversion(out: Path) -> None:
    from benchmarks.studies.inversion import posterior_target
    posterior_target(out, study_csv=out / "wp_quick.csv")
    print((out / "inversion.md").read_text())


def _calibration(out: Path) -> None:
    from benchmarks.studies.inversion import calibration_study
    calibration_study(out)
    print((out / "calibration.md").read_text().split("\n## ")[0])


def _solver_effect(out: Path) -> None:
    from benchmarks.studies.solver_effect import solver_effect_study
    solver_effect_study(out, study_csv=out / "wp_full.csv", progress=True)
    print((out / "solver_effect.md").read_text().split("\n## ")[1])


COMPARE_RTOL = 1e-8          # the side-by-side comparison of every backend (issue 3)
#: the steps in order; ``minutes``: on 2 cores at fcab60f, measured, or for the full steps
#: estimated from the wall times in their results files (docs/reproduce.md)
STEPS = (
    Step("integrators", "integrators", _integrators, minutes=0.05),
    Step("windows", "W1–W4 limit cycles (ETD2, both laws)", _windows, minutes=0.15),
    Step("paper-example", "paper example (Appendix 1.4)", _paper_example, minutes=0.05),
    Step("references", "reference solutions (two independent solvers, checked)", _references,
         minutes=0.4),
    Step("speedup", "the paper's speed-up claim", _speedup, full=True, timed=True,
         settings={"scipy_budget": 600.0}, minutes=13),
    Step("convergence", "convergence of the fixed-step methods", _convergence, minutes=0.05),
    Step("fixed-steps", "fixed-step order of the compiled stiff methods (stiff segment, control "
         "off)", _fixed_steps, minutes=0.3),
    Step("work-precision", "quick work-precision study", _work_precision, full=True, timed=True,
         minutes=19),
    Step("target", "issue 6's target on the quick study", _target, reads=("wp_quick.csv",),
         minutes=0.05),
    Step("target-full", "issue 6's target on every study problem (full work-precision study of "
         "the stiff adaptive integrators)", _target_full, full=True, timed=True, minutes=26),
    Step("compare", f"every integrator on the paper example, rtol = atol = {COMPARE_RTOL:g}",
         _compare, timed=True, settings={"rtol": COMPARE_RTOL, "wall_budget": 60.0},
         minutes=3.6),
    Step("sweeps", "Section 4: (b, Lc) sweeps around the published best fits", _sweeps,
         reads=("wp_quick.csv",), minutes=0.2),
    Step("sweep-scaling", "sweep speed: 21 x 21 on W2, serial and on 2 workers", _sweep_scaling,
         timed=True, reads=("wp_quick.csv",), minutes=0.1),
    Step("ensemble-scaling", "ensembles: 21 x 21 on 1 and 2 threads, 10^5 points killed and "
         "resumed, 10^4 on a local Dask cluster", _ensemble_scaling, full=True, timed=True,
         reads=("wp_quick.csv",), minutes=4),
    Step("classification", "the locking rule of stick-slip, against the trajectory",
         _classification, minutes=0.05),
    Step("etd-validity", "the ETD family's step-rule check on the studied problems",
         _etd_validity, minutes=3.7),
    Step("misfit", "what J2 sees: friction against the spring force", _misfit,
         data=("tests/data/W2_slip_weakening.csv",), minutes=1.4),
    Step("engine-speed", "the own compiled engine against issue 14's targets and numbalsoda's "
         "lsoda", _engine_speed, timed=True, minutes=0.6),
    Step("binding-overhead", "the same solver called compiled and from Python (SUNDIALS, "
         "LSODA)", _binding_overhead, full=True, timed=True, minutes=6),
    Step("inversion", "a W2/slip inversion: fit, profiles, a 64,000-solve posterior (timed)",
         _inversion, timed=True, reads=("wp_quick.csv",), minutes=0.9),
    Step("calibration", "coverage of the 95 % regions over 1000 seeded synthetic data sets",
         _calibration, minutes=2),
    Step("solver-effect", "the solver's effect on the inferred (b, Lc): W1–W4, both laws",
         _solver_effect, full=True, timed=True, reads=("wp_full.csv",), minutes=101),
    Step("problem-family", "the problem family: Marone's numbers, velocity steps, healing",
         _problem_family, minutes=0.1),
    Step("family", "which integrator for a velocity step, a slide-hold-slide test, the "
         "quasi-dynamic and the damped slider (work-precision)", _family, full=True,
         timed=True, minutes=17.5),
    Step("mass-limit", "where the paper's ETD advantage goes as the mass goes", _mass_limit,
         full=True, timed=True, minutes=4),
    Step("probe", "the reliability probe, slow cases included", _probe,
         data=("results/wp_quick.csv",), modules=("benchmarks.cli",), minutes=19),
)
STEP_NAMES = tuple(s.name for s in STEPS)
QUICK_STEPS = tuple(s.name for s in STEPS if not s.full)
FULL_STEPS = tuple(s.name for s in STEPS if s.full)


def reproduce(out: Path, full: bool = False, force: bool = False, start: str | None = None,
              only: str | None = None, scipy_budget: float | None = None,
              dry_run: bool = False) -> list[dict]:
    """Bring ``out`` up to date (see the module docstring) and write ``REPORT.md``; return one
    row per step considered (``step``, ``status``, ``why``).

    ``full``: the full plan. ``force``: rerun every step of the plan, reusing none. ``start``:
    begin at this step (the earlier ones are left alone). ``only``: rerun this step alone, quick
    or full. ``scipy_budget``: the speed-up step's wall budget for scipy's RK45 in s.
    ``dry_run``: say what would run, run nothing, write nothing."""
    for what, name in (("start", start), ("only", only)):
        if name is not None and name not in STEP_NAMES:
            raise ValueError(f"unknown step {what}={name!r}: expected one of "
                             f"{', '.join(STEP_NAMES)}")
    if only and start:
        raise ValueError("only and start exclude each other")
    if start and not full and _step(start).full:
        raise ValueError(f"step {start!r} is in the full plan only: add --full (full=True), or "
                         f"rerun it alone with --only {start}")
    if scipy_budget is not None and not (full or only == "speedup"):
        raise ValueError("the scipy budget is a setting of the speedup step, which only the "
                         "full plan runs: add --full (full=True), or --only speedup")
    steps = [s if s.name != "speedup" or scipy_budget is None
             else dataclasses.replace(s, settings={**s.settings, "scipy_budget": scipy_budget})
             for s in STEPS]
    if only:
        modes = {only: "run"}
    else:
        first = STEP_NAMES.index(start) if start else 0
        modes = {s.name: ("keep" if s.full and not full else "run" if force else "check")
                 for s in steps[first:]}
    out = Path(out)
    if not dry_run:
        out.mkdir(parents=True, exist_ok=True)
    rows = run_steps(steps, out, modes, dry_run=dry_run)
    if dry_run:
        return rows
    (out / "REPORT.md").write_text(_report_markdown(_collect(out)))
    print(f"\nwritten: {out / 'REPORT.md'}")
    from benchmarks.pipeline.readme import ROOT, refresh
    if out.resolve() == (ROOT / "results").resolve():    # the README quotes these files
        stale = refresh()
        print(f"README blocks refilled: {', '.join(stale) or 'none changed'}")
    return rows


def _step(name: str) -> Step:
    return STEPS[STEP_NAMES.index(name)]


def run_steps(steps, out: Path, modes: dict[str, str], dry_run: bool = False,
              **code) -> list[dict]:
    """Take each step of ``steps`` named in ``modes`` in order: ``run`` reruns it, ``check``
    reruns it unless its inputs and files are unchanged (then it is reused), ``keep`` only
    says whether its files are up to date. Each step that ran is recorded in ``out``'s
    manifest at once. ``code``: :func:`benchmarks.pipeline.manifest.step_inputs`' ``root``,
    ``packages`` and ``whole``.

    The manifest on disk is read again before each step and before each record is written, so
    that two runs of different steps (``--only``) at once keep each other's records, and a file
    both claim goes to the one that finished first after it was written
    (:func:`benchmarks.pipeline.manifest.assign_outputs`)."""
    said = []

    def current() -> dict[str, dict]:
        try:
            return M.read_manifest(out)
        except BadResultsFile as exc:
            if not said:                     # once, not before every step
                print(f"{exc}: every step reruns")
                said.append(exc)
            return {}

    order = [s.name for s in steps]
    rows = []
    for step in steps:
        mode = modes.get(step.name)
        if mode is None:
            continue
        inputs = _inputs(step, out, **code)
        ok, why = M.reusable(current().get(step.name), inputs, out)
        if mode == "keep" or (mode == "check" and ok):
            row = {"step": step.name, "status": "reused" if ok else "stale",
                   "why": why if ok else f"{why}; `make reproduce-full` reruns it"}
        elif dry_run:
            row = {"step": step.name, "status": "would run",
                   "why": "rerun as asked" if mode == "run" else why, "minutes": step.minutes}
        else:
            row = None
        if row is not None:
            rows.append(row)
            if not dry_run:
                print(describe(row), flush=True)
            continue
        why = "rerun as asked" if mode == "run" else why
        missing = [r for r in step.reads if not (out / r).is_file()]
        if missing:
            raise FileNotFoundError(f"step {step.name} reads {out / missing[0]}, which is not "
                                    "there: run the step that writes it first (`rsfbench "
                                    f"reproduce --full --out {out}`)")
        _section(step.title)
        print(f"({why})", flush=True)
        before = M.snapshot(out)
        started = time.perf_counter()
        step.run(out, **step.settings)
        wall = time.perf_counter() - started
        records = current()
        records[step.name] = M.make_record(step.name, "full" if step.full else "quick", inputs,
                                           M.written_since(before, out), wall)
        M.assign_outputs(records, out)
        M.write_manifest(out, records, order)
        rows.append({"step": step.name, "status": "ran", "why": why})
    return rows


def describe(row: dict) -> str:
    """One line for a row of :func:`run_steps`."""
    if row["status"] == "reused":
        return f"{row['step']}: reused (inputs unchanged)"
    if row["status"] == "stale":
        return f"{row['step']}: kept, a step of the full plan ({row['why']})"
    if row["status"] == "would run":
        return f"{row['step']}: would run ({row['why']}; ~{_duration(60 * row['minutes'])})"
    return f"{row['step']}: {row['status']} ({row['why']})"


def summary(rows: list[dict]) -> str:
    """One line: how many steps ran (or would, and for how long) and were reused, and which
    full steps are stale."""
    would = [r["minutes"] for r in rows if r["status"] == "would run"]
    ran = [r["step"] for r in rows if r["status"] == "ran"]
    reused = [r["step"] for r in rows if r["status"] == "reused"]
    stale = [r["step"] for r in rows if r["status"] == "stale"]
    text = (f"{_steps(len(would))} would run (~{_duration(60 * sum(would))}), " if would
            else f"{_steps(len(ran))} ran, ") + f"{len(reused)} reused"
    return text + (f"; stale, kept from an earlier run: {', '.join(stale)} (`make "
                   "reproduce-full` reruns them)" if stale else "")


def _steps(n: int) -> str:
    return f"{n} step" + ("" if n == 1 else "s")


def _inputs(step: Step, out: Path, **code) -> dict:
    return M.step_inputs(step.run, step.settings, out, reads=step.reads, data=step.data,
                         modules=step.modules, timed=step.timed, **code)


def _collect(out: Path) -> dict:
    """The pieces of REPORT.md, read from the files the steps wrote."""
    import pandas as pd

    from benchmarks.records.report import markdown_table

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
        "target": read("target_quick.md", "target"),
        "target_full": read("target_full.md", "target-full"),
        "compare": read("compare_paper_example.md", "compare"),
        "sweeps": read("sweeps.md", "sweeps"),
        "sweep_scaling": read("sweep_scaling.md", "sweep-scaling"),
        "ensemble_scaling": read("ensemble_scaling.md", "ensemble-scaling"),
        "classification": read("classification.md", "classification"),
        "reliability": read("reliability.md", "probe"),
        "misfit": read("j2_information.md", "misfit"),
        "etd_validity": read("etd_validity.md", "etd-validity"),
        "engine_speed": read("engine_speed.md", "engine-speed"),
        "binding_overhead": read("binding_overhead.md", "binding-overhead"),
        "inversion": read("inversion.md", "inversion"),
        "calibration": read("calibration.md", "calibration"),
        "solver_effect": read("solver_effect.md", "solver-effect").split("\n## ")[1],
        "problem_family": read("problem_family.md", "problem-family"),
        "family": read("family_advice.md", "family"),
        "mass_limit": read("mass_limit_summary.md", "mass-limit"),
        "steps": markdown_table(pd.DataFrame(_step_states(out))),
    }


def _step_states(out: Path) -> list[dict]:
    """One row per step: its plan, its last run (from the manifest) and whether its files are
    up to date with its inputs."""
    try:
        records = M.read_manifest(out)
    except BadResultsFile:
        records = {}
    rows = []
    for step in STEPS:
        r = records.get(step.name)
        ok, why = M.reusable(r, _inputs(step, out), out)
        rows.append({"step": step.name, "plan": "full" if step.full else "quick",
                     "last run": r["finished"] if r else "", "commit": r["git_commit"] if r else "",
                     "took": _duration(r["wall_s"]) if r else "",
                     "files": "up to date" if ok else why})
    return rows


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 100 else f"{seconds / 60:.1f} min"


def _report_markdown(r: dict) -> str:
    from benchmarks.records.provenance import provenance
    meta = provenance()
    figures = "\n".join(f"![{f}]({f})" for f in r["wp_figures"])
    return f"""# rsfbench report

Assembled by `make reproduce` (`rsfbench reproduce --out results`) on {meta['date']}, commit
`{meta['git_commit']}`, {meta['cpu']} ({meta['n_cpus']} CPUs), Python {meta['python']},
numpy {meta['v_numpy']}, scipy {meta['v_scipy']}, numba {meta['v_numba']}. Every number below
is in a file of this directory, written by a step of `rsfbench reproduce`; the last section says
when each step last ran and whether its files are up to date with its inputs
(`manifest.json`).

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
## Ensembles at kernel speed (`ensemble_scaling.*`)

{r['ensemble_scaling']}
## Reliability: the probe (`reliability.*`)

Every case of `benchmarks/probe_cases.py`, by kind and outcome (`rsfbench probe --slow`):

{r['reliability']}
## The ETD family's step-rule check (`etd_validity.*`)

{r['etd_validity']}
## The own compiled engine against issue 14's targets (`engine_speed.*`)

{r['engine_speed']}
## What a way of calling costs (`binding_overhead.*`)

{r['binding_overhead']}
## An inversion: fit, profiles, posterior (`inversion.md`, `inversion_W2_slip/`)

{r['inversion']}
![posterior](inversion_W2_slip/corner.png)

## Coverage of the 95 % regions (`calibration.*`)

{r['calibration'].split(chr(10), 1)[1]}
![coverage](calibration.png)

## The solver's effect on the inferred (b, Lc) (`solver_effect.*`)

{r['solver_effect'].split(chr(10), 1)[1]}
Every window and law: `solver_effect.md`.

![solver effect](solver_effect.png)

## The problem family: Marone's numbers, laboratory tests (`problem_family.*`)

{r['problem_family'].split(chr(10), 2)[2]}
![healing](problem_family_healing.png)

## Which integrator for a lab test, without mass, with damping (`family_wp.*`)

{r['family']}
Every error level and the runner-up: `family_wp.md`.

![family work-precision](family_wp.png)

## Where the paper's ETD advantage goes as the mass goes (`mass_limit.*`)

{r['mass_limit']}
The table: `mass_limit.md`.

![mass limit](mass_limit.png)

## What J2 sees (`j2_information.*`)

{r['misfit']}
## Stick–slip needs the fault to lock (`classification.*`)

{r['classification']}
## W1–W4 limit cycles, ETD2 at the paper's settings (`windows.*`, `simulate_*.json`)

{r['windows']}
## The registry (`integrators.md`)

{r['integrators']}
## The steps (`manifest.json`)

"Up to date": the step's code, package versions, settings, files read and (for timings) machine
are those it last ran on. `make reproduce` reruns the quick steps that are not; `make
reproduce-full` also the full ones.

{r['steps']}"""
