"""``rsfbench observe``: a laboratory recording in, the observations of an inversion out.

    rsfbench observe run42.csv --column time=t:s --column shear_force=Fs:kN \\
        --column acceleration=a1:g --column slip=LDT:mm --column table=Table:mm \\
        --normal-force 997500 --mass 1100 --out obs_run42
    rsfbench observe run42.parquet --columns run42.toml --json
    rsfbench observe --catalogue events.csv --column onset=t0:s \
        --column drop=stress_drop:MPa --column slip=slip:mm --area 0.4 --normal-stress 2e6
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
shows it) and observe.png. Or read an event catalogue (--catalogue FILE: one
row per event) into observations.json and events.csv, and with the slip per
event and the normal load, apparatus.toml: the stiffness (median drop/slip) and
the load-point speed (the loading rate between events over k) estimated from
it with their standard errors; the mass (--mass) and the law's a not in it.

Map each column to a channel with its unit, CHANNEL=COLUMN[:UNIT] (the unit
after the column's last colon; a column's name may hold colons and brackets).
Recording channels (SI unit): time (s), shear_force (N; the load cell) or
shear_stress (Pa; with --area) or friction (dimensionless Fs/Fn),
normal_force (N) or normal_stress (Pa; with --area), acceleration (m/s2; the
slider's a1), acceleration_lower (m/s2; a2), slip (m; across the fault), table
(m; the load point's position). Catalogue channels: onset (s); the drop as
shear_stress_before and shear_stress_after (Pa), or friction_before and
friction_after, or drop (a friction drop, or with a stress unit a stress
drop); slip (m), duration (s), peak_slip_rate (m/s). Units: s, ms, us; N, kN,
MN; Pa, kPa, MPa; m, mm, um, nm; m/s2, mm/s2, g; m/s, mm/s; 1.

The events that differ from the settled cycle by more than 5 robust σ are
named: a leading run of them (the start-up) is left out of the means unless
--keep-startup; later ones (outliers) are kept. --window START END measures
only that part of the record."""


def cmd_observe(args) -> int:
    from benchmarks.lab.catalogue import observe_catalogue
    from benchmarks.lab.observe_recording import check_window, observe
    source = _source(args)
    window = check_window(args.window)
    columns, constants = _columns(args)
    out = args.out or Path(f"observe_{Path(source).stem}")
    record = {**provenance(), "command": args.command_line}
    common = dict(sigma=args.sigma, provenance=record, window=window,
                  keep_startup=args.keep_startup)
    if args.catalogue:
        doc = observe_catalogue(source, columns, out, **common, after_delay=args.after_delay,
                                **{k: v for k, v in constants.items()
                                   if k in ("area", "normal_force", "normal_stress", "mass")})
    else:
        doc = observe(source, columns, out, plot=not args.no_plot, **common, **constants)
    if args.json:
        shown = {k: v for k, v in doc.items() if k not in ("curves", "events")}
        shown["curves_samples"] = len(doc["curves"]["slip_m"]) if doc["curves"] else 0
        say(json.dumps(jsonable(shown), indent=2))
        return 0
    _print(doc, source)
    return 0


def _source(args) -> Path:
    """The recording or the catalogue: one of them; options of the other refused."""
    if (args.recording is None) == (args.catalogue is None):
        raise ValueError("give a recording (RECORDING) or an event catalogue (--catalogue "
                         "FILE), one of them")
    if args.catalogue:
        given = [f for f, v in (("--columns", args.columns), ("--vls", args.vls),
                                ("--stiffness", args.stiffness), ("--no-plot", args.no_plot))
                 if v]
        if given:
            raise ValueError(f"{given[0]} is for a recording, not for a catalogue "
                             f"({args.catalogue}: its k and vL are estimated from it; edit "
                             "apparatus.toml to take others)")
    elif args.after_delay is not None:
        raise ValueError(f"--after-delay is for a catalogue (--catalogue FILE), not for the "
                         f"recording {args.recording}")
    return args.catalogue or args.recording


def _columns(args) -> tuple[dict, dict]:
    from benchmarks.lab.catalogue import CATALOGUE_CHANNELS
    from benchmarks.lab.channels import column_spec
    from benchmarks.lab.observe_recording import read_column_file
    columns, constants = read_column_file(args.columns) if args.columns else ({}, {})
    known = CATALOGUE_CHANNELS if args.catalogue else None
    given = set()
    for spec in args.column:
        channel, column, unit = column_spec(spec, known)
        if channel in given:
            raise ValueError(f"--column {spec}: channel {channel} is mapped twice")
        given.add(channel)
        columns[channel] = (column, unit)
    if not columns:
        raise ValueError("map the columns: --column CHANNEL=COLUMN[:UNIT] (time and "
                         "shear_force at least; a catalogue's onset and its drop) or "
                         "--columns FILE.toml")
    for key in ("normal_force", "normal_stress", "area", "mass", "vls", "stiffness"):
        if getattr(args, key) is not None:
            constants[key] = getattr(args, key)
    return columns, constants


def _print(doc: dict, source) -> None:
    m, rec = doc["metrics"], doc["recording"]
    used, n = doc.get("n_events_used", doc["n_events"]), doc["n_events"]
    if rec.get("kind") == "catalogue":
        say(f"{n} events in the catalogue {source}, {used} in the means")
    else:
        say(f"{n} complete events in {source}, {used} in the means ({rec['rows']:,} rows at "
            f"{rec['rate_hz']:.6g} Hz; slip from {rec['slip_from']})")
    every = doc.get("metrics_all_events", m)
    for name, label, scale, unit in (("recurrence_s", "recurrence interval", 1.0, "s"),
                                     ("friction_drop", "friction drop", 1.0, ""),
                                     ("slip_m", "slip per event", 1e3, "mm"),
                                     ("peak_velocity_m_s", "peak slip rate", 1.0, "m/s")):
        x = {k: _scaled(m[name].get(k), scale) for k in ("mean", "std", "sem")}
        also = (f" (all {n} events: mean {_scaled(every[name].get('mean'), scale)}, std "
                f"{_scaled(every[name].get('std'), scale)})" if used < n else "")
        say(f"  {label:20s} {x['mean']} {unit:3s} std {x['std']}, sem {x['sem']}{also}")
    a = doc["apparatus"]
    if rec.get("kind") == "catalogue":
        _print_constants(doc)
    else:
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


def _print_constants(doc: dict) -> None:
    """A catalogue's estimates of k and vL with their standard errors, and the mass."""
    c = doc.get("constants")
    if c is None:
        return
    k, ka, kf, vl = c["stiffness"], c["stiffness_per_area"], c["stiffness_per_fn"], c["vl"]
    say(f"  {'stiffness k':20s} " + (f"{k['value']:.4g} N/m ± {k['se']:.2g}" if k else "–")
        + (f" ({ka['value']:.4g} Pa/m ± {ka['se']:.2g} per unit area)" if ka else "")
        + f"; k/Fn = {kf['value']:.4g} 1/m ± {kf['se']:.2g}: the median of {c['n_events']} "
        f"events' drop/slip (regression through the origin: {c['stiffness_regression']:.4g})")
    say(f"  {'load-point speed vL':20s} {vl['value']:.4g} m/s ± {vl['se']:.2g}: the loading "
        f"rate between events over k/Fn (the median interval's rate gives "
        f"{c['vl_median_interval']:.4g})")
    a = doc["apparatus"]
    if a.get("mass") is not None:
        say(f"  {'moving mass':20s} {a['mass']:.6g} kg, {doc['how']['mass']} (--mass KG)")
    else:
        say(f"  {'moving mass':20s} {c['mass']}")


def _scaled(value, scale: float) -> str:
    """A metric of the file (None where it is not a number: not measured on this record, or
    a spread of fewer than two events) for the text output."""
    return "–" if value is None else f"{value * scale:.6g}"


def add_parsers(sub) -> None:
    o = sub.add_parser("observe", help="measure a laboratory recording (or read an event "
                       "catalogue): its events, ΔT, Δμ, slip, peak slip rate, curves and "
                       "apparatus, for an inversion",
                       description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    o.add_argument("recording", type=in_file, metavar="RECORDING", nargs="?",
                   help="the recording: .csv, .txt, .tsv, .dat (one header line) or .parquet "
                        "(default: none; then --catalogue)")
    o.add_argument("--catalogue", type=in_file, metavar="FILE",
                   help="an event catalogue instead of a recording: one row per event (CSV, "
                        "TSV or Parquet); writes observations.json and events.csv, no curves "
                        "(default: none)")
    o.add_argument("--column", action="append", default=[], metavar="CHANNEL=COLUMN[:UNIT]",
                   help="a column and its unit (repeatable; the unit defaults to the "
                        "channel's SI unit; overrides --columns)")
    o.add_argument("--columns", type=in_file, metavar="FILE.toml",
                   help="a column file: [columns] and [apparatus] (default: none)")
    o.add_argument("--normal-force", type=positive, metavar="N",
                   help="the normal force in N, when no column holds it (default: the "
                        "normal_force column, or the column file's)")
    o.add_argument("--normal-stress", type=positive, metavar="PA",
                   help="the normal stress in Pa, instead of --normal-force: Fn = σn × area "
                        "(needs --area; default: none)")
    o.add_argument("--area", type=positive, metavar="M2",
                   help="the fault's area in m², which makes a stress a force (stress × "
                        "area); required with a stress channel or --normal-stress (default: "
                        "none)")
    o.add_argument("--mass", type=positive, metavar="KG",
                   help="the slider's mass in kg, for Ft = Fs - m·a and the curves (default: "
                        "none, and no curves); with --catalogue, the mass of apparatus.toml "
                        "(default: the paper's 1100 kg, assumed: a catalogue cannot tell it)")
    o.add_argument("--after-delay", type=positive, metavar="S",
                   help="with --catalogue: when its stress after an event is read, in s after "
                        "the onset; the bias this causes in the estimates of k and vL is "
                        "stated, not corrected (default: none)")
    o.add_argument("--vls", type=positive, metavar="M/S",
                   help="the slow load-point speed in m/s (default: from the table column)")
    o.add_argument("--stiffness", type=positive, metavar="N/M",
                   help="the apparatus's stiffness in N/m (default: measured)")
    o.add_argument("--window", type=float, nargs=2, metavar=("START", "END"),
                   help="measure only from START to END, in s of the file's time (default: "
                        "the whole record); refused if outside the record")
    o.add_argument("--keep-startup", action="store_true",
                   help="keep the start-up events (the leading ones that differ from the "
                        "settled cycle) in the means; they are named either way (default: "
                        "left out)")
    o.add_argument("--sigma", choices=("std", "sem"), default="std",
                   help="the σ an inversion reads from the file: the events' standard "
                        "deviation (the paper's) or the mean's standard error (default: std)")
    o.add_argument("--out", type=out_dir, metavar="DIR",
                   help="directory of the files (default: ./observe_<recording's name>)")
    o.add_argument("--no-plot", action="store_true", help="do not draw observe.png")
    o.add_argument("--json", action="store_true",
                   help="print the observations (without the curves) as one JSON object")
    o.set_defaults(func=cmd_observe)
