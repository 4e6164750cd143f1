"""``rsfbench``: the command line of the harness.

    rsfbench simulate --preset W2 --law aging --json
    rsfbench windows --out results          # W1–W4 limit cycles, both laws, CSV + Markdown
    rsfbench integrators                    # the registry
    rsfbench work-precision --study quick   # every integrator over a ladder of settings
    rsfbench convergence --json             # observed orders of the fixed-step methods
    rsfbench convergence --fixed-steps      # ... and of the compiled stiff methods, control off
    rsfbench sweep --preset W2 --b 0.009:0.0098:0.0001 --lc 1e-7:1e-6:9log --json
    rsfbench reproduce --out results        # what `make reproduce` runs (--full: reproduce-full)
    rsfbench study --list                   # the studies behind results/, one by one:
    rsfbench study speedup --set scipy_budget=3600   # the paper's 1/10,000 claim
    rsfbench readme [--check]               # refill the README's numbers from results/
    rsfbench lab shs --holds 1 10 100       # a slide-hold-slide test and its healing
    rsfbench lab fit rec.txt --column ...   # (a, b, Dc) of a velocity-step record
    rsfbench observe rec.csv --columns rec.toml   # a recording in: observations.json out
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import shlex
import sys
import warnings
from pathlib import Path

from benchmarks.cli.args import (
    Parser,
    RunStopped,
    ShowVersion,
    add_integrator_options,
    add_overwrite_options,
    add_problem_options,
    flagged,
    in_file,
    integrator_from_args,
    out_dir,
    out_file,
    positive,
    preset_name,
    problem_from_args,
    say,
    show_progress,
    wants_json,
)
from benchmarks.devtools.timing import warm_up
from benchmarks.physics import metrics
from benchmarks.physics.summary import (
    integrator_rows,
    integrators_markdown,
    simulate_summary,
)
from benchmarks.records.files import allow_overwrite, begin_run, claim_outputs, write_output, \
    write_table, writing
from benchmarks.records.optional import MissingExtra
from benchmarks.records.report import jsonable as _jsonable
from integrators import REGISTRY, algorithm_class, solve
from problems import PRESET_NAMES, WINDOWS, preset

__all__ = ["main"]

REPRODUCE_HELP = """\
Bring the results directory up to date, write its REPORT.md and, for the
project's results/, refill the README's generated blocks.

The quick plan (the default; `make reproduce`) runs the quick studies; the
full plan (--full; `make reproduce-full`) also the long ones. The quick plan
keeps the files of the full studies and says which are stale. `rsfbench study
--list` lists the studies, their plan, minutes and files.

A study is reused, not rerun, when its code, the package versions, its
settings, the files it reads and, for a timing, the machine are those of its
last run, and the files it wrote are there unchanged (results/manifest.json).
--force reruns every study of the plan; `rsfbench study NAME` reruns one.
See docs/reproduce.md."""

STUDY_HELP = """\
Run one study of the pipeline, whatever its inputs: it writes its declared
files to --out, records them in the manifest and rewrites REPORT.md. --set
changes one of its settings (`--list --json` shows each study's settings,
defaults and limits), and the next `rsfbench reproduce` reruns it at its
defaults. --list lists the studies: plan, minutes, files read and written."""


def algorithm_name(name: str, flag: str = "--integrators") -> str:
    """The registry's spelling of ``name`` (lookups are case-insensitive)."""
    return flagged(flag, algorithm_class, name).name


def _print_summary(s: dict) -> None:
    lc = s["limit_cycle"]
    say(f"{s['problem']}  (b = {s['b']:.5g}, Lc = {s['lc_m'] * 1e6:.4g} µm, {s['t_end']:g} s)")
    say(f"  integrator  {s['integrator']}   {s['retcode']}  {s['message']}".rstrip())
    if s.get("integrator_choice"):
        say(f"              ({s['integrator_choice']})")
    say(f"  cost        {s['steps']} steps, {s['nfev']} rhs evaluations, {s['wall_s']:.4g} s wall")
    say(f"  events      {s['n_events']}   classification: {lc['classification']}")
    if lc.get("reason"):
        say(f"              ({lc['reason']})")
    if lc["classification"] in metrics.CYCLES:
        say(f"  limit cycle (period {lc['period']}, converged from event {lc['cycles_to_converge']}):")
        say(f"    recurrence interval  {lc['recurrence_s']:.6g} s")
        say(f"    friction drop        {lc['friction_drop']:.6g}")
        say(f"    slip per event       {lc['slip_m'] * 1e3:.6g} mm")
        say(f"    peak slip rate       {lc['peak_velocity_m_s']:.6g} m/s")
    elif s["last_event"]:
        e = s["last_event"]
        recurrence = "n/a" if e["recurrence_s"] is None else f"{e['recurrence_s']:.6g} s"
        say(f"  last event  at t = {e['t_start']:.6g} s: recurrence {recurrence}, "
            f"friction drop {e['friction_drop']:.6g}, slip {e['slip_m'] * 1e3:.6g} mm, "
            f"peak {e['peak_velocity_m_s']:.6g} m/s (not a limit cycle)")


def cmd_simulate(args) -> int:
    if args.save and args.save.suffix.lower() == ".parquet":
        from benchmarks.records.optional import require
        require("pyarrow", "ensemble", "--save FILE.parquet")
    problem = problem_from_args(args)
    algorithm, why = integrator_from_args(args)
    claim_outputs([p for p in (args.save, args.save and args.save.with_name(
        args.save.name + ".json"), args.plot) if p])   # a user's file there: refused now
    warm_up(problem, algorithm, wall_budget=args.wall_budget)   # wall_s excludes compiling
    # 20,000 points over the run; a figure draws each event from the dense output besides
    sol = solve(problem, algorithm, max_points=20_000, progress=args.progress,
                wall_budget=args.wall_budget)
    summary = {**simulate_summary(sol), "integrator_choice": why}
    if args.save:
        summary["trajectory"] = _save_trajectory(sol, args.save, summary, args.command_line)
    if args.plot:
        from benchmarks.physics.plots import plot_solution
        args.plot.parent.mkdir(parents=True, exist_ok=True)   # a creatable place (its check)
        plot_solution(sol.resolved(), args.plot)     # a failed run comes back as it is
    if args.json:
        say(json.dumps(summary, indent=2))
    else:
        _print_summary(summary)
        if args.save:
            say(f"  trajectory  {args.save} (and {summary['trajectory']['about']})")
        if args.plot:
            say(f"  figure      {args.plot}")
    return 0 if sol.success else 1


def _save_trajectory(sol, path: Path, summary: dict, command: str) -> dict:
    """Write ``sol``'s trajectory to ``path`` (.csv or .parquet: t, v, fs, ft, mu, theta) and
    what it is to ``path`` + ".json" (units, command, versions, the run's summary)."""
    from benchmarks.records.provenance import provenance, version_line
    df = sol.to_dataframe()
    path.parent.mkdir(parents=True, exist_ok=True)      # a creatable place (--save's check)
    about = {"tool": version_line(), "command": command, **provenance(),
             "columns": df.attrs["units"], "rows": len(df), "run": summary}
    if path.suffix.lower() == ".parquet":
        df.attrs["about"] = json.dumps(_jsonable(about))
        with writing(path) as tmp:
            df.to_parquet(tmp, index=False)
    else:
        write_table(df, path)
    side = path.with_name(path.name + ".json")
    write_output(side, json.dumps(_jsonable(about), indent=2))
    return {"file": str(path), "about": str(side), "rows": len(df)}


def cmd_integrators(args) -> int:
    rows, missing = integrator_rows(), REGISTRY.unavailable()
    if args.json:
        say(json.dumps([{**r, "available": True} for r in rows]
                       + [{**m, "available": False} for m in missing], indent=2))
    elif args.markdown:
        say(integrators_markdown(), end="")
    else:
        say(f"{'name':<22} {'order':>5}  {'adaptive':<8} {'family':<32} library")
        for r in rows:
            say(f"{r['name']:<22} {r['order']:>5}  {str(r['adaptive']):<8} {r['family']:<32} "
                  f"{r['library']} ({r['version']})")
        if missing:
            say("\nnot available here (the library did not import):")
            for m in missing:
                say(f"  {m['name']:<22} {m['install']}  [{m['reason']}]")
    return 0


def cmd_windows(args) -> int:
    from benchmarks.studies.windows import windows_table, write_windows
    algorithm, why = integrator_from_args(args)
    if args.out:                              # a user's file there: refused before the work
        claim_outputs([Path(args.out) / "windows.csv", Path(args.out) / "windows.md"])
    if not args.json:
        say(f"integrator: {why}")
    table = windows_table(laws=args.law, names=args.window, integrator=algorithm,
                          t_end=args.t_end, wall_budget=args.wall_budget,
                          progress=show_progress(args))
    if args.out:
        write_windows(table, Path(args.out))
    if args.json:
        say(table.to_json(orient="records", indent=2))
    else:
        say(table.to_string(index=False))
    return 0


def cmd_compare(args) -> int:
    from benchmarks.devtools.compare import compare_integrators
    from benchmarks.records.report import markdown_table
    if args.problem is not None:
        if args.preset is not None or args.law is not None:
            raise ValueError("--problem FILE names its own law: drop --preset and --law")
        from problems import load_problem, variant
        problem = load_problem(args.problem)
        problem = variant(problem, t_end=args.t_end) if args.t_end else problem
    else:
        problem = preset(args.preset or "paper-example", law=args.law or "slip",
                         t_end=args.t_end)
    if args.out:
        claim_outputs([args.out])             # a user's file there: refused before the work
    names = None if not args.integrators else [algorithm_name(n) for n in args.integrators]
    table = compare_integrators(problem, args.rtol, args.atol, names=names,
                                wall_budget=args.wall_budget, progress=show_progress(args))
    table.insert(0, "problem", problem.name)
    if args.observations is not None:
        table = _errors_in_sigma(table, problem, args.observations, args.wall_budget)
    from benchmarks.records.provenance import version_line
    table["rsfbench"], table["command"] = version_line(), args.command_line
    if args.out:
        write_table(table, args.out)
    if args.json:
        say(table.to_json(orient="records", indent=2))
    else:
        shown = table.drop(columns=["library", "message", "problem", "rsfbench",
                                    "command"]).assign(
            wall_s=table.wall_s.map("{:.4g}".format),
            recurrence_s=table.recurrence_s.map(lambda x: f"{x:.8g}" if x == x and x is not None else ""),
            friction_drop=table.friction_drop.map(lambda x: f"{x:.7g}" if x == x and x is not None else ""),
            **{c: table[c].map(lambda x: "" if x != x else f"{x:.2g}")
               for c in table.columns if c.endswith("_sigma")})
        say(markdown_table(shown), end="")
    return 0


def _errors_in_sigma(table, problem, path, wall_budget):
    """``table`` with each integrator's ΔT and Δμ (of the last event) off the tight reference
    in units of the observations' σ, and whether both are within σ/10: the references are
    those of invert's check, which must agree to σ/100."""
    import numpy as np

    from benchmarks.devtools.compare import compare_integrators
    from benchmarks.inversion.observations import read_observations
    from benchmarks.inversion.solver_check import FRACTION, REFERENCES
    try:
        obs = read_observations(path, curve_noise="none")   # ΔT and Δμ only
    except ValueError as exc:
        raise ValueError(f"--observations: {exc}") from None
    refs = [compare_integrators(problem, tol, tol, names=[name], wall_budget=wall_budget,
                                progress=False).iloc[0] for name, tol in REFERENCES]
    sigma = {"recurrence_s": obs.sigma_recurrence_s, "friction_drop": obs.sigma_friction_drop}
    for ref in refs:
        if ref.recurrence_s is None or not np.isfinite(ref.recurrence_s):
            raise ValueError(f"the reference {ref.integrator} at 1e-9 did not finish this "
                             f"problem ({ref.retcode}): no error in σ to report")
    apart = max(abs(refs[0][k] - refs[1][k]) / s for k, s in sigma.items())
    if apart > FRACTION / 10:
        raise ValueError(f"the references {refs[0].integrator} and {refs[1].integrator} at 1e-9 "
                         f"differ by {apart:.2g} σ on this problem (more than σ/100): no error "
                         "in σ to report")
    for k, s in sigma.items():
        short = "recurrence" if k == "recurrence_s" else "drop"
        got = table[k].astype(float)
        table[f"err_{short}_sigma"] = (got - refs[0][k]).abs() / s
    ok = (table.err_recurrence_sigma <= FRACTION) & (table.err_drop_sigma <= FRACTION)
    table["within_a_tenth_of_sigma"] = ok.where(table.err_recurrence_sigma.notna())
    return table


def _study_problem(spec: str, flag: str = "--problems"):
    """``W2``, ``W2:aging`` or ``paper-example`` → the preset problem."""
    name, _, law = spec.partition(":")
    return flagged(flag, preset, preset_name(name), law or "slip")


def cmd_work_precision(args) -> int:
    from benchmarks.devtools.work_precision import (
        FULL,
        QUICK,
        best_at_levels,
        study_problems,
        work_precision,
    )
    from benchmarks.devtools.wp_files import ERROR_LEVELS, write_work_precision
    ladder = FULL if args.study == "full" else QUICK
    if args.wall_budget is not None:
        ladder = dataclasses.replace(ladder, wall_budget=args.wall_budget)
    problems = [_study_problem(x) for x in args.problems] if args.problems else []
    if args.problem:
        from problems import load_problem
        problems += [load_problem(f) for f in args.problem]
    problems = problems or study_problems(args.study)
    limits = None
    if args.observations is not None:
        limits = _limits_of(args.observations)
    if args.t_end is not None:
        problems = [dataclasses.replace(p, t_end=args.t_end) for p in problems]
    names = None if not args.integrators else [algorithm_name(n) for n in args.integrators]
    import re
    stem = Path(args.out) / f"wp_{args.name or args.study}"
    claim_outputs([*(Path(f"{stem}{tail}") for tail in (".csv", "_pareto.csv", "_pareto.md",
                                                        "_for_sigma.csv")),
                   *(Path(f"{stem}_{re.sub(r'[^A-Za-z0-9._-]+', '_', p.name)}.png")
                     for p in problems)])       # before the work: a user's file is refused
    from benchmarks.devtools.reference import ReferenceDisagreement, no_stick_slip, reference
    for problem in problems:                   # before any run; the study reads them cached
        why = no_stick_slip(problem)
        if why:                                # nothing to measure: refused, one line
            return _fail(f"work-precision: {why}", 2, args.json)
        try:
            reference(problem)
        except ReferenceDisagreement as exc:   # no stick–slip, or no reference: one line
            return _fail(f"work-precision: {_one_line(exc)}", 1, args.json)
    tiers = tuple(args.tiers or ("numba", "python"))
    if args.problem and names is None:       # on your problem: the compiled ones, in minutes
        names = REGISTRY.select("compiled")
        tiers = tuple(args.tiers or ("numba",))
    df = work_precision(problems, ladder, names=names, tiers=tiers,
                        progress=show_progress(args))
    df["command"] = args.command_line                 # the rows carry the machine's already
    paths = write_work_precision(df, Path(args.out), args.name or args.study, error=args.error)
    pareto = best_at_levels(df, ERROR_LEVELS, args.error)
    yours = None
    if limits is not None:
        from benchmarks.devtools.work_precision import fastest_within
        within = fastest_within(df, limits)
        paths["for_your_sigma"] = Path(args.out) / f"wp_{args.name or args.study}_for_sigma.csv"
        write_table(within, paths["for_your_sigma"])
        yours = {"limits": limits, "observations": str(args.observations),
                 "choice": within.iloc[0].to_dict() if len(within) else None,
                 "n_within": len(within)}
    if args.json:
        from benchmarks.devtools.work_precision import recommend
        say(json.dumps(_jsonable({
            "csv": str(paths["csv"]), "error": args.error,
            "recommendation": recommend(df, ERROR_LEVELS, args.error).to_dict(orient="records"),
            "pareto": pareto.to_dict(orient="records"), "for_your_sigma": yours,
            "problems": [p.name for p in problems], "command": args.command_line}), indent=2))
    else:
        say(paths["pareto_md"].read_text())
        if yours is not None:
            c = yours["choice"]
            levels = ", ".join(f"{k} ≤ {v:.3g}" for k, v in limits.items())
            say(f"for your σ (σ/10 of each mean: {levels}): " + (
                f"{c['integrator']} [{c['rhs_tier']}] at {c['setting']:g}, "
                f"{c['total_wall_s']:.3g} s over the problems; {yours['n_within'] - 1} other "
                "settings also qualify" if c is not None else
                "no setting of this study is accurate enough on every problem"))
        say("written: " + ", ".join(str(p) for p in paths.values()))
    return 0


def _limits_of(path) -> dict:
    """The relative errors an inversion of the observations file ``path`` tolerates: σ/10 of
    each mean, as the solver check of invert requires."""
    from benchmarks.inversion.observations import read_observations
    from benchmarks.inversion.solver_check import FRACTION
    try:
        o = read_observations(path, curve_noise="none")     # ΔT and Δμ only
    except ValueError as exc:
        raise ValueError(f"--observations: {exc}") from None
    return {"err_recurrence": FRACTION * o.sigma_recurrence_s / o.recurrence_s,
            "err_drop": FRACTION * o.sigma_friction_drop / o.friction_drop}


def cmd_convergence(args) -> int:
    from benchmarks.devtools.convergence import (
        convergence_study,
        convergence_summary,
        write_convergence,
    )
    names = None if not args.integrators else [algorithm_name(n) for n in args.integrators]
    if args.fixed_steps:
        return _fixed_step_orders(args, names)
    problem = _study_problem(args.problem, "--problem")
    if args.t_end:
        problem = dataclasses.replace(problem, t_end=args.t_end)
    if args.out:                              # a user's file there: refused before the work
        stem = Path(args.out) / f"convergence_{problem.name.replace('/', '_')}"
        claim_outputs(stem.with_suffix(tail) for tail in (".csv", ".json", ".png"))
    table, orders = convergence_study(problem, names=names, progress=show_progress(args))
    summary = (write_convergence(problem, table, orders, args.out) if args.out
               else convergence_summary(problem, table, orders))
    if args.json:
        say(json.dumps(_jsonable(summary), indent=2))
    else:
        say(table[["integrator", "dtau_cnst", "steps", "wall_s", "err_recurrence", "err_drop",
                     "fitted"]].to_string(index=False))
        for name, order in orders.items():
            say(f"{name}: observed order {order:.3f} (declared {REGISTRY[name].order}, on this "
                  f"stiff problem {REGISTRY[name].stiff_order}); finest error "
                  f"{summary['finest_error'][name]:.3g}")
    return 0


def _fixed_step_orders(args, names) -> int:
    from benchmarks.devtools.convergence import (
        fixed_step_orders,
        write_fixed_step_orders,
    )
    if args.out:                              # a user's file there: refused before the work
        claim_outputs(Path(args.out) / f"convergence_fixed_steps{tail}"
                      for tail in (".csv", ".md", ".json", ".png"))
    table, orders = fixed_step_orders(names, progress=show_progress(args))
    summary = (write_fixed_step_orders(table, orders, args.out) if args.out
               else {"orders": orders})
    if args.json:
        say(json.dumps(_jsonable(summary), indent=2))
    else:
        say(table.to_string(index=False))
        for key, order in orders.items():
            name = key.split("/")[0]
            say(f"{key}: observed order {order:.2f} (declared {REGISTRY[name].order})")
    return 0


def cmd_readme(args) -> int:
    from benchmarks.pipeline.readme import refresh_pages
    stale = refresh_pages(check=args.check)
    verb = "out of date" if args.check else "refilled"
    say(f"generated blocks {verb}: {', '.join(stale)}" if stale
        else "generated blocks up to date (README and docs)")
    return 1 if stale and args.check else 0


def cmd_reproduce(args) -> int:
    from benchmarks.pipeline.reproduce import describe, reproduce, summary
    rows = reproduce(Path(args.out), full=args.full, force=args.force, start=args.start,
                     dry_run=args.dry_run)
    if args.dry_run:
        for row in rows:
            say(describe(row))
    say(summary(rows))
    return 0


def cmd_study(args) -> int:
    from benchmarks.pipeline.reproduce import describe, list_markdown, reproduce, studies, summary
    if args.list:
        if args.name or args.settings:
            raise ValueError("--list takes no study name or --set")
        if args.json:
            say(json.dumps([{"name": s.name, "title": s.title, "plan": s.plan,
                             "minutes": s.minutes, "reads": list(s.reads),
                             "writes": list(s.writes), "settings": s.settings,
                             "limits": s.limits,
                             "timed": s.timed} for s in studies()], indent=2))
        else:
            say(list_markdown(), end="")
        return 0
    if not args.name:
        raise ValueError("name a study (`rsfbench study --list` lists them)")
    if args.json:
        raise ValueError("--json goes with --list")
    settings = dict(_setting(text) for text in args.settings)
    rows = reproduce(Path(args.out), only=args.name, dry_run=args.dry_run,
                     settings=settings or None)
    if args.dry_run:
        for row in rows:
            say(describe(row))
    say(summary(rows))
    return 0


def _setting(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` of ``--set``: the value as an int, a float or the word itself."""
    key, sep, value = text.partition("=")
    if not sep or not key.isidentifier():
        raise ValueError(f"--set: expected KEY=VALUE, got {text!r}")
    for kind in (int, float):
        try:
            return key, kind(value)
        except ValueError:
            pass
    return key, value


def build_parser() -> Parser:
    parser = Parser(prog="rsfbench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action=ShowVersion)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("simulate", help="run one problem (a preset or your own file) and "
                       "summarise its limit cycle")
    add_problem_options(s, PRESET_NAMES)
    add_integrator_options(s)
    s.add_argument("--wall-budget", type=positive, metavar="S",
                   help="stop after S seconds of wall time (default: no budget)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.add_argument("--plot", metavar="FILE.png", type=out_file(".png", ".pdf", ".svg"),
                   help="draw v(t), μ(t) and the phase portrait (default: no figure)")
    s.add_argument("--save", metavar="FILE", type=out_file(".csv", ".parquet"),
                   help="write the trajectory (t s, v m/s, fs N, ft N, mu, theta) to FILE.csv "
                        "or FILE.parquet, and what it is to FILE.csv.json or FILE.parquet.json "
                        "beside it (default: not written)")
    s.add_argument("--progress", action="store_true", help="show a progress bar")
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("integrators", help="list the registry")
    i.add_argument("--json", action="store_true", help="print one JSON array")
    i.add_argument("--markdown", action="store_true", help="a Markdown table (for the README)")
    i.set_defaults(func=cmd_integrators)

    w = sub.add_parser("windows", help="limit cycles of W1–W4 against the observed means")
    w.add_argument("--window", nargs="+", choices=sorted(WINDOWS), default=sorted(WINDOWS),
                   type=str.upper, help="the windows to run")
    w.add_argument("--law", nargs="+", choices=("slip", "aging"), default=["slip", "aging"],
                   help="friction laws")
    add_integrator_options(w)
    w.add_argument("--t-end", type=positive, metavar="S",
                   help="simulated time of each window in s (default: 40 s)")
    w.add_argument("--wall-budget", type=positive, metavar="S",
                   help="wall-time budget of each run in s (default: no budget)")
    w.add_argument("--out", type=out_dir, metavar="DIR",
                   help="directory for windows.csv and windows.md (default: write nothing)")
    w.add_argument("--json", action="store_true", help="print one JSON array")
    w.set_defaults(func=cmd_windows)

    c = sub.add_parser("compare", help="every integrator on one problem, side by side")
    c.add_argument("--preset", choices=PRESET_NAMES, type=preset_name,
                   help="the problem (default: paper-example)")
    c.add_argument("--problem", type=in_file, metavar="FILE",
                   help="or your own apparatus: a TOML or JSON problem file (default: none)")
    c.add_argument("--law", choices=("slip", "aging"), help="friction law of --preset "
                   "(default: slip)")
    c.add_argument("--observations", type=in_file, metavar="FILE.json",
                   help="an observations file (rsfbench observe): add each integrator's ΔT and "
                        "Δμ errors against a tight reference in units of its σ, and whether "
                        "both are within σ/10 (default: none)")
    c.add_argument("--t-end", type=positive, metavar="S",
                   help="simulated time in s (default: the preset's)")
    c.add_argument("--rtol", type=positive, required=True,
                   help="relative tolerance of every adaptive integrator")
    c.add_argument("--atol", type=positive, required=True,
                   help="absolute tolerance of every adaptive integrator (nondimensional)")
    c.add_argument("--integrators", nargs="+", metavar="NAME",
                   help="registry names (default: all)")
    c.add_argument("--wall-budget", type=positive, default=120.0, metavar="S",
                   help="per-solve wall-time budget in s")
    c.add_argument("--out", type=out_file(".csv"), metavar="FILE.csv",
                   help="write the table as CSV (default: print only)")
    c.add_argument("--json", action="store_true", help="print one JSON array")
    c.set_defaults(func=cmd_compare)

    wp = sub.add_parser("work-precision", help="every integrator over a ladder of settings")
    wp.add_argument("--study", choices=("quick", "full"), default="quick",
                    help="quick: paper example + W2 aging, budget 10 s/run; full: paper example "
                         "and W1–W4 under both laws, budget 120 s/run")
    wp.add_argument("--problems", nargs="+", metavar="PRESET[:LAW]",
                    help="instead of the study's problems, e.g. paper-example W2:aging "
                         "(default: the study's)")
    wp.add_argument("--problem", type=in_file, nargs="+", metavar="FILE",
                    help="your own apparatus: TOML or JSON problem files, with --problems' or "
                         "instead of the study's; without --integrators, the compiled "
                         "integrators only (own, CyRK, numbalsoda, SUNDIALS from C) at the "
                         "numba tier: minutes (default: none)")
    wp.add_argument("--observations", type=in_file, metavar="FILE.json",
                    help="an observations file (rsfbench observe): also name the fastest "
                         "setting whose ΔT and Δμ errors are within σ/10 of its means on every "
                         "problem (default: none)")
    wp.add_argument("--t-end", type=positive, metavar="S",
                    help="simulated time of every problem in s (default: each preset's own)")
    wp.add_argument("--integrators", nargs="+", metavar="NAME",
                    help="registry names (default: all)")
    wp.add_argument("--tiers", nargs="+", choices=("numba", "python"),
                    help="right-hand-side tiers (default: both; numba only with --problem and "
                         "no --integrators)")
    wp.add_argument("--wall-budget", type=positive, metavar="S",
                    help="per-run wall-time budget in s (default: the study's, 10 or 120 s)")
    wp.add_argument("--error", default="err_recurrence",
                    choices=("err_recurrence", "err_drop", "err_slip", "err_peak_velocity",
                             "err_event_time", "err_trajectory"),
                    help="the error of the Pareto summary and the plots")
    wp.add_argument("--out", type=out_dir, default="results", metavar="DIR",
                    help="directory for the CSV, the Pareto summary and the plots")
    wp.add_argument("--name", help="file stem (default: the study's name)")
    wp.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    wp.add_argument("--no-progress", action="store_true", help="no progress bar")
    wp.set_defaults(func=cmd_work_precision)

    cv = sub.add_parser("convergence", help="observed order of the fixed-step (ETD) methods")
    cv.add_argument("--problem", default="paper-example", metavar="PRESET[:LAW]",
                    help="the problem, e.g. W2:aging")
    cv.add_argument("--t-end", type=positive, metavar="S",
                    help="simulated time in s (default: the preset's)")
    cv.add_argument("--integrators", nargs="+", metavar="NAME",
                    help="fixed-step registry names (default: all; with --fixed-steps, the "
                         "compiled stiff methods)")
    cv.add_argument("--fixed-steps", action="store_true",
                    help="the compiled stiff methods (Rosenbrock23, Rodas5P, RadauIIA5, Exprb32, "
                         "Exprb43) with error control off, on a stiff stick-phase segment")
    cv.add_argument("--out", type=out_dir, metavar="DIR",
                    help="directory for the CSV, JSON and plot (default: write nothing)")
    cv.add_argument("--json", action="store_true", help="print one JSON object")
    cv.set_defaults(func=cmd_convergence)

    rd = sub.add_parser("readme", help="refill the generated blocks of the README and the docs "
                        "from results/")
    rd.add_argument("--check", action="store_true",
                    help="only say which blocks are out of date (exit status 1 if any)")
    rd.set_defaults(func=cmd_readme)

    r = sub.add_parser("reproduce", help="bring results/ up to date (what `make reproduce` runs)",
                       description=REPRODUCE_HELP)
    r.add_argument("--out", type=out_dir, default="results", metavar="DIR",
                   help="directory of the results")
    r.add_argument("--full", action="store_true",
                   help="the full plan: also the long studies (about 3.5 h on 2 cores; "
                        "`rsfbench study --list` says which) (default: the quick plan)")
    r.add_argument("--force", action="store_true",
                   help="rerun every study of the plan, reusing none (default: reuse the "
                        "studies whose inputs did not change)")
    r.add_argument("--dry-run", action="store_true",
                   help="say which studies would run and why, run nothing")
    r.add_argument("--from", dest="start", metavar="STUDY",
                   help="start at this study of the plan, leaving the earlier ones alone "
                        "(default: the first)")
    r.set_defaults(func=cmd_reproduce)

    st = sub.add_parser("study", help="run one study of the pipeline (or --list them)",
                        description=STUDY_HELP)
    st.add_argument("name", nargs="?", metavar="NAME",
                    help="the study to run (default: none; --list lists them)")
    st.add_argument("--list", action="store_true",
                    help="list the studies: plan, expected minutes, files read and written")
    st.add_argument("--out", type=out_dir, default="results", metavar="DIR",
                    help="directory of the results (default: results)")
    st.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="a setting of the study, by name (a number or a word; repeatable; "
                         "default: the study's own, which --list --json shows)")
    st.add_argument("--dry-run", action="store_true", help="say what would run, run nothing")
    st.add_argument("--json", action="store_true", help="with --list: one JSON array")
    st.set_defaults(func=cmd_study)

    from benchmarks.cli.sweep import add_parsers
    add_parsers(sub, PRESET_NAMES)
    from benchmarks.cli.invert import add_parsers as add_inversion_parsers
    add_inversion_parsers(sub, PRESET_NAMES)
    from benchmarks.cli.lab import add_parsers as add_lab_parsers
    add_lab_parsers(sub)
    from benchmarks.cli.observe import add_parsers as add_observe_parsers
    add_observe_parsers(sub)
    from benchmarks.cli.solver_effect import add_parsers as add_solver_effect_parsers
    add_solver_effect_parsers(sub)
    add_overwrite_options(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one command; return its exit status: 0 done, 1 the run failed (its retcode, or one
    line, says why), 2 a usage error (one line on stderr; with --json also one JSON document on
    stdout), 3 an internal error, 130 interrupted.

    Whatever a library writes to the standard output (assimulo's Fortran and SUNDIALS' warnings,
    also from pool workers) goes to the standard error instead, so that the standard output holds
    the command's own output only: with ``--json``, exactly one JSON document. Run as a program
    (``argv`` None) the redirection is kept until exit, when Fortran flushes its buffers.
    """
    json_mode = wants_json(argv)
    with _library_output_to_stderr(keep=argv is None), warnings.catch_warnings():
        warnings.showwarning = _show_warning
        args = None
        try:
            begin_run()                           # nothing written yet, no inputs known
            args = build_parser().parse_args(argv)
            allow_overwrite(getattr(args, "overwrite", False))
            args.command_line = shlex.join(["rsfbench", *(sys.argv[1:] if argv is None
                                                          else argv)])
            return args.func(args)
        except ValueError as exc:                 # a user's mistake: say which, no traceback
            return _fail(_one_line(exc), 2, json_mode)
        except (RunStopped, OSError, MissingExtra) as exc:   # the run could not go on: say why
            return _fail(_one_line(exc), 1, json_mode)
        except KeyboardInterrupt as exc:          # a command may say what it kept
            kept = (" (a sweep keeps its finished points: run it again to resume)"
                    if getattr(args, "command", None) == "sweep" else "")
            return _fail(_one_line(exc) if str(exc) else f"interrupted{kept}", 130, json_mode)
        except Exception as exc:                  # a bug: one line, the traceback on request
            if os.environ.get("RSFBENCH_DEBUG"):
                raise
            return _fail(f"internal error: {type(exc).__name__}: {_one_line(exc)} (set "
                         "RSFBENCH_DEBUG=1 for the traceback; please report it)", 3, json_mode)


def _one_line(exc: BaseException) -> str:
    text = str(exc) if str(exc) else type(exc).__name__
    if isinstance(exc, OSError) and exc.filename is not None:
        text = f"{exc.strerror or text}: {exc.filename}"
    return " ".join(text.split())


def _fail(message: str, status: int, json_mode: bool) -> int:
    prefix = "" if message.startswith("rsfbench") else "rsfbench: error: "
    print(f"{prefix}{message}", file=sys.stderr)
    if json_mode:
        say(json.dumps({"error": message, "exit_status": status}))
    return status


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"rsfbench: warning: {' '.join(str(message).split())}", file=sys.stderr)


@contextlib.contextmanager
def _library_output_to_stderr(keep: bool):
    """While a command runs, the standard output is the standard error — for Python code
    (``sys.stdout``) and for C and Fortran (file descriptor 1) — and :func:`say` writes to the
    standard output as it was. ``keep``: leave descriptor 1 on the standard error at the end (a
    program exits next, and Fortran flushes unit 6 at exit)."""
    from benchmarks.cli import args as cli_args
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    entry, mine = sys.stdout, None
    if sys.stdout is sys.__stdout__:          # the real stdout: write to it by the saved copy
        mine = io.TextIOWrapper(os.fdopen(os.dup(saved), "wb", buffering=0),
                                encoding=entry.encoding, errors=entry.errors, line_buffering=True)
    outer = cli_args._OUTPUT                  # a command run by a command (the probe)
    cli_args._OUTPUT = mine or entry          # under a test's capture: the capture
    sys.stdout = sys.stderr
    try:
        yield
    finally:
        sys.stdout = entry
        cli_args._OUTPUT = outer
        if mine is not None:
            mine.close()
        if not keep:
            os.dup2(saved, 1)
        os.close(saved)


if __name__ == "__main__":
    sys.exit(main())
