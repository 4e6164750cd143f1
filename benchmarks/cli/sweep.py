"""``rsfbench sweep`` and ``rsfbench slip-weakening``: the inversion side of the command line.

    rsfbench sweep --preset W2 --law slip --b 0.0090:0.0098:0.0001 --lc 1e-7:1e-6:9log --json
    rsfbench slip-weakening --preset W2 --law slip --events 3 --out tests/data/W2_slip_weakening.csv
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pandas as pd

from benchmarks.cli.args import (
    add_integrator_options,
    add_sensitivity_option,
    add_observation_options,
    add_problem_choice,
    add_problem_options,
    add_solver_check_option,
    b_lc,
    check_observation_options,
    checked_integrator,
    count,
    in_file,
    integrator_from_args,
    non_negative,
    observations_from_args,
    out_dir,
    out_file,
    positive,
    problem_from_args,
    say,
    seed,
    sensitivity_request,
    show_progress,
)
from benchmarks.cli.invert import WALL_BUDGET
from benchmarks.ensemble.executors import CONNECT_TIMEOUT_S, WORKER_TIMEOUT_S
from benchmarks.ensemble.store import held_algorithm
from benchmarks.inversion.observations import observations
from benchmarks.inversion.sweep import MAX_GRID_POINTS, parse_b, parse_lc, sweep
from benchmarks.physics.curves import read_curves, sample_curves, write_curves
from benchmarks.physics.metrics import CYCLES, summarize
from benchmarks.records.files import claim_outputs
from benchmarks.records.report import jsonable, literal
from integrators import solve
from integrators.core.solve import SETTLE_MAX, check_settle
from problems import PRESET_NAMES, WINDOWS

__all__ = ["add_parsers", "observations", "synthetic_curves"]

def sweep_problem(args):
    """The problem a sweep varies (``--preset`` with ``--law`` and ``--t-end``, or ``--problem
    FILE``) and whether a window's published fit and observations apply."""
    problem = problem_from_args(args, fields=("t_end",))     # --b and --lc are the grid
    return problem, args.problem is None and args.preset.upper() in WINDOWS


def settle_rtol(text: str) -> float:
    """--settle's value: a relative tolerance in (0, SETTLE_MAX]."""
    x = positive(text)
    if x > SETTLE_MAX:
        raise argparse.ArgumentTypeError(f"must be a relative tolerance ≤ {SETTLE_MAX:g}, "
                                         f"got {text!r}")
    return x


def _check_settle(args, algorithm, names, problem) -> None:
    """check_settle's refusal as a line naming --settle."""
    try:
        check_settle(algorithm, args.settle, bool(names), problem)
    except ValueError as exc:
        said = str(exc).removeprefix("settle: ").replace("(solve without settle)",
                                                         "(drop --settle)")
        raise ValueError(f"--settle {args.settle:g}: {said}") from None


def cmd_sweep(args) -> int:
    from benchmarks.inversion.maps import plot_sweep
    problem, published = sweep_problem(args)
    check_observation_options(args, problem, published)
    b_values = parse_b(args.b, args.max_points)
    lc_values = parse_lc(args.lc, args.max_points)
    if args.slip_weakening and args.observations:
        raise ValueError("--slip-weakening: the --observations file holds its own curves")
    curves = read_curves(args.slip_weakening) if args.slip_weakening else None
    obs = observations_from_args(args, published, curves)
    if args.sensitivity is not None and obs.curves is not None:
        raise ValueError("--sensitivity: not with slip-weakening curves (--slip-weakening, or "
                         "curves in --observations); a batch with curves has no sensitivities")
    algorithm, why = integrator_from_args(args)
    names, algorithm, why = sensitivity_request(args, problem, algorithm, why)
    _check_settle(args, algorithm, names, problem)
    name = args.preset if args.problem is None else Path(args.problem).stem
    out = Path(args.out or f"sweep_{name}_{problem.law.name}")
    claim_outputs([out / "sweep.csv", out / "summary.json",      # a user's file there:
                   *([] if args.no_plot else [out / "maps.png"])])  # refused before the work
    algorithm, why, check = checked_integrator(
        args, problem, obs, (float(min(b_values)), float(max(b_values))),
        (float(min(lc_values)), float(max(lc_values))), algorithm, why, keep_method=bool(names),
        held=held_algorithm(out / "chunks"))          # a sweep resumed keeps its setting
    _check_settle(args, algorithm, names, problem)      # the setting the check kept
    if not args.json:
        say(f"integrator: {why}")
        if obs.assumed_sigma:
            say("σ not given: assumed 10 % of the observed mean (an assumption, not data)")
    result = sweep(problem, b_values, lc_values, algorithm, obs, out, workers=args.workers,
                   scheduler=args.scheduler, backend=args.backend, wall_budget=args.wall_budget,
                   progress=show_progress(args), max_points=args.max_points,
                   connect_timeout=args.connect_timeout, worker_timeout=args.worker_timeout,
                   chunk_size=args.chunk_size, sensitivity=names or None, settle=args.settle,
                   provenance={"command": args.command_line, "integrator_choice": why,
                               "solver_check": None if check is None else check.summary(),
                               "problem_file": (None if args.problem is None
                                                else str(Path(args.problem).resolve())),
                               "observations_file": (None if args.observations is None
                                                     else str(Path(args.observations).resolve()))})
    s = {**result.summary, "integrator_choice": why, "out": str(out)}
    if not args.no_plot:
        # the published fit is marked only against the published observations it was fitted to
        own_obs = (args.obs_recurrence is not None or args.obs_drop is not None
                   or args.observations is not None)
        mark, label = ((args.mark, "given") if args.mark is not None else
                       ((problem.law.b, problem.law.lc), "published")
                       if published and not own_obs else (None, ""))
        plot_sweep(result.table, out / "maps.png", title=literal(problem.name or name), mark=mark,
                   mark_label=label,
                   best=None if s["best_b"] is None else (s["best_b"], s["best_lc_m"]))
        s["maps"] = str(out / "maps.png")
    if args.json:
        say(json.dumps(jsonable(s), indent=2))
    else:
        _report(s, out, args.no_plot)
    return 1 if s["n_failed"] == s["n_points"] else 0     # nothing but failures (_report)


def _report(s: dict, out: Path, no_plot: bool) -> None:
    say(f"{s['n_points']} points ({s['n_resumed']} resumed, {s['n_failed']} failed) in "
        f"{s['wall_s']:.1f} s; {s['n_in_region']} in the 95 % region J1 ≤ 5.99")
    if s["n_failed"] == s["n_points"]:
        say("every point failed (exit status 1): nothing in this map is physics; see each "
            "point's message in sweep.csv (a --wall-budget too small?)")
    if s["best_b"] is not None:
        say(f"best ({s['best_by']}): b = {s['best_b']:.5g}, Lc = {s['best_lc_m'] * 1e6:.4g} µm,"
            f" J1 = {s['best_J1']:.3g}")
    say(f"classification: {s['classification']}")
    store = (f", {s['store']} (the store: benchmarks.ensemble.read_store reads it)"
             if s["store"] else "")
    say(f"written: {out / 'sweep.csv'}, {out / 'summary.json'}{store}"
        + ("" if no_plot else f", {out / 'maps.png'}"))


def synthetic_curves(problem, algorithm, n_events: int = 3, n_points: int = 25,
                     noise: float = 0.0, seed: int = 0, curve_dt: float = 5e-5,
                     wall_budget: float | None = None) -> pd.DataFrame:
    """Slip-weakening curves (friction Ft/Fn against slip) of the last ``n_events`` events of a
    simulation, sampled as :func:`benchmarks.physics.curves.sample_curves` does. A run that fails, or
    does not reach a limit cycle, makes no curves (``ValueError`` with its retcode or
    classification)."""
    sol = solve(problem, algorithm, save_every=curve_dt, wall_budget=wall_budget)
    cycle = summarize(sol)
    if cycle.classification not in CYCLES:
        raise ValueError(f"{problem.name} with {algorithm.name}: {cycle.classification} "
                         f"({cycle.reason or sol.message}); no slip-weakening curves from it")
    if len(sol.events) < n_events:
        raise ValueError(f"the run has {len(sol.events)} events, fewer than --events {n_events}")
    # the curves interpolate the saved trajectory: an event needs saved points inside it
    shortest = float((sol.events.t_end - sol.events.t_start).iloc[-n_events:].min())
    if curve_dt > shortest / CURVE_POINTS:
        raise ValueError(f"--curve-dt = {curve_dt:g} s does not resolve the events (the shortest "
                         f"of the last {n_events} lasts {shortest:.3g} s): use at most "
                         f"{shortest / CURVE_POINTS:.2g} s ({CURVE_POINTS} saved points an event)")
    return sample_curves(sol, n_events, n_points, noise, seed)


#: saved points an event needs at least for its slip-weakening curve
CURVE_POINTS = 20


def cmd_slip_weakening(args) -> int:
    claim_outputs([args.out])                # a user's file there: refused before the work
    problem = problem_from_args(args)
    algorithm, why = integrator_from_args(args)
    df = synthetic_curves(problem, algorithm, args.events, args.points, args.noise, args.seed,
                          args.curve_dt, args.wall_budget)
    write_curves(df, args.out)
    summary = {"out": str(args.out), "events": int(df.event_id.nunique()), "samples": len(df),
               "problem": problem.name, "b": problem.law.b, "lc_m": problem.law.lc,
               "integrator": algorithm.name, "options": algorithm.options(),
               "integrator_choice": why, "noise": args.noise, "seed": args.seed}
    if args.json:
        say(json.dumps(jsonable(summary), indent=2))
    else:
        say(f"{summary['events']} events, {len(df)} samples from {problem.name} "
              f"(b = {problem.law.b:.5g}, Lc = {problem.law.lc:.4g} m; {why}): {args.out}")
    return 0


def add_parsers(sub) -> None:
    _add_sweep(sub, PRESET_NAMES)
    _add_slip_weakening(sub, PRESET_NAMES)


def _add_sweep(sub, preset_names) -> None:
    s = sub.add_parser("sweep", help="J1/J2/J over a (b, Lc) grid: parallel, resumable")
    add_problem_choice(s, preset_names, "the problem whose (b, Lc) the grid replaces")
    s.add_argument("--b", required=True, metavar="START:STOP:STEP",
                   help="b values (dimensionless), STOP included")
    s.add_argument("--lc", required=True, metavar="START:STOP:N[log]",
                   help="Lc values in metres: N of them, log-spaced with the suffix 'log'")
    s.add_argument("--max-points", type=count, default=MAX_GRID_POINTS, metavar="N",
                   help="refuse a grid of more points than this (a typo in a step)")
    add_observation_options(s)
    s.add_argument("--slip-weakening", type=in_file, metavar="FILE.csv",
                   help="observed curves, CSV with event_id, slip_m (m), friction (Ft/Fn): adds "
                        "J2 and J (default: J1 only)")
    s.add_argument("--t-end", type=positive, metavar="S",
                   help="simulated time per point in s (default: the preset's or the file's)")
    add_integrator_options(s)
    add_solver_check_option(s)
    where = s.add_mutually_exclusive_group()
    where.add_argument("--workers", type=count, metavar="N",
                       help="local workers, N ≥ 1 (default: all cores)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on this Dask scheduler, e.g. tcp://host:8786 (default: local)")
    s.add_argument("--backend", choices=("processes", "threads"),
                   help="local parallelism (default: threads for the own compiled methods, one "
                        "compiled batch a chunk; processes for the others)")
    s.add_argument("--chunk-size", type=count, metavar="N",
                   help="points per chunk, the unit of work and storage (default: 256 for "
                        "compiled batches, about 1/64 of the grid for the others)")
    s.add_argument("--mark", type=b_lc, metavar="B,LC",
                   help="a point (b, Lc in m) to mark on the maps (default: a window's published "
                        "fit, when scored against its published means)")
    s.add_argument("--connect-timeout", type=positive, default=CONNECT_TIMEOUT_S, metavar="S",
                   help="s the Dask scheduler has to answer before the sweep is refused")
    s.add_argument("--worker-timeout", type=positive, default=WORKER_TIMEOUT_S, metavar="S",
                   help="s a Dask cluster may have no worker before the sweep stops")
    s.add_argument("--wall-budget", type=positive, default=WALL_BUDGET, metavar="S",
                   help="wall budget per point in s: a point over it is a failed point, read "
                        f"as without a limit cycle, never as one (default: {WALL_BUDGET:g} s, "
                        "as invert's)")
    s.add_argument("--settle", type=settle_rtol, metavar="RTOL",
                   help="stop each point at the end of the event where its cycle has settled: "
                        "its last periods' four metrics repeat, and changed by less than RTOL "
                        "since half its time (relative, ≤ 1e-3, e.g. 1e-4). The own compiled "
                        "methods, a loading without speed switches; the solver check runs "
                        "full points (default: every point runs to t_end)")
    s.add_argument("--out", type=out_dir, metavar="DIR",
                   help="directory of the store (DIR/chunks), table and maps (default: "
                        "./sweep_<preset or file name>_<law>)")
    add_sensitivity_option(s, "of each point's limit-cycle metrics, columns "
                              "d_<metric>/d_<parameter> of sweep.csv (SI per unit; not with "
                              "slip-weakening curves)")
    s.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--no-plot", action="store_true", help="do not draw maps.png")
    s.set_defaults(func=cmd_sweep)


def _add_slip_weakening(sub, preset_names) -> None:
    c = sub.add_parser("slip-weakening", help="synthetic slip-weakening curves (CSV) from a run")
    add_problem_options(c, preset_names)
    add_integrator_options(c)
    c.add_argument("--events", type=count, default=3, help="the last N complete events")
    c.add_argument("--points", type=count, default=25, help="samples per event")
    c.add_argument("--noise", type=non_negative, default=0.0,
                   help="std of Gaussian noise added to the friction Ft/Fn")
    c.add_argument("--seed", type=seed, default=0, help="seed of the noise, an integer ≥ 0")
    c.add_argument("--curve-dt", type=positive, default=5e-5, metavar="S",
                   help="s between saved points: the resolution of the curves")
    c.add_argument("--wall-budget", type=positive, metavar="S",
                   help="wall budget of the run in s (default: none)")
    c.add_argument("--out", required=True, type=out_file(".csv"), metavar="FILE.csv",
                   help="where to write the curves")
    c.add_argument("--json", action="store_true", help="print a summary as one JSON object")
    c.set_defaults(func=cmd_slip_weakening)
