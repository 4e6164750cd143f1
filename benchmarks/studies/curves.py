"""What the slip-weakening curves add to an inversion of W2, and what it costs (``curves.*``).

Synthetic data at a known truth, W2/slip at its published fit (b = 0.0094, Lc = 0.3 µm),
simulated with Rodas5P at rtol = atol = 1e−10: the means ΔT and Δμ of its limit cycle plus
Gaussian noise of σ = ``sigma_rel`` of each (as :func:`benchmarks.inversion.synthetic`), and
``events`` events' slip-weakening curves sampled as a recorder does, ``points`` samples evenly in
time over each event, plus white noise of ``curve_noise`` in μ (seed s, the same for both).
Inverted with the recommended integrator (checked on the box first), uniform prior on the box
b ∈ [0.0086, 0.0102], Lc ∈ [3e−8, 3e−6] m:

* **coverage**: for seeds 0 … ``seeds`` − 1 the grid posterior (``n`` × ``n`` nodes over the box,
  one map of the metrics and curves for every seed) of the means alone and of the means with
  the curves under each noise model — ``scatter`` (their covariance over the events, as the
  model's error: σ = the events' spread), ``scatter (sem)`` (÷ n: the mean curve's error, which
  is what these synthetic curves' white noise is) and ``sample`` (σ per sample given, the
  generator's): the 95 % marginal intervals of b and log10 Lc, their widths, and how often they
  hold the truth, against Binomial(seeds, 0.95);
* **targets**: one inversion with the curves (scatter model) by ``rsfbench invert``'s default,
  the refined grid (target: its posterior in ≤ 30 s), and an emcee posterior of 64 walkers ×
  1024 steps with the curves (target: ≥ 64,000 solves in ≤ 2 minutes on 2 cores), with the
  solver check's cost beside the inversion's (target: ≤ 10 %);
* **through a recording**: ``recordings`` synthetic recordings of the truth
  (:func:`benchmarks.lab.synthetic.synthetic_recording`, 1 % noise) measured by
  :func:`benchmarks.lab.observe_recording.observe` and inverted from its observations file with and without
  the curves: the recording route end to end.
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from benchmarks.devtools.recommendation import recommended
from benchmarks.inversion import Misfit, synthetic
from benchmarks.inversion.adaptive import grid_posterior
from benchmarks.inversion.grid import box_grid, metric_map
from benchmarks.inversion.observations import read_observations
from benchmarks.inversion.posterior import sample
from benchmarks.physics.curves import sample_curves
from benchmarks.physics.metrics import summarize
from benchmarks.records.files import write_figure, write_output, write_table
from benchmarks.records.report import jsonable, markdown_table
from benchmarks.studies.study import Study
from integrators import Rodas5P, solve
from problems import window

__all__ = ["STUDY", "curves_study", "TRUTH", "BOX", "MODELS"]

#: the truth: W2/slip's published fit (b, Lc in m)
TRUTH = (0.0094, 3e-7)
#: the prior box: b, Lc (m)
BOX = ((0.0086, 0.0102), (3e-8, 3e-6))
#: the likelihoods compared: (label, curve noise model, curve reading, σ per sample given,
#: the map it is read on: the whole box, or a zoom about the truth for the sharper ones)
MODELS = (("means only", None, None, False, "box"), ("scatter", "scatter", "std", False, "box"),
          ("scatter (sem)", "scatter", "sem", False, "zoom"),
          ("sample", "sample", "std", True, "fine zoom"))
#: a synthetic recording's length and the start it skips (the transient to the limit cycle), s
RECORDING_S, RECORDING_SKIP_S = 80.0, 20.0
#: emcee's steps of 64 walkers: 65,536 proposals, of which those outside the box are not solved
EMCEE_STEPS = 1024
#: the zooms' half-widths about the truth: in b, and in log10 Lc
ZOOMS = {"zoom": (1.5e-4, 0.2), "fine zoom": (1.2e-5, 0.015)}


def _data(sol, c, seed: int, sigma_rel: float, events: int, points: int, noise: float):
    """The means and the curves of seed ``seed`` (module docstring)."""
    with warnings.catch_warnings():          # σ a stated fraction of the truth: no unit slip
        warnings.simplefilter("ignore")
        means = synthetic(c.recurrence_s, c.friction_drop, sigma_rel, seed)
    curves = sample_curves(sol, n_events=events, n_points=points, noise=noise, seed=seed,
                           spacing="time")
    return means, curves


def _with(means, curves, model, noise):
    label, kind, reading, given, _ = model
    if kind is None:
        return means
    return dataclasses.replace(means, curves=curves, curve_noise=kind, curve_reading=reading,
                               curve_sigma=noise if given else None)


def _maps(problem, algorithm, boxes, n, means, curves, curve_noise, say):
    """Each box's grid and metric map, and the solver check that chose its integrator."""
    from benchmarks.inversion.solver_check import check_solver
    grids, maps, checks = {}, {}, {}
    for name, box in boxes.items():
        # the integrator checked for the sharpest likelihood read on this map (seed 0's data)
        sharpest = [mo for mo in MODELS if mo[4] == name][-1]
        check = check_solver(problem, algorithm, _with(means, curves, sharpest, curve_noise),
                             *box)
        checks[name] = {"likelihood": sharpest[0], "passed": check.passed,
                        "message": check.message}
        say(f"the map of the {name}: {n} × {n} nodes with curves; {check.message}")
        grids[name] = box_grid(*box, n, n)
        maps[name] = metric_map(problem, check.algorithm, *grids[name], curves=True)
    return grids, maps, checks


def _posterior_rows(sol, truth_cycle, maps, seeds, sigma_rel, events, points,
                    curve_noise) -> pd.DataFrame:
    """One row per seed and likelihood: the posterior's intervals, moments and coverage."""
    rows = []
    for seed in range(seeds):
        means, curves = _data(sol, truth_cycle, seed, sigma_rel, events, points, curve_noise)
        for model in MODELS:
            m = maps[model[4]]
            post = m.posterior(_with(means, curves, model, curve_noise))
            row = {"seed": seed, "model": model[0], "map": model[4], "ok": post.ok}
            for name, true in (("b", TRUTH[0]), ("log10_lc", np.log10(TRUTH[1]))):
                lo, hi = post.interval[name]
                row.update({f"{name}_low": lo, f"{name}_high": hi, f"{name}_width": hi - lo,
                            f"{name}_covered": bool(lo <= true <= hi),
                            f"{name}_mean": post.mean[name], f"{name}_std": post.std[name]})
            row["hpd_covered"] = bool(_hpd_covers(m, post, TRUTH))
            row["correlation"] = _correlation(m, post)
            row["edge_mass"] = post.edge_mass
            rows.append(row)
    return pd.DataFrame(rows)


def _coverage(table: pd.DataFrame, grids: dict) -> list[dict]:
    """Per likelihood: each marginal's and the HPD set's coverage, widths in grid nodes."""
    from benchmarks.inversion.calibration import binomial_check
    coverage = []
    for label, g in table.groupby("model", sort=False):
        grid = grids[g["map"].iloc[0]]
        spacing = {"b": float(grid[0][1] - grid[0][0]),
                   "log10_lc": float(grid[1][1] - grid[1][0])}
        for name in ("b", "log10_lc"):
            k = int(g[f"{name}_covered"].sum())
            coverage.append({"model": label, "map": g["map"].iloc[0], "parameter": name,
                             "median_width": float(g[f"{name}_width"].median()),
                             "median_sd_in_nodes": float(g[f"{name}_std"].median()
                                                         / spacing[name]),
                             "max_edge_mass": float(g.edge_mass.max()),
                             **binomial_check(k, len(g))})
        # the HPD set of a ridge narrower than a node across is the grid's: its width across
        transverse = min(float((g[f"{k}_std"] * np.sqrt(1 - g.correlation ** 2)).median()
                               / spacing[k]) for k in ("b", "log10_lc"))
        coverage.append({"model": label, "map": g["map"].iloc[0], "parameter": "hpd",
                         "max_edge_mass": float(g.edge_mass.max()),
                         "median_sd_in_nodes": transverse,
                         "median_correlation": float(g.correlation.median()),
                         **binomial_check(int(g.hpd_covered.sum()), len(g))})
    return coverage


def curves_study(out, seeds: int = 200, n: int = 61, sigma_rel: float = 0.01,
                 curve_noise: float = 2e-3, events: int = 10, points: int = 50,
                 recordings: int = 3, progress: bool = False) -> dict:
    """Run the study of the module docstring; write ``out/curves.{csv,json,md,png}``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    say = (lambda text: print(f"  {text}", flush=True)) if progress else (lambda text: None)
    started = time.perf_counter()
    problem = window("W2", "slip")
    sol = solve(problem, Rodas5P(rtol=1e-10, atol=1e-10), save_every=5e-6, max_points=10 ** 8)
    truth_cycle = summarize(sol)
    algorithm, why = recommended(1e-3)
    boxes = {"box": BOX, **{k: ((TRUTH[0] - db, TRUTH[0] + db),
                                (TRUTH[1] * 10 ** -dl, TRUTH[1] * 10 ** dl))
                            for k, (db, dl) in ZOOMS.items()}}
    means, curves = _data(sol, truth_cycle, 0, sigma_rel, events, points, curve_noise)
    grids, maps, checks = _maps(problem, algorithm, boxes, n, means, curves, curve_noise, say)
    table = _posterior_rows(sol, truth_cycle, maps, seeds, sigma_rel, events, points,
                            curve_noise)
    write_table(table, out / "curves.csv")
    coverage = _coverage(table, grids)
    say("targets: the refined grid and emcee with the curves")
    means, curves = _data(sol, truth_cycle, 0, sigma_rel, events, points, curve_noise)
    targets = _targets(problem, algorithm, _with(means, curves, MODELS[1], curve_noise))
    say(f"{recordings} recordings through observe")
    through = [_through_a_recording(problem, algorithm, seed, out) for seed in range(recordings)]
    info = {"truth": {"b": TRUTH[0], "lc_m": TRUTH[1]}, "box": BOX, "seeds": seeds,
            "grid": f"{n} x {n}", "sigma_rel": sigma_rel, "curve_noise": curve_noise,
            "events": events, "points": points, "integrator": algorithm.name,
            "options": algorithm.options(), "integrator_choice": why,
            "boxes": boxes,
            "maps": {k: {"n_solves": v.n_solves, "run_wall_s": v.run_wall_s,
                         "integrator": v.algorithm, "check": checks[k],
                         "n_cycle_nodes": int(v.cycle.sum())} for k, v in maps.items()},
            "coverage": coverage, "targets": targets, "recordings": through,
            "wall_s": time.perf_counter() - started}
    write_output(out / "curves.json", json.dumps(jsonable(info), indent=2) + "\n")
    write_output(out / "curves.md", _markdown(info))
    _plot(table, out / "curves.png")
    return info


def _correlation(m, post) -> float:
    """The posterior's correlation of b and log10 Lc on the grid (NaN without a posterior)."""
    if not post.ok:
        return float("nan")
    db = m.b[:, None] - post.mean["b"]
    dl = m.log10_lc[None, :] - post.mean["log10_lc"]
    cov = float((post.mass * db * dl).sum())
    return cov / (post.std["b"] * post.std["log10_lc"])


def _hpd_covers(m, post, truth) -> bool:
    i = int(np.argmin(np.abs(m.b - truth[0])))
    j = int(np.argmin(np.abs(m.log10_lc - np.log10(truth[1]))))
    return bool(post.hpd[i, j])


def _targets(problem, algorithm, obs) -> dict:
    """The refined grid's and emcee's posteriors with the curves, timed; the solver check's
    cost beside the inversion's."""
    from benchmarks.inversion.invert import invert
    from benchmarks.inversion.solver_check import check_solver
    started = time.perf_counter()
    check = check_solver(problem, algorithm, obs, *BOX)
    check_s = time.perf_counter() - started
    misfit = Misfit(problem, obs, check.algorithm)
    started = time.perf_counter()
    inv = invert(misfit, *BOX)                   # the default: the refined grid, fit, profiles
    inversion_s = time.perf_counter() - started
    post = inv.posterior
    if post is None:
        raise RuntimeError(f"the inversion of the targets has no posterior: {inv.no_posterior}")
    chain = sample(misfit, *BOX, start=(post.best[0], post.best[1]), walkers=64,
                   steps=EMCEE_STEPS)
    return {
        "check": {"passed": check.passed, "wall_s": check_s, "n_solves": check.n_solves,
                  "message": check.message},
        "grid": {"wall_s": post.wall_s, "n_solves": post.n_solves, "levels": post.levels,
                 "settled": post.settled, "interval": post.interval, "max_wall_s": 30.0,
                 "met": bool(post.wall_s <= 30.0)},
        "inversion": {"wall_s": inversion_s, "stages_s": inv.wall_s,
                      "fit": {"b": inv.fit.b, "lc_m": inv.fit.lc},
                      "profiles": {k: [p.low, p.high] for k, p in inv.profiles.items()}},
        "emcee": {"wall_s": chain.wall_s, "n_solves": chain.n_solves,
                  "acceptance": chain.acceptance, "tau": chain.tau,
                  "interval": {k: [float(chain.samples[k].quantile(0.025)),
                                   float(chain.samples[k].quantile(0.975))]
                               for k in ("b", "log10_lc")},
                  "min_solves": 64_000, "max_wall_s": 120.0,
                  "met": bool(chain.n_solves >= 64_000 and chain.wall_s <= 120.0)},
        "check_share": {"of_inversion": check_s / inversion_s,
                        "met": bool(check_s <= 0.1 * inversion_s)}}


def _through_a_recording(problem, algorithm, seed: int, out: Path) -> dict:
    """One synthetic recording of the truth measured by observe and inverted with and without
    its curves on the refined grid."""
    from benchmarks.lab.observe_recording import observe
    from benchmarks.lab.synthetic import synthetic_recording
    rec, _ = synthetic_recording(dataclasses.replace(problem, t_end=RECORDING_S),
                                 t_skip=RECORDING_SKIP_S, noise=0.01, seed=seed)
    result = {"seed": seed}
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")          # a synthetic record's σ of ΔT warns tiny
        path = Path(tmp) / "recording.csv"
        write_table(rec, path)
        columns = {c: c for c in rec.columns}
        observe(path, columns, Path(tmp) / "obs", normal_force=problem.normal_force,
                mass=problem.mass, plot=False)
        for label, noise in (("means only", "none"), ("scatter", "scatter")):
            obs = read_observations(Path(tmp) / "obs" / "observations.json", curve_noise=noise)
            post = grid_posterior(Misfit(problem, obs, algorithm), *BOX)
            holds = {k: bool(post.interval[k][0] <= t <= post.interval[k][1])
                     for k, t in (("b", TRUTH[0]), ("log10_lc", np.log10(TRUTH[1])))}
            result[label] = {"interval": post.interval, "settled": post.settled,
                             "holds_truth": holds,
                             "n_events": (None if obs.curves is None
                                          else int(obs.curves.event_id.nunique())),
                             "sigma_recurrence_s": obs.sigma_recurrence_s,
                             "sigma_friction_drop": obs.sigma_friction_drop}
    return result


def _coverage_rows(cov: pd.DataFrame) -> list[dict]:
    rows = []
    for c in cov.itertuples():
        rows.append({"likelihood": c.model, "map": c.map, "parameter": c.parameter,
                     "median 95 % width": ("" if c.parameter == "hpd" else
                                           f"{c.median_width:.3g}"),
                     "sd in grid nodes": (f"{c.median_sd_in_nodes:.2f} across the ridge "
                                          f"(ρ = {c.median_correlation:+.3f})"
                                          if c.parameter == "hpd" else
                                          f"{c.median_sd_in_nodes:.1f}"),
                     "covered": f"{c.covered} / {c.n}", "coverage": f"{c.coverage:.3f}",
                     "Binomial 95 % range": f"{c.binomial_low}–{c.binomial_high}",
                     "consistent": "yes" if c.consistent else "**no**",
                     "edge mass (max)": f"{c.max_edge_mass:.1g}"})
    return rows


def _recording_rows(recordings: list[dict]) -> list[dict]:
    rec_rows = []
    for r in recordings:
        for label in ("means only", "scatter"):
            i = r[label]["interval"]
            rec_rows.append({"recording seed": r["seed"], "likelihood": label,
                             "b 95 %": f"{i['b'][0]:.6g}–{i['b'][1]:.6g}",
                             "log10 Lc 95 %": f"{i['log10_lc'][0]:.5g}–{i['log10_lc'][1]:.5g}",
                             "holds the truth (b, log10 Lc)": ", ".join(
                                 "yes" if v else "**no**"
                                 for v in r[label]["holds_truth"].values()),
                             "curve events": r[label]["n_events"] or "",
                             "σ ΔT (s)": f"{r[label]['sigma_recurrence_s']:.3g}",
                             "settled": "yes" if r[label]["settled"] else "no"})
    return rec_rows


def _markdown(info: dict) -> str:
    cov = pd.DataFrame(info["coverage"])
    rows = _coverage_rows(cov)
    t = info["targets"]
    widths = cov[cov.parameter == "log10_lc"].set_index("model").median_width
    narrowing = widths.get("scatter", np.nan) / widths.get("means only", np.nan)
    rec_rows = _recording_rows(info["recordings"])
    g, e, ch = t["grid"], t["emcee"], t["check"]
    return (
        "# What the slip-weakening curves add\n\n"
        f"Truth: W2/slip at b = {info['truth']['b']}, Lc = {info['truth']['lc_m']:g} m. Data "
        f"per seed: ΔT and Δμ plus {info['sigma_rel']:.0%} noise; {info['events']} events' "
        f"curves, {info['points']} samples each evenly in time, plus white noise of "
        f"{info['curve_noise']:g} in μ. {info['seeds']} seeds, each posterior on one of three "
        f"{info['grid']} maps with curves: the prior box, and for the sharper likelihoods a "
        "zoom about the truth, uniform prior there (its edge mass is the last column): "
        + "; ".join(f"{k}: b {b[0][0]:.6g}–{b[0][1]:.6g}, Lc {b[1][0]:.4g}–{b[1][1]:.4g} m "
                    f"({info['maps'][k]['check']['message']})"
                    for k, b in info["boxes"].items())
        + f". Integrator before its check: {info['integrator_choice']}.\n\n"
        + markdown_table(pd.DataFrame(rows)) +
        f"\nThe curves (scatter model) narrow the median 95 % interval of log10 Lc to "
        f"{narrowing:.2f} of the means' alone. The means' marginal intervals cover more than "
        "95 %, as the calibration study finds: two observations for two parameters along a "
        "valley the box cuts make them conservative. The scatter model reads the events' spread as "
        "the model's error (σ = std, as J1 does); these synthetic events differ only by white "
        "noise, for which the mean curve's error (sem) is the exact one, so the std reading is "
        "conservative here by design, and the sample model (the generator's own σ) is exact. "
        "An interval whose posterior sd spans fewer than about two grid nodes is the grid's, "
        "not the method's; so is the HPD set of a ridge narrower than a node across (its sd "
        "across the ridge, sd·√(1 − ρ²), is in the hpd rows): the set then holds the nodes "
        "nearest the ridge, and the truth's node only by chance.\n\n"
        "## Targets (W2 with its curves, seed 0, scatter model)\n\n"
        f"* The refined grid posterior: {g['wall_s']:.1f} s, {g['n_solves']:,} solves, "
        f"{g['levels']} levels{'' if g['settled'] else ' (not settled)'} — target ≤ 30 s "
        f"**{'met' if g['met'] else 'missed'}**.\n"
        f"* emcee, 64 walkers × {EMCEE_STEPS} steps: {e['n_solves']:,} solves in {e['wall_s']:.1f} s "
        f"(acceptance {e['acceptance']:.2f}) — target ≥ 64,000 in ≤ 120 s "
        f"**{'met' if e['met'] else 'missed'}**.\n"
        f"* The solver check: {ch['wall_s']:.2f} s ({ch['n_solves']} solves; "
        f"{ch['message']}), {t['check_share']['of_inversion']:.0%} of the inversion it guards "
        f"({t['inversion']['wall_s']:.1f} s: the refined grid, the fit and both profiles) — "
        f"target ≤ 10 % **{'met' if t['check_share']['met'] else 'missed'}**.\n\n"
        "## Through a recording\n\n"
        f"Synthetic recordings of the truth ({RECORDING_S:g} s at 10 kHz, the first "
        f"{RECORDING_SKIP_S:g} s skipped, 1 % noise), measured by `rsfbench observe` and "
        "inverted from its observations file on the refined grid, σ the events' spread:\n\n"
        + markdown_table(pd.DataFrame(rec_rows)) +
        "\nThe model's own limit cycle hardly scatters from event to event, so σ of ΔT from a "
        "synthetic record is set by the noise, not by natural scatter (a stochastic forward "
        "model would be needed for that). `observe` computes the friction after its own "
        "low-pass of the acceleration (750 Hz), which smears the near-step of m·a as the "
        "slider stops and the first millisecond of the event, and times each event on a "
        "smoothed slip rate; the model's curve goes through neither, so an interval with the "
        "curves that misses the truth here is that mismatch, not noise (docs/inversion.md).\n\n"
        f"Wall time of the study: {info['wall_s'] / 60:.1f} min. Command: `rsfbench study "
        "curves`.\n")


def _plot(table: pd.DataFrame, path: Path) -> None:
    fig = Figure(figsize=(9, 3.6))
    axes = fig.subplots(1, 2)
    for ax, name, label in ((axes[0], "b", "b"), (axes[1], "log10_lc", "log10 Lc (m)")):
        data = [g[f"{name}_width"].to_numpy() for _, g in table.groupby("model", sort=False)]
        ax.boxplot(data, tick_labels=list(table.model.unique()), showfliers=False)
        ax.set_ylabel(f"95 % interval width of {label}")
        ax.tick_params(axis="x", labelsize=7, rotation=15)
    fig.suptitle("W2/slip synthetic data: interval widths over seeds", fontsize=10)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def run(out: Path, seeds: int, n: int, recordings: int) -> None:
    curves_study(out, seeds=seeds, n=n, recordings=recordings, progress=True)
    print((out / "curves.md").read_text())


def report(out: Path) -> str:
    return (out / "curves.md").read_text().split("\n", 2)[2] + "\n![widths](curves.png)\n"


STUDY = Study("curves", "What the slip-weakening curves add to an inversion, and its targets "
              "(`curves.*`)", 207, run, report=report, timed=True,
              settings={"seeds": 200, "n": 61, "recordings": 3},
              limits={"seeds": (10, 10_000), "n": (11, 301), "recordings": (0, 20)},
              writes=("curves.csv", "curves.json", "curves.md", "curves.png"), minutes=6)
