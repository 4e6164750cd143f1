"""The inversion studies ``make reproduce`` runs, and their files in ``results/``.

* ``inversion``, :func:`posterior_target`: one full inversion of W2/slip's published means
  (fit, profiles, posterior) with the study's recommended integrator, timed against its target
  (a posterior of ≥ 64,000 forward solves in ≤ 2 minutes on 2 cores) → ``inversion_W2_slip/``
  and ``inversion.md``;
* ``calibration``, :func:`calibration_study`: coverage of the 95 % regions on seeded synthetic
  data (:mod:`benchmarks.inversion.calibration`) → ``calibration.{csv,md,json,png}``.

The solver-effect study writes its own files (:mod:`benchmarks.studies.solver_effect`): its
step does not depend on these.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from benchmarks.devtools.recommendation import recommended
from benchmarks.inversion.grid import cell_box
from benchmarks.inversion.misfit import Misfit
from benchmarks.inversion.observations import observations
from benchmarks.inversion.published import T_END, prior_box
from benchmarks.records.files import write_figure, write_output, write_table
from benchmarks.records.report import fmt, jsonable, markdown_table
from benchmarks.studies.study import Study
from integrators import Rodas5P
from problems import preset

__all__ = ["STUDIES", "posterior_target", "calibration_study", "TARGET_SOLVES",
           "TARGET_WALL_S", "CALIBRATION_TRUTH"]

#: the posterior target: at least this many forward solves …
TARGET_SOLVES = 64_000
#: … in at most this many seconds on 2 cores
TARGET_WALL_S = 120.0
#: the calibration's truth: W2/slip's published fit (b, Lc in m)
CALIBRATION_TRUTH = (0.0094, 3e-7)


def posterior_target(out, walkers: int = 32, steps: int = 2500, seed: int = 0,
                     progress: bool = False) -> dict:
    """Invert W2/slip's published means (σ 10 %, assumed) in the paper sweep's box with the
    integrator the work-precision study recommends for 1e−3 in ΔT; check the posterior's size
    and time against the target; write ``out/inversion_W2_slip/`` and ``out/inversion.md``."""
    from benchmarks.inversion.invert import inversion_files, invert, write_inversion
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    algorithm, why = recommended(1e-3)
    misfit = Misfit(preset("W2", law="slip", t_end=T_END["W2"]), observations("W2"), algorithm)
    inv = invert(misfit, *prior_box("W2", "slip"), walkers=walkers, steps=steps, seed=seed,
                 progress=progress, method="emcee")
    summary = write_inversion(inv, out / "inversion_W2_slip")
    p = summary["posterior"] or {"n_solves": 0, "wall_s": float("nan")}
    target = {"solves": p["n_solves"], "wall_s": p["wall_s"], "cores": os.cpu_count(),
              "min_solves": TARGET_SOLVES, "max_wall_s": TARGET_WALL_S,
              "met": bool(p["n_solves"] >= TARGET_SOLVES and p["wall_s"] <= TARGET_WALL_S)}
    written = [f.name for f in inversion_files(out / "inversion_W2_slip") if f.is_file()]
    summary.update(target=target, integrator_choice=why, files=written)
    write_output(out / "inversion_W2_slip" / "inversion.json",
        json.dumps(jsonable(summary), indent=2) + "\n")
    write_output(out / "inversion.md", _inversion_markdown(summary))
    return summary


def _inversion_markdown(s: dict) -> str:
    f, p, t = s["fit"], s["posterior"], s["target"]
    if p is None or f["log10_lc"] is None:
        return (f"An inversion of W2/slip's published means **failed**: fit: {f['message']}; "
                f"posterior: {s.get('no_posterior', '')}. Target missed.\n")
    pr = s["profiles"]
    o = s["observations"]
    rows = pd.DataFrame([
        {"estimate": "least squares (± 1 σ, Gauss–Newton)",
         "b": f"{f['b']:.5f} ± {f['sigma_b']:.2g}",
         "log10 Lc (m)": f"{f['log10_lc']:.3f} ± {fmt(f['sigma_log10_lc'], '.2g')}",
         "solves": f["n_solves"], "wall (s)": fmt(s["wall_s"]["fit"], ".3g")},
        {"estimate": "profile, 95 % interval",
         "b": _interval(pr["b"]), "log10 Lc (m)": _interval(pr["log10_lc"]),
         "solves": pr["b"]["n_solves"] + pr["log10_lc"]["n_solves"],
         "wall (s)": fmt(s["wall_s"]["profile_b"] + s["wall_s"]["profile_log10_lc"], ".3g")},
        {"estimate": "posterior mean ± sd [95 % interval]",
         "b": f"{p['mean']['b']:.5f} ± {p['std']['b']:.2g} "
              f"[{p['interval_95']['b'][0]:.5f}, {p['interval_95']['b'][1]:.5f}]",
         "log10 Lc (m)": f"{p['mean']['log10_lc']:.3f} ± {p['std']['log10_lc']:.2g} "
                         f"[{p['interval_95']['log10_lc'][0]:.3f}, "
                         f"{p['interval_95']['log10_lc'][1]:.3f}]",
         "solves": p["n_solves"], "wall (s)": fmt(p["wall_s"], ".3g")}])
    return (
        f"An inversion of W2/slip's published means. Data: ΔT = {o['recurrence_s']:g} ± {o['sigma_recurrence_s']:.3g} s, Δμ = "
        f"{o['friction_drop']:g} ± {o['sigma_friction_drop']:.3g} (σ = 10 % of the mean, "
        f"assumed: the paper publishes none). Integrator: {s['integrator_choice']}. Box: b in "
        f"[{s['b_range'][0]:g}, {s['b_range'][1]:g}], Lc in [{s['lc_range_m'][0]:.3g}, "
        f"{s['lc_range_m'][1]:.3g}] m (the paper sweep's). Prior: {p['prior']}.\n\n"
        + markdown_table(rows) +
        f"\nPosterior: acceptance {p['acceptance']:.2f}, autocorrelation time τ = "
        f"{p['tau']['b']:.1f} (b), {p['tau']['log10_lc']:.1f} (log10 Lc) steps"
        f"{'' if p['tau_reliable'] else ' (chain shorter than 50 τ: τ itself is uncertain)'}, "
        f"{p['effective_samples']:.0f} effective samples of {p['n_samples']}.\n\n"
        f"**Target** (≥ {t['min_solves']:,} forward solves in ≤ {t['max_wall_s']:g} s on 2 "
        f"cores): {t['solves']:,} solves in {t['wall_s']:.1f} s on {t['cores']} cores — "
        f"{'met' if t['met'] else 'missed'}.\n\n"
        f"Files: `inversion_W2_slip/` ({', '.join(s['files'])}). Command: `rsfbench "
        "study inversion`.\n")


def _interval(p: dict) -> str:
    """A profile interval, each end that is the box's end marked so."""
    lo = f"{p['low']:.5g}" + (" (box end)" if p["open_low"] else "")
    hi = f"{p['high']:.5g}" + (" (box end)" if p["open_high"] else "")
    return f"[{lo}, {hi}]" + ("" if p.get("resolved", True) else " (not resolved)")


def calibration_study(out, seeds: int = 1000, n: int = 121, sigma_rel: float = 0.05,
                      check_seeds: int = 2, check_steps: int = 1000,
                      progress: bool = False) -> pd.DataFrame:
    """Coverage of the 95 % regions for W2/slip at its published fit (σ = ``sigma_rel`` of the
    true values, uniform prior on b ± 0.0012 and Lc within a factor 100), with Rodas5P at
    rtol = atol = 1e−6 simulating and inverting; write ``out/calibration.*``."""
    from benchmarks.inversion.calibration import coverage
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    b_t, lc_t = CALIBRATION_TRUTH
    algorithm = Rodas5P(rtol=1e-6, atol=1e-6)
    started = time.perf_counter()
    cal = coverage(preset("W2", law="slip", t_end=T_END["W2"]), CALIBRATION_TRUTH, algorithm,
                   (b_t - 0.0012, b_t + 0.0012), (lc_t / 100, lc_t * 100), sigma_rel=sigma_rel,
                   seeds=seeds, n_b=n, n_lc=n, check_seeds=check_seeds, check_steps=check_steps,
                   progress=progress)
    wall = time.perf_counter() - started
    write_table(cal.seeds, out / "calibration.csv")
    g = cal.grid_map
    (b_lo, b_hi), (lc_lo, lc_hi) = cell_box(g.b, g.log10_lc)
    info = {"truth": {"b": b_t, "lc_m": lc_t}, "sigma_rel": sigma_rel, "seeds": seeds,
            "integrator": algorithm.name, "options": algorithm.options(),
            "grid": f"{len(g.b)} x {len(g.log10_lc)}", "b_range": [b_lo, b_hi],
            "log10_lc_range": [np.log10(lc_lo), np.log10(lc_hi)],
            "nodes_per_posterior_sd_min": cal.nodes_per_sigma, "n_solves": g.n_solves,
            "n_cycle_nodes": int(g.cycle.sum()), "wall_s": wall,
            "coverage": cal.summary.to_dict(orient="records"),
            "checks": cal.checks.to_dict(orient="records")}
    write_output(out / "calibration.json", json.dumps(jsonable(info), indent=2) + "\n")
    write_output(out / "calibration.md", _calibration_markdown(cal, info))
    _plot_calibration(cal, out / "calibration.png")
    return cal.summary


def _calibration_markdown(cal, info) -> str:
    s = cal.summary
    table = pd.DataFrame({
        "region": s.what, "covered": [f"{k} / {n}" for k, n in zip(s.covered, s.n)],
        "coverage": [f"{c:.3f}" for c in s.coverage],
        "95 % CI (Clopper–Pearson)": [f"{a:.3f}–{b:.3f}" for a, b in zip(s.cp_low, s.cp_high)],
        "Binomial(n, 0.95) 95 % range": [f"{a}–{b}" for a, b in
                                          zip(s.binomial_low, s.binomial_high)],
        "consistent with 95 %": ["yes" if c else "**no**" for c in s.consistent],
        "80 % excluded": ["yes" if c else "no" for c in s.excludes_80]})
    c = cal.checks
    if c.empty:
        check_text = ("No seed was checked against the continuous methods (`--check-seeds 0`): "
                      "the grid's answers above stand unchecked by emcee and refined "
                      "profiles.\n")
    else:
        check_text = _checks_markdown(c)
    return (
        "# Coverage of the 95 % regions on seeded synthetic data\n\n"
        f"Truth: W2/slip at b = {info['truth']['b']}, Lc = {info['truth']['lc_m']:g} m; "
        f"observations ΔT and Δμ of its limit cycle plus Gaussian noise of σ = "
        f"{info['sigma_rel']:.0%} of each, seeds 0–{info['seeds'] - 1}. Simulated and inverted "
        f"with {info['integrator']} at rtol = atol = 1e−6 on a {info['grid']} grid of "
        f"(b, log10 Lc) whose cells tile the prior box (uniform in b "
        f"{info['b_range'][0]:.5f}–{info['b_range'][1]:.5f} and log10 Lc "
        f"{info['log10_lc_range'][0]:.2f}–{info['log10_lc_range'][1]:.2f}), {info['n_solves']:,} forward solves for all seeds, {info['wall_s']:.0f} s in all. "
        f"The posterior's standard deviation spans at least "
        f"{info['nodes_per_posterior_sd_min']['b']:.1f} nodes in b and "
        f"{info['nodes_per_posterior_sd_min']['log10_lc']:.1f} in log10 Lc"
        + ("" if min(info["nodes_per_posterior_sd_min"].values()) >= 1 else
           " — **fewer than one**: the grid does not resolve the posterior, and the coverage "
           "below is of the grid, not of the method (a finer --n, or a larger --sigma)")
        + ".\n\n" + markdown_table(table) +
        "\nA region's coverage is consistent with 95 % when the count lies in the central 95 % "
        "range of Binomial(n, 0.95). The J1 region is exact by construction (J1 at the truth is "
        "χ²₂ when the solver is exact); the others are not, and where they cover more than 95 % "
        "they are conservative: with two observations for two parameters, a misfit valley along "
        "which Lc is barely constrained, and a prior box that cuts that valley, neither Wilks' "
        "χ²₁ for the profiles nor a frequentist reading of the marginal credible intervals "
        "holds exactly.\n\n"
        "## The grid against the continuous methods\n\n" + check_text +
        "\nCommand: `rsfbench study calibration`.\n")


def _checks_markdown(c: pd.DataFrame) -> str:
    checks = pd.DataFrame({
        "seed": c.seed, "emcee solves": c.emcee_solves,
        "emcee τ max": [f"{x:.1f}" for x in c.emcee_tau_max],
        "mean b shift (grid sd)": [f"{x:+.3f}" for x in c.mean_b_shift_sd],
        "sd b ratio": [f"{x:.3f}" for x in c.std_b_ratio],
        "mean log10 Lc shift (grid sd)": [f"{x:+.3f}" for x in c.mean_log10_lc_shift_sd],
        "sd log10 Lc ratio": [f"{x:.3f}" for x in c.std_log10_lc_ratio],
        # an interval within fewer than three nodes is narrower than the grid can say
        "profile of b: grid nodes": [f"{a:.5f}–{b:.5f}" + ("" if k >= 3 else " (unresolved)")
                                     for a, b, k in zip(c.profile_b_grid_low,
                                                        c.profile_b_grid_high,
                                                        c.profile_b_grid_nodes)],
        "refined": [f"{a:.5f}–{b:.5f}" + ("" if ok else " (unresolved)") for a, b, ok in
                    zip(c.profile_b_refined_low, c.profile_b_refined_high,
                        c.profile_b_refined_resolved)]})
    return (
        "emcee (32 walkers, a quarter of the steps as burn-in, the prior box the grid's cells) "
        "against the grid posterior; the profile of b read on the grid's nodes against the one "
        "refined between them (:func:`benchmarks.inversion.profile`):\n\n"
        + markdown_table(checks))


def _plot_calibration(cal, path: Path) -> None:
    s = cal.summary
    fig = Figure(figsize=(7.5, 4.2))
    ax = fig.subplots()
    y = np.arange(len(s))
    ax.errorbar(s.coverage, y, xerr=[s.coverage - s.cp_low, s.cp_high - s.coverage], fmt="o",
                capsize=3, label="coverage (Clopper–Pearson 95 %)")
    n = int(s.n.iloc[0])
    ax.axvspan(s.binomial_low.iloc[0] / n, s.binomial_high.iloc[0] / n, color="C2", alpha=0.2,
               label=f"Binomial({n}, 0.95): central 95 %")
    ax.axvline(0.95, color="C2", lw=0.8)
    ax.axvline(0.80, color="C3", lw=0.8, ls="--", label="80 %")
    ax.set_yticks(y, s.what, fontsize=8)
    ax.set_xlabel("fraction of seeds whose region covers the truth")
    ax.set_xlim(0.75, 1.0)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.3, -0.2), ncol=3)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def run_inversion(out: Path) -> None:
    posterior_target(out)
    print((out / "inversion.md").read_text())


def report_inversion(out: Path) -> str:
    return (out / "inversion.md").read_text() + "![posterior](inversion_W2_slip/corner.png)\n"


def run_calibration(out: Path, seeds: int, n: int, sigma: float, check_seeds: int) -> None:
    calibration_study(out, seeds=seeds, n=n, sigma_rel=sigma, check_seeds=check_seeds)
    print((out / "calibration.md").read_text().split("\n## ")[0])


def check_calibration(settings: dict) -> None:
    if settings["check_seeds"] > settings["seeds"]:
        raise ValueError(f"study calibration: setting check_seeds = {settings['check_seeds']} "
                         f"is more than seeds = {settings['seeds']}: the checked seeds are "
                         "among the study's")


def report_calibration(out: Path) -> str:
    text = (out / "calibration.md").read_text()
    return text.split("\n", 1)[1] + "![coverage](calibration.png)\n"


STUDIES = (
    Study("inversion", "An inversion: fit, profiles, posterior (`inversion.md`, "
          "`inversion_W2_slip/`)", 200, run_inversion, report=report_inversion, timed=True,
          writes=("inversion.md", "inversion_W2_slip/*.png", "inversion_W2_slip/*.csv",
                  "inversion_W2_slip/inversion.json"), minutes=0.9),
    Study("calibration", "Coverage of the 95 % regions (`calibration.*`)", 210, run_calibration,
          report=report_calibration,
          settings={"seeds": 1000, "n": 121, "sigma": 0.05, "check_seeds": 2},
          limits={"seeds": (1, 100_000), "n": (5, 1001), "sigma": (1e-6, 0.5),
                  "check_seeds": (0, 100)}, check=check_calibration,
          writes=("calibration.csv", "calibration.json", "calibration.md", "calibration.png"),
          minutes=2),
)
