"""``rsfbench invert``: an inversion of (b, Lc).

    rsfbench invert --preset W2 --law slip --out inv_W2     # posterior, fit, profiles, plots
    rsfbench invert --problem my.toml --observations observations.json \\
        --b-range 0.008,0.012 --lc-range 1e-8,1e-5 --json   # the means and the curves
    rsfbench invert --preset W2 --method emcee --walkers 32 --steps 1000
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np

from benchmarks.cli.args import (
    MAX_STEPS,
    MAX_WALKERS,
    add_integrator_options,
    add_model_error_options,
    add_observation_options,
    add_problem_choice,
    add_solver_check_option,
    b_range,
    bounded,
    chain_steps,
    chain_walkers,
    check_observation_options,
    checked_integrator,
    flagged,
    integrator_from_args,
    lc_range,
    observations_from_args,
    out_dir,
    positive,
    problem_from_args,
    say,
    seed,
    show_progress,
    stopped_by,
    workers,
)
from benchmarks.cli.invert_nuisance import (
    SAMPLER_HELP,
    SPEC_HELP,
    check_nuisance_observations,
    check_nuisance_options,
    nuisance_algorithm,
    nuisance_spec,
    run_nuisance,
)
from benchmarks.inversion import Misfit
from benchmarks.inversion.curve_likelihood import CURVE_NOISES
from benchmarks.inversion.fit_figure import observed_events
from benchmarks.inversion.invert import (
    MAX_SAMPLES_SAVED,
    METHODS,
    check_box,
    inversion_files,
    invert,
    write_inversion,
)
from benchmarks.inversion.nuisance import nuisance_files
from benchmarks.inversion.posterior import MAX_POSTERIOR_SOLVES, check_sampler
from benchmarks.records.files import claim_outputs, remove_own
from benchmarks.records.optional import require
from benchmarks.records.report import jsonable
from problems import PRESET_NAMES, WINDOWS

__all__ = ["add_parsers"]


#: simulated cycles of the observed ΔT per forward solve at most (t_end / ΔT)
MAX_CYCLES = 10_000
#: profile points per parameter at most (each is a line of ≥ 41 solves, then refined)
MAX_PROFILE_POINTS = 1001
#: s of wall time per forward solve unless told (a W2 solve takes milliseconds; a point that
#: crawls, as b ≈ 0.2 of W2 does at 300,000 steps a second, would hold the grid for hours)
WALL_BUDGET = 10.0


def _interrupted(args, command: str, where: str) -> int:
    """Ctrl-C (or SIGTERM): one line (and with --json one JSON document), exit status 130
    (143)."""
    what, status = stopped_by()
    message = f"rsfbench: error: {command} interrupted ({what}) {where}"
    print(message, file=sys.stderr)
    if getattr(args, "json", False):
        say(json.dumps({"error": message, "exit_status": status}))
    return status


def _drop_if_empty(out: Path, made: bool) -> None:
    """The output directory this run made, removed again where an interrupt left it empty
    (never a directory it did not make, never one with a file in it)."""
    if made:
        try:
            out.rmdir()
        except OSError:
            pass


def _box(args, problem, published: bool):
    """The prior box: the options', or a window's paper sweep box (slip and aging laws only)."""
    from benchmarks.inversion.published import GRID, prior_box
    law = args.law or "slip"
    if args.b_range is not None and args.lc_range is not None:
        return args.b_range, args.lc_range
    if not published:
        raise ValueError("--b-range and --lc-range are required for a problem without a "
                         "published fit (the prior box is yours to state)")
    if law not in GRID:
        raise ValueError(f"--law {law}: the paper publishes no fit of the {law} law to centre a "
                         f"prior box on (it fits the {' and '.join(GRID)} laws): give --b-range "
                         "and --lc-range")
    box_b, box_lc = prior_box(args.preset.upper(), law)
    return args.b_range or box_b, args.lc_range or box_lc


def cmd_invert(args) -> int:
    problem, published, box_b, box_lc, walkers, steps = _checked(args)
    obs = observations_from_args(args, published)
    if args.nuisance:
        check_nuisance_observations(obs)
    # the per-event table fit.png draws, read now: the file may change during the work
    events = None if args.observations is None else observed_events(args.observations)
    cycles = problem.t_end / obs.recurrence_s
    if cycles > MAX_CYCLES:                  # each of thousands of solves would run for hours
        raise ValueError(f"--t-end {problem.t_end:g} s simulates {cycles:,.0f} cycles of the "
                         f"observed ΔT = {obs.recurrence_s:g} s per solve; a limit cycle is "
                         f"read in tens: at most {MAX_CYCLES:,}")
    algorithm, why = nuisance_algorithm(args) if args.nuisance else integrator_from_args(args)
    name = args.preset if args.problem is None else Path(args.problem).stem
    out = Path(args.out or f"invert_{name}_{problem.law.name}")
    # a user's file there: refused now
    claim_outputs(nuisance_files(out) if args.nuisance else inversion_files(out))
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)               # before the work, not after it
    try:
        algorithm, why, check = checked_integrator(args, problem, obs, box_b, box_lc,
                                                   algorithm, why,
                                                   keep_method=bool(args.nuisance))
    except KeyboardInterrupt:
        _drop_if_empty(out, made)
        return _interrupted(args, "invert", f"during the integrator's check: nothing written "
                                            f"to {out}")
    misfit = Misfit(problem, obs, algorithm, wall_budget=args.wall_budget, workers=args.workers)
    if not args.json:
        _say_setting(why, obs)
    if args.nuisance:
        try:
            return run_nuisance(args, misfit, (box_b, box_lc), steps, out,
                                _record(args, why, check))
        except KeyboardInterrupt:
            _drop_if_empty(out, made)
            raise
    stage = ["the start"]
    try:
        inv, summary = _run(args, misfit, (box_b, box_lc), walkers, steps, out, why, check,
                            stage, events)
    except KeyboardInterrupt:
        written = (f"{out} is incomplete" if stage[0].startswith("writing") else
                   f"nothing written to {out}")
        _drop_if_empty(out, made)
        return _interrupted(args, "invert", f"during the {stage[0]}: {written}")
    failed = not np.isfinite(inv.fit.misfit)         # no point of the box had a limit cycle
    _warn(args, inv, summary)
    if args.json:
        say(json.dumps(jsonable(summary), indent=2))
        return 1 if failed or inv.posterior_missed else 0
    if failed:
        say(f"inversion failed: {summary['fit']['message']} (failed solves, e.g. over "
            f"--wall-budget, count as without a cycle); written: {summary['files']['summary']}")
        return 1
    _report(args, summary)
    return 1 if inv.posterior_missed else 0


def _checked(args):
    """``(problem, published, box_b, box_lc, walkers, steps)`` of the options, every
    combination checked before any work."""
    problem = problem_from_args(args, fields=("t_end",))
    published = args.problem is None and args.preset.upper() in WINDOWS
    check_observation_options(args, problem, published)
    box_b, box_lc = _box(args, problem, published)
    flagged("--b-range/--lc-range", check_box, problem, box_b, box_lc)
    if args.curve_sigma is not None and args.curve_noise != "sample":
        raise ValueError(f"--curve-sigma is the σ per sample of --curve-noise sample, not of "
                         f"{args.curve_noise}")
    if args.method == "emcee" and args.grid is not None:
        raise ValueError("--grid is the grid posterior's first grid: drop it with --method emcee")
    walkers = 32 if args.walkers is None else args.walkers
    steps = 2000 if args.steps is None else args.steps
    if args.nuisance:                    # a fit by gradients and its own samplers: no emcee
        check_nuisance_options(args, problem)
        return problem, published, box_b, box_lc, walkers, steps
    if args.nuisance_sampler is not None:
        raise ValueError("--nuisance-sampler samples the --nuisance inversion: add --nuisance "
                         "NAME=SIGMA or drop it")
    if steps:                            # the corner plot is written after all the work
        require("corner", "inversion", "the corner plot of a posterior")
        require("emcee", "inversion", "a posterior sample")
    if args.grid is not None and not steps:
        raise ValueError("--grid is the grid posterior's, and --steps 0 asks for none: drop one")
    if args.curve_noise == "sample" and args.curve_sigma is None:
        raise ValueError("--curve-noise sample needs --curve-sigma X (σ per sample of the "
                         "curves' friction Ft/Fn)")
    if steps:                            # emcee's chain, alone or the grid route's last resort
        flagged("--walkers/--steps", check_sampler, box_b, box_lc, walkers, steps)
    return problem, published, box_b, box_lc, walkers, steps


def _say_setting(why: str, obs) -> None:
    """The integrator chosen, and what the likelihood reads of the observations."""
    say(f"integrator: {why}")
    if obs.assumed_sigma:
        say("σ not given: assumed 10 % of the observed mean (an assumption, not data)")
    if any(obs.model_error[k] for k in ("recurrence", "drop")):
        sigma_t, sigma_mu = obs.sigmas
        say(f"model error: σ of ΔT {sigma_t:.3g} s, of Δμ {sigma_mu:.3g} (the data's "
            f"{obs.sigma_recurrence_s:.3g} s and {obs.sigma_friction_drop:.3g}, with the "
            "model's added in quadrature)")
    if obs.curve_likelihood is not None:
        say(obs.curve_likelihood.describe())
    elif obs.curves is not None:
        say("curves: in no likelihood (--curve-noise none)")


def _run(args, misfit, box, walkers, steps, out: Path, why: str, check, stage: list,
         events=None):
    """``(inversion, summary)`` with its files written to ``out``; ``stage[0]``: what runs
    now (a Ctrl-C says it); ``events``: the observed events fit.png draws."""
    def progress(text: str) -> None:
        stage[0] = text
        if not args.json:
            say(f"… {text}")
    inv = invert(misfit, *box, walkers=walkers, steps=steps, profile_points=args.profile_points,
                 seed=args.seed, progress=not args.json and show_progress(args), say=progress,
                 method=args.method, grid=args.grid or 33)
    stage[0] = "writing of its files"
    summary = write_inversion(inv, out, _record(args, why, check), events)
    for path in nuisance_files(out):         # an earlier run's, of the other route
        remove_own(path)
    return inv, {**summary, "integrator_choice": why, "out": str(out)}


def _record(args, why: str, check) -> dict:
    """The run's provenance beside the machine's: command, integrator, check, input files."""
    return {"command": args.command_line, "integrator_choice": why,
            "solver_check": None if check is None else check.summary(),
            "observations_file": (None if args.observations is None
                                  else str(Path(args.observations).resolve())),
            "problem_file": (None if args.problem is None
                             else str(Path(args.problem).resolve()))}


def _warn(args, inv, summary) -> None:
    """Failed solves, profiles' warnings and a posterior not to be read: on the standard
    error, also with --json."""
    solves = summary["solves"]
    if solves["failed"]:
        warnings.warn(f"{solves['failed']:,} of {solves['solves']:,} forward solves failed "
                      f"({solves['over_budget']:,} over the wall budget of "
                      f"{args.wall_budget:g} s per solve, --wall-budget): each is a point "
                      "without a limit cycle, never read as one", stacklevel=1)
    for p in summary["profiles"].values():
        for text in p["warnings"]:
            warnings.warn(text, stacklevel=1)
    if inv.posterior_missed:                     # a posterior not to be read fails the run
        warnings.warn(inv.posterior_missed, stacklevel=1)


def _report(args, summary) -> None:
    """The fit, the profiles, the posterior and the solves, for a reader."""
    f, solves = summary["fit"], summary["solves"]
    say(f"least squares: b = {f['b']:.5g} ± {f['sigma_b']:.2g}, Lc = {f['lc_m'] * 1e6:.4g} µm "
        f"(log10 Lc ± {f['sigma_log10_lc']:.2g}), misfit = {f['misfit']:.3g}"
        + ("" if f["success"] else f" — not converged: {f['message']}"))
    m, o = f.get("model"), summary["observations"]
    if m and np.isfinite(m["recurrence_s"]):       # the one solve of fit.png, with a cycle
        say(f"the model at the fit: ΔT = {m['recurrence_s']:.6g} s (observed "
            f"{o['recurrence_s']:.6g} ± {o['sigma_recurrence_s']:.2g}), Δμ = "
            f"{m['friction_drop']:.5g} (observed {o['friction_drop']:.5g} ± "
            f"{o['sigma_friction_drop']:.2g})")
    for k, p in summary["profiles"].items():
        opens = [e for e, o in (("low", p["open_low"]), ("high", p["open_high"])) if o]
        say(f"profile of {k}: 95 % interval [{p['low']:.5g}, {p['high']:.5g}]"
            + (f" (open at the {' and '.join(opens)} end of the box)" if opens else "")
            + ("" if p["resolved"] else " (not resolved: the points about it)"))
    p = summary["posterior"]
    if p is None:
        say(f"posterior: {summary['no_posterior']}")
    elif p["method"] == "grid":
        _report_grid(p)
    else:
        _report_sample(p)
    say(f"forward solves: {solves['solves']:,}, {solves['failed']:,} failed "
        f"({solves['over_budget']:,} over the wall budget of {args.wall_budget:g} s per solve)")
    say(f"written: {', '.join(summary['files'].values())}")


def _report_grid(p: dict) -> None:
    ib, il = p["interval_95"]["b"], p["interval_95"]["log10_lc"]
    say(f"posterior ({p['route']}, {p['n_cells']:,} cells in {p['levels']} levels, "
        f"{p['n_solves']:,} solves"
        + (f" of which {p['n_failed']:,} failed" if p["n_failed"] else "")
        + f", {p['wall_s']:.1f} s): b = {p['mean']['b']:.5g} ± "
        f"{p['std']['b']:.2g} (95 %: {ib[0]:.5g} to {ib[1]:.5g}), log10 Lc = "
        f"{p['mean']['log10_lc']:.3f} ± {p['std']['log10_lc']:.2g} (95 %: {il[0]:.3f} to "
        f"{il[1]:.3f})" + ("" if p["settled"] else " — the refinement did not settle: "
                           "see refinement in inversion.json"))
    if p["edge_mass"] > 0.01:
        say(f"{p['edge_mass']:.0%} of the posterior is on the box's edge: the box cuts it")
    _report_checks(p)
    say(f"prior: {p['prior']}")


def _report_checks(p: dict) -> None:
    """What the posterior was checked against, in one line."""
    c = p["checks"]
    ratio = ", ".join(f"{k} {c['sd_ratio'][k]:.2f} ×" for k in c["sd_ratio"])
    allowed = ("" if all(s == "Gauss-Newton" for s in c["sd_reference_source"].values())
               else ", or of the range from it to the profile's where the profile is not "
                    "quadratic")
    say(f"checked: the 95 % region holds the least-squares fit; sd {ratio} the Gauss–Newton sd "
        f"(allowed: within {c['sd_factor']:g} × of it{allowed})")


def _report_sample(p: dict) -> None:
    say(f"posterior ({p['route']}, emcee, {p['n_solves']:,} solves, {p['wall_s']:.1f} s): b = "
        f"{p['mean']['b']:.5g} ± {p['std']['b']:.2g}, log10 Lc = "
        f"{p['mean']['log10_lc']:.3f} ± {p['std']['log10_lc']:.2g}; acceptance "
        f"{p['acceptance']:.2f}, "
        + (f"τ = {max(p['tau'].values()):.1f} steps"
           f"{'' if p['tau_reliable'] else ' (chain < 50 τ: run more --steps)'}, "
           f"{p['effective_samples']:.0f} effective samples"
           if np.isfinite(p["effective_samples"]) else
           "τ not estimable (a walker never moved: run more --steps)"))
    _report_checks(p)
    say(f"prior: {p['prior']}")


def add_parsers(sub) -> None:
    i = sub.add_parser("invert", help="invert observed means (and slip-weakening curves) for "
                       "(b, Lc): posterior (refined grid or emcee), least-squares fit with "
                       "covariance, profiles of b and log10 Lc, corner and profile plots, and "
                       "the fit drawn over the observations (fit.png)")
    add_problem_choice(i, PRESET_NAMES, "the problem whose (b, Lc) is inferred")
    add_observation_options(i)
    i.add_argument("--b-range", type=b_range, metavar="LO,HI",
                   help="the prior box of b (uniform): required for --problem; default for "
                        "W1–W4: the paper sweep's, the published fit ± 0.0008 (slip law) or "
                        "± 0.0015 (aging)")
    i.add_argument("--lc-range", type=lc_range, metavar="LO,HI",
                   help="the prior box of Lc in m (uniform in log10 Lc): required for "
                        "--problem; default for W1–W4: the published fit ÷ and × 10 (slip "
                        "law) or 30 (aging)")
    i.add_argument("--t-end", type=positive, metavar="S",
                   help="simulated time per solve in s (default: the preset's or the file's)")
    add_integrator_options(i)
    add_solver_check_option(i)
    _add_posterior_options(i)
    i.add_argument("--workers", type=workers, metavar="N",
                   help="threads (own methods) or processes per batch, and threads fitting "
                        "the nested sampler's draws side by side (default: all cores)")
    i.add_argument("--nuisance", type=nuisance_spec, action="append", metavar="NAME=SIGMA",
                   help=SPEC_HELP)
    i.add_argument("--nuisance-sampler", choices=("nested", "metropolis"),
                   help=SAMPLER_HELP)
    i.add_argument("--wall-budget", type=positive, default=WALL_BUDGET, metavar="S",
                   help="wall budget per forward solve in s, of the inversion and of its "
                        "solver check; a solve over it is a failed point, counted in the "
                        "output and read as without a limit cycle, never as one (default: "
                        f"{WALL_BUDGET:g} s per solve)")
    i.add_argument("--out", type=out_dir, metavar="DIR",
                   help="where to write inversion.json, the CSVs (posterior.csv: at most "
                        f"{MAX_SAMPLES_SAVED} samples) and PNGs (corner.png, profiles.png, "
                        "fit.png: the model at the fit over the observed events and curves) "
                        "(default: ./invert_<preset or file name>_<law>)")
    i.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    i.add_argument("--no-progress", action="store_true", help="no progress bar")
    i.set_defaults(func=cmd_invert)


def _add_posterior_options(i) -> None:
    """The posterior's method and size, the curves' noise, the profiles and the seed."""
    i.add_argument("--method", choices=METHODS, default="grid",
                   help="the posterior: 'grid', on a grid zoomed onto the least-squares fit "
                        "(or over the box, for a broad posterior) and refined where its mass "
                        "is, emcee from the fit if no grid passes the checks; or 'emcee' alone, "
                        "started from the fit and its Gauss–Newton covariance (default: grid)")
    i.add_argument("--grid", type=bounded(3, 1001, "the first grid is solved in one batch"),
                   metavar="N", help="the grid posterior's first grid, N × N cells over the box "
                                     "and over the zoom on the fit (default: 33)")
    i.add_argument("--walkers", type=chain_walkers, metavar="N",
                   help=f"emcee walkers: --method emcee's, or the grid route's last resort when no "
                        f"grid passes the checks; 4 to {MAX_WALKERS:,}; walkers × steps at most "
                        f"{MAX_POSTERIOR_SOLVES:,}, each a forward solve (default: 32)")
    i.add_argument("--steps", type=chain_steps, metavar="N",
                   help="emcee steps per walker (as --walkers), a quarter dropped as burn-in; "
                        f"at most {MAX_STEPS:,}; 0: no posterior, with either method "
                        "(default: 2000)")
    i.add_argument("--curve-noise", choices=(*CURVE_NOISES, "none"), default="scatter",
                   help="the slip-weakening curves of an --observations file in the "
                        "likelihood: 'scatter' (their covariance over the events, ≥ 3 events), "
                        "'sample' (a σ per sample, --curve-sigma) or 'none' (the means only) "
                        "(default: scatter)")
    i.add_argument("--curve-sigma", type=positive, metavar="X",
                   help="σ per sample of the curves' friction (Ft/Fn, dimensionless) for "
                        "--curve-noise sample (default: none)")
    add_model_error_options(i)
    i.add_argument("--profile-points", type=bounded(3, MAX_PROFILE_POINTS, "each is a line "
                                                    "of at least 41 solves"),
                   default=21, metavar="N",
                   help="values of each profiled parameter across the box, 3 to "
                        f"{MAX_PROFILE_POINTS}; the profile adds the fit's value and bisects "
                        "where its interval's ends are not resolved (default: 21)")
    i.add_argument("--seed", type=seed, default=0, help="seed of the walkers' start and moves "
                   "(default: 0)")
