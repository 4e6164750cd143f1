"""``rsfbench``: the command line of the harness.

    rsfbench simulate --preset W2 --law aging --json
    rsfbench windows --out results          # W1–W4 limit cycles, both laws, CSV + Markdown
    rsfbench integrators                    # the registry
    rsfbench work-precision --study quick   # every integrator over a ladder of settings
    rsfbench convergence --json             # observed orders of the fixed-step methods
    rsfbench convergence --fixed-steps      # ... and of the compiled stiff methods, control off
    rsfbench speedup --json                 # the paper's 1/10,000 claim, three ways
    rsfbench target --csv results/wp_quick.csv   # own integrators against LSODA and SUNDIALS
    rsfbench sweep --preset W2 --b 0.009:0.0098:0.0001 --lc 1e-7:1e-6:9log --json
    rsfbench reproduce --out results        # what `make reproduce` runs
    rsfbench readme [--check]               # refill the README's numbers from results/
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from benchmarks import metrics
from benchmarks.report import jsonable as _jsonable
from benchmarks.timing import warm_up
from integrators import REGISTRY, algorithm_class, make_algorithm, solve
from problems import PRESET_NAMES, preset

__all__ = ["main"]


def algorithm_name(name: str) -> str:
    """The registry's spelling of ``name`` (lookups are case-insensitive)."""
    return algorithm_class(name).name


def simulate_summary(sol) -> dict:
    """The JSON summary of one run (the keys ``rsfbench simulate --json`` promises)."""
    lc = metrics.summarize(sol)
    p = sol.problem
    per_event = metrics.event_metrics(sol.events, p.normal_force)
    last = per_event.iloc[-1].to_dict() if len(per_event) else {}
    return _jsonable({
        "problem": p.name, "law": p.law.name, "b": p.law.b, "lc_m": p.law.lc, "t_end": p.t_end,
        "integrator": sol.algorithm.name, "options": sol.algorithm.options(),
        "retcode": sol.retcode.value, "message": sol.message,
        "wall_s": sol.stats.wall_s, "steps": sol.stats.steps, "nfev": sol.stats.nfev,
        "njev": sol.stats.njev, "n_events": len(sol.events),
        "limit_cycle": lc.as_dict(),
        "last_event": {k: float(v) for k, v in last.items()},
    })


def _print_summary(s: dict) -> None:
    lc = s["limit_cycle"]
    print(f"{s['problem']}  (b = {s['b']:.5g}, Lc = {s['lc_m'] * 1e6:.4g} µm, {s['t_end']:g} s)")
    print(f"  integrator  {s['integrator']}   {s['retcode']}  {s['message']}".rstrip())
    print(f"  cost        {s['steps']} steps, {s['nfev']} rhs evaluations, {s['wall_s']:.4g} s wall")
    print(f"  events      {s['n_events']}   classification: {lc['classification']}")
    if lc["period"]:
        print(f"  limit cycle (period {lc['period']}, converged from event {lc['cycles_to_converge']}):")
        print(f"    recurrence interval  {lc['recurrence_s']:.6g} s")
        print(f"    friction drop        {lc['friction_drop']:.6g}")
        print(f"    slip per event       {lc['slip_m'] * 1e3:.6g} mm")
        print(f"    peak slip rate       {lc['peak_velocity_m_s']:.6g} m/s")
    elif s["last_event"]:
        e = s["last_event"]
        recurrence = "n/a" if e["recurrence_s"] is None else f"{e['recurrence_s']:.6g} s"
        print(f"  last event  at t = {e['t_start']:.6g} s: recurrence {recurrence}, "
              f"friction drop {e['friction_drop']:.6g}, slip {e['slip_m'] * 1e3:.6g} mm, "
              f"peak {e['peak_velocity_m_s']:.6g} m/s (run longer for the limit cycle)")


def cmd_simulate(args) -> int:
    problem = preset(args.preset, law=args.law, b=args.b, lc=args.lc, t_end=args.t_end)
    algorithm = make_algorithm(args.integrator, rtol=args.rtol, atol=args.atol, rhs=args.rhs)
    warm_up(problem, algorithm)     # so that wall_s excludes numba compilation
    sol = solve(problem, algorithm, max_points=200_000 if args.plot else 20_000,
                progress=args.progress, wall_budget=args.wall_budget)
    summary = simulate_summary(sol)
    if args.plot:
        from benchmarks.plots import plot_solution
        plot_solution(sol, args.plot)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        _print_summary(summary)
        if args.plot:
            print(f"  figure      {args.plot}")
    return 0 if sol.success else 1


def cmd_integrators(args) -> int:
    rows = [{"name": name, "family": cls.family, "order": cls.order,
             "stiff_order": cls.order if cls.stiff_order is None else cls.stiff_order, "adaptive": cls.adaptive,
             "stiff": cls.stiff, "library": cls.library, "version": cls.library_version()}
            for name, cls in sorted(REGISTRY.items(), key=lambda kv: kv[0].lower())]
    if args.json:
        print(json.dumps(rows, indent=2))
    elif args.markdown:
        import pandas as pd
        from benchmarks.report import markdown_table
        print(markdown_table(pd.DataFrame(rows)), end="")
    else:
        print(f"{'name':<22} {'order':>5}  {'adaptive':<8} {'family':<32} library")
        for r in rows:
            print(f"{r['name']:<22} {r['order']:>5}  {str(r['adaptive']):<8} {r['family']:<32} "
                  f"{r['library']} ({r['version']})")
    return 0


def cmd_windows(args) -> int:
    from benchmarks.windows import windows_table, write_windows
    table = windows_table(laws=args.law, integrator=make_algorithm(args.integrator),
                          t_end=args.t_end, progress=not args.json)
    if args.out:
        write_windows(table, Path(args.out))
    if args.json:
        print(table.to_json(orient="records", indent=2))
    else:
        print(table.to_string(index=False))
    return 0


def cmd_compare(args) -> int:
    from benchmarks.compare import compare_integrators
    from benchmarks.report import markdown_table
    problem = preset(args.preset, law=args.law, t_end=args.t_end)
    names = None if not args.integrators else [algorithm_name(n) for n in args.integrators]
    table = compare_integrators(problem, args.rtol, args.atol, names=names,
                                wall_budget=args.wall_budget, progress=not args.json)
    if args.out:
        table.to_csv(args.out, index=False)
    if args.json:
        print(table.to_json(orient="records", indent=2))
    else:
        shown = table.drop(columns=["library", "message"]).assign(
            wall_s=table.wall_s.map("{:.4g}".format),
            recurrence_s=table.recurrence_s.map(lambda x: f"{x:.8g}" if x == x and x is not None else ""),
            friction_drop=table.friction_drop.map(lambda x: f"{x:.7g}" if x == x and x is not None else ""))
        print(markdown_table(shown), end="")
    return 0


def _study_problem(spec: str):
    """``W2``, ``W2:aging`` or ``paper-example`` → the preset problem."""
    name, _, law = spec.partition(":")
    name = "paper-example" if name.lower() == "paper-example" else name.upper()
    return preset(name, law=law or "slip")


def cmd_work_precision(args) -> int:
    from benchmarks.report import ERROR_LEVELS, write_work_precision
    from benchmarks.work_precision import FULL, QUICK, best_at_levels, study_problems, work_precision
    ladder = FULL if args.study == "full" else QUICK
    if args.wall_budget is not None:
        ladder = dataclasses.replace(ladder, wall_budget=args.wall_budget)
    problems = ([_study_problem(x) for x in args.problems] if args.problems
                else study_problems(args.study))
    names = None if not args.integrators else [algorithm_name(n) for n in args.integrators]
    df = work_precision(problems, ladder, names=names, tiers=tuple(args.tiers),
                        progress=not args.no_progress)
    paths = write_work_precision(df, Path(args.out), args.name or args.study, error=args.error)
    pareto = best_at_levels(df, ERROR_LEVELS, args.error)
    if args.json:
        from benchmarks.work_precision import recommend
        print(json.dumps(_jsonable({
            "csv": str(paths["csv"]), "error": args.error,
            "recommendation": recommend(df, ERROR_LEVELS, args.error).to_dict(orient="records"),
            "pareto": pareto.to_dict(orient="records")}), indent=2))
    else:
        print(paths["pareto_md"].read_text())
        print("written: " + ", ".join(str(p) for p in paths.values()))
    return 0


def cmd_convergence(args) -> int:
    from benchmarks.convergence import convergence_study, convergence_summary, write_convergence
    names = None if not args.integrators else [algorithm_name(n) for n in args.integrators]
    if args.fixed_steps:
        return _fixed_step_orders(args, names)
    problem = _study_problem(args.problem)
    if args.t_end:
        problem = dataclasses.replace(problem, t_end=args.t_end)
    table, orders = convergence_study(problem, names=names, progress=not args.json)
    summary = (write_convergence(problem, table, orders, args.out) if args.out
               else convergence_summary(problem, table, orders))
    if args.json:
        print(json.dumps(_jsonable(summary), indent=2))
    else:
        print(table[["integrator", "dtau_cnst", "steps", "wall_s", "err_recurrence", "err_drop",
                     "fitted"]].to_string(index=False))
        for name, order in orders.items():
            print(f"{name}: observed order {order:.3f} (declared {REGISTRY[name].order}, on this "
                  f"stiff problem {REGISTRY[name].stiff_order}); finest error "
                  f"{summary['finest_error'][name]:.3g}")
    return 0


def _fixed_step_orders(args, names) -> int:
    from benchmarks.convergence import fixed_step_orders, write_fixed_step_orders
    table, orders = fixed_step_orders(names, progress=not args.json)
    summary = (write_fixed_step_orders(table, orders, args.out) if args.out
               else {"orders": orders})
    if args.json:
        print(json.dumps(_jsonable(summary), indent=2))
    else:
        print(table.to_string(index=False))
        for key, order in orders.items():
            name = key.split("/")[0]
            print(f"{key}: observed order {order:.2f} (declared {REGISTRY[name].order})")
    return 0


def cmd_readme(args) -> int:
    from benchmarks.readme import refresh
    stale = refresh(check=args.check)
    verb = "out of date" if args.check else "refilled"
    print(f"README blocks {verb}: {', '.join(stale)}" if stale else "README blocks up to date")
    return 1 if stale and args.check else 0


def cmd_speedup(args) -> int:
    from benchmarks.speedup import DEFAULT_SCIPY_BUDGET, speedup, speedup_markdown, write_speedup
    problem = preset("paper-example", t_end=args.t_end)
    budget = None if args.full else (args.scipy_budget or DEFAULT_SCIPY_BUDGET)
    implicit = None if not args.implicit else [algorithm_name(n) for n in args.implicit]
    summary, table = speedup(problem, rk_tol=args.rk_tol, scipy_budget=budget,
                             compiled_budget=args.compiled_budget, implicit=implicit,
                             progress=not args.json)
    if args.out:
        write_speedup(summary, table, args.out)
    if args.json:
        print(json.dumps(_jsonable(summary), indent=2))
    else:
        print(speedup_markdown(summary, table))
    return 0


def cmd_target(args) -> int:
    from benchmarks.target import write_target
    table = write_target(args.csv, args.out)
    if args.json:
        print(json.dumps(_jsonable(table.to_dict(orient="records")), indent=2))
    else:
        name = Path(args.csv).stem.removeprefix("wp_")
        print((Path(args.out) / f"target_{name}.md").read_text())
    return 0


def cmd_reproduce(args) -> int:
    from benchmarks.reproduce import reproduce
    reproduce(Path(args.out), scipy_budget=args.scipy_budget, start=args.start, only=args.only)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rsfbench", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="run one preset and summarise its limit cycle")
    s.add_argument("--preset", required=True, choices=PRESET_NAMES,
                   type=lambda x: "paper-example" if x.lower() == "paper-example" else x.upper())
    s.add_argument("--law", choices=("slip", "aging"), default="slip")
    s.add_argument("--b", type=float, help="evolution parameter b (default: the preset's)")
    s.add_argument("--lc", type=float, metavar="LC_METRES", help="critical slip distance Lc in m")
    s.add_argument("--t-end", type=float, help="simulated time in s (default: the preset's)")
    s.add_argument("--integrator", default="ETD2", help="registry name (see `rsfbench integrators`)")
    s.add_argument("--rtol", type=float, help="relative tolerance (adaptive integrators: required)")
    s.add_argument("--atol", type=float, help="absolute tolerance (adaptive integrators: required)")
    s.add_argument("--rhs", choices=("python", "numba"),
                   help="right-hand-side tier of adaptive integrators (default numba)")
    s.add_argument("--wall-budget", type=float, metavar="S", help="stop after S seconds of wall time")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.add_argument("--plot", metavar="FILE.png", help="draw v(t), μ(t) and the phase portrait")
    s.add_argument("--progress", action="store_true", help="show a progress bar")
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("integrators", help="list the registry")
    i.add_argument("--json", action="store_true")
    i.add_argument("--markdown", action="store_true", help="a Markdown table (for the README)")
    i.set_defaults(func=cmd_integrators)

    w = sub.add_parser("windows", help="limit cycles of W1–W4 against the observed means")
    w.add_argument("--law", nargs="+", choices=("slip", "aging"), default=["slip", "aging"])
    w.add_argument("--integrator", default="ETD2")
    w.add_argument("--t-end", type=float, default=None)
    w.add_argument("--out", help="directory for windows.csv and windows.md")
    w.add_argument("--json", action="store_true")
    w.set_defaults(func=cmd_windows)

    c = sub.add_parser("compare", help="every integrator on one preset, side by side")
    c.add_argument("--preset", default="paper-example", choices=PRESET_NAMES,
                   type=lambda x: "paper-example" if x.lower() == "paper-example" else x.upper())
    c.add_argument("--law", choices=("slip", "aging"), default="slip")
    c.add_argument("--t-end", type=float)
    c.add_argument("--rtol", type=float, required=True)
    c.add_argument("--atol", type=float, required=True)
    c.add_argument("--integrators", nargs="+", help="registry names (default: all)")
    c.add_argument("--wall-budget", type=float, default=120.0, metavar="S",
                   help="per-solve wall-time budget (default 120 s)")
    c.add_argument("--out", metavar="FILE.csv")
    c.add_argument("--json", action="store_true")
    c.set_defaults(func=cmd_compare)

    wp = sub.add_parser("work-precision", help="every integrator over a ladder of settings")
    wp.add_argument("--study", choices=("quick", "full"), default="quick",
                    help="quick: paper example + W2 aging, budget 10 s/run; full: paper example "
                         "and W1–W4 under both laws, budget 120 s/run")
    wp.add_argument("--problems", nargs="+", metavar="PRESET[:LAW]",
                    help="instead of the study's problems, e.g. paper-example W2:aging")
    wp.add_argument("--t-end", type=float, help="simulated time of every problem (default: each "
                    "preset's own)")
    wp.add_argument("--integrators", nargs="+", help="registry names (default: all)")
    wp.add_argument("--tiers", nargs="+", choices=("numba", "python"), default=["numba", "python"])
    wp.add_argument("--wall-budget", type=float, metavar="S", help="per-run wall-time budget")
    wp.add_argument("--error", default="err_recurrence",
                    choices=("err_recurrence", "err_drop", "err_slip", "err_peak_velocity",
                             "err_event_time", "err_trajectory"),
                    help="the error of the Pareto summary and the plots")
    wp.add_argument("--out", default="results")
    wp.add_argument("--name", help="file stem (default: the study's name)")
    wp.add_argument("--json", action="store_true", help="print the summary as JSON")
    wp.add_argument("--no-progress", action="store_true")
    wp.set_defaults(func=cmd_work_precision)

    cv = sub.add_parser("convergence", help="observed order of the fixed-step (ETD) methods")
    cv.add_argument("--problem", default="paper-example", metavar="PRESET[:LAW]")
    cv.add_argument("--t-end", type=float)
    cv.add_argument("--integrators", nargs="+", help="fixed-step registry names (default: all; "
                    "with --fixed-steps, the compiled stiff methods)")
    cv.add_argument("--fixed-steps", action="store_true",
                    help="the compiled stiff methods (Rosenbrock23, Rodas5P, Exprb32, Exprb43) "
                         "with error control off, on a stiff stick-phase segment")
    cv.add_argument("--out", help="directory for the CSV, JSON and plot")
    cv.add_argument("--json", action="store_true")
    cv.set_defaults(func=cmd_convergence)

    sp = sub.add_parser("speedup", help="the paper's 1/10,000 claim: ETD2 against RK45 three ways")
    sp.add_argument("--rk-tol", type=float, default=1e-6,
                    help="rtol = atol of both RK45 runs (default 1e-6)")
    sp.add_argument("--scipy-budget", type=float, metavar="S",
                    help="wall budget of scipy's RK45 (default 600 s; the full run takes ~40 min)")
    sp.add_argument("--full", action="store_true", help="run scipy's RK45 to the end, no budget")
    sp.add_argument("--compiled-budget", type=float, metavar="S",
                    help="wall budget of the compiled RK45 (default: none)")
    sp.add_argument("--t-end", type=float, help="simulated time (default: the paper's 20 s)")
    sp.add_argument("--implicit", nargs="+", metavar="NAME",
                    help="the implicit methods to search (default: every stiff adaptive one)")
    sp.add_argument("--out", help="directory for speedup.json, .csv and .md")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_speedup)

    t = sub.add_parser("target", help="issue 6's target: own integrators ≥ 2x faster than LSODA "
                       "and SUNDIALS at each error level, from a work-precision CSV")
    t.add_argument("--csv", default="results/wp_quick.csv")
    t.add_argument("--out", default="results")
    t.add_argument("--json", action="store_true")
    t.set_defaults(func=cmd_target)

    rd = sub.add_parser("readme", help="refill the README's generated blocks from results/")
    rd.add_argument("--check", action="store_true",
                    help="only say which blocks are out of date (exit status 1 if any)")
    rd.set_defaults(func=cmd_readme)

    r = sub.add_parser("reproduce", help="regenerate results/ (what `make reproduce` runs)")
    r.add_argument("--out", default="results")
    r.add_argument("--scipy-budget", type=float, metavar="S",
                   help="wall budget of scipy's RK45 in the speed-up step (default 600 s)")
    from benchmarks.reproduce import STEP_NAMES
    which = r.add_mutually_exclusive_group()
    which.add_argument("--from", dest="start", choices=STEP_NAMES, metavar="STEP",
                       help="start at this step, keeping the files of the earlier ones (steps: "
                            f"{', '.join(STEP_NAMES)})")
    which.add_argument("--only", choices=STEP_NAMES, metavar="STEP",
                       help="run this step alone, keeping the files of the others")
    r.set_defaults(func=cmd_reproduce)

    from benchmarks.cli_sweep import add_parsers
    add_parsers(sub, PRESET_NAMES)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:   # bad parameters: say which, no traceback
        print(f"rsfbench: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
