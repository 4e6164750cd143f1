"""``rsfbench design``: before a velocity-step test, how well would it resolve (a, b, Dc, k′), and
which change to the plan resolves a chosen parameter best?

    rsfbench design --velocities 1,10 --durations 20,40 --rate 50 --noise 6e-4 \\
        --a 0.006 --b 0.009 --dc 10 --stiffness 3000 \\
        --vary rate=500 --vary stiffness=30000 --vary velocities=1,30 --vary durations=20,120
    rsfbench design ... --check 100 --out design          # against 100 repeated fits

The expected standard errors come from the Fisher information of the planned record, with the
exact sensitivities of the fit's own model (:mod:`benchmarks.lab.design`, which states what it
assumes); ``--check N`` fits N records of an independent model with the plan's noise and sets the
spread of the estimates beside them.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from benchmarks.cli.args import (bounded, non_negative, numbers, out_dir, positive, quantity,
                                 say, seed, show_progress)
from benchmarks.lab.design import (CHECK_MIN, DETRENDS, Plan, check_plan, compare_plans,
                                   fisher_errors, undetermined)
from benchmarks.records.files import claim_outputs, write_output, write_table
from benchmarks.records.provenance import provenance, version_line
from benchmarks.records.report import jsonable
from problems import LAWS

__all__ = ["add_parsers"]

#: the files ``design --out DIR`` may write
DESIGN_FILES = ("design.csv", "design_errors.csv", "design_check.csv",
                "design_provenance.json")
#: what ``--vary`` may change, with the unit its value is given in and the Plan field's factor
VARIABLE = {"velocities": ("µm/s", 1e-6), "durations": ("s", 1.0), "rate": ("Hz", 1.0),
            "noise": ("σ of μ", 1.0), "stiffness": ("per m", 1.0), "a": ("1", 1.0),
            "b": ("1", 1.0), "dc": ("µm", 1e-6)}
_FIELD = {"stiffness": "k"}
_PIECES = ("velocities", "durations")


def _variation(text: str) -> tuple[str, str, object]:
    """``--vary NAME=VALUE``: (the text, a field of the plan, its value in the field's unit)."""
    name, sep, value = text.partition("=")
    if not sep or name not in VARIABLE:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE with NAME one of "
                                         f"{', '.join(VARIABLE)}, got {text!r}")
    unit, factor = VARIABLE[name]
    values = tuple(v * factor for v in numbers(f"numbers in {unit}", "1,10")(value))
    if name not in _PIECES and len(values) != 1:
        raise argparse.ArgumentTypeError(f"--vary {name}: one number in {unit}, got {value!r}")
    return text, _FIELD.get(name, name), values if name in _PIECES else values[0]


def _plans(args) -> dict:
    """The plan and each ``--vary`` of it, by label."""
    base = Plan(velocities=tuple(v * 1e-6 for v in args.velocities), durations=args.durations,
                rate=args.rate, noise=args.noise, a=args.a, b=args.b, dc=args.dc * 1e-6,
                k=args.stiffness, law=args.law, c=args.c, detrend=args.detrend)
    plans = {"plan": base}
    for text, field, value in args.vary or ():
        if text in plans:
            raise ValueError(f"--vary {text} is given twice")
        try:
            plans[text] = Plan(**{**base.__dict__, field: value})
        except ValueError as exc:
            raise ValueError(f"--vary {text}: {exc}") from None
    return plans


def _check(args, plan):
    """``--check N``'s table, with a progress bar on a terminal."""
    if not args.check:
        return None
    from tqdm.auto import tqdm
    with tqdm(total=args.check, desc="repeated fits", unit="fit",
              disable=not show_progress(args)) as bar:
        return check_plan(plan, n=args.check, seed=args.seed,
                          progress=lambda i, n: bar.update(1))


def cmd_design(args) -> int:
    if 0 < args.check < CHECK_MIN:
        raise ValueError(f"--check {args.check}: 0 (none) or at least {CHECK_MIN} fits (the "
                         "spread of fewer is no measure of an error)")
    plans = _plans(args)
    if args.target not in plans["plan"].fitted + ("a_minus_b",):
        raise ValueError(f"--target {args.target}: the {args.law} law's fit has "
                         f"{', '.join(plans['plan'].fitted)} and a_minus_b")
    mine = [args.out / n for n in DESIGN_FILES] if args.out else []
    claim_outputs(mine)                   # before the work: a user's file of these names
    table = compare_plans(plans, target=args.target)
    errors = fisher_errors(plans["plan"])
    check = _check(args, plans["plan"])
    record = {"tool": version_line(), **provenance(), "command": args.command_line,
              "assumes": "white noise of --noise; the law and values given (the fit lands "
                         "near them); the history known; the level (and --detrend) fitted "
                         "linearly (benchmarks/lab/design.py)",
              "plans": {k: {**p.__dict__, "samples": p.samples} for k, p in plans.items()}}
    if args.out:
        _write(args.out, table, errors, check, record)
    _report(args, table, errors, check, record)
    return 0


def _write(out: Path, table, errors, check, record) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_table(table, out / "design.csv")
    write_table(errors, out / "design_errors.csv")
    if check is not None:
        write_table(check, out / "design_check.csv")
    write_output(out / "design_provenance.json", json.dumps(jsonable(record), indent=2))


def _report(args, table, errors, check, record) -> None:
    if args.json:
        say(json.dumps(jsonable({"errors": errors.to_dict(orient="records"),
                                 "undetermined": undetermined(errors),
                                 "designs": table.to_dict(orient="records"),
                                 "check": None if check is None else
                                 check.to_dict(orient="records"),
                                 "out": str(args.out) if args.out else None,
                                 "provenance": record}), indent=2))
        return
    say("expected standard errors of the plan (Fisher information, white noise):")
    say(errors.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    lost = undetermined(errors)
    if lost:
        say(f"the plan does not determine {', '.join(lost)}: the other errors hold "
            f"{'it' if len(lost) == 1 else 'them'} fixed, and a fit would not")
    say(f"\nthe designs, by the target {args.target}'s relative se (relative se per parameter; "
        "gain over the plan):")
    say(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    best = table.loc[table.best, "design"]
    say(f"\nbest for {args.target}: {best.iloc[0]}" if len(best) else
        f"\nno design determines {args.target}")
    if check is not None:
        say(f"\nagainst {int(check.fits.iloc[0])} fits to records of the independent model "
            "(ratio = Fisher se / the fits' spread):")
        say(check.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


def add_parsers(sub) -> None:
    p = sub.add_parser("design", help="before a velocity-step test: the expected standard "
                       "errors of (a, b, Dc, k′) from the Fisher information, and which change "
                       "to the plan resolves a parameter best")
    p.add_argument("--velocities", type=numbers("speeds in µm/s", "1,10"), required=True,
                   metavar="V1,V2,…", help="the load point's speed on each piece, µm/s (0 a "
                   "hold; the first > 0; no default)")
    p.add_argument("--durations", type=numbers("times in s", "20,40"), required=True,
                   metavar="S1,S2,…", help="how long each piece lasts, s (no default)")
    p.add_argument("--rate", type=quantity(positive, "a sampling rate in Hz"), required=True,
                   metavar="HZ", help="samples per second (no default)")
    p.add_argument("--noise", type=quantity(positive, "σ of μ, dimensionless"), required=True,
                   metavar="SIGMA", help="σ of the friction's white noise (no default)")
    p.add_argument("--a", type=quantity(positive, "dimensionless"), required=True,
                   help="the expected a (no default)")
    p.add_argument("--b", type=float, required=True, help="the expected b (no default)")
    p.add_argument("--dc", type=quantity(positive, "a slip in µm"), required=True,
                   metavar="UM", help="the expected Dc, µm (no default)")
    p.add_argument("--stiffness", type=quantity(positive, "k′ per m of load point"),
                   required=True, metavar="PER_M",
                   help="the expected k′, friction per m of load-point travel (0.001 per µm is "
                        "1000; no default)")
    p.add_argument("--law", choices=tuple(LAWS), default="aging", help="default: aging")
    p.add_argument("--c", type=quantity(non_negative, "dimensionless"), default=2.0,
                   help="the Nagata law's c (default 2)")
    p.add_argument("--detrend", choices=DETRENDS, default="none",
                   help="what the fit takes out linearly besides the level (default: none)")
    p.add_argument("--vary", type=_variation, action="append", metavar="NAME=VALUE",
                   help=f"an alternative plan: the plan with one change, NAME one of "
                        f"{', '.join(f'{k} ({u})' for k, (u, _) in VARIABLE.items())}; "
                        "repeat for more (default: none)")
    p.add_argument("--target", default="dc", help="the parameter the designs are ranked by: "
                   "a, b, dc, k, c (Nagata) or a_minus_b (default: dc)")
    p.add_argument("--check", type=bounded(0, 10_000, "fits"), default=0, metavar="N",
                   help=f"fit N records (at least {CHECK_MIN}) of the independent model with "
                        "the plan's noise and compare their spread with the Fisher errors "
                        "(default: 0, none)")
    p.add_argument("--seed", type=seed, default=0, help="the check's first seed (default 0)")
    p.add_argument("--out", type=out_dir, metavar="DIR",
                   help="write design.csv, design_errors.csv, design_check.csv and "
                        "design_provenance.json there (default: nothing written)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--no-progress", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_design)
