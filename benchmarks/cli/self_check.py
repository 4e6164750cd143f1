"""``rsfbench self-check``: would an inversion of a recording like mine find the truth?

    rsfbench self-check --problem apparatus.toml --observations obs/observations.json \\
        --inversion inv --out check                 # the truth: inv's fit, its box
    rsfbench self-check --problem apparatus.toml --observations obs/observations.json \\
        --b 0.0096 --lc 5e-7 --b-range 0.0086,0.0102 --lc-range 3e-8,3e-6 --json

See :mod:`benchmarks.lab.self_check` for what is copied of the recording and what is written.
"""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.cli.args import (add_integrator_options, add_problem_choice, b_range, bounded,
                                 chain_steps, chain_walkers, in_file, integrator_from_args,
                                 lc_range, out_dir, positive, problem_from_args, say, seed,
                                 workers)
from benchmarks.records.report import jsonable
from problems import PRESET_NAMES

__all__ = ["add_parsers"]

HELP = """\
A recording of your apparatus made by the model at a truth you choose (by
default the fit of your inversion, --inversion DIR), with your recording's
sampling rate, duration, channels and noise level (read from the observations
file observe wrote), measured by observe and inverted with the means alone and
with the curves, in your inversion's prior box. It says whether each 95 %
region (the posterior's marginal intervals of b and log10 Lc) holds the truth:
if it does not, the same inversion of your recording is not to be read.

Runtime: two inversions (each the grid posterior, the fit and two profiles)
and one forward run of the recording; minutes on two cores with the defaults,
about a quarter of that with --grid 9 --profile-points 5. When no grid
posterior passes its checks, emcee runs walkers × steps more forward solves
(64,000 by default: an hour or more at a tight tolerance); --steps 0 judges
the profiles' intervals instead."""


def _truth_and_box(args):
    """``(b, lc, b_range, lc_range)``: the options', else the fit and box of --inversion."""
    fit = box = None
    if args.inversion is not None:
        path = Path(args.inversion)
        path = path / "inversion.json" if path.is_dir() else path
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
            fit, box = doc["fit"], (tuple(doc["b_range"]), tuple(doc["lc_range_m"]))
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"--inversion {args.inversion}: not an inversion of `rsfbench "
                             f"invert` (its inversion.json: {exc})") from None
    b = args.b if args.b is not None else (fit or {}).get("b")
    lc = args.lc if args.lc is not None else (fit or {}).get("lc_m")
    if b is None or lc is None:
        raise ValueError("the truth: give --inversion DIR (its fit) or --b and --lc")
    ranges = (args.b_range or (box or (None, None))[0], args.lc_range or (box or (None, None))[1])
    if ranges[0] is None or ranges[1] is None:
        raise ValueError("the prior box: give --inversion DIR (its box) or --b-range and "
                         "--lc-range")
    return float(b), float(lc), ranges[0], ranges[1]


def cmd_self_check(args) -> int:
    from benchmarks.lab.self_check import covered_text, self_check
    problem = problem_from_args(args, fields=())
    b, lc, box_b, box_lc = _truth_and_box(args)
    algorithm, why = integrator_from_args(args)
    out = Path(args.out or "self_check")
    talk = (lambda text: None) if args.json else (lambda text: say(f"… {text}"))
    result = self_check(args.observations, problem, b, lc, out, box_b, box_lc, algorithm,
                        grid=args.grid, profile_points=args.profile_points, seed=args.seed,
                        walkers=args.walkers, steps=args.steps, workers=args.workers, say=talk)
    result["integrator"] = why
    if args.json:
        say(json.dumps(jsonable(result), indent=2))
    else:
        say(f"integrator: {why}")
        for label in ("means", "curves"):
            say(covered_text(f"{label:6s}", result[label], result["truth"]))
        say(f"wall time {result['wall_s']:.0f} s; written under {out}")
    return 0 if all(result[k] is None or result[k]["covered"] for k in ("means", "curves")) \
        else 1


def add_parsers(sub) -> None:
    import argparse
    p = sub.add_parser("self-check", help="a recording like yours made by the model at a known "
                       "truth, through observe and invert: does the 95 %% region hold it?",
                       description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_problem_choice(p, PRESET_NAMES, "your apparatus (its mass, k, Fn, loading, a)")
    p.add_argument("--observations", type=in_file, required=True, metavar="FILE.json",
                   help="the observations file observe wrote of your recording: its rate, "
                        "duration, channels and noise are copied (no default)")
    p.add_argument("--inversion", metavar="DIR",
                   help="your inversion's directory (or its inversion.json): the truth is its "
                        "least-squares fit, the box its box (default: none; then --b, --lc, "
                        "--b-range, --lc-range)")
    p.add_argument("--b", type=positive, help="the truth's b, dimensionless (default: the "
                   "--inversion's fit)")
    p.add_argument("--lc", type=positive, metavar="M", help="the truth's Lc in metres (default: the "
                   "--inversion's fit)")
    p.add_argument("--b-range", type=b_range, metavar="LO,HI",
                   help="the prior box in b (default: the --inversion's)")
    p.add_argument("--lc-range", type=lc_range, metavar="LO,HI",
                   help="the prior box in Lc, m (default: the --inversion's)")
    p.add_argument("--grid", type=bounded(3, 1001, "the first grid is solved in one batch"),
                   default=33, metavar="N", help="the grid posterior's first grid, N × N "
                   "(default: 33)")
    p.add_argument("--profile-points", type=bounded(3, 1001, "each is a line of solves"),
                   default=21, metavar="N", help="values of each profiled parameter "
                   "(default: 21)")
    p.add_argument("--walkers", type=chain_walkers, default=32, metavar="N",
                   help="emcee walkers of the posterior's last resort, when no grid passes "
                        "its checks (default: 32)")
    p.add_argument("--steps", type=chain_steps, default=2000, metavar="N",
                   help="emcee steps per walker of that last resort (walkers × steps forward "
                        "solves); 0: no posterior, the profiles' 95 %% intervals are judged "
                        "(default: 2000)")
    p.add_argument("--seed", type=seed, default=0, help="the recording's noise seed "
                   "(default: 0)")
    p.add_argument("--workers", type=workers, metavar="N",
                   help="threads of a batch of solves (default: all cores)")
    add_integrator_options(p)
    p.add_argument("--out", type=out_dir, metavar="DIR",
                   help="directory of the files (default: ./self_check)")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.set_defaults(func=cmd_self_check)
