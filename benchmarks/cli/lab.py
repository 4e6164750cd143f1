"""rsfbench lab: a velocity step or a slide-hold-slide test, and what it measures.

    rsfbench lab step --law aging --v1 1e-6 --v2 1e-5 --json
    rsfbench lab shs --law nagata --holds 1 10 100 --out results/lab
    rsfbench lab fit run.txt --column time=Time:s --column friction=Friction \\
        --column load_point=Displ:um                 (benchmarks.cli.lab_fit)

The apparatus is that of Marone's code as distributed with rsfmodel (problems.presets.LAB:
a = 0.005, b = 0.01, Dc = 10 µm, k = 1e7 N/m on 10 kN, V0 = 1 µm/s), quasi-static unless
--mass is given; --problem FILE runs your own apparatus and history instead (TOML or JSON).

μ is the spring force over the normal force (what a load cell reads; with mass it is not the
friction). The peaks are located by re-solving from the run's states (benchmarks.lab.measures), not read
off the saved trajectory: the save grid (the trajectory file and plot) does not move them. A
piece that has not settled is named in a warning, and its steady-state change is null.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.cli.args import (
    SPEED,
    TIME,
    RunStopped,
    in_file,
    non_negative,
    out_dir,
    positive,
    quantity,
    say,
    show_progress,
)
from benchmarks.cli.lab_fit import add_parser as add_fit_parser
from benchmarks.records.files import claim_outputs, write_figure, write_table
from benchmarks.records.report import jsonable, literal
from integrators import make_algorithm, solve
from problems import LAWS, law_parameters, load_problem, slide_hold_slide_test, velocity_step_test

__all__ = ["add_parsers"]

DEFAULT_INTEGRATOR, DEFAULT_TOL = "Rodas5P", 1e-8
#: saved points per run, for lab_trajectory.csv and lab.png only (the measures re-solve)
SAVED_POINTS = 20_000


#: the options of each test, with their defaults (None on the command line: "not given")
STEP_OPTIONS = {"v1": 1e-6, "v2": 1e-5, "t_step": 10.0, "after": 30.0}
#: a slide of 300 s (30 Dc at 1 µm/s) settles after a 100 s hold to SETTLED of a (100 s did not)
SHS_OPTIONS = {"holds": [1.0, 10.0, 100.0], "v": 1e-6, "slide": 300.0, "first_slide": 10.0}



def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _problem(args):
    own, other = ((STEP_OPTIONS, SHS_OPTIONS) if args.test == "step"
                  else (SHS_OPTIONS, STEP_OPTIONS))
    wrong = [k for k in other if getattr(args, k) is not None]
    if wrong:
        raise ValueError(f"{_flag(wrong[0])} is an option of `lab "
                         f"{'shs' if args.test == 'step' else 'step'}`, not of `lab {args.test}`")
    if args.problem is not None:
        given = [f for f in ("law", "mass", "radiation_damping", "c", "stiffness", *own)
                 if getattr(args, f) is not None]
        if given:
            raise ValueError(f"{_flag(given[0])} applies to the built-in apparatus; a problem "
                             "file states it")
        problem = load_problem(args.problem)
        hist = problem.loading.history
        if hist.overshoots:
            raise ValueError(f"{args.problem}: its loading has an overshoot (two-speed "
                             "loading), whose load-point velocity changes after each event: "
                             "a laboratory test needs a history of fixed switch times")
        pairs = list(zip(hist.velocities, hist.velocities[1:]))
        if args.test == "step" and not any(0 < v1 != v2 > 0 for v1, v2 in pairs):
            raise ValueError(f"{args.problem}: its load-point history has no velocity step")
        if args.test == "shs" and not any(v1 == 0 and v2 > 0 for v1, v2 in pairs):
            raise ValueError(f"{args.problem}: its load-point history has no hold followed by "
                             "sliding")
        return problem
    opt = {k: d if getattr(args, k) is None else getattr(args, k) for k, d in own.items()}
    kw = dict(law=args.law or "aging", mass=args.mass or 0.0,
              radiation_damping=args.radiation_damping or 0.0, c=args.c,
              stiffness=args.stiffness)
    if kw["c"] is not None and "c" not in law_parameters(kw["law"]):
        raise ValueError(f"--c is a stress coefficient (the Nagata law's): the {kw['law']} law "
                         "has none")
    if args.test == "step" and opt["v1"] == opt["v2"]:
        raise ValueError(f"--v2 = {opt['v2']:g} m/s equals --v1: a velocity step needs two "
                         "different speeds")
    try:
        if args.test == "step":
            return velocity_step_test(v1=opt["v1"], v2=opt["v2"], t_step=opt["t_step"],
                                      t_end=opt["t_step"] + opt["after"], **kw)
        return slide_hold_slide_test(holds=tuple(opt["holds"]), v=opt["v"], slide=opt["slide"],
                                     first_slide=opt["first_slide"], **kw)
    except ValueError as exc:       # the problem names its field (t_end): say which flags set it
        given = " ".join(f"{_flag(k)} {' '.join(f'{x:g}' for x in np.atleast_1d(getattr(args, k)))}"
                         for k in own if getattr(args, k) is not None)
        raise ValueError(f"lab {args.test} {given}: {exc}" if given else str(exc)) from None


def _measures(sol, args):
    """The step and healing tables; a peak that cannot be located is a refusal naming what to
    lengthen (exit 2), a re-solve that failed a stopped run (exit 1)."""
    from benchmarks.lab.measures import (
        PeakNotReached,
        ResolveFailed,
        healing,
        step_response,
    )
    try:
        return step_response(sol), healing(sol)
    except ResolveFailed as exc:
        raise RunStopped(str(exc)) from None
    except PeakNotReached as exc:
        if args.problem is not None:
            hint = f"lengthen that piece of {args.problem}'s history"
        elif exc.too_short:
            hint = "lengthen --after" if args.test == "step" else "lengthen --slide"
        else:
            hint = "lengthen --t-step" if args.test == "step" else "lengthen --first-slide"
        raise ValueError(f"{exc}: {hint}") from None


def cmd_lab(args) -> int:
    from benchmarks.lab.measures import healing_rate
    problem = _problem(args)
    name = args.integrator or DEFAULT_INTEGRATOR
    tol = args.rtol if args.rtol is not None else (None if args.integrator else DEFAULT_TOL)
    algorithm = make_algorithm(name, rtol=tol, atol=args.atol if args.atol is not None else tol)
    out = args.out
    if out is not None:                   # before the work: a bad --out or a user's file
        claim_outputs(out / n for n in ("lab_steps.csv", "lab_healing.csv",
                                        "lab_trajectory.csv", "lab.png"))
        out.mkdir(parents=True, exist_ok=True)
    sol = solve(problem, algorithm, save_every=problem.t_end / (SAVED_POINTS - 1),
                progress=show_progress(args))
    if not sol.success:
        raise RunStopped(f"{algorithm.name} stopped at t = {sol.t_reached:.6g} s of "
                            f"{problem.t_end:g} s ({sol.retcode.value}: {sol.message})"
                            + (": without mass nor damping an instability runs away (v → ∞ in "
                               "finite time); add --mass or --radiation-damping"
                               if problem.quasi_static and not problem.radiation_damping
                               and sol.retcode.value == "StepUnderflow" else ""))
    hist = problem.loading.history
    steps, heal = _measures(sol, args)
    doc = {"problem": problem.name, "law": problem.law.name, "mass_kg": problem.mass,
           "radiation_damping_N_s_per_m": problem.radiation_damping,
           "velocities_m_s": list(hist.velocities), "switch_times_s": list(hist.switch_times),
           "integrator": algorithm.name, "options": algorithm.options(),
           "retcode": sol.retcode.value, "wall_s": sol.stats.wall_s, "steps": sol.stats.steps,
           "nfev": sol.stats.nfev, "steps_response": steps.to_dict(orient="records"),
           "healing": heal.to_dict(orient="records"),
           "healing_per_decade": healing_rate(heal)}
    if out is not None:
        write_table(steps, out / "lab_steps.csv")
        write_table(heal, out / "lab_healing.csv")
        write_table(pd.DataFrame({"t_s": sol.t, "v_m_s": sol.v,
                                  "mu": sol.fs / problem.normal_force, "theta": sol.theta}),
                    out / "lab_trajectory.csv")
        _plot(sol, heal, out / "lab.png")
        doc["out"] = str(out)
    if args.json:
        say(json.dumps(jsonable(doc), indent=2))
        return 0
    say(f"{problem.name}: {algorithm.name}, {sol.stats.steps} steps, {sol.stats.wall_s:.3g} s")
    if len(steps):
        say(steps.to_string(index=False))
    if len(steps) and not steps.settled.all():
        say("(a piece before or after a step has not settled, see the warning: its "
            "delta_mu_ss is NaN)")
    if len(heal):
        say(heal.to_string(index=False))
        if len(heal) >= 2:
            say(f"healing: {doc['healing_per_decade']:.4g} in μ per decade of hold time")
    if hist.velocities[-1] == 0.0:
        say("(the run ends in a hold: no reloading, no healing for it)")
    if out is not None:
        say(f"wrote lab_steps.csv, lab_healing.csv, lab_trajectory.csv and lab.png to {out}")
    return 0


def _plot(sol, heal, path: Path) -> None:
    from matplotlib.figure import Figure
    n = 3 if len(heal) >= 2 else 2
    fig = Figure(figsize=(4.5 * n, 3.8))
    axes = fig.subplots(1, n)
    mu = sol.fs / sol.problem.normal_force
    axes[0].plot(sol.t, mu, lw=0.8)
    axes[0].set_xlabel("t (s)")
    axes[0].set_ylabel("μ = Fs/Fn")
    axes[1].semilogy(sol.t, sol.v, lw=0.8)
    axes[1].set_xlabel("t (s)")
    axes[1].set_ylabel("slip rate (m/s)")
    if n == 3:
        axes[2].semilogx(heal.hold_s, heal.delta_mu_peak, "o-")
        axes[2].set_xlabel("hold time (s)")
        axes[2].set_ylabel("Δμ_peak")
        axes[2].grid(True, which="both", alpha=0.3)
    fig.suptitle(literal(sol.problem.name), fontsize=9)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def add_parsers(sub) -> None:
    lab = sub.add_parser("lab", help="a velocity step or a slide-hold-slide test: simulate "
                         "one (peaks, healing), or fit a record",
                         description=__doc__.split("\n\n")[0])
    tests = lab.add_subparsers(dest="test", required=True, metavar="{step,shs,fit}",
                               help="step: simulate a velocity step; shs: a slide-hold-slide "
                                    "sequence; fit: fit a record (required)")
    lab = argparse.ArgumentParser(add_help=False)       # the options step and shs share
    lab.add_argument("--problem", type=in_file, metavar="FILE",
                     help="your own apparatus and load-point history (TOML or JSON, "
                          "docs/problem-family.md); default: the built-in apparatus")
    lab.add_argument("--law", choices=tuple(LAWS),
                     help="friction law of the built-in apparatus (default: aging)")
    lab.add_argument("--c", type=quantity(non_negative, "dimensionless"),
                     help="the Nagata law's stress coefficient "
                     "(default: 2)")
    lab.add_argument("--mass", type=quantity(non_negative, "a mass in kg"), metavar="KG",
                     help="slider mass in kg (default: 0, quasi-static)")
    lab.add_argument("--radiation-damping", type=quantity(non_negative, "a damping in N s/m"),
                     metavar="N_S_PER_M",
                     help="radiation damping ηr in N s/m (default: 0)")
    lab.add_argument("--stiffness", type=quantity(positive, "a stiffness in N/m"),
                     metavar="N_PER_M",
                     help="spring stiffness in N/m (default: 1e7, on a 10 kN normal force)")
    lab.add_argument("--v1", type=SPEED, metavar="M_S",
                     help="step: load-point velocity before the step, m/s (default: 1e-6)")
    lab.add_argument("--v2", type=SPEED, metavar="M_S",
                     help="step: after the step, m/s (default: 1e-5)")
    lab.add_argument("--t-step", type=TIME, metavar="S",
                     help="step: time of the step, s (default: 10)")
    lab.add_argument("--after", type=TIME, metavar="S",
                     help="step: simulated time after the step, s (default: 30)")
    lab.add_argument("--holds", type=TIME, nargs="+",
                     metavar="S", help="shs: hold times, s (default: 1 10 100)")
    lab.add_argument("--v", type=SPEED, metavar="M_S",
                     help="shs: sliding velocity, m/s (default: 1e-6)")
    lab.add_argument("--slide", type=TIME, metavar="S",
                     help="shs: sliding after each hold, s (default: 300)")
    lab.add_argument("--first-slide", type=TIME, metavar="S",
                     help="shs: sliding before the first hold, s (default: 10)")
    lab.add_argument("--integrator", metavar="NAME",
                     help=f"registry name (default: {DEFAULT_INTEGRATOR} at rtol = atol = "
                          f"{DEFAULT_TOL:g}; results/family_wp.md compares them)")
    lab.add_argument("--rtol", type=quantity(positive, "dimensionless"),
                     help=f"relative tolerance (default: "
                     f"{DEFAULT_TOL:g} with the default integrator; required with --integrator "
                     "NAME of an adaptive method)")
    lab.add_argument("--atol", type=quantity(positive, "dimensionless"),
                     help="absolute tolerance on (h, ln w, Ψ or ln Ψ), "
                     "nondimensional (default: --rtol)")
    lab.add_argument("--out", type=out_dir, metavar="DIR",
                     help="write lab_steps.csv, lab_healing.csv, lab_trajectory.csv and lab.png "
                          "there (default: print only)")
    lab.add_argument("--json", action="store_true", help="print one JSON object")
    lab.add_argument("--no-progress", action="store_true", help="no progress bar")
    for name, what in (("step", "a velocity step"), ("shs", "a slide-hold-slide sequence")):
        tests.add_parser(name, parents=[lab], help=f"simulate {what} and what it measures",
                         description=__doc__.split("\n\n")[0]).set_defaults(func=cmd_lab)
    add_fit_parser(tests)
