"""The lead on problems nobody here chose: Im, Elsworth, Marone & Leeman's stick-slip
spring-slider (:func:`problems.external.im_spring_slider`) and NIED's 4-m apparatus as its
catalogue gives it (:func:`problems.external.nied_4m`); every stiff adaptive method of the
project and of its compiled peers over the quick ladder, and the three ways Im et al. solved
it (their implicit method at 1e−4 s and classical RK4 at 1e−6 s, ported to numba by
:mod:`benchmarks.devtools.im_methods`; ode23s, the Shampine–Reichelt Rosenbrock 2(3), is the
project's Rosenbrock23). Achieved errors against the reference of two solvers that agree
(:mod:`benchmarks.devtools.reference`), on the last complete event of each run.

Writes the work-precision files ``wp_external*``, the 2× target on these problems
(``target_external.*``, as :mod:`benchmarks.studies.target` reads it, CyRK also called
plainly), and ``external.md``: their ways beside the project's, and whether the recommendation
for each error level reaches that level here, the quick study's alone and both studies'; the
commands' default integrator is then written from both (:func:`benchmarks.devtools.
work_precision.write_recommendation`).
"""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from benchmarks.devtools.errors import HEADLINE_ERRORS, errors
from benchmarks.devtools.im_methods import IM_STEP, RK4_STEP, im_scheme, rk4, trajectory_events
from benchmarks.devtools.reference import reference
from benchmarks.devtools.work_precision import (
    QUICK,
    advice_study,
    read_study,
    recommend,
    reliable_error,
    work_precision,
    write_recommendation,
)
from benchmarks.devtools.wp_files import ERROR_LEVELS, write_work_precision
from benchmarks.records.files import write_output, write_table
from benchmarks.records.provenance import checkout
from benchmarks.records.report import fmt, markdown_table
from benchmarks.studies.study import Study
from benchmarks.studies.target import target_integrators, target_markdown, write_target
from integrators import REGISTRY
from problems.external import im_spring_slider, nied_4m

__all__ = ["STUDY", "their_ways"]

#: timed runs of each ported method (the minimum counts), after one that compiles and warms up
REPEATS = 5


def their_ways(problem, ref) -> pd.DataFrame:
    """One row per way the authors solved ``problem``: their implicit method and RK4 (the
    ports, timed as the minimum of :data:`REPEATS` runs after a warm-up), with the errors of
    :func:`benchmarks.devtools.errors.errors` and how far the run got."""
    rows = []
    for name, run, step in (("their implicit method (port), their step", im_scheme, IM_STEP),
                            ("classical RK4 (port) at their step, which they ran on their "
                             "velocity-strengthening case only", rk4, RK4_STEP)):
        run(problem, step)
        walls = []
        for _ in range(REPEATS):
            started = time.perf_counter()
            out = run(problem, step)
            walls.append(time.perf_counter() - started)
        t, v, slip, fs = out[:4]
        reached = float(t[-1])
        # a Newton that broke (v < 0) sets v = 0, whose log is -inf: no run after it
        done = reached >= problem.t_end - step / 2 and bool(np.isfinite(v).all())
        events = trajectory_events(t, v, slip, fs, problem.loading)
        sol = SimpleNamespace(success=done, events=events, problem=problem, t=t,
                              mu=fs / problem.normal_force)
        rows.append({"way": name, "step_s": step, "wall_s": min(walls), "reached_s": reached,
                     "events": len(events), **errors(sol, ref)})
    return pd.DataFrame(rows)


def problems() -> list:
    """The study's problems: Im et al.'s stick-slip case and NIED's 4-m apparatus."""
    return [im_spring_slider("stick-slip"), nied_4m()]


def run(out: Path) -> None:
    im, *others = cases = problems()
    names = sorted(set(target_integrators()) | set(REGISTRY.select("own")), key=str.lower)
    df = work_precision(cases, QUICK, names=names, tiers=("numba",))
    paths = write_work_precision(df, out, "external")
    target = write_target(paths["csv"], out, problems=cases)
    ways = their_ways(im, reference(im))
    write_table(ways, out / "external_their_ways.csv")
    advice = _advice(read_study(paths["csv"]), out)
    write_table(advice, out / "external_advice.csv")
    write_output(out / "external.md", _markdown(cases, df, ways, target, advice))
    root = checkout()
    if root is not None and out.resolve() == (root / "results").resolve():
        print(f"wrote {write_recommendation(out)}")   # the default integrator, over both
    print((out / "external.md").read_text())


def _advice(df: pd.DataFrame, out: Path) -> pd.DataFrame:
    """Each error level's setting as the quick study alone recommends it (a check on problems
    it never saw) and as both studies do (the commands' default from now on: :func:`benchmarks.
    devtools.work_precision.advice_study`), and its reliable error on each external problem
    (met: the setting reaches the level there)."""
    df = df.assign(reliable=reliable_error(df, "err_recurrence"))
    rows = []
    for advice, study in (("quick study alone", read_study(out / "wp_quick.csv")),
                          ("both studies", advice_study(out))):
        rec = recommend(study, ERROR_LEVELS)
        for problem, p in df.groupby("problem", sort=False):
            for r in rec.itertuples():
                if not isinstance(getattr(r, "integrator", None), str):
                    continue
                here = p[(p.integrator == r.integrator) & (p.rhs_tier == r.rhs_tier)
                         & (p.setting == r.setting)]
                err = float(here.reliable.iloc[0]) if len(here) else float("nan")
                met = ("not run here" if here.empty else "failed here" if not np.isfinite(err)
                       else "yes" if err <= r.level else "no")
                rows.append({"advice": advice, "problem": problem, "level": r.level,
                             "integrator": r.integrator, "rhs_tier": r.rhs_tier,
                             "setting": r.setting, "error_here": err,
                             "wall_s_here": float(here.wall_s.iloc[0]) if len(here) else np.nan,
                             "met": met})
    return pd.DataFrame(rows)


def _describe(problem) -> str:
    """One paragraph: the problem's constants and its reference's last complete event."""
    ref, law = reference(problem), problem.law
    m = ref.metrics
    return (f"**{problem.name}**: {law.name} law a = {law.a:g}, b = {law.b:.6g}, "
            f"Lc = {law.lc * 1e6:.4g} µm, m = {problem.mass:.6g} kg, "
            f"k = {problem.stiffness:.6g} N/m, Fn = {problem.normal_force:g} N, "
            f"vL = {problem.loading.vl:.4g} m/s, {problem.t_end:g} s. The reference's event "
            f"{ref.event_index + 1} (the last complete): ΔT = {m['recurrence_s']:.6g} s, "
            f"Δμ = {m['friction_drop']:.6g}, slip {m['slip_m'] * 1e6:.5g} µm, peak slip rate "
            f"{m['peak_velocity_m_s']:.5g} m/s; its two solvers agree to "
            f"{ref.agreement['max']:.2g}.\n\n")


def _markdown(cases, df, ways, target, advice) -> str:
    problem = cases[0]
    head = ("The problems (Im et al.'s per m² of fault, in SI; NIED's constants as "
            "`problems/external.py` says where each comes from):\n\n"
            + "".join(_describe(p) for p in cases))
    rb = df[(df.problem == problem.name) & (df.integrator == "Rosenbrock23")
            & (df.setting == 1e-3)]
    ways = pd.concat([ways, pd.DataFrame([{
        "way": "ode23s's method (Rosenbrock23) at the project's rtol = atol = 1e-3 (theirs "
               "ran RelTol 1e-3, AbsTol 1e-6 on u, v, θ, MaxStep 1e-4 s)", "step_s": None,
        "wall_s": float(rb.wall_s.iloc[0]) if len(rb) else float("nan"),
        "reached_s": problem.t_end if len(rb) and rb.retcode.iloc[0] == "Success" else None,
        "events": int(rb.n_events.iloc[0]) if len(rb) else None,
        **{c: float(rb[c].iloc[0]) if len(rb) else float("nan") for c in HEADLINE_ERRORS}}])])
    table = pd.DataFrame({"way": ways.way, "wall (ms)": [fmt(w * 1e3, ".3g") for w in ways.wall_s],
                          "reached (s)": [fmt(x, "g") for x in ways.reached_s],
                          **{c.removeprefix("err_"): [fmt(x, ".2g") for x in ways[c]]
                             for c in HEADLINE_ERRORS}})
    adv = pd.DataFrame({"advice": advice.advice, "problem": advice.problem,
                        "level": advice.level.map("{:g}".format),
                        "recommended": [f"{i} [{t}] {s:g}" for i, t, s in
                                        zip(advice.integrator, advice.rhs_tier, advice.setting)],
                        "its error here": [fmt(x, ".2g") for x in advice.error_here],
                        "wall here (ms)": [fmt(x * 1e3, ".3g") for x in advice.wall_s_here],
                        "reaches the level here": advice.met})
    return (head + f"## Im et al.'s three ways ({problem.name})\n\nTheir implicit method "
            "and RK4 at their own steps "
            "(ports to numba, the minimum of 5 runs after a warm-up); ode23s's method from the "
            "work-precision run below. Errors relative, on the reference's last complete "
            "event.\n\n" + markdown_table(table) + "\n\n## The 2× target here\n\n"
            + target_markdown(target) + "\n\n## The advice, here\n\nThe quick study alone "
            "recommends from the paper's example and W2; the commands' default is now the front "
            "of both studies, these problems included (`benchmarks/devtools/recommendation.py`), "
            "so it reaches each level here by construction, wherever a setting does.\n\n"
            + markdown_table(adv) + "\n")


def report(out: Path) -> str:
    return ((out / "external.md").read_text()
            + "\n![work-precision](wp_external_im_stick-slip.png)\n"
            + "\n![work-precision](wp_external_nied_fb03-087.png)\n")


STUDY = Study("external", "The lead on Im et al.'s slider and NIED's 4-m apparatus: their "
              "solvers, ours and the compiled peers (`external.*`, `wp_external*`, "
              "`target_external.*`)", 105, run,
              report=report, plan="full", timed=True, reads=("wp_quick.csv",),
              writes=("external.md", "external_their_ways.csv", "external_advice.csv",
                      "wp_external.csv", "wp_external_pareto.*", "wp_external_*.png",
                      "target_external.csv", "target_external.md"), minutes=6)
