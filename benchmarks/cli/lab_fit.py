"""rsfbench lab fit: (a, b, Dc) — and the stiffness — from a velocity-step or slide-hold-slide
record.

    rsfbench lab fit run.txt --column time=Time:s --column friction=Friction \\
        --column load_point=Displ:um --out fit/

The load point's history (its speeds and switch times) is found in the record; the fit is
least squares on μ(t) (benchmarks.lab.fit: the noise model, the intervals), with
profile intervals of the friction parameters, a check of the integrator at the best fit, and
with --mass the inertial slider fitted too and compared. With several laws (--law aging,slip)
each is fitted and compared (benchmarks.lab.laws), and the lowest BIC is reported in full.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import sys
import warnings
from pathlib import Path

import pandas as pd

from benchmarks.cli.args import (in_file, non_negative, numbers, out_dir, positive, say, seed,
                                 show_progress, stopped_by, workers)
from benchmarks.lab.model import DEFAULT_ALGORITHM, DETRENDS, WALL_BUDGET, LabModel
from benchmarks.records.files import claim_outputs, write_figure, write_output, write_table
from benchmarks.records.optional import require
from benchmarks.records.provenance import provenance, version_line
from benchmarks.records.report import jsonable
from integrators import REGISTRY, make_algorithm
from problems import LAWS, law_parameters

#: the files ``lab fit --out DIR`` may write
LAB_FIT_FILES = ("lab_fit.json", "lab_fit_parameters.csv", "lab_fit_residuals.csv",
                 "lab_fit_profiles.csv", "lab_fit_posterior.csv", "lab_fit_laws.csv",
                 "lab_fit_switches.csv", "lab_fit_trends.csv", "lab_fit.png")

__all__ = ["add_parser"]

#: the parameters profiled (those fitted): the friction's, not the machine's k′
PROFILED = ("a", "b", "dc", "c", "b2", "dc2")


def _constant_normal_force(args) -> bool:
    """Does --normal-force stand for a column (a shear force mapped, no normal force column)?"""
    mapped = {spec.partition("=")[0].strip() for spec in args.column}
    return "shear_force" in mapped and "normal_force" not in mapped


def _record(args):
    from benchmarks.lab.step_data import read_lab_record
    if not args.column:
        raise ValueError("map the record's columns: --column CHANNEL=COLUMN[:UNIT] (time, "
                         "friction or shear_force, load_point or load_velocity)")
    constant = _constant_normal_force(args)
    return read_lab_record(args.recording, args.column,
                           normal_force=args.normal_force if constant else None,
                           window=args.window)


def _model(args, record, law: str):
    algorithm = None
    if args.integrator is not None or args.rtol is not None:
        name = args.integrator or DEFAULT_ALGORITHM[0]
        cls = REGISTRY.get(name)
        if cls is not None and not cls.saves_at_times:
            raise ValueError(f"--integrator {name} saves at its own step ends: a fit needs μ at "
                             "the record's times from a method's dense output (Rodas5P, "
                             "Exprb43, scipy-Radau, …)")
        tol = args.rtol if args.rtol is not None else DEFAULT_ALGORITHM[1]
        algorithm = make_algorithm(name, rtol=tol, atol=tol)
    return LabModel(record, law, detrend="piece" if args.detrend == "auto" else args.detrend,
                    algorithm=algorithm,
                    states=args.states, wall_budget=args.wall_budget)


def _check_flags(args, laws) -> None:
    if args.c is not None and not any("c" in law_parameters(law) for law in laws):
        raise ValueError(f"--c is a stress coefficient (the Nagata law's): the "
                         f"{' and '.join(laws)} law{'s have' if len(laws) > 1 else ' has'} none")
    if (args.mass is not None or args.radiation_damping is not None) and args.normal_force is None:
        raise ValueError("--mass and --radiation-damping need --normal-force (N): the inertial "
                         "slider's friction depends on it")
    if args.states == 2 and (args.mass is not None or args.radiation_damping is not None):
        raise ValueError("--states 2 fits the quasi-static slider only: no --mass or "
                         "--radiation-damping")
    if args.states == 2 and (args.integrator is not None or args.rtol is not None):
        raise ValueError("--states 2 has its own compiled model (Rodas5P's tableau at 1e-11): "
                         "--integrator and --rtol do not apply")
    if args.weights is not None and any(w < 0 for w in args.weights):
        raise ValueError("--weights must be non-negative")
    given = [f for f, d in (("--walkers", 32), ("--steps", 600), ("--seed", 0))
             if getattr(args, f[2:]) != d]
    if given and not args.posterior:
        raise ValueError(f"{given[0]} sets the posterior: it needs --posterior")
    if args.walkers < 2 or args.walkers % 2:
        raise ValueError(f"--walkers {args.walkers}: an even number, at least twice the "
                         "fitted parameters (8 for a, b, Dc, k′)")
    if args.steps < 20:
        raise ValueError(f"--steps {args.steps}: at least 20")
    if (args.normal_force is not None and args.mass is None
            and args.radiation_damping is None and not _constant_normal_force(args)):
        raise ValueError("--normal-force is for a shear_force column without a normal_force "
                         "one, or for the inertial slider (--mass): here it would be unused")
    if args.posterior:
        require("emcee", "inversion", "--posterior")


def cmd_lab_fit(args) -> int:
    from benchmarks.lab.laws import parse_laws
    laws = parse_laws(args.law, tuple(LAWS))
    if args.workers is None:
        from benchmarks.lab.parallel import cores
        args.workers = cores()
    _check_flags(args, laws)
    models = _models(args, laws)
    given = {k: v for k, v in (("k", args.stiffness), ("c", args.c)) if v is not None}
    free = max(([n for n in m.parameters if n not in given] for m in models.values()), key=len)
    if args.posterior and args.walkers < 2 * len(free):
        raise ValueError(f"--walkers {args.walkers}: at least {2 * len(free)}, twice the "
                         f"{len(free)} fitted parameters ({', '.join(free)})")
    if args.out is not None:              # a user's file of one of these names: refused now
        claim_outputs(args.out / n for n in LAB_FIT_FILES)
        args.out.mkdir(parents=True, exist_ok=True)
    fit, notes, laws_table, switches = _fit_laws(args, models, given)
    trends = None
    if args.detrend == "auto":
        fit, notes, trends = _choose_trend(args, fit)
    notes = [*args.record_notes, *notes]
    fixed = {k: v for k, v in given.items() if k in fit.model.parameters}
    record = fit.model.record             # the switches where the friction put them
    profiles, check, early = _profiles_and_check(args, fit, notes)
    posterior = _posterior(args, fit) if args.posterior else None
    inertia = (_inertia(args, fit, record)
               if args.mass is not None or args.radiation_damping is not None else None)
    table = _table(fit, profiles, posterior)
    doc = _doc(args, record, fit, table, fixed, notes, profiles, check, inertia, posterior)
    for name, extra, compared in (("laws", laws_table, list(laws)),
                                  ("trends", trends, list(AUTO_TRENDS))):
        doc[name] = None if extra is None else {
            "compared": compared, "chosen_by": CHOSEN_BY, "table": extra.to_dict("records")}
    doc["switches"] = _switches_doc(args, switches)
    if args.out is not None:
        _write_all(args, early, table, profiles, doc, posterior,
                   {"laws": laws_table, "switches": switches, "trends": trends})
    # a fit whose integrator failed its check, or that did not converge, is no answer: exit 1
    status = 0 if fit.success and (check is None or check["passed"]) else 1
    if args.json:
        say(json.dumps(jsonable(doc), indent=2))
        return status
    for extra, what in ((laws_table, "laws"), (trends, "trends")):
        if extra is not None:
            _report_variants(extra, what)
    _report_switches(args, switches)
    _report(fit, table, profiles, check, inertia, notes, record, args)
    if posterior is not None:
        say(f"posterior: {args.walkers} walkers × {args.steps} steps, {posterior.solves} solves "
            f"in {posterior.wall_s:.1f} s, acceptance {posterior.acceptance:.2f}, "
            + ("τ reliable" if posterior.tau_reliable else
               "the chain is shorter than 50 τ: lengthen --steps before trusting its tails")
            + f"; prior {posterior.prior}")
    return status


def _models(args, laws) -> dict:
    """Each law's model of the record (its switches ``--switches`` if given), every check of
    the record and the options made before any fit."""
    from problems._validate import UnitWarning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        record = _record(args)
    for w in caught:                        # on the standard error as before, and in the notes
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    args.record_notes = [str(w.message) for w in caught if issubclass(w.category, UnitWarning)]
    if args.switches is not None:
        from benchmarks.lab.switches import with_switches
        record = with_switches(record, [s - record.t_offset for s in args.switches])
    if args.velocities is not None:
        from benchmarks.lab.switches import with_velocities
        record = with_velocities(record, [v * 1e-6 for v in args.velocities])
    if args.clock == "displacement":
        from benchmarks.lab.clock import displacement_clock
        record, clock_notes = displacement_clock(record, refit=args.switches is None)
        args.record_notes += clock_notes
    if args.weights is not None and len(args.weights) != len(record.velocities):
        raise ValueError(f"--weights: {len(args.weights)} given, but the record's history has "
                         f"{len(record.velocities)} pieces (one weight each): "
                         f"{_pieces_line(record)}")
    return {law: _model(args, record, law) for law in laws}


def _fit_laws(args, models: dict, given: dict):
    """``(fit, notes, laws, switches)``: each law's model fitted (``given``: the held
    parameters, each where its law has it) and its switch times refined on the friction with
    that law (``--switches-from friction``; :mod:`benchmarks.lab.switches`, their table: the
    chosen law's); with several laws, their table (:func:`benchmarks.lab.laws.compare_laws`)
    and ``args.law`` set to the chosen one, whose fit and notes are returned. (Refining with
    the first law alone and fitting the others there made the comparison depend on the laws'
    order: a slip-law record compared as aging,slip read the slip law as not fitting.)"""
    from benchmarks.lab.parallel import run_all
    done = run_all([functools.partial(_fit_law, args, law, model, given)
                    for law, model in models.items()], args.workers)
    fits = {law: (fit, notes) for law, (fit, notes, _) in zip(models, done)}
    tables = {law: table for law, (_, _, table) in zip(models, done) if table is not None}
    for law, (fit, notes) in fits.items():
        if fit.failed_solves:
            notes.append(f"{fit.failed_solves} of {fit.solves} solves failed or ran over the "
                         f"{args.wall_budget:g} s budget each (--wall-budget): the fit, its "
                         "switch times and profiles stand on the others, and open intervals "
                         "may be the budget's, not the record's")
    laws = list(models)
    table = None
    if len(laws) > 1:
        from benchmarks.lab.laws import compare_laws
        table = compare_laws({law: f for law, (f, _) in fits.items()})
        chosen = table.law[table.chosen]
        args.law = str(chosen.iloc[0]) if len(chosen) else laws[0]
    return (*fits[args.law], table, tables.get(args.law))


def _fit_law(args, law: str, model, given: dict):
    """``(fit, notes, switches)`` of one law (:func:`_fit_laws`); ``switches`` is None unless
    refined on the friction."""
    fixed = {k: v for k, v in given.items() if k in model.parameters}
    _stage(args, f"fitting {', '.join(n for n in model.parameters if n not in fixed)} "
                 f"({law} law) to {len(model.record.t):,} samples")
    fit, notes = _fit(model, fixed, args.weights)
    if args.switches is None and args.switches_from == "friction" and fit.success:
        from benchmarks.lab.switches import refine_switches
        _stage(args, f"the switch times on the friction ({law} law)")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            refined, table = refine_switches(fit)
        return refined, list(refined.notes), table
    return fit, notes, None


def _switches_doc(args, switches) -> dict:
    """lab_fit.json's ``switches``: where the history's switch times came from, and each
    switch's profile on the friction."""
    source = ("given (--switches)" if args.switches is not None else
              "the displacement's piecewise line" if args.switches_from == "displacement" else
              "the displacement's piecewise line, refined on the friction (the fit's squares "
              "profiled over each switch time; benchmarks/lab/switches.py)")
    return {"from": source, "table": None if switches is None else
            switches.to_dict(orient="records")}


def _report_switches(args, switches) -> None:
    """Each switch: where the displacement and the friction put it."""
    if switches is None:
        say("switch times: " + ("as given (--switches)" if args.switches is not None else
                                "from the displacement alone (--switches-from displacement)"))
        return
    for r in switches.itertuples():
        ends = "–".join(f"{v:.3f}{'' if c else ' (open)'}" for v, c in
                        ((r.low95_s, r.low_closed), (r.high95_s, r.high_closed)))
        say(f"switch {r.switch}: the displacement puts it at {r.displacement_s:.3f} s, the "
            f"friction at {r.friction_s:.3f} s (95 %: {ends} s; {r.fits} fits)"
            + (f"; they disagree: the friction's squares rise by {r.rise_at_displacement:.3g} "
               "f σ² at the displacement's time" if r.disagree else "")
            + f"; over its interval k′ runs {r.k_min * 1e-6:.3g}–{r.k_max * 1e-6:.3g} per µm, "
              f"Dc {r.dc_min * 1e6:.3g}–{r.dc_max * 1e6:.3g} µm")


def _stage(args, text: str) -> None:
    """What runs now, on a terminal only (not with --json)."""
    if show_progress(args):
        print(f"  {text} …", file=sys.stderr, flush=True)


def _fit(model, fixed: dict, weights):
    """The least-squares fit and the notes of its warnings (:class:`LabFitWarning`)."""
    from benchmarks.lab.fit import LabFitWarning, fit_lab
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LabFitWarning)
        fit = fit_lab(model, fixed=fixed, weights=weights)
    return fit, [str(w.message) for w in caught if issubclass(w.category, LabFitWarning)]


def _profiles_and_check(args, fit, notes: list):
    """``(profiles, check, early)``: the profile of each fitted parameter of :data:`PROFILED`
    (a profile's note joins ``notes``) and the solver check, side by side on ``--workers``;
    each None or empty where its option turns it off. With ``--out``, the files' parts that
    need the fit alone are made meanwhile (``early``, else None): the figure begun here
    (:class:`~benchmarks.lab.fit_figure.FitFigure`, matplotlib imported with it) and the
    residuals' table as CSV text by a worker."""
    from benchmarks.lab.parallel import run_all
    names = [] if args.no_profiles else [n for n in PROFILED if n in fit.free]
    pieces = [functools.partial(_profile, args, fit, n) for n in names]
    if not args.no_solver_check:
        pieces.append(functools.partial(_check, args, fit))
    files = args.out is not None
    # the CSV first: a worker takes it while this process begins the figure
    csv = [functools.partial(_residuals_csv, fit)] if files else []
    done = run_all(csv + pieces, args.workers,
                   here=functools.partial(_figure, fit, names) if files else None)
    early = (done.pop(), done.pop(0)) if files else None      # (the figure, the CSV)
    profiles = dict(zip(names, done))
    notes.extend(p.note for p in profiles.values() if p.note)
    return profiles, None if args.no_solver_check else done[-1], early


def _figure(fit, names: list):
    from benchmarks.lab.fit_figure import FitFigure
    return FitFigure(fit, names)


def _residuals_csv(fit) -> str:
    """lab_fit_residuals.csv's text: the record, the fit and their difference."""
    rec = fit.model.record
    # t_s is the file's time; on the displacement's clock, the model's is t_clock_s
    clock = {} if rec.file_t is None else {"t_clock_s": rec.t + rec.t_offset}
    return pd.DataFrame({
        "t_s": rec.t + rec.t_offset if rec.file_t is None else rec.file_t, **clock,
        "load_point_m": rec.load_point, "mu": rec.mu, "mu_model": fit.mu_model,
        "residual": rec.mu - fit.mu_model}).to_csv(index=False, lineterminator="\n")


def _profile(args, fit, name: str):
    from benchmarks.lab.profile_intervals import profile_lab
    _stage(args, f"the profile of {name}")
    return profile_lab(fit, name)


def _check(args, fit) -> dict:
    from benchmarks.lab.checks import check_lab_solver
    _stage(args, "the solver check")
    return check_lab_solver(fit)


def _posterior(args, fit):
    from benchmarks.lab.sampling import sample_lab
    try:
        return sample_lab(fit, walkers=args.walkers, steps=args.steps, seed=args.seed,
                          progress=not args.json and not args.no_progress)
    except KeyboardInterrupt as exc:      # one line (main), never emcee's traceback
        raise KeyboardInterrupt(f"lab fit interrupted ({stopped_by()[0]}): "
                                f"{str(exc) or 'the posterior'}; nothing written") from None


def _inertia(args, fit, record) -> dict:
    """The inertial (and damped) slider fitted too, and how far its parameters moved."""
    from benchmarks.lab.checks import inertia_check
    from benchmarks.lab.fit import LabFitWarning
    _stage(args, "the inertial fit")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LabFitWarning)
        inertial, shifts = inertia_check(fit, args.mass or 0.0, args.normal_force,
                                         args.radiation_damping or 0.0)
    moved = shifts[shifts.shift_se.abs() > 1.0]
    k_n_per_m = fit.values["k"] * args.normal_force
    period = 2 * math.pi * math.sqrt((args.mass or 0.0) / k_n_per_m)
    fastest = max(record.velocities)
    return {"mass_kg": args.mass or 0.0, "normal_force_N": args.normal_force,
            "period_s": period, "dc_time_s": fit.values["dc"] / fastest,
            "radiation_damping_N_s_per_m": args.radiation_damping or 0.0,
            "shifts": shifts.to_dict(orient="records"),
            "matters": bool(len(moved)),
            "parameters": inertial.table().to_dict(orient="records")}


def _table(fit, profiles: dict, posterior):
    """The fit's parameter table with the profile and posterior intervals beside."""
    table = fit.table()
    for name, prof in profiles.items():
        i = table.index[table.parameter == name][0]
        table.loc[i, "profile_low95"], table.loc[i, "profile_high95"] = prof.interval
        table.loc[i, "profile_low_closed"], table.loc[i, "profile_high_closed"] = prof.closed
    if posterior is not None:
        for name, (low, median, high) in posterior.quantiles.items():
            i = table.index[table.parameter == name][0]
            table.loc[i, ["posterior_low95", "posterior_median", "posterior_high95"]] = \
                low, median, high
    return table


def _doc(args, record, fit, table, fixed, notes, profiles, check, inertia, posterior) -> dict:
    """lab_fit.json: the record, the history, the fit, its noise, intervals and checks."""
    return {"tool": version_line(), **provenance(), "command": args.command_line,
            "recording": str(Path(args.recording).resolve()), "sha256": record.sha256,
            "columns": record.columns, "window_s": list(args.window) if args.window else None,
            "law": args.law, "states": args.states, "detrend": args.detrend, "clock": args.clock,
            "fixed": fixed,
            "weights": list(args.weights) if args.weights else None,
            "history": {"velocities_m_s": list(record.velocities),
                        "switch_times_s": record.file_time(record.switch_times).tolist(),
                        "pieces": record.pieces.assign(
                            t_start_s=record.file_time(record.pieces.t_start_s),
                            t_end_s=record.file_time(record.pieces.t_end_s)).to_dict(
                            orient="records")},
            "samples": fit.n, "parameters": table.to_dict(orient="records"),
            "trend": _trend_doc(fit, record),
            "noise": {"model": "white + AR(1) + random walk, fitted to the residuals' "
                               "variogram (benchmarks.lab.noise): covariance = inflation * "
                               "sigma^2 (J'J)^-1 (inflation * sigma^2 the white + AR(1) part's "
                               "long-run variance) plus the walk's share (drift_sigma per "
                               "sample; benchmarks.lab.noise.drift_covariance); with "
                               "--detrend steady the held slopes and the fit mapped through "
                               "that one noise together "
                               "(benchmarks.lab.noise.propagated_covariance); rho is the "
                               "residuals' lag-1 autocorrelation",
                      "white_variance": _noise_part(fit, "white"),
                      "ar1_variance": _noise_part(fit, "correlated"),
                      "ar1_phi": _noise_part(fit, "phi"),
                      "sigma": fit.sigma, "rho": fit.rho, "inflation": fit.inflation,
                      "drift_sigma": fit.drift_sigma, "drift_factor": fit.drift_factor,
                      "record_noise": fit.noise,
                      "record_noise_is": "the robust spread of mu's second differences / "
                                         "sqrt(6), no model (benchmarks.lab.fit.sample_noise)"},
            "success": fit.success, "message": fit.message, "at_bound": list(fit.at_bound),
            "notes": notes, "solves": fit.solves, "failed_solves": fit.failed_solves,
            "wall_budget_s": args.wall_budget, "wall_s": fit.wall_s,
            "profiles": {n: {"interval": list(p.interval), "closed": list(p.closed),
                             "solves": p.solves, "wall_s": p.wall_s}
                         for n, p in profiles.items()},
            "solver_check": check, "inertia": inertia,
            "posterior": None if posterior is None else {
                "walkers": args.walkers, "steps": args.steps, "seed": args.seed,
                "prior": posterior.prior, "likelihood": posterior.likelihood,
                "acceptance": posterior.acceptance, "tau": posterior.tau,
                "tau_reliable": posterior.tau_reliable,
                "effective_samples": posterior.effective_samples, "solves": posterior.solves,
                "wall_s": posterior.wall_s}}


def _trend_doc(fit, record) -> dict:
    """lab_fit.json's trend: ln Dc's correlation with the slope it follows most, and with
    ``--detrend steady`` each piece's held slope (per m; None where the slope was fitted or
    the piece is a hold), its
    error, where its steady part starts and where the fit said it may ("steady_after_s"):
    file times in s, None where no word, "never" for a piece whose evolution does not end;
    and the law's parameters with every slope fitted instead ("alternatives")."""
    def when(v):
        return (None if math.isnan(v) else "never" if math.isinf(v) else
                float(record.file_time(v)))

    doc = {"dc_trend_correlation": None if math.isnan(fit.trend_rho) else fit.trend_rho}
    steady = fit.model.steady
    if steady is not None:
        after = fit.model.steady_after or (math.nan,) * len(steady.slopes)
        moving = [v > 0 for v in fit.model.record.velocities]    # a hold has no trend
        doc.update(held_slopes_per_m=[float(v) if m and not f else None for v, f, m in
                                      zip(steady.slopes, steady.fitted, moving)],
                   held_se_per_m=[fit.linear_se.get(f"trend_{i}") if m and not f else None
                                  for i, (f, m) in enumerate(zip(steady.fitted, moving))],
                   fitted_pieces=[i for i, f in enumerate(steady.fitted) if f],
                   steady_from_s=[when(v) for v in steady.steady_from],
                   steady_after_s=[when(v) for v in after],
                   alternatives=fit.alternatives)
    return doc


#: the trends --detrend auto compares: not steady, whose slopes are the piece trend's held at
#: other values (its squares are never below piece's, and it has as many parameters)
AUTO_TRENDS = ("piece", "one", "none")

#: how the laws and the trends are chosen, for lab_fit.json
CHOSEN_BY = ("the lowest bic_eff = n ln(RSS/n)/f + p ln(n/f), the BIC of n/f independent "
             "samples, f the long-run inflation of the noise model of the fit with the "
             "smallest squares "
             "(benchmarks/lab/laws.py)")


def _report_variants(table, what: str) -> None:
    """The laws or the trends side by side, and which is reported in full."""
    label = table.columns[0]
    shown = table[[label, "rss", "sigma", "rho", "sigma_over_noise", "fits", "bic", "bic_eff",
                   "delta_bic_eff", "a", "b", "dc", "k"]].copy()
    shown["dc"], shown["k"] = shown.dc * 1e6, shown.k * 1e-6
    shown = shown.rename(columns={"dc": "dc_um", "k": "k_per_um"})
    from benchmarks.lab.fit import NOT_FIT, NOT_FIT_RHO
    say(f"the {what} on this record (the lowest BIC of n/f independent samples chosen, f the "
        f"noise model's long-run inflation; 'fits' False: residuals over {NOT_FIT:g} × the record's "
        f"sample-to-sample noise with ρ over {NOT_FIT_RHO:g}):")
    say(shown.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    chosen = table[label][table.chosen]
    say(f"chosen: {label} {chosen.iloc[0]}, reported below" if len(chosen) else
        f"no fit succeeded: the first {label}'s is reported below")


def _choose_trend(args, fit):
    """``--detrend auto``: the chosen law refitted with each trend at its switches, the lowest
    ``bic_eff`` chosen (``args.detrend`` set to it); ``(fit, notes, table)``."""
    from benchmarks.lab.laws import compare_laws
    fits = {}
    for trend in AUTO_TRENDS:
        model = dataclasses.replace(fit.model, detrend=trend)
        _stage(args, f"the {args.law} law with the trend {trend}")
        fits[trend] = (fit if trend == fit.model.detrend else
                       _fit(model, fit.fixed, args.weights)[0])
    table = compare_laws({t: f for t, f in fits.items()}, label="detrend")
    chosen = table.detrend[table.chosen]
    args.detrend = str(chosen.iloc[0]) if len(chosen) else fit.model.detrend
    best = fits[args.detrend]
    return best, list(best.notes), table


def _pieces_line(record) -> str:
    return ", ".join(f"{v * 1e6:.4g} µm/s from {record.file_time(t):.6g} s"
                     for v, t in zip(record.pieces.velocity_m_s, record.pieces.t_start_s))


def _report(fit, table, profiles, check, inertia, notes, record, args) -> None:
    say(f"{record.source}: {fit.n} samples; the load point: {_pieces_line(record)}")
    say(f"{args.law} law{', two state variables' if args.states == 2 else ''}, detrend "
        f"{args.detrend}: {fit.solves} solves, {fit.wall_s:.2f} s"
        + (f" ({fit.failed_solves} failed or over the {args.wall_budget:g} s budget per solve: "
           "not read as μ)" if fit.failed_solves else "")
        + ("" if fit.success else f" — the fit did not converge: {fit.message}"))
    shown = table.copy()
    for col in ("value", "se", "wald_low95", "wald_high95", "profile_low95", "profile_high95",
                "posterior_low95", "posterior_median", "posterior_high95"):
        if col in shown:
            shown[col] = [_num(v, u) for v, u in zip(shown[col], shown.unit)]
    for side in ("low", "high"):        # an open end is the bound, not an interval's end
        if f"profile_{side}_closed" in shown:
            col = shown[f"profile_{side}95"].astype(object)
            open_end = shown[f"profile_{side}_closed"] == False  # noqa: E712 (NaN: not profiled)
            shown[f"profile_{side}95"] = [f"{v} open" if o else v for v, o in zip(col, open_end)]
            shown = shown.drop(columns=f"profile_{side}_closed")
    shown["unit"] = shown.unit.replace({"m": "µm", "1/m": "1/µm", "1": ""})
    say(shown.to_string(index=False))
    model = fit.noise_model.describe() if fit.noise_model is not None else "AR(1)"
    say(f"noise: σ = {fit.sigma:.3g} (the residuals' scatter; lag-1 autocorrelation "
        f"ρ = {fit.rho:.3f}), {model}: the variances are "
        f"f σ² (JᵀJ)⁻¹ with f = {fit.inflation:.3g} (standard errors ×"
        f"{math.sqrt(max(fit.inflation, 0.0)):.3g}); Wald intervals are value ± 1.96 se, "
        "profile ones where the squares rise by 3.84 f σ² (trust the profile where they "
        "differ; an open end is the parameter's bound)")
    _report_trend(fit)
    for note in notes:
        say(f"note: {note}")
    if check is not None:
        _report_check(check)
    if inertia is not None:
        say(f"with the mass ({inertia['mass_kg']:g} kg on {inertia['normal_force_N']:g} N: a "
            f"period 2π√(m/k) of {inertia['period_s']:.3g} s against {inertia['dc_time_s']:.3g} "
            "s to slip one Dc at the fastest speed): "
            + ", ".join(f"{r['parameter']} moves {r['shift_se']:+.2g} s.e."
                        for r in inertia["shifts"])
            + (" — the inertia changes the fit beyond its error bars" if inertia["matters"]
               else " — within the error bars: the quasi-static fit stands"))
        if inertia["matters"]:
            inertial = pd.DataFrame(inertia["parameters"])
            for col in ("value", "se", "wald_low95", "wald_high95"):
                inertial[col] = [_num(v, u) for v, u in zip(inertial[col], inertial.unit)]
            inertial["unit"] = inertial.unit.replace({"m": "µm", "1/m": "1/µm", "1": ""})
            say("the inertial fit (lab_fit.json: inertia):")
            say(inertial[["parameter", "value", "se", "wald_low95", "wald_high95",
                          "unit"]].to_string(
                index=False))
    if args.out is not None:
        say(f"wrote {', '.join(args.written)} to {args.out}")


def _report_trend(fit) -> None:
    """What widens the errors beyond the noise (a walk, a held trend's slopes); with a held
    trend, which slopes were held from where, and the law's parameters with every slope
    fitted instead."""
    steady = fit.model.steady
    why = ([f"the residuals wander as a random walk of {fit.drift_sigma:.3g} per sample beyond "
            "their AR(1) correlation"] if fit.drift_sigma > 0 else [])
    if steady is not None and not all(steady.fitted):
        why.append("the held trend's slopes carry their own errors")
    if why and any(v > 1 for v in fit.drift_factor.values()):
        grown = ", ".join(f"{k} ×{math.sqrt(v):.3g}" for k, v in fit.drift_factor.items())
        say(f"drift: {'; '.join(why)}: these widen the standard errors ({grown}) and each "
            "profile's unit alike")
    if steady is None:
        return
    # each held slope's error as the covariance carries it (the fit's noise model)
    held = [f"piece {i} {s * 1e-6:.3g} ± {fit.linear_se.get(f'trend_{i}', math.nan) * 1e-6:.2g}"
            f" per µm from {fit.model.record.file_time(t):.6g} s"
            for i, (s, t, f, v) in enumerate(zip(steady.slopes, steady.steady_from,
                                                  steady.fitted, fit.model.record.velocities))
            if not f and v > 0 and math.isfinite(s)]
    fitted = [str(i) for i, (f, v) in enumerate(zip(steady.fitted, fit.model.record.velocities))
              if f and v > 0]
    say("trend: held where the slider is steady: " + ("; ".join(held) or "none")
        + (f"; fitted with the rest: piece {', '.join(fitted)}" if fitted else ""))
    piece = fit.alternatives.get("piece")
    if piece:
        from benchmarks.lab.fit import PARAMETER_UNITS
        shown = {"m": " µm", "1/m": " per µm"}
        say("with every slope fitted instead (--detrend piece): " + ", ".join(
            f"{n} {_num(v, PARAMETER_UNITS.get(n, '1'))}{shown.get(PARAMETER_UNITS.get(n), '')}"
            for n, v in piece.items()))


def _noise_part(fit, name: str) -> float:
    """One number of the fit's noise model (NaN without one)."""
    return getattr(fit.noise_model, name) if fit.noise_model is not None else math.nan


def _report_check(check: dict) -> None:
    """The solver check's line."""
    if not check["checked"]:
        say(f"solver check: not run: {check['reason']}")
    elif check.get("reason"):
        say(f"solver check: FAILED: {check['reason']}")
    else:
        say(f"solver check: {check['integrator']} is {check['error_sigma']:.2g} σ from "
            f"{check['references'][0]}, whose gap to {check['references'][1]} is "
            f"{check['references_disagree_sigma']:.2g} σ"
            + ("" if check.get("scale", "the residuals' σ") == "the residuals' σ" else
               f" (σ here: {check['scale']})") + ": "
            + ("passed (≤ 0.1 σ)" if check["passed"] else
               "FAILED: tighten --rtol or choose another --integrator"))


#: ``--switches``: times in s; ``--velocities``: speeds in µm/s
_times, _speeds = numbers("times in s", "11676.3,11720"), numbers("speeds in µm/s", "3,10")


def _num(v, unit) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    scale = {"m": 1e6, "1/m": 1e-6}.get(unit, 1.0)      # shown in µm and per µm
    return f"{v * scale:.5g}"


def _write_all(args, early, table, profiles, doc, posterior, extras: dict) -> None:
    """Every file of ``--out`` (``early``: the figure begun and the residuals' CSV text,
    :func:`_profiles_and_check`'s; ``extras``: name → a table or None, lab_fit_NAME.csv),
    their names into ``args.written``."""
    args.written = _write(args.out, early, table, profiles, doc)
    for name, extra in extras.items():
        if extra is not None:
            write_table(extra.assign(command=doc["command"], tool=doc["tool"]),
                        args.out / f"lab_fit_{name}.csv")
            args.written.append(f"lab_fit_{name}.csv")
    if posterior is not None:
        write_table(posterior.samples, args.out / "lab_fit_posterior.csv")
        args.written.append("lab_fit_posterior.csv")
    from benchmarks.records.files import remove_own
    for name in LAB_FIT_FILES:              # an earlier run's this one did not make again
        if name not in args.written:
            remove_own(args.out / name)
    doc["out"] = str(args.out)


def _write(out: Path, early, table, profiles, doc) -> list[str]:
    figure, residuals = early
    write_table(table.assign(command=doc["command"], tool=doc["tool"]),
                out / "lab_fit_parameters.csv")
    write_output(out / "lab_fit_residuals.csv", residuals)
    if profiles:
        from benchmarks.lab.fit import PARAMETER_UNITS
        write_table(pd.concat([p.points.rename(columns={p.parameter: "value"}).assign(
            parameter=p.parameter, unit=PARAMETER_UNITS[p.parameter])
            for p in profiles.values()]), out / "lab_fit_profiles.csv")
    write_output(out / "lab_fit.json", json.dumps(jsonable(doc), indent=2))
    write_figure(figure.finish(profiles), out / "lab_fit.png", dpi=110)
    return ["lab_fit.json", "lab_fit_parameters.csv", "lab_fit_residuals.csv",
            *(["lab_fit_profiles.csv"] if profiles else []), "lab_fit.png"]


def add_parser(tests) -> None:
    p = tests.add_parser("fit", help="fit (a, b, Dc) and the stiffness to a velocity-step or "
                         "slide-hold-slide record", description=__doc__.split("\n\n")[0])
    p.add_argument("recording", type=in_file, metavar="RECORDING",
                   help="the record: CSV, TSV, TXT or Parquet (required)")
    p.add_argument("--column", action="append", default=[], metavar="CHANNEL=COLUMN[:UNIT]",
                   help="a column and its unit (repeatable; required): time (s, ms, us), "
                        "friction (μ) or shear_force (N, kN, MN), load_point (m, mm, um, nm) or "
                        "load_velocity (m/s, mm/s, um/s; held over each sample interval); the "
                        "unit defaults to SI")
    p.add_argument("--normal-force", type=positive, metavar="N",
                   help="the normal force in N, for a shear_force column or the inertial "
                        "slider (default: none)")
    p.add_argument("--window", type=float, nargs=2, metavar=("START", "END"),
                   help="fit the part of the record from START to END, in the file's time, s "
                        "(default: all of it; it must start in steady sliding)")
    _add_history_options(p)
    p.add_argument("--law", default="aging", metavar="LAW[,LAW…]",
                   help=f"the friction law ({', '.join(LAWS)}), or several separated by commas "
                        "to compare them (aging,slip): each is fitted, the laws are tabled "
                        "(RSS, AIC, BIC, the residuals against the record's own noise) and the "
                        "lowest BIC is reported in full (default: aging)")
    p.add_argument("--states", type=int, choices=(1, 2), default=1,
                   help="state variables: 1, or 2 for a second evolution (b2, Dc2; b2 may be "
                        "negative; quasi-static only) (default: 1)")
    p.add_argument("--stiffness", type=positive, metavar="PER_M",
                   help="k′ = k/Fn, friction per metre of load-point travel (1/m; 0.001 per µm "
                        "is 1000), held fixed (default: fitted)")
    p.add_argument("--c", type=non_negative,
                   help="the Nagata law's c, dimensionless, held fixed (default: fitted)")
    p.add_argument("--detrend", choices=(*DETRENDS, "auto"), default="steady",
                   help="a linear trend in the load point's displacement: steady (a slope per "
                        "piece read only where the slider is steady, before the step and after "
                        "the evolution has ended, as Giacomel et al.'s steadystate finds it, "
                        "then held, its error carried into the intervals), piece (a slope per "
                        "piece fitted with the rest), one slope, none, or auto: piece, one and "
                        "none fitted and the lowest BIC of n/f independent samples chosen (f "
                        "the noise's long-run inflation; lab_fit_trends.csv) (default: "
                        "steady)")
    p.add_argument("--weights", type=float, nargs="+", metavar="W",
                   help="a weight per piece of the history, multiplying its residuals "
                        "(default: 1 each)")
    p.add_argument("--mass", type=non_negative, metavar="KG",
                   help="the slider's mass in kg: fit the inertial slider too and say whether "
                        "it moves the fit beyond its error bars (default: quasi-static only)")
    p.add_argument("--radiation-damping", type=non_negative, metavar="N_S_PER_M",
                   help="radiation damping in N s/m: the check refits the damped (and, with "
                        "--mass, inertial) slider too (default: 0)")
    _add_run_options(p)
    p.add_argument("--out", type=out_dir, metavar="DIR",
                   help="write lab_fit.json, lab_fit_parameters.csv, lab_fit_residuals.csv, "
                        "lab_fit_profiles.csv and lab_fit.png there (default: print only)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_lab_fit)


def _add_history_options(p) -> None:
    """The load point's history and clock: switches, speeds by hand, the clock."""
    p.add_argument("--switches-from", choices=("friction", "displacement"), default="friction",
                   help="where the history's switch times come from: the displacement's "
                        "piecewise line refined on the friction (each switch profiled within "
                        "±50 samples; default), or the displacement alone")
    p.add_argument("--velocities", type=_speeds, metavar="V1,V2,…",
                   help="the load point's speeds by hand, in µm/s, one per piece of the "
                        "history, comma-separated (0: a hold): the commanded speeds (default: "
                        "each piece's slope in the displacement)")
    p.add_argument("--clock", choices=("time", "displacement"), default="time",
                   help="the model's clock: the record's time, or the load point's "
                        "displacement (each sample at the time a load point keeping the "
                        "history's speeds reaches its measured displacement, as xlook and "
                        "RSFit3000 fit; for a poor time base) (default: time)")
    p.add_argument("--switches", type=_times, metavar="T1,T2,…",
                   help="the switch times by hand, in the file's time (s), comma-separated: "
                        "taken as they are (default: found; see --switches-from)")


def _add_run_options(p) -> None:
    """The integrator, the posterior, what to skip and the wall budget of each solve."""
    p.add_argument("--integrator", metavar="NAME",
                   help=f"registry name of a method with dense output: the project's slider "
                        f"through solve, its Jacobian by finite differences ({DEFAULT_ALGORITHM[0]} "
                        "with --rtol alone; default: none, the compiled model with exact "
                        "sensitivities)")
    p.add_argument("--rtol", type=positive,
                   help=f"rtol = atol of --integrator, dimensionless ({DEFAULT_ALGORITHM[1]:g} "
                        "with --integrator alone; default: none, the compiled model at 1e-11)")
    p.add_argument("--posterior", action="store_true",
                   help="sample the posterior with emcee too (the inversion extra; uniform "
                        "prior in a, b, c, b2, ln Dc, ln k′, ln Dc2 within the fit's bounds)")
    p.add_argument("--walkers", type=int, default=32,
                   help="emcee walkers, with --posterior (default: 32)")
    p.add_argument("--steps", type=int, default=600,
                   help="emcee steps, with --posterior; a quarter is dropped (default: 600)")
    p.add_argument("--seed", type=seed, default=0,
                   help="the posterior's random seed (default: 0)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-profiles", action="store_true",
                   help="skip the profile intervals of a, b and Dc (and b2, Dc2)")
    p.add_argument("--no-solver-check", action="store_true",
                   help="skip the check of the integrator against two references at 1e-12")
    p.add_argument("--workers", type=workers, metavar="N",
                   help="processes for the independent pieces: each law's fit and switch "
                        "times, each profile and the solver check (the results do not depend "
                        "on it, unless a solve runs into --wall-budget: more processes than "
                        "cores make each solve slower) (default: this machine's cores)")
    p.add_argument("--wall-budget", type=positive, default=WALL_BUDGET, metavar="S",
                   help="wall-time budget of each solve in s: the fit's, its profiles', the "
                        "posterior's and the solver check's (a reference over it fails the "
                        "check: exit status 1; the compiled model has a step budget too) "
                        f"(default: {WALL_BUDGET:g} s per solve)")
