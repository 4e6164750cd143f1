"""``rsfbench simulate``, ``integrators`` and ``windows``: one problem run, the registry listed,
the windows' limit cycles against their observed means.

    rsfbench simulate --preset W2 --law aging --json
    rsfbench simulate --preset W2 --save-rate 10000 --save run.csv --plot run.png
    rsfbench integrators                    # the registry
    rsfbench windows --out results          # W1–W4 limit cycles, both laws, CSV + Markdown
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

from benchmarks.cli.args import (
    add_integrator_options,
    add_sensitivity_option,
    add_problem_options,
    integrator_from_args,
    out_dir,
    out_file,
    positive,
    problem_from_args,
    say,
    sensitivity_request,
    show_progress,
)
from benchmarks.devtools.timing import warm_up
from benchmarks.physics import metrics
from benchmarks.physics.summary import integrator_rows, integrators_markdown, simulate_summary
from benchmarks.records.files import claim_outputs, write_output, write_table, writing
from benchmarks.records.optional import require
from benchmarks.records.provenance import provenance, version_line
from benchmarks.records.report import jsonable as _jsonable
from integrators import REGISTRY, solve
from integrators.core.solution import DEFAULT_POINTS, SAVE_LIMIT, Output, RunNotRepeated
from problems import LAWS, PRESET_NAMES, WINDOWS

__all__ = ["add_parsers"]


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
        say(f"  limit cycle (period {lc['period']}, converged from event "
            f"{lc['cycles_to_converge']}):")
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
        require("pyarrow", "ensemble", "--save FILE.parquet")
    problem = problem_from_args(args)
    check_save_rate(args.save_rate, problem.t_end, args.save or args.plot)
    algorithm, why = integrator_from_args(args)
    names, algorithm, why = sensitivity_request(args, problem, algorithm, why)
    grads = args.save and names and args.save.with_name(args.save.stem + ".sensitivity.csv")
    claim_outputs([p for p in (args.save, args.save and args.save.with_name(
        args.save.name + ".json"), args.plot, grads, grads and grads.with_name(
        grads.name + ".json")) if p])   # a user's file there: refused now
    warm_up(problem, algorithm, wall_budget=args.wall_budget)   # wall_s excludes compiling
    # the run summarised: saved as it always was, unless a method without dense output saves
    # at the rate (its steps are its rule's: it saves the step end at or after each time)
    saving = {"max_points": DEFAULT_POINTS}
    if args.save_rate and not algorithm.saves_at_times:
        saving = {"save_every": 1.0 / args.save_rate}
    sol = solve(problem, algorithm, **saving, progress=args.progress,
                wall_budget=args.wall_budget, sensitivity=names or None)
    summary = {**simulate_summary(sol), "integrator_choice": why}
    if names:
        summary["sensitivity"] = _sensitivity_summary(sol, grads, args.command_line)
    samples = sampled(sol, args.save_rate)
    if args.save:
        summary["trajectory"] = _save_trajectory(samples, args.save, summary,
                                                 args.command_line)
    if args.plot:
        from benchmarks.physics.plots import plot_solution
        args.plot.parent.mkdir(parents=True, exist_ok=True)   # a creatable place (its check)
        # a failed run comes back as it is; the zoom on an event marks the saved samples
        plot_solution(sol.resolved(), args.plot, saved=samples)
    if args.json:
        say(json.dumps(summary, indent=2))
    else:
        _print_summary(summary)
        if names:
            _print_sensitivity(summary["sensitivity"])
        if args.save:
            say(f"  trajectory  {args.save} (and {summary['trajectory']['about']})")
        if args.plot:
            say(f"  figure      {args.plot}")
    return 0 if sol.success else 1


def _sensitivity_summary(sol, path, command: str) -> dict:
    """The gradients of the limit cycle's metrics and of the last event's (SI per unit of
    each parameter); with ``path``, every event's metrics and their derivatives written
    there (CSV, one row per event)."""
    import pandas as pd
    sens, p = sol.sensitivity, sol.problem
    if sens is None or not sol.reached_end:
        return {"parameters": list(sens.names) if sens else [], "limit_cycle": {},
                "last_event": {}, "note": "the run did not reach its end: no gradients"}
    per = metrics.event_gradients(sol)
    last = ({m: {n: float(per[-1, i, j]) for j, n in enumerate(sens.names)}
             for i, m in enumerate(metrics.METRICS)} if len(per) else {})
    out = {"parameters": list(sens.names), "limit_cycle": metrics.cycle_gradient(sol),
           "last_event": last, "note": sens.message,
           "method": f"forward sensitivities through {sol.algorithm.name}'s steps and the event "
                     "roots"}
    if path:
        table = metrics.event_metrics(sol.events, p.normal_force)
        cols = {f"d_{m}/d_{n}": per[:, i, j] for i, m in enumerate(metrics.METRICS)
                for j, n in enumerate(sens.names)}
        write_table(pd.concat([table, pd.DataFrame(cols)], axis=1), path)
        side = path.with_name(path.name + ".json")
        write_output(side, json.dumps(_jsonable(
            {"tool": version_line(), "command": command, **provenance(),
             "columns": "each event's metrics (SI) and d(metric)/d(parameter), SI per unit of "
                        "the parameter", "gradients": out}), indent=2))
        out["file"], out["about"] = str(path), str(side)
    return _jsonable(out)


def _print_sensitivity(s: dict) -> None:
    grads = s["limit_cycle"] or s["last_event"]
    if not grads:
        say(f"  gradients   none ({s.get('note', 'no events')})")
        return
    which = "limit cycle" if s["limit_cycle"] else "last event (not a limit cycle)"
    say(f"  gradients of the {which}, per unit of each parameter (SI):")
    width = {n: max(16, len(n) + 5) for n in s["parameters"]}
    say("    " + " " * 20 + "".join(f"{'d/d' + n:>{width[n]}}" for n in s["parameters"]))
    for m, row in grads.items():
        say(f"    {m:<20}" + "".join(f"{row[n]:>{width[n]}.6g}" if row[n] is not None
                                     else f"{'n/a':>{width[n]}}" for n in s["parameters"]))
    if s.get("file"):
        say(f"  per event   {s['file']}")


def check_save_rate(rate, t_end: float, used) -> None:
    """Refuse (``ValueError``, one line) a --save-rate that would save more than
    :data:`SAVE_LIMIT` samples over ``t_end`` (s), or one that nothing ``used`` (--save,
    --plot) reads; None (no rate) passes."""
    if rate is None:
        return
    if not used:
        raise ValueError(f"--save-rate {rate:g} Hz sets the samples of --save and --plot, and "
                         "neither is given: add one (the summary reads the exact events, not "
                         "the samples)")
    samples = t_end * rate + 1
    if samples > SAVE_LIMIT:
        raise ValueError(f"--save-rate {rate:g} Hz would save {samples:.3g} samples over "
                         f"t_end = {t_end:g} s, more than {SAVE_LIMIT:,}: at most "
                         f"{(SAVE_LIMIT - 1) / t_end:.4g} Hz for this run, or a shorter --t-end")


def sampled(sol, rate):
    """``sol``'s trajectory every 1/``rate`` s (``rate`` in Hz; None: as it was saved), as a
    :meth:`~integrators.core.solution.Solution.to_dataframe` table.

    The samples come from the method's dense output, ``sol(times)``: the solve repeated saving
    at those times, accepted when it is the same run (its events agree within its accuracy,
    :meth:`~integrators.core.solution.Solution.repeats`), so that the run summarised is the
    one saved whatever the rate (the own methods take the very same steps; CVODE and LSODA
    step to their output times). A method without dense output saved at the rate already
    (:func:`cmd_simulate`); a failed run keeps what it saved (a warning says so). A repeat
    that is not the same run is refused (``ValueError``)."""
    if rate is None or not sol.algorithm.saves_at_times:
        return sol.to_dataframe()
    if not sol.success:
        warnings.warn(f"--save-rate {rate:g} Hz: the run ended {sol.retcode.value}, so its "
                      f"trajectory is what it saved ({DEFAULT_POINTS:,} samples over the run), "
                      "not a repeat at the rate", stacklevel=1)
        return sol.to_dataframe()
    try:
        return sol(Output(save_every=1.0 / rate).times(sol.problem.t_end))
    except RunNotRepeated as exc:
        raise ValueError(f"--save-rate {rate:g} Hz: {exc}") from None


def _save_trajectory(df, path: Path, summary: dict, command: str) -> dict:
    """Write the trajectory ``df`` (:func:`sampled`) to ``path`` (.csv or .parquet: t, v, fs,
    ft, mu, theta) and what it is to ``path`` + ".json" (units, command, versions, the samples'
    mean rate, the run's summary)."""
    path.parent.mkdir(parents=True, exist_ok=True)      # a creatable place (--save's check)
    span = float(df.t.iloc[-1] - df.t.iloc[0]) if len(df) > 1 else 0.0
    rate = (len(df) - 1) / span if span > 0 else None
    about = {"tool": version_line(), "command": command, **provenance(),
             "columns": df.attrs["units"], "rows": len(df), "rate_hz": rate, "run": summary}
    if path.suffix.lower() == ".parquet":
        df.attrs["about"] = json.dumps(_jsonable(about))
        with writing(path) as tmp:
            df.to_parquet(tmp, index=False)
    else:
        write_table(df, path)
    side = path.with_name(path.name + ".json")
    write_output(side, json.dumps(_jsonable(about), indent=2))
    return {"file": str(path), "about": str(side), "rows": len(df), "rate_hz": rate}


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



def add_parsers(sub) -> None:
    s = sub.add_parser("simulate", help="run one problem (a preset or your own file) and "
                       "summarise its limit cycle")
    add_problem_options(s, PRESET_NAMES)
    add_integrator_options(s)
    s.add_argument("--wall-budget", type=positive, metavar="S",
                   help="stop after S seconds of wall time (default: no budget)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.add_argument("--plot", metavar="FILE.png", type=out_file(".png", ".pdf", ".svg"),
                   help="draw v(t), μ(t), a zoom on the last complete event (from the dense "
                        "output, the saved samples marked) and the phase portrait (default: no "
                        "figure)")
    s.add_argument("--save", metavar="FILE", type=out_file(".csv", ".parquet"),
                   help="write the trajectory (t s, v m/s, fs N, ft N, mu, theta) to FILE.csv "
                        "or FILE.parquet, and what it is to FILE.csv.json or FILE.parquet.json "
                        "beside it (default: not written)")
    s.add_argument("--save-rate", type=positive, metavar="HZ",
                   help="samples per second (Hz) of --save's trajectory and of --plot's "
                        "samples, from the integrator's dense output on a repeat of the run "
                        "that is checked to be the same run (the run summarised is the same "
                        "whatever the rate; the ETD family, without dense output, saves the "
                        "first step end at or after each sample time); at most "
                        f"{SAVE_LIMIT:,} samples over the run (default: {DEFAULT_POINTS:,} "
                        f"samples over the run, t_end/{DEFAULT_POINTS - 1:,} apart: "
                        "about 500 Hz over 40 s)")
    s.add_argument("--progress", action="store_true", help="show a progress bar")
    add_sensitivity_option(s, "of the limit cycle's metrics (SI per unit), from forward "
                              "sensitivities through the steps (Rodas5P's or RadauIIA5's) and "
                              "event roots; with --save, every event's in "
                              "FILE.sensitivity.csv")
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("integrators", help="list the registry")
    i.add_argument("--json", action="store_true", help="print one JSON array")
    i.add_argument("--markdown", action="store_true", help="a Markdown table (for the README)")
    i.set_defaults(func=cmd_integrators)

    w = sub.add_parser("windows", help="limit cycles of W1–W4 against the observed means")
    w.add_argument("--window", nargs="+", choices=sorted(WINDOWS), default=sorted(WINDOWS),
                   type=str.upper, help="the windows to run")
    w.add_argument("--law", nargs="+", choices=tuple(LAWS), default=["slip", "aging"],
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
