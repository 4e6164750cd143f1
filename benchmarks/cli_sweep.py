"""``rsfbench sweep`` and ``rsfbench slip-weakening``: the inversion side of the command line.

    rsfbench sweep --preset W2 --law slip --b 0.0090:0.0098:0.0001 --lc 1e-7:1e-6:9log --json
    rsfbench slip-weakening --preset W2 --law slip --events 3 --out tests/data/W2_slip_weakening.csv
    rsfbench paper-sweeps --out results     # Sect. 4: W1–W4, both laws, around the best fits
    rsfbench sweep-scaling --out results    # 21 x 21 on W2: serial, 2 processes, 2 threads
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.report import jsonable

__all__ = ["add_parsers", "observations", "synthetic_curves"]

#: σ assumed when the user gives none: 10 % of the observed mean (flagged in the output)
ASSUMED_SIGMA = 0.10


def observations(preset_name: str, obs_recurrence=None, sigma_recurrence=None, obs_drop=None,
                 sigma_drop=None, curves=None):
    """Observations from the flags; a window's published means fill what is not given, and a
    missing σ is 10 % of its mean (``assumed_sigma`` says so)."""
    from benchmarks.sweep import Observations
    from problems import WINDOWS
    w = WINDOWS.get(preset_name.upper())
    obs_recurrence = obs_recurrence if obs_recurrence is not None else (w and w.observed_recurrence)
    obs_drop = obs_drop if obs_drop is not None else (w and w.observed_drop)
    for flag, value in (("--obs-recurrence", obs_recurrence), ("--obs-drop", obs_drop)):
        if value is None:
            raise ValueError(f"{flag} is required for {preset_name!r} (it has no observed means)")
        if not value > 0:
            raise ValueError(f"{flag} must be positive, got {value!r}")
    assumed = sigma_recurrence is None or sigma_drop is None
    return Observations(
        recurrence_s=obs_recurrence,
        sigma_recurrence_s=(sigma_recurrence if sigma_recurrence is not None
                            else ASSUMED_SIGMA * obs_recurrence),
        friction_drop=obs_drop,
        sigma_friction_drop=sigma_drop if sigma_drop is not None else ASSUMED_SIGMA * obs_drop,
        curves=curves, assumed_sigma=assumed)


def _algorithm(args):
    """The integrator of a sweep: named by ``--integrator``, or the study's recommendation."""
    from benchmarks.work_precision import recommended_algorithm
    from integrators import algorithm_class, make_algorithm
    if args.integrator:
        cls = algorithm_class(args.integrator)
        return (make_algorithm(cls.name, rtol=args.rtol, atol=args.atol),
                f"{cls.name}, as asked (--integrator)")
    return recommended_algorithm(args.accuracy)


def cmd_sweep(args) -> int:
    from benchmarks.fitting import read_curves
    from benchmarks.maps import plot_sweep
    from benchmarks.sweep import parse_b, parse_lc, sweep
    from problems import preset
    b_values, lc_values = parse_b(args.b), parse_lc(args.lc)
    curves = read_curves(args.slip_weakening) if args.slip_weakening else None
    obs = observations(args.preset, args.obs_recurrence, args.sigma_recurrence, args.obs_drop,
                       args.sigma_drop, curves)
    algorithm, why = _algorithm(args)
    out = Path(args.out or f"sweep_{args.preset}_{args.law}")
    if not args.json:
        print(f"integrator: {why}")
        if obs.assumed_sigma:
            print("σ not given: assumed 10 % of the observed mean (an assumption, not data)")
    result = sweep(args.preset, args.law, b_values, lc_values, algorithm, obs, out,
                   t_end=args.t_end, workers=args.workers, scheduler=args.scheduler,
                   backend=args.backend, wall_budget=args.wall_budget,
                   progress=not args.no_progress)
    s = {**result.summary, "integrator_choice": why, "out": str(out)}
    if not args.no_plot:
        p = preset(args.preset, law=args.law)
        plot_sweep(result.table, out / "maps.png", title=f"{args.preset}/{args.law}",
                   mark=(p.law.b, p.law.lc),
                   best=None if s["best_b"] is None else (s["best_b"], s["best_lc_m"]))
        s["maps"] = str(out / "maps.png")
    if args.json:
        print(json.dumps(jsonable(s), indent=2))
    else:
        print(f"{s['n_points']} points ({s['n_resumed']} resumed, {s['n_failed']} failed) in "
              f"{s['wall_s']:.1f} s; {s['n_in_region']} in the 95 % region J1 ≤ 5.99")
        if s["best_b"] is not None:
            print(f"best ({s['best_by']}): b = {s['best_b']:.5g}, Lc = {s['best_lc_m'] * 1e6:.4g} µm,"
                  f" J1 = {s['best_J1']:.3g}")
        print(f"classification: {s['classification']}")
        print(f"written: {out / 'sweep.csv'}, {out / 'summary.json'}"
              + ("" if args.no_plot else f", {out / 'maps.png'}"))
    return 0


def synthetic_curves(problem, algorithm, n_events: int = 3, n_points: int = 25,
                     noise: float = 0.0, seed: int = 0, curve_dt: float = 5e-5) -> pd.DataFrame:
    """Slip-weakening curves of the last ``n_events`` events of a simulation, each sampled at
    ``n_points`` slips from 0 to its total slip, plus Gaussian noise of std ``noise`` on μ."""
    from benchmarks.fitting import event_curve
    from integrators import solve
    sol = solve(problem, algorithm, save_every=curve_dt)
    if len(sol.events) < n_events:
        raise ValueError(f"the run has {len(sol.events)} events, fewer than --events {n_events}")
    rng = np.random.default_rng(seed)
    frames = []
    for i in range(n_events):
        slip, mu = event_curve(sol, index=len(sol.events) - n_events + i)
        s = np.linspace(0.0, slip[-1], n_points)
        frames.append(pd.DataFrame({"event_id": i + 1, "slip_m": s,
                                    "friction": np.interp(s, slip, mu)
                                    + noise * rng.standard_normal(n_points)}))
    return pd.concat(frames, ignore_index=True)


def cmd_slip_weakening(args) -> int:
    from benchmarks.fitting import write_curves
    from integrators import make_algorithm
    from problems import preset
    problem = preset(args.preset, law=args.law, b=args.b, lc=args.lc, t_end=args.t_end)
    df = synthetic_curves(problem, make_algorithm(args.integrator), args.events, args.points,
                          args.noise, args.seed)
    write_curves(df, args.out)
    print(f"{df.event_id.nunique()} events, {len(df)} samples from {problem.name} "
          f"(b = {problem.law.b:.5g}, Lc = {problem.law.lc:.4g} m): {args.out}")
    return 0


def cmd_paper_sweeps(args) -> int:
    from benchmarks.paper_sweeps import paper_sweeps
    table = paper_sweeps(Path(args.out), windows=args.windows, laws=args.laws,
                         workers=args.workers, progress=not args.no_progress)
    print((Path(args.out) / "sweeps.md").read_text())
    return 0 if len(table) else 1


def cmd_sweep_scaling(args) -> int:
    from benchmarks.paper_sweeps import sweep_scaling
    summary = sweep_scaling(Path(args.out), n=args.n, t_end=args.t_end,
                            progress=not args.no_progress)
    if args.json:
        print(json.dumps(jsonable(summary), indent=2))
    else:
        print((Path(args.out) / "sweep_scaling.md").read_text())
    return 0


def add_parsers(sub, preset_names) -> None:
    s = sub.add_parser("sweep", help="J1/J2/J over a (b, Lc) grid: parallel, resumable")
    s.add_argument("--preset", required=True, choices=preset_names)
    s.add_argument("--law", choices=("slip", "aging"), default="slip")
    s.add_argument("--b", required=True, metavar="START:STOP:STEP", help="b values, STOP included")
    s.add_argument("--lc", required=True, metavar="START:STOP:N[log]",
                   help="Lc values in metres: N of them, log-spaced with the suffix 'log'")
    s.add_argument("--obs-recurrence", type=float, metavar="S",
                   help="observed mean ΔT (default: the window's published mean)")
    s.add_argument("--sigma-recurrence", type=float, metavar="S",
                   help="σ of ΔT (default: 10 %% of the mean, flagged as an assumption)")
    s.add_argument("--obs-drop", type=float, metavar="X", help="observed mean Δμ")
    s.add_argument("--sigma-drop", type=float, metavar="X", help="σ of Δμ (default: 10 %%)")
    s.add_argument("--slip-weakening", metavar="FILE",
                   help="observed curves, CSV with event_id, slip_m, friction: adds J2 and J")
    s.add_argument("--t-end", type=float, metavar="S", help="simulated time per point")
    s.add_argument("--integrator", help="registry name (default: the work-precision study's "
                   "recommendation for --accuracy)")
    s.add_argument("--rtol", type=float)
    s.add_argument("--atol", type=float)
    s.add_argument("--accuracy", type=float, default=1e-3,
                   help="relative error in ΔT the default integrator must reach (default 1e-3)")
    where = s.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N", help="local workers (default: all cores)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask scheduler")
    s.add_argument("--backend", choices=("processes", "threads"), default="processes",
                   help="local parallelism (default: processes, measured faster)")
    s.add_argument("--wall-budget", type=float, metavar="S", help="wall budget per point")
    s.add_argument("--out", metavar="DIR", help="default: ./sweep_<preset>_<law>")
    s.add_argument("--json", action="store_true")
    s.add_argument("--no-progress", action="store_true")
    s.add_argument("--no-plot", action="store_true")
    s.set_defaults(func=cmd_sweep)

    c = sub.add_parser("slip-weakening", help="synthetic slip-weakening curves (CSV) from a run")
    c.add_argument("--preset", required=True, choices=preset_names)
    c.add_argument("--law", choices=("slip", "aging"), default="slip")
    c.add_argument("--b", type=float)
    c.add_argument("--lc", type=float, metavar="LC_METRES")
    c.add_argument("--t-end", type=float)
    c.add_argument("--integrator", default="ETD2")
    c.add_argument("--events", type=int, default=3)
    c.add_argument("--points", type=int, default=25, help="samples per event")
    c.add_argument("--noise", type=float, default=0.0, help="std of Gaussian noise added to μ")
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--out", required=True, metavar="FILE.csv")
    c.set_defaults(func=cmd_slip_weakening)

    p = sub.add_parser("paper-sweeps", help="Sect. 4: J1 sweeps around the published best fits")
    p.add_argument("--out", default="results")
    p.add_argument("--windows", nargs="+", default=["W1", "W2", "W3", "W4"],
                   choices=["W1", "W2", "W3", "W4"])
    p.add_argument("--laws", nargs="+", default=["slip", "aging"], choices=["slip", "aging"])
    p.add_argument("--workers", type=int, metavar="N")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=cmd_paper_sweeps)

    g = sub.add_parser("sweep-scaling", help="time a 21 x 21 W2 sweep on 1 and 2 workers")
    g.add_argument("--out", default="results")
    g.add_argument("--n", type=int, default=21, help="grid points per axis")
    g.add_argument("--t-end", type=float, default=40.0)
    g.add_argument("--json", action="store_true")
    g.add_argument("--no-progress", action="store_true")
    g.set_defaults(func=cmd_sweep_scaling)
