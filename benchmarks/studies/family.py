"""The problem family beyond the paper's (docs/problem-family.md): the work-precision study
``family``, and ``problem-family``, its laboratory tests against Marone's published numbers
(:func:`write_lab_checks`).

The work-precision study has five problems, at quick settings:

* ``velocity-step/aging`` and ``velocity-step/nagata``: a tenfold velocity step on the laboratory
  apparatus of Marone's code (quasi-static), 30 s after the step;
* ``slide-hold-slide/aging``: holds of 1, 10 and 100 s, each followed by 100 s of sliding;
* ``W2/aging/quasi-dynamic``: the paper's W2 slider without mass, with the radiation damping of
  its fault (:func:`problems.presets.fault_radiation_damping`), 10 s;
* ``W2/aging/damped``: the same with its mass.

The quasi-static slider has no stick–slip cycle to measure: below kcr every run runs away to
v → ∞ in finite time (:func:`runaway` records where each stiff solver stops).

Errors, against a reference of two independent solvers that agree
(:data:`benchmarks.devtools.reference.REFERENCE_SOLVERS`):

* laboratory tests: ``err_peak``, the largest error of what the test measures (the excursion
  μ_extreme − μ_before after each step, the healing Δμ_peak of each hold: :mod:`benchmarks.lab.measures`)
  relative to the largest of them, and ``err_trajectory``, max |μ − μ_ref| over the common grid divided
  by the reference's range of μ. Timed with the trajectory saved on the grid, as a fit to
  sampled data needs it;
* stick–slip: the limit-cycle errors of :mod:`benchmarks.devtools.errors` (``err_recurrence`` ...).

The paper's ETD cannot run without mass: its rows there are ``Refused``. What happens to it as
the mass goes is :mod:`benchmarks.studies.mass_limit`.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from benchmarks.devtools.errors import ERROR_COLUMNS
from benchmarks.devtools.reference import (
    GRID_POINTS,
    REFERENCE_SOLVERS,
    ReferenceDisagreement,
    reference,
)
from benchmarks.devtools.work_precision import Ladder, best_at_levels, work_precision
from benchmarks.lab.measures import (
    PeakNotReached,
    healing,
    healing_rate,
    marone_check,
    step_response,
)
from benchmarks.records.files import atomic_write, write_figure, write_table
from benchmarks.records.provenance import provenance
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study
from integrators import REGISTRY, Rodas5P, solve
from problems import slide_hold_slide_test, velocity_step_test, window
from problems.presets import fault_radiation_damping

__all__ = ["STUDIES", "FAMILY", "family_problems", "LAB_PROBLEMS", "LabReference", "lab_reference",
           "lab_errors", "family_study", "FAMILY_LADDER", "LEVELS", "summary", "runaway",
           "write_family", "write_lab_checks", "advice"]

#: rtol = atol 1e−3 … 1e−10, ETD at 4 … 1/16 of the paper's Δτ; 10 s a solve
FAMILY_LADDER = Ladder(tolerances=tuple(10.0 ** -k for k in range(3, 11)),
                       etd_factors=(4, 2, 1, 0.5, 0.25, 0.125, 1 / 16), wall_budget=10.0)
#: the error levels of the summary
LEVELS = (1e-2, 1e-4, 1e-6)
#: the reference pair's agreement the laboratory references must meet (on err_peak's measures)
LAB_AGREEMENT = 1e-7


def _named(problem, name):
    return dataclasses.replace(problem, name=name)


FAMILY = {
    "velocity-step/aging": lambda: _named(velocity_step_test("aging", t_end=40.0),
                                          "velocity-step/aging"),
    "velocity-step/nagata": lambda: _named(velocity_step_test("nagata", t_end=40.0),
                                           "velocity-step/nagata"),
    "slide-hold-slide/aging": lambda: _named(slide_hold_slide_test(
        "aging", holds=(1.0, 10.0, 100.0), first_slide=10.0, slide=100.0),
        "slide-hold-slide/aging"),
    "W2/aging/quasi-dynamic": lambda: _named(dataclasses.replace(
        window("W2", "aging", t_end=10.0), mass=0.0,
        radiation_damping=fault_radiation_damping()), "W2/aging/quasi-dynamic"),
    "W2/aging/damped": lambda: _named(dataclasses.replace(
        window("W2", "aging", t_end=10.0), radiation_damping=fault_radiation_damping()),
        "W2/aging/damped"),
}
LAB_PROBLEMS = ("velocity-step/aging", "velocity-step/nagata", "slide-hold-slide/aging")


def family_problems(names=None) -> list:
    return [FAMILY[n]() for n in (FAMILY if names is None else names)]


def _is_lab(problem) -> bool:
    return problem.name in LAB_PROBLEMS


# --- laboratory references and errors ---------------------------------------------------------
@dataclasses.dataclass
class LabReference:
    """The reference of a laboratory test: μ on the common grid, the measured peaks (each
    step's excursion and each hold's healing, in that order), the pair's agreement."""

    grid_t: np.ndarray
    grid_mu: np.ndarray
    peaks: np.ndarray
    agreement: dict


def _peaks(solution) -> np.ndarray:
    steps = step_response(solution)
    heal = healing(solution)
    return np.concatenate([(steps.mu_extreme - steps.mu_before).to_numpy(),
                           heal.delta_mu_peak.to_numpy()])


def lab_reference(problem) -> LabReference:
    """Two independent solvers (:data:`REFERENCE_SOLVERS`) on the grid; their peaks must agree to
    :data:`LAB_AGREEMENT` (relative), else :class:`ReferenceDisagreement`."""
    pair = next(p for p in REFERENCE_SOLVERS if all(n in REGISTRY for n, _ in p))
    grid = np.linspace(0.0, problem.t_end, GRID_POINTS)
    runs = []
    for name, tol in pair:
        sol = solve(problem, REGISTRY[name](rtol=tol, atol=tol),
                    save_every=problem.t_end / (GRID_POINTS - 1))
        if not sol.success:
            raise ReferenceDisagreement(f"reference solver {name} failed on {problem.name}: "
                                        f"{sol.retcode.value}: {sol.message}")
        runs.append(sol)
    peaks = [_peaks(s) for s in runs]
    if not len(peaks[1]):
        raise ReferenceDisagreement(f"{problem.name}: no step and no hold to measure")
    rel = float(np.max(np.abs(peaks[0] - peaks[1])) / np.max(np.abs(peaks[1])))
    mus = [np.interp(grid, s.t, s.mu) for s in runs]
    if not np.ptp(mus[1]) > 0:
        raise ReferenceDisagreement(f"{problem.name}: μ never changes")
    traj = float(np.max(np.abs(mus[0] - mus[1])) / np.ptp(mus[1]))
    agreement = {"peaks": rel, "trajectory": traj, "max": max(rel, traj)}
    if not agreement["max"] <= LAB_AGREEMENT:
        raise ReferenceDisagreement(f"{problem.name}: reference solvers disagree by "
                                    f"{agreement['max']:.3g} (> {LAB_AGREEMENT:g}): {agreement}")
    return LabReference(grid_t=grid, grid_mu=mus[0], peaks=peaks[0], agreement=agreement)


def lab_errors(solution, ref: LabReference) -> dict:
    """``err_peak`` and ``err_trajectory`` (module docstring); the limit-cycle errors NaN."""
    out = dict.fromkeys(ERROR_COLUMNS + ("err_peak",), math.nan)
    if not solution.success:
        return out
    try:
        peaks = _peaks(solution)
    except PeakNotReached:          # its trajectory misses a peak the reference has: NaN
        peaks = np.empty(0)
    if len(peaks) == len(ref.peaks):
        out["err_peak"] = float(np.max(np.abs(peaks - ref.peaks)) / np.max(np.abs(ref.peaks)))
    mu = np.interp(ref.grid_t, solution.t, solution.mu)
    out["err_trajectory"] = float(np.max(np.abs(mu - ref.grid_mu)) / np.ptp(ref.grid_mu))
    return out


# --- the study ----------------------------------------------------------------------------------
def family_study(names=None, problems=None, ladder: Ladder = FAMILY_LADDER,
                 progress: bool = True) -> pd.DataFrame:
    """Every integrator (numba tier) over the ladder on the family's problems: the rows of
    :func:`benchmarks.devtools.work_precision.work_precision`, plus ``err_peak`` and ``kind`` (``lab`` or
    ``stick-slip``)."""
    problems = family_problems() if problems is None else problems
    lab = [p for p in problems if _is_lab(p)]
    slip = [p for p in problems if not _is_lab(p)]
    parts = []
    if lab:
        parts.append(work_precision(lab, ladder, names, ("numba",), progress,
                                    reference_of=lab_reference, error_of=lab_errors,
                                    gridded_timing=True).assign(kind="lab"))
    if slip:
        parts.append(work_precision(slip, ladder, names, ("numba",), progress,
                                    reference_of=reference).assign(kind="stick-slip"))
    return pd.concat(parts, ignore_index=True)


def summary(df: pd.DataFrame, levels=LEVELS) -> pd.DataFrame:
    """Per problem and error level, the fastest integrator that reaches the level reliably
    (:func:`benchmarks.devtools.work_precision.best_at_levels`) on the measure that matters there:
    ``err_peak`` for a laboratory test, ``err_recurrence`` for stick–slip."""
    parts = []
    for (problem, kind), g in df.groupby(["problem", "kind"], sort=False):
        error = "err_peak" if kind == "lab" else "err_recurrence"
        parts.append(best_at_levels(g, levels, error))
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def runaway(names=("Rodas5P", "sundials-CVODE-BDF", "sundials-IDA", "scipy-Radau"),
            tol: float = 1e-10) -> pd.DataFrame:
    """The quasi-static slider below kcr (W2, aging law, no mass, no damping): each stiff solver
    stops with a failure where the slip rate runs away (v → ∞ in finite time, the physics of the
    limit: Dieterich 1992). They agree on when v passes 10 vLs (an event's start), read off a
    1 µs grid of the part each run reached."""
    p = _named(dataclasses.replace(window("W2", "aging", t_end=0.01), mass=0.0),
               "W2/aging/quasi-static")
    threshold = 10.0 * p.loading.v_slow
    rows = []
    for name in names:
        sol = solve(p, REGISTRY[name](rtol=tol, atol=tol), save_every=1e-6)
        above = np.flatnonzero(sol.v >= threshold)
        t_run = math.nan
        if len(above) and above[0] > 0:
            i = above[0]
            t_run = float(np.interp(np.log(threshold), np.log(sol.v[i - 1:i + 1]),
                                    sol.t[i - 1:i + 1]))
        rows.append({"problem": p.name, "integrator": name, "tol": tol,
                     "retcode": sol.retcode.value, "t_stop_s": sol.t_reached,
                     "t_v_above_10_vls_s": t_run, "nfev": sol.stats.nfev})
    return pd.DataFrame(rows)


def write_family(out: Path, progress: bool = True, names=None) -> pd.DataFrame:
    """The study into ``out``: family_wp.csv (every row), family_wp.md (the summary and the
    quasi-static runaway), family_wp.png (error against time per problem)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    df = family_study(names=names, progress=progress)
    write_table(df, out / "family_wp.csv")
    best = summary(df)[["problem", "error", "level", "fastest", "fastest_setting",
                        "fastest_wall_s", "runner_up", "runner_up_ratio"]]
    run = runaway()
    lines = ["# The problem family: which integrator for which problem", "",
             "Generated by `rsfbench study family` (benchmarks/studies/family.py). "
             "Every integrator, compiled right-hand side, rtol = atol from 1e-3 to 1e-10 (ETD: "
             "4 to 1/16 of the paper's step); the fastest setting that reaches each error level "
             "at every tighter setting too. Laboratory tests: `err_peak` (the step's excursion, "
             "each hold's healing); stick-slip: `err_recurrence`. Wall time: minimum over up to "
             "3 runs, trajectory saved on 2001 points for the laboratory tests, events only for "
             "stick-slip.", "",
             markdown_table(best, ".3g"), "",
             "## Refused", "",
             _refused(df), "",
             "## The quasi-static slider has no stick-slip cycle", "",
             _runaway_sentence(run), "",
             markdown_table(run, ".6g"), "",
             f"Provenance: {provenance()}", ""]
    atomic_write(out / "family_wp.md", "\n".join(lines))
    atomic_write(out / "family_advice.md", advice(df) + "\n")
    _plot(df, out / "family_wp.png")
    return df


#: what each problem of the study is, for the advice
_DESCRIPTIONS = {
    "velocity-step/aging": "a velocity step (aging law, no mass)",
    "velocity-step/nagata": "a velocity step (Nagata law, no mass)",
    "slide-hold-slide/aging": "a slide-hold-slide test (aging law, no mass)",
    "W2/aging/quasi-dynamic": "stick-slip without mass, with radiation damping (W2, aging law)",
    "W2/aging/damped": "stick-slip with mass and radiation damping (W2, aging law)",
}


def advice(df: pd.DataFrame, levels=(1e-4, 1e-6)) -> str:
    """One bullet per problem: the fastest integrator and setting that reliably reach each of
    ``levels`` in the measure that matters there, and how the paper's ETD2 did."""
    best = summary(df, levels)
    lines = []
    for problem, g in best.groupby("problem", sort=False):
        error = g.error.iloc[0]
        parts = []
        for row in g.itertuples():
            level = f"{row.level:.0e}".replace("e-0", "e-")
            if isinstance(getattr(row, "fastest", None), str):
                parts.append(f"to {level}: `{row.fastest}` at {row.fastest_setting:g} "
                             f"({1e3 * row.fastest_wall_s:.3g} ms)")
            else:
                parts.append(f"to {level}: nothing in the study")
        etd = df[(df.problem == problem) & (df.integrator == "ETD2")]
        if (etd.retcode == "Refused").all():
            etd_note = "ETD2: refused (no mass)"
        else:
            paper = etd[np.isclose(etd.setting, REGISTRY["ETD2"]().dtau_cnst)]
            etd_note = (f"ETD2 at the paper's step: {error} {paper[error].iloc[0]:.2g} in "
                        f"{1e3 * paper.wall_s.iloc[0]:.3g} ms"
                        if len(paper) and paper.retcode.iloc[0] == "Success"
                        else "ETD2 at the paper's step: no result")
        lines.append(f"* **{_DESCRIPTIONS.get(problem, problem)}** ({error}): "
                     + "; ".join(parts) + f"; {etd_note}.")
    return "\n".join(lines)


def _runaway_sentence(run: pd.DataFrame) -> str:
    """What the runaway table shows, checked: every solver stopped with a failure, and when
    they passed 10 vLs (the spread, relative)."""
    head = "W2 (aging law) without mass and without damping, below kcr: "
    stopped = (run.retcode != "Success").all()
    t = run.t_v_above_10_vls_s
    if not stopped or not np.isfinite(t).all():
        return head + "not every solver stopped after passing 10 vLs (the table says which)."
    spread = float((t.max() - t.min()) / t.mean())
    return (head + f"every stiff solver stopped with a failure ({', '.join(sorted(set(run.retcode)))}) "
            f"after the slip rate passed 10 vLs at {t.mean():.6g} s (spread {spread:.1g} of that "
            "time between solvers): the slip rate runs away in finite time.")


def _refused(df: pd.DataFrame) -> str:
    """One line per reason: the integrators and problems it covers, then the reason (the
    message without the integrator's name that starts it)."""
    r = df[df.retcode == "Refused"].drop_duplicates(["problem", "integrator"])
    if not len(r):
        return "None."
    reasons: dict[str, tuple[dict, dict]] = {}
    for row in r.itertuples():
        integrators, problems = reasons.setdefault(
            row.message.removeprefix(row.integrator).strip(), ({}, {}))
        integrators[row.integrator] = problems[row.problem] = None
    return "\n".join(f"- {', '.join(i)} on {', '.join(p)}: {reason}"
                      for reason, (i, p) in reasons.items())


def _plot(df: pd.DataFrame, path: Path) -> None:
    problems = list(dict.fromkeys(df.problem))
    fig = Figure(figsize=(4.2 * len(problems), 4.2))
    axes = fig.subplots(1, len(problems), squeeze=False)
    for ax, problem in zip(axes[0], problems):
        g = df[(df.problem == problem) & (df.retcode == "Success")]
        error = "err_peak" if g.kind.iloc[0] == "lab" else "err_recurrence"
        for name, h in g.groupby("integrator"):
            h = h[np.isfinite(h[error]) & (h[error] > 0)].sort_values("setting")
            if len(h):
                ax.loglog(h.wall_s, h[error], marker="o", ms=3, lw=1, label=name)
        ax.set_title(problem, fontsize=9)
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel(error)
        ax.grid(True, which="both", alpha=0.3)
    axes[0][-1].legend(fontsize=5, ncol=2, loc="best")
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def write_lab_checks(out: Path) -> dict:
    """problem_family.md and problem_family_healing.png: Marone's numbers against ours, each
    law's velocity step (direct effect, steady-state change against (a − b) ln 10) and
    slide-hold-slide healing (holds 1 to 300 s; after 1000 s the slip law runs away on
    reloading), quasi-static, the steps also with 1 kg of mass."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    marone = marone_check()
    steps, heals = [], {}
    for law in ("slip", "aging", "nagata"):
        for mass in (0.0, 1.0):
            p = velocity_step_test(law, v2=3e-6, t_end=150.0, mass=mass)
            sol = solve(p, Rodas5P(rtol=1e-10, atol=1e-10), save_every=1e-3)
            r = step_response(sol).iloc[0]
            steps.append({"law": law, "mass_kg": mass, "retcode": sol.retcode.value,
                          "direct_jump": r.mu_extreme - r.mu_before,
                          "a_ln_ratio": p.law.a * math.log(3.0),
                          "delta_mu_end": r.delta_mu_end,
                          "expected_delta_mu_ss": r.expected_delta_mu_ss})
        p = slide_hold_slide_test(law, holds=(1.0, 3.0, 10.0, 30.0, 100.0, 300.0),
                                  first_slide=10.0, slide=200.0)
        sol = solve(p, Rodas5P(rtol=1e-10, atol=1e-10), save_every=0.01)
        heals[law] = healing(sol)
    steps = pd.DataFrame(steps)
    heal = pd.concat([h.assign(law=law) for law, h in heals.items()], ignore_index=True)
    write_table(heal, out / "problem_family_healing.csv")
    rates = {law: healing_rate(h) for law, h in heals.items()}
    lines = ["# The problem family: checks and laboratory measures", "",
             "Generated by `rsfbench study problem-family` (benchmarks/studies/family.py).", "",
             "## Marone's code (rsfmodel's cjm_model_comparison), against ours at 1e-11", "",
             markdown_table(marone, ".3g"), "",
             "## Velocity steps 1 → 3 µm/s on the laboratory apparatus (Rodas5P 1e-10)", "",
             "The jump is the peak of μ after the step above μ before it: a ln 3 on a stiff "
             "machine, less here (k Lc/A = 2: the state moves during the rise), and for the "
             "Nagata law less again. The change at the end, 140 s after the step, against "
             "(a − b) ln 3.", "",
             markdown_table(steps, ".6g"), "",
             "## Healing: slide-hold-slide, holds 1 to 300 s (Rodas5P 1e-10)", "",
             "Per decade of hold time (least squares of Δμ_peak on log10 hold): " +
             ", ".join(f"{law} {r:.4g}" for law, r in rates.items()) + ".", "",
             markdown_table(heal, ".6g"), "",
             f"Provenance: {provenance()}", ""]
    atomic_write(out / "problem_family.md", "\n".join(lines))
    fig = Figure(figsize=(5, 3.8))
    ax = fig.subplots()
    for law, h in heals.items():
        ax.semilogx(h.hold_s, h.delta_mu_peak, "o-", label=f"{law} ({rates[law]:.3g}/decade)")
    ax.set_xlabel("hold time (s)")
    ax.set_ylabel("Δμ_peak")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    write_figure(fig, out / "problem_family_healing.png", dpi=110)
    return {"marone": marone, "steps": steps, "healing": heal, "rates": rates}


def run_lab_checks(out: Path) -> None:
    checks = write_lab_checks(out)
    print(checks["marone"].to_string(index=False))


def report_lab_checks(out: Path) -> str:
    return ((out / "problem_family.md").read_text().split("\n", 2)[2]
            + "![healing](problem_family_healing.png)\n")


def run_family(out: Path) -> None:
    print(summary(write_family(out, progress=False)).to_string(index=False))


def report_family(out: Path) -> str:
    return ((out / "family_advice.md").read_text() + "Every error level and the runner-up: "
            "`family_wp.md`.\n\n![family work-precision](family_wp.png)\n")


STUDIES = (
    Study("problem-family", "The problem family: Marone's numbers, laboratory tests "
          "(`problem_family.*`)", 230, run_lab_checks, report=report_lab_checks,
          writes=("problem_family.md", "problem_family_healing.csv",
                  "problem_family_healing.png"), minutes=0.1),
    Study("family", "Which integrator for a lab test, without mass, with damping "
          "(`family_wp.*`)", 240, run_family, report=report_family, plan="full", timed=True,
          writes=("family_advice.md", "family_wp.csv", "family_wp.md", "family_wp.png"),
          minutes=17.5),
)
