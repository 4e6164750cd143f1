"""``rsfbench observe``: a laboratory recording in, the observations of an inversion out.

    rsfbench observe run42.csv --column time=t:s --column shear_force=Fs:kN \\
        --column acceleration=a1:g --column slip=LDT:mm --column table=Table:mm \\
        --normal-force 997500 --mass 1100 --out obs_run42
    rsfbench observe run42.parquet --columns run42.toml --json
    rsfbench invert --problem obs_run42/apparatus.toml \\
        --observations obs_run42/observations.json --b-range 0.0086,0.0102 --lc-range 3e-8,3e-6

See :mod:`benchmarks.lab.observe_recording` for the files written and the column file, and
:mod:`benchmarks.lab.events` for how each quantity is measured.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from benchmarks.cli.args import in_file, out_dir, positive, say
from benchmarks.records.provenance import provenance
from benchmarks.records.report import jsonable

__all__ = ["add_parsers"]

HELP = """\
Measure a laboratory recording of stick-slip (CSV or Parquet) and write
what an inversion compares with: observations.json (the mean, standard
deviation and standard error of the recurrence interval, friction drop, slip
per event and peak slip rate; the events; the slip-weakening curves), events.csv,
curves.csv, apparatus.toml (a problem file of the apparatus as the record
shows it) and observe.png.

Map each column to a channel with its unit, CHANNEL=COLUMN[:UNIT]; channels
(SI unit): time (s), shear_force (N; the load cell), normal_force (N),
acceleration (m/s2; the slider's a1), acceleration_lower (m/s2; a2),
slip (m; across the fault), table (m; the load point's position). Units: s,
ms, us; N, kN, MN; m, mm, um, nm; m/s2, mm/s2, g. time and shear_force are
required; accelerations and the mass give the fault's friction Ft = Fs - m*a
and the curves; the table's position gives vLs, vLf, df and the stiffness."""


def cmd_observe(args) -> int:
    from benchmarks.lab.observe_recording import observe, read_column_file
    from benchmarks.lab.channels import column_spec
    columns, constants = read_column_file(args.columns) if args.columns else ({}, {})
    given = set()
    for spec in args.column:
        channel, column, unit = column_spec(spec)
        if channel in given:
            raise ValueError(f"--column {spec}: channel {channel} is mapped twice")
        given.add(channel)
        columns[channel] = (column, unit)
    if not columns:
        raise ValueError("map the recording's columns: --column CHANNEL=COLUMN[:UNIT] "
                         "(time and shear_force at least) or --columns FILE.toml")
    for key in ("normal_force", "mass", "vls", "stiffness"):
        if getattr(args, key) is not None:
            constants[key] = getattr(args, key)
    out = args.out or Path(f"observe_{Path(args.recording).stem}")
    record = {**provenance(), "command": args.command_line}
    doc = observe(args.recording, columns, out, sigma=args.sigma, plot=not args.no_plot,
                  provenance=record, **constants)
    if args.json:
        shown = {k: v for k, v in doc.items() if k not in ("curves", "events")}
        shown["curves_samples"] = len(doc["curves"]["slip_m"]) if doc["curves"] else 0
        say(json.dumps(jsonable(shown), indent=2))
        return 0
    m = doc["metrics"]
    say(f"{doc['n_events']} complete events in {args.recording} "
        f"({doc['recording']['rows']:,} rows at {doc['recording']['rate_hz']:.6g} Hz; slip from "
        f"{doc['recording']['slip_from']})")
    for name, label, scale, unit in (("recurrence_s", "recurrence interval", 1.0, "s"),
                                     ("friction_drop", "friction drop", 1.0, ""),
                                     ("slip_m", "slip per event", 1e3, "mm"),
                                     ("peak_velocity_m_s", "peak slip rate", 1.0, "m/s")):
        x = {k: _scaled(m[name].get(k), scale) for k in ("mean", "std", "sem")}
        say(f"  {label:20s} {x['mean']} {unit:3s} std {x['std']}, sem {x['sem']}")
    a = doc["apparatus"]
    for key, label, unit in (("stiffness", "stiffness k", "N/m"), ("vls", "vLs", "m/s"),
                             ("vlf", "vLf", "m/s"), ("df", "df", "s")):
        if a.get(key) is not None:
            say(f"  {label:20s} {a[key]:.6g} {unit:3s} ({doc['how'].get(key, '')})")
    for note in doc["notes"]:
        say(f"  note: {note}")
    say(f"  σ of an inversion: {doc['sigma']} (the events' standard deviation, as the paper's; "
        "--sigma sem for the mean's standard error)" if doc["sigma"] == "std" else
        f"  σ of an inversion: {doc['sigma']}")
    say(f"written: {', '.join(doc['files'].values())}")
    return 0


def _scaled(value, scale: float) -> str:
    """A metric of the file (None where it is not a number: not measured on this record, or
    a spread of fewer than two events) for the text output."""
    return "–" if value is None else f"{value * scale:.6g}"


def add_parsers(sub) -> None:
    o = sub.add_parser("observe", help="measure a laboratory recording: its events, ΔT, Δμ, "
                       "slip, peak slip rate, curves and apparatus, for an inversion",
                       description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    o.add_argument("recording", type=in_file, metavar="RECORDING",
                   help="the recording: .csv, .txt, .tsv, .dat (one header line) or .parquet")
    o.add_argument("--column", action="append", default=[], metavar="CHANNEL=COLUMN[:UNIT]",
                   help="a column and its unit (repeatable; the unit defaults to the "
                        "channel's SI unit; overrides --columns)")
    o.add_argument("--columns", type=in_file, metavar="FILE.toml",
                   help="a column file: [columns] and [apparatus] (default: none)")
    o.add_argument("--normal-force", type=positive, metavar="N",
                   help="the normal force in N, when no column holds it (default: the "
                        "normal_force column, or the column file's)")
    o.add_argument("--mass", type=positive, metavar="KG",
                   help="the slider's mass in kg, for Ft = Fs - m·a and the curves (default: "
                        "none, and no curves)")
    o.add_argument("--vls", type=positive, metavar="M/S",
                   help="the slow load-point speed in m/s (default: from the table column)")
    o.add_argument("--stiffness", type=positive, metavar="N/M",
                   help="the apparatus's stiffness in N/m (default: measured)")
    o.add_argument("--sigma", choices=("std", "sem"), default="std",
                   help="the σ an inversion reads from the file: the events' standard "
                        "deviation (the paper's) or the mean's standard error (default: std)")
    o.add_argument("--out", type=out_dir, metavar="DIR",
                   help="directory of the files (default: ./observe_<recording's name>)")
    o.add_argument("--no-plot", action="store_true", help="do not draw observe.png")
    o.add_argument("--json", action="store_true",
                   help="print the observations (without the curves) as one JSON object")
    o.set_defaults(func=cmd_observe)
