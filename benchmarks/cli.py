"""``rsfbench``: the command line of the harness.

    rsfbench simulate --preset W2 --law aging --json
    rsfbench windows --out results          # W1–W4 limit cycles, both laws, CSV + Markdown
    rsfbench integrators                    # the registry
    rsfbench reproduce --out results        # what `make reproduce` runs
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from benchmarks import metrics
from benchmarks.timing import warm_up
from integrators import REGISTRY, algorithm_class, make_algorithm, solve
from problems import PRESET_NAMES, preset

__all__ = ["main"]


def _jsonable(x):
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_jsonable(v) for v in x]
    return x


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
             "stiff_order": cls.stiff_order or cls.order, "adaptive": cls.adaptive,
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


def cmd_reproduce(args) -> int:
    from benchmarks.reproduce import reproduce
    reproduce(Path(args.out))
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

    r = sub.add_parser("reproduce", help="regenerate results/ (what `make reproduce` runs)")
    r.add_argument("--out", default="results")
    r.set_defaults(func=cmd_reproduce)
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
