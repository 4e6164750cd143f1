"""Do the Fisher errors of ``rsfbench design`` hold? Each plan's expected standard errors of (a, b,
ln Dc, ln k′) against the spread of the fits to ``fits`` records of the independent model
(scipy's Radau on the published equations, white noise of the plan's σ, seeds 0, 1, …), fitted
by ``fit_lab`` with the plan's detrend from the law's values
(``benchmarks.lab.design.check_plan``). Target: each ratio within 25 % of 1. The plans: a 1 → 10 µm/s aging step at 50 Hz;
a slip-law 1 → 10 → 1 µm/s with a slope fitted (``detrend one``); a precise, coarsely sampled one
(σ 1e−4 at 5 Hz, a 3 → 30 µm/s step with Dc = 20 µm). And stick–slip plans: the Fisher errors
of (b, log10 Lc) from the means of a settled cycle's events against ``fits``/2 exact-Jacobian
fits of noisy means (:mod:`benchmarks.inversion.design`).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import pandas as pd

from benchmarks.lab.design import Plan, check_plan
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study, markdown_file

__all__ = ["STUDY", "PLANS", "design_study"]

#: the plans checked, by label
PLANS = {
    "aging step, 50 Hz": Plan(velocities=(1e-6, 1e-5), durations=(20.0, 40.0), rate=50.0,
                              noise=6e-4, a=0.006, b=0.009, dc=10e-6, k=3e3),
    "slip law, up and down, slope fitted": Plan(
        velocities=(1e-6, 1e-5, 1e-6), durations=(20.0, 30.0, 60.0), rate=50.0, noise=6e-4,
        a=0.006, b=0.009, dc=10e-6, k=3e3, law="slip", detrend="one"),
    "precise, coarse: σ 1e-4 at 5 Hz": Plan(
        velocities=(3e-6, 3e-5), durations=(20.0, 40.0), rate=5.0, noise=1e-4, a=0.008,
        b=0.01, dc=20e-6, k=2e3),
}
#: the stick–slip plans checked (:mod:`benchmarks.inversion.design`), by label: (window, law,
#: changes to it, seconds recorded, one event's relative σ of ΔT and of Δμ)
STICK_SLIP = {
    "stick-slip W2/slip, k 2.5e8 N/m, 120 s, 5 %/10 %": ("W2", "slip", {"stiffness": 2.5e8},
                                                         120.0, 0.05, 0.10),
    "stick-slip W2/slip, 240 s, 1 %/2 %": ("W2", "slip", {}, 240.0, 0.01, 0.02),
    "stick-slip W2/slip, 60 s, 5 %/10 % (vague)": ("W2", "slip", {}, 60.0, 0.05, 0.10),
}
#: the target: |Fisher se / spread − 1| at most this
TOLERANCE = 0.25


def design_study(fits: int = 100, progress: bool = False) -> pd.DataFrame:
    """One row per plan and coordinate: the Fisher se, the fits' spread, their ratio and bias,
    and the plan's wall time (s)."""
    rows = [_checked(label, lambda plan=plan: check_plan(plan, n=fits), progress)
            for label, plan in PLANS.items()]
    rows += stick_slip_rows(fits // 2, progress)
    return pd.concat(rows, ignore_index=True)


def _checked(label: str, check, progress: bool) -> pd.DataFrame:
    """``check()``'s table (Fisher se against the fits' spread), labelled, timed and judged
    against :data:`TOLERANCE`."""
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # a fit's notes; its values are what is read
        table = check()
    table.insert(0, "plan", label)
    table["wall_s"] = time.perf_counter() - started
    table["within"] = (table.ratio - 1.0).abs() <= TOLERANCE
    if progress:
        print(f"design: {label}: ratios {', '.join(f'{r:.2f}' for r in table.ratio)}")
    return table


def stick_slip_rows(fits: int, progress: bool = False) -> list:
    """The :data:`STICK_SLIP` plans' Fisher errors of (b, log10 Lc) against ``fits`` fits each
    (:func:`benchmarks.inversion.design.check_stick_slip`: exact-Jacobian fits of the cycle's
    means with Gaussian errors; the truth's own model, a different solve per fit)."""
    from benchmarks.inversion.design import StickSlipPlan, check_stick_slip
    from problems.presets import window
    from problems.slider import variant
    rows = []
    for label, (name, law, changes, duration, s_t, s_mu) in STICK_SLIP.items():
        plan = StickSlipPlan(variant(window(name, law=law), **changes), duration, s_t, s_mu)
        rows.append(_checked(label, lambda plan=plan: check_stick_slip(plan, n=fits),
                             progress))
    return rows


def run(out: Path, fits: int = 100) -> None:
    rows = design_study(fits=fits, progress=True)
    write_table(rows, out / "design.csv")
    held = int(rows.within.sum())
    text = ("# Experiment design: Fisher errors against repeated fits\n\n"
            + __doc__.split("\n\n")[0].replace("\n", " ") + "\n\n"
            + markdown_table(rows, floatfmt=".4g")
            + f"\n{held} of {len(rows)} ratios within {TOLERANCE:.0%} of 1. The stick–slip "
            "plans' Fisher errors are those of the means of the settled cycle's events, from "
            "the engine's forward sensitivities (`benchmarks.inversion.design`); a vague plan "
            "(its log10 Lc error past the fits' box, ±1.5 decades) is listed to show where the "
            "linear errors stop holding.\n\n"
            f"Command: `rsfbench study design --set fits={fits}`.\n")
    write_output(out / "design.md", text)
    print(text)


STUDY = Study("design", "Experiment design: the Fisher errors of `rsfbench design` against the "
              "spread of repeated fits (`design.*`)", 209, run,
              report=markdown_file("design.md"), timed=True, settings={"fits": 100},
              limits={"fits": (10, 10_000)}, minutes=5, writes=("design.csv", "design.md"))
