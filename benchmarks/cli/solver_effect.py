"""``rsfbench solver-effect``: does the integrator change what your data infer, on your problem?

    rsfbench solver-effect --problem apparatus.toml --observations obs/observations.json \\
        --b-range 0.0086,0.0102 --lc-range 3e-8,3e-6 --out se_mine          # quick: minutes
    rsfbench solver-effect --problem apparatus.toml --observations obs/observations.json \\
        --b-range 0.0086,0.0102 --lc-range 3e-8,3e-6 --full --study results/wp_full.csv

Every candidate setting inverts the observations' means (ΔT and Δμ with their σ: J1; the
file's slip-weakening curves are left out here) on the problem's own box and is compared with
the inversion by a tight reference (:mod:`benchmarks.inversion.solver_effect`, which writes the
files); the settings whose posterior is indistinguishable from the reference's are ranked by
their cost.
"""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.cli.args import b_range, bounded, flagged, in_file, lc_range, out_dir, say
from benchmarks.inversion.invert import check_box
from benchmarks.inversion.observations import read_observations
from benchmarks.inversion.solver_effect import QUICK_N, recommendation, write_solver_effect
from benchmarks.records.files import adopt, claim_outputs, write_output
from benchmarks.records.provenance import provenance, version_line
from benchmarks.records.report import jsonable
from problems import load_problem

#: the files ``solver-effect --out DIR`` writes (the study's, then its provenance)
SOLVER_EFFECT_FILES = ("solver_effect.csv", "solver_effect_recommendation.csv",
                       "solver_effect.md", "solver_effect.png", "solver_effect_provenance.json")

__all__ = ["add_parsers"]


def cmd_solver_effect(args) -> int:
    problem = load_problem(args.problem)
    flagged("--b-range/--lc-range", check_box, problem, args.b_range, args.lc_range)
    try:
        yours = read_observations(args.observations, curve_noise="none")  # J1 (docstring)
    except ValueError as exc:
        raise ValueError(f"--observations: {exc}") from None
    if args.study is not None and not args.full:
        raise ValueError("--study names the work-precision study of --full's candidates: add "
                         "--full")
    out = Path(args.out or f"solver_effect_{Path(args.problem).stem}")
    mine = [out / n for n in SOLVER_EFFECT_FILES]
    claim_outputs(mine)                   # before the work: a user's file of these names
    out.mkdir(parents=True, exist_ok=True)
    n = args.n or (31 if args.full else QUICK_N)
    own = (Path(args.problem).stem, problem, (args.b_range, args.lc_range))
    table = write_solver_effect(out, n=n, windows=(), laws=(), yours=yours, own=own,
                                quick=not args.full, study_csv=args.study,
                                progress=not args.json and not args.no_progress,
                                command=args.command_line)
    advice = recommendation(table)
    record = {"tool": version_line(), **provenance(), "command": args.command_line,
              "problem_file": str(Path(args.problem).resolve()),
              "observations_file": str(Path(args.observations).resolve()),
              "b_range": list(args.b_range), "lc_range_m": list(args.lc_range), "n": n,
              "mode": "full" if args.full else "quick"}
    adopt([p for p in mine[:-1] if p.exists()])   # the study's files, written by it just now
    write_output(mine[-1], json.dumps(jsonable(record), indent=2))
    summary = {"out": str(out), "recommendation": advice.to_dict(orient="records"),
               "rows": len(table), "provenance": record}
    if args.json:
        say(json.dumps(jsonable(summary), indent=2))
    else:
        say((out / "solver_effect.md").read_text())
        say(f"written: {out}/solver_effect.csv, solver_effect.md, solver_effect.png, "
            "solver_effect_recommendation.csv, solver_effect_provenance.json")
    return 0


def add_parsers(sub) -> None:
    p = sub.add_parser("solver-effect", help="does the integrator change what your observations "
                       "infer on your problem? every candidate's posterior (J1: the means; "
                       "curves left out) against a tight reference's, the indistinguishable "
                       "ones ranked by cost")
    p.add_argument("--problem", type=in_file, required=True, metavar="FILE",
                   help="your apparatus: a TOML or JSON problem file (no default)")
    p.add_argument("--observations", type=in_file, required=True, metavar="FILE.json",
                   help="your observations file, from rsfbench observe (no default)")
    p.add_argument("--b-range", type=b_range, required=True, metavar="LO,HI",
                   help="the prior box of b (no default)")
    p.add_argument("--lc-range", type=lc_range, required=True, metavar="LO,HI",
                   help="the prior box of Lc in m (no default)")
    p.add_argument("--full", action="store_true",
                   help="every candidate of the full work-precision study (--study) on 31-node "
                        f"grids (default: quick, the own methods' front settings and the "
                        f"paper's ETD2 on {QUICK_N}-node grids)")
    p.add_argument("--study", type=in_file, metavar="FILE.csv",
                   help="with --full: the work-precision study whose LSODA and SUNDIALS "
                        "settings are candidates too (default: none)")
    p.add_argument("--n", type=bounded(5, 301, "each setting solves N × N points"), metavar="N",
                   help=f"nodes per parameter of the posterior's grid, 5 to 301 (default: "
                        f"{QUICK_N}, or 31 with --full)")
    p.add_argument("--out", type=out_dir, metavar="DIR",
                   help="where to write solver_effect.* (default: ./solver_effect_<file name>)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.add_argument("--no-progress", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_solver_effect)
