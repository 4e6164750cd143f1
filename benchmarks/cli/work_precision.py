"""``rsfbench compare``, ``work-precision`` and ``convergence``: the integrators measured, side by
side on one problem, over a ladder of settings, and their observed orders.

    rsfbench compare --preset W2 --rtol 1e-6 --atol 1e-9
    rsfbench work-precision --study quick   # every integrator over a ladder of settings
    rsfbench convergence --json             # observed orders of the fixed-step methods
    rsfbench convergence --fixed-steps      # ... and of the compiled stiff methods, control off
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np

from benchmarks.cli.args import (
    RunStopped,
    flagged,
    in_file,
    out_dir,
    out_file,
    positive,
    preset_name,
    say,
    show_progress,
)
from benchmarks.devtools.reference import ReferenceDisagreement, no_stick_slip, reference
from benchmarks.devtools.work_precision import (
    FULL,
    QUICK,
    best_at_levels,
    fastest_within,
    recommend,
    study_problems,
    work_precision,
)
from benchmarks.inversion.observations import read_observations
from benchmarks.records.files import claim_outputs, write_table
from benchmarks.records.provenance import version_line
from benchmarks.records.report import jsonable as _jsonable, markdown_table
from integrators import REGISTRY, algorithm_class
from problems import LAWS, PRESET_NAMES, load_problem, preset, variant

__all__ = ["add_parsers"]


def algorithm_name(name: str, flag: str = "--integrators") -> str:
    """The registry's spelling of ``name`` (lookups are case-insensitive)."""
    return flagged(flag, algorithm_class, name).name


def cmd_compare(args) -> int:
    from benchmarks.devtools.compare import compare_integrators
    if args.problem is not None:
        if args.preset is not None or args.law is not None:
            raise ValueError("--problem FILE names its own law: drop --preset and --law")
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
    table["rsfbench"], table["command"] = version_line(), args.command_line
    if args.out:
        write_table(table, args.out)
    if args.json:
        say(table.to_json(orient="records", indent=2))
    else:
        shown = table.drop(columns=["library", "message", "problem", "rsfbench",
                                    "command"]).assign(
            wall_s=table.wall_s.map("{:.4g}".format),
            recurrence_s=table.recurrence_s.map(
                lambda x: f"{x:.8g}" if x == x and x is not None else ""),
            friction_drop=table.friction_drop.map(
                lambda x: f"{x:.7g}" if x == x and x is not None else ""),
            **{c: table[c].map(lambda x: "" if x != x else f"{x:.2g}")
               for c in table.columns if c.endswith("_sigma")})
        say(markdown_table(shown), end="")
    return 0


def _errors_in_sigma(table, problem, path, wall_budget):
    """``table`` with each integrator's ΔT and Δμ (of the last event) off the tight reference
    in units of the observations' σ, and whether both are within σ/10: the references are
    those of invert's check, which must agree to σ/100."""
    from benchmarks.devtools.compare import compare_integrators
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
    from benchmarks.devtools.wp_files import ERROR_LEVELS, write_work_precision
    ladder = FULL if args.study == "full" else QUICK
    if args.wall_budget is not None:
        ladder = dataclasses.replace(ladder, wall_budget=args.wall_budget)
    problems = _wp_problems(args)
    limits = None
    if args.observations is not None:
        limits = _limits_of(args.observations)
    names = None if not args.integrators else [algorithm_name(n) for n in args.integrators]
    _claim_wp_files(args, problems)
    _check_references(problems)
    tiers = tuple(args.tiers or ("numba", "python"))
    if args.problem and names is None:       # on your problem: the compiled ones, in minutes
        names = REGISTRY.select("compiled")
        tiers = tuple(args.tiers or ("numba",))
    df = work_precision(problems, ladder, names=names, tiers=tiers,
                        progress=show_progress(args))
    df["command"] = args.command_line                 # the rows carry the machine's already
    paths = write_work_precision(df, Path(args.out), args.name or args.study, error=args.error)
    pareto = best_at_levels(df, ERROR_LEVELS, args.error)
    yours = None if limits is None else _for_your_sigma(args, df, limits, paths)
    if args.json:
        say(json.dumps(_jsonable({
            "csv": str(paths["csv"]), "error": args.error,
            "recommendation": recommend(df, ERROR_LEVELS, args.error).to_dict(orient="records"),
            "pareto": pareto.to_dict(orient="records"), "for_your_sigma": yours,
            "problems": [p.name for p in problems], "command": args.command_line}), indent=2))
    else:
        say(paths["pareto_md"].read_text())
        if yours is not None:
            say(_your_sigma_line(yours, limits))
        say("written: " + ", ".join(str(p) for p in paths.values()))
    return 0


def _wp_problems(args) -> list:
    """The problems of --problems and --problem (the study's without either), at --t-end."""
    problems = [_study_problem(x) for x in args.problems] if args.problems else []
    if args.problem:
        problems += [load_problem(f) for f in args.problem]
    problems = problems or study_problems(args.study)
    if args.t_end is not None:
        problems = [dataclasses.replace(p, t_end=args.t_end) for p in problems]
    return problems


def _claim_wp_files(args, problems) -> None:
    """The study's files, claimed before the work: a user's file of their names is refused."""
    stem = Path(args.out) / f"wp_{args.name or args.study}"
    claim_outputs([*(Path(f"{stem}{tail}") for tail in (".csv", "_pareto.csv", "_pareto.md",
                                                        "_for_sigma.csv")),
                   *(Path(f"{stem}_{re.sub(r'[^A-Za-z0-9._-]+', '_', p.name)}.png")
                     for p in problems)])


def _check_references(problems) -> None:
    """Refuse a problem without stick–slip (exit 2) or without a reference the two tight
    solvers agree on (exit 1), before any run; the study reads the references cached."""
    for problem in problems:
        why = no_stick_slip(problem)
        if why:                                # nothing to measure: refused, one line
            raise ValueError(f"work-precision: {why}")
        try:
            reference(problem)
        except ReferenceDisagreement as exc:   # no stick–slip, or no reference: one line
            raise RunStopped(f"work-precision: {exc}") from None


def _for_your_sigma(args, df, limits, paths) -> dict:
    """The settings within ``limits`` on every problem, written to ``paths["for_your_sigma"]``
    (added to ``paths``), and the fastest of them."""
    within = fastest_within(df, limits)
    paths["for_your_sigma"] = Path(args.out) / f"wp_{args.name or args.study}_for_sigma.csv"
    write_table(within, paths["for_your_sigma"])
    return {"limits": limits, "observations": str(args.observations),
            "choice": within.iloc[0].to_dict() if len(within) else None,
            "n_within": len(within)}


def _your_sigma_line(yours: dict, limits: dict) -> str:
    c = yours["choice"]
    levels = ", ".join(f"{k} ≤ {v:.3g}" for k, v in limits.items())
    return f"for your σ (σ/10 of each mean: {levels}): " + (
        f"{c['integrator']} [{c['rhs_tier']}] at {c['setting']:g}, "
        f"{c['total_wall_s']:.3g} s over the problems; {yours['n_within'] - 1} other "
        "settings also qualify" if c is not None else
        "no setting of this study is accurate enough on every problem")


def _limits_of(path) -> dict:
    """The relative errors an inversion of the observations file ``path`` tolerates: σ/10 of
    each mean, as the solver check of invert requires."""
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


def add_parsers(sub) -> None:
    _add_compare(sub)
    _add_work_precision(sub)
    _add_convergence(sub)


def _add_compare(sub) -> None:
    c = sub.add_parser("compare", help="every integrator on one problem, side by side")
    c.add_argument("--preset", choices=PRESET_NAMES, type=preset_name,
                   help="the problem (default: paper-example)")
    c.add_argument("--problem", type=in_file, metavar="FILE",
                   help="or your own apparatus: a TOML or JSON problem file (default: none)")
    c.add_argument("--law", choices=tuple(LAWS), help="friction law of --preset "
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


def _add_work_precision(sub) -> None:
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


def _add_convergence(sub) -> None:
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
