"""One inversion from start to end, as ``rsfbench invert`` runs it, and its files.

:func:`invert` chains three estimates on one :class:`~benchmarks.inversion.Misfit` (the means'
J1, plus the slip-weakening curves' χ² when the observations have curves): the posterior — on a
grid refined where its mass is (:mod:`benchmarks.inversion.adaptive`, the default) or sampled
with emcee —, the least-squares fit with its covariance (started from the grid's best cell, or
multi-start), and the profiles of b and of log10 Lc over the prior box (the fit one of their
points, so that it lies in its own intervals; an interval that is not resolved, or a profile
that is jagged, comes with a warning in ``inversion.json`` and on the standard error).
:func:`write_inversion` writes:

* ``inversion.json``: the problem, the observations, the likelihood and what it assumed, the
  method and seed, the algorithm, the box and prior, the fit (with covariance), the profile
  intervals, the posterior's mean, standard deviation, 95 % intervals and diagnostics, the number
  of forward solves and the wall time of each stage, and the provenance (tool version and
  commit, machine, packages, command line);
* ``posterior_cells.csv`` (grid): every cell, its centre, widths, misfit and mass;
* ``fit_starts.csv``, ``profile_b.csv``, ``profile_log10_lc.csv`` (each profile point, and
  whether it is the grid's, the fit's or one added where the interval was not resolved);
* ``posterior.csv``: ``MAX_SAMPLES_SAVED`` draws from the grid's cells (seeded), or emcee's
  samples after burn-in thinned to at most that many rows (every k-th of the flattened chain;
  the summaries use all of them);
* ``corner.png`` (the ``corner`` package), ``profiles.png`` and, when the fit found a limit
  cycle, ``fit.png``: the model at the fit over the observations, per event and with the curves
  (:mod:`benchmarks.inversion.fit_figure`; one more forward solve, its values in the summary's
  ``fit.model``).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from benchmarks.inversion.adaptive import GridPosterior, grid_posterior
from benchmarks.inversion.fit_figure import plot_fit
from benchmarks.inversion.least_squares import FitResult, fit
from benchmarks.inversion.misfit import Misfit
from benchmarks.inversion.posterior import Posterior, check_sampler
from benchmarks.inversion.profile import CHI2_95_1DOF, NOISE_J1, lowest_point, profile
from benchmarks.inversion.zoom import posterior_missed, posterior_route
from benchmarks.records.files import (
    claim_outputs,
    remove_own,
    write_figure,
    write_output,
    write_table,
)
from benchmarks.records.optional import require
from benchmarks.records.provenance import provenance as machine, version_line
from benchmarks.records.report import jsonable, literal
from problems import variant

__all__ = ["invert", "Inversion", "write_inversion", "check_box", "MAX_SAMPLES_SAVED",
           "METHODS", "posterior_missed"]

#: rows of posterior.csv at most
MAX_SAMPLES_SAVED = 4000


@dataclass
class Inversion:
    """The three estimates of one inversion, the box they searched, and their wall times;
    ``no_posterior``: why there is no posterior, when there is none."""

    misfit: Misfit = field(repr=False)
    b_range: tuple
    lc_range: tuple
    fit: FitResult
    profiles: dict
    posterior: Posterior | GridPosterior | None
    wall_s: dict
    no_posterior: str = ""
    method: str = "grid"
    seed: int = 0
    #: why no posterior passed its checks (:mod:`benchmarks.inversion.zoom`), or ""
    posterior_missed: str = ""
    #: the route that made the posterior ("zoomed grid", "box grid", "sampler"), its checks,
    #: and every attempt's route and checks
    route: str = ""
    checks: dict = field(default_factory=dict)
    attempts: list = field(default_factory=list)


def check_box(problem, b_range, lc_range) -> None:
    """Refuse a prior box that is not 0 ≤ b_lo < b_hi, 0 < Lc_lo < Lc_hi (finite), or whose
    corners are problems the problem's own checks refuse (b ≥ 1, a t_end too long in units of
    Lc/v0, …): ``ValueError`` naming the corner, before any solve."""
    try:
        (b_lo, b_hi), (lc_lo, lc_hi) = (tuple(map(float, b_range)), tuple(map(float, lc_range)))
    except (TypeError, ValueError):
        raise ValueError(f"the box must be two pairs (b_lo, b_hi), (Lc_lo, Lc_hi) in m, got "
                         f"b_range = {b_range!r}, lc_range = {lc_range!r}") from None
    if not (np.isfinite([b_lo, b_hi, lc_lo, lc_hi]).all() and 0 <= b_lo < b_hi
            and 0 < lc_lo < lc_hi):
        raise ValueError(f"the box must have 0 ≤ b_lo < b_hi and 0 < lc_lo < lc_hi (finite, Lc "
                         f"in m), got b_range = {b_range!r}, lc_range = {lc_range!r}")
    for b in (b_lo, b_hi):
        for lc in (lc_lo, lc_hi):
            try:
                variant(problem, b=b, lc=lc)
            except ValueError as exc:
                raise ValueError(f"the box's corner (b = {b:g}, Lc = {lc:g} m) is refused: "
                                 f"{exc}") from None


#: how the warning of a fit outside its profile's interval (a local minimum) begins
FIT_OUTSIDE = "the least-squares fit"
#: the posterior's methods: the refined grid (the default) and emcee's sampler
METHODS = ("grid", "emcee")


def invert(misfit: Misfit, b_range, lc_range, walkers: int = 32, steps: int = 2000,
           profile_points: int = 21, seed: int = 0, progress: bool = False,
           say=None, method: str = "grid", grid: int = 33) -> Inversion:
    """The posterior, the least-squares fit and the profiles within ``b_range`` × ``lc_range``
    (Lc in m). First a ``grid`` × ``grid`` grid of the box (``method="grid"``; the fit starts
    from its best cell) or the fit's own scan (``"emcee"``), then the fit and the profiles
    (``profile_points`` values of each parameter across the box, the fit one of them), then the
    posterior by :func:`benchmarks.inversion.zoom.posterior_route`: ``"grid"``, the grid zoomed
    onto the fit or the box's grid refined, else emcee (``walkers`` × ``steps``) from the fit;
    ``"emcee"``, emcee alone. A posterior is reported only if it passes the checks (its 95 %
    region holds the fit, its sd agrees with the Gauss–Newton or profile sd within a factor
    2); else ``no_posterior`` and ``posterior_missed`` say why. A fit that the profiles beat by
    more than the 95 % level (a local minimum) is fitted again from their best point; the
    profiles are made again only if that fit beats their minimum by more than NOISE_J1.
    ``steps`` = 0: no posterior. A box without a limit cycle has none either. ``say``: a
    callable given a line of text as each stage starts."""
    say = say or (lambda text: None)
    _check_options(misfit, b_range, lc_range, method, profile_points, steps, walkers)
    wall = {}
    first, start = None, None
    if method == "grid" and steps:
        t = time.perf_counter()
        say(f"first grid ({grid} × {grid} over the box)")
        first = grid_posterior(misfit, b_range, lc_range, n=grid, progress=progress, say=say,
                               refine=False)
        wall["first_grid"] = time.perf_counter() - t
        start = first.best[:2] if np.isfinite(first.best[2]) else None
    t = time.perf_counter()
    say("least-squares fit" + (" from the grid's best cell" if start else " (multi-start)"))
    best = fit(misfit, b_range, lc_range, start=start)
    wall["fit"] = time.perf_counter() - t
    profiles = _profiles(misfit, b_range, lc_range, best, profile_points, wall, say)
    better = _better_start(best, profiles)
    if better is not None:               # the fit was a local minimum: again from the profiles'
        t = time.perf_counter()
        say(f"least-squares fit again, from the profiles' best point (misfit "
            f"{better[2]:.4g} < the fit's {best.misfit:.4g}: the fit was a local minimum)")
        again = fit(misfit, b_range, lc_range, start=better[:2])
        wall["fit"] += time.perf_counter() - t
        if again.misfit < best.misfit:
            best = again
            profiles = _after_refit(profiles, best, better[2], (misfit, b_range, lc_range,
                                                                profile_points, wall, say))
    inv = Inversion(misfit, tuple(b_range), tuple(lc_range), best, profiles, None, wall,
                    "not asked for (steps = 0)", method=method, seed=seed)
    if steps:
        _posterior(inv, first, grid, {"walkers": walkers, "steps": steps, "seed": seed},
                   progress, say)
    return inv


def _check_options(misfit, b_range, lc_range, method, profile_points, steps, walkers) -> None:
    """Refuse a bad method, number of profile points, steps, box or chain, before any work."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if (isinstance(profile_points, bool) or not isinstance(profile_points, int)
            or not 3 <= profile_points <= 1001):
        raise ValueError(f"profile_points must be an integer from 3 to 1001, got "
                         f"{profile_points!r}")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise ValueError(f"steps must be 0 (no posterior) or an integer ≥ 2, got {steps!r}")
    check_box(misfit.problem, b_range, lc_range)
    if steps:                            # a bad chain is refused before the fit, not after it
        check_sampler(b_range, lc_range, walkers, steps)


def _profiles(misfit, b_range, lc_range, best: FitResult, points: int, wall: dict,
              say) -> dict:
    """The profiles of b and of log10 Lc across the box, the fit a point of each."""
    profiles = {}
    for name, values, other in (
            ("b", np.linspace(*b_range, points), lc_range),
            ("log10_lc", np.linspace(*np.log10(lc_range), points), b_range)):
        t = time.perf_counter()
        say(f"profile of {name}")
        profiles[name] = profile(misfit, name, values, other,
                                 best=(best.b, best.lc, best.misfit)
                                 if np.isfinite(best.misfit) else None)
        wall[f"profile_{name}"] = time.perf_counter() - t
        _check_fit_inside(profiles[name], best)
    return profiles


def _posterior(inv: Inversion, first, grid: int, sampler: dict, progress, say) -> None:
    """The posterior of ``inv`` by its route (:func:`benchmarks.inversion.zoom.posterior_route`),
    in place: a posterior that passed its checks, or why there is none."""
    best = inv.fit
    if first is not None and not first.ok:
        inv.no_posterior = "no cell of the grid has a limit cycle"
        return
    if not np.isfinite(best.misfit):
        inv.no_posterior = (f"not sampled: {best.message} (no point of the box is known to "
                            "have a cycle)")
        return
    t = time.perf_counter()
    routed = posterior_route(inv.misfit, inv.b_range, inv.lc_range, best, inv.profiles, first,
                             n=grid, sampler=sampler, grid=inv.method == "grid",
                             progress=progress, say=say)
    inv.wall_s["posterior"] = time.perf_counter() - t + inv.wall_s.get("first_grid", 0.0)
    inv.posterior, inv.route, inv.checks = routed.posterior, routed.route, routed.checks
    inv.attempts = routed.attempts
    if routed.posterior is None:
        inv.no_posterior = inv.posterior_missed = (
            "no posterior passed its checks, so none is reported (the least-squares fit and "
            f"the profile intervals stand): {routed.reason}")
    else:
        inv.no_posterior = ""


def _after_refit(profiles: dict, best: FitResult, lowest: float, remake) -> dict:
    """The profiles about the fit made again from their best point: kept, the old fit's
    warnings replaced by the new one's, when the new fit is within NOISE_J1 of the profiles'
    minimum ``lowest`` (the level they were read at stands); else made again (``remake``: the
    arguments of :func:`_profiles` but the fit)."""
    if lowest - best.misfit > NOISE_J1:
        misfit, b_range, lc_range, points, wall, say = remake
        return _profiles(misfit, b_range, lc_range, best, points, wall, say)
    for p in profiles.values():
        p.warnings = [w for w in p.warnings if not w.startswith(FIT_OUTSIDE)]
        _check_fit_inside(p, best)
    return profiles


def _better_start(best: FitResult, profiles: dict) -> tuple | None:
    """(b, Lc in m, misfit) of the profiles' best point when it beats the fit by more than the
    95 % level (the fit is a local minimum, outside its own profiles' intervals), else None."""
    found = lowest_point(profiles)
    if found is None or not np.isfinite(best.misfit):
        return None
    lowest, at, _ = found
    if best.misfit - lowest <= CHI2_95_1DOF:
        return None
    return float(at["b"]), float(10.0 ** at["log10_lc"]), lowest


def _check_fit_inside(p, best: FitResult) -> None:
    """The fit is a point of each profile, so it lies in its interval unless the profile found
    a lower misfit elsewhere by more than the level: then the fit is a local minimum, and the
    profile's warnings say so (nothing is read as if the fit were the global one)."""
    if not np.isfinite(best.misfit) or not np.isfinite(p.low):
        return
    x = best.b if p.parameter == "b" else float(np.log10(best.lc))
    if not p.low <= x <= p.high:
        label = "b" if p.parameter == "b" else "log10 Lc"
        p.warnings.append(
            f"{FIT_OUTSIDE} ({label} = {x:.6g}, misfit = {best.misfit:.4g}) is outside "
            f"the profile's 95 % interval [{p.low:.6g}, {p.high:.6g}]: the profile found "
            f"misfit = {p.table.misfit.min():.4g} elsewhere, so the fit is a local minimum")


def _summary(inv: Inversion) -> dict:
    m, f = inv.misfit, inv.fit
    o = m.obs
    out = {
        "problem": m.problem.name, "law": m.problem.law.name,
        "observations": {"recurrence_s": o.recurrence_s,
                         "sigma_recurrence_s": o.sigma_recurrence_s,
                         "friction_drop": o.friction_drop,
                         "sigma_friction_drop": o.sigma_friction_drop,
                         "sigma_assumed": o.assumed_sigma,
                         "model_error": o.model_error,
                         "sigma_in_j1": list(o.sigmas),
                         "curve_events": (None if o.curves is None
                                          else int(o.curves.event_id.nunique()))},
        "likelihood": {
            "means": "J1 (Eq. 10): ΔT̄ and Δμ̄ Gaussian about the limit cycle's with the "
                     "stated σ" + (" (σ assumed: 10 % of the mean)" if o.assumed_sigma else ""),
            "curves": None if o.curve_likelihood is None else o.curve_likelihood.describe(),
            "misfit": "−2 log L = J1" + ("" if o.curve_likelihood is None
                                         else " + χ²_curves")},
        "method": inv.method, "seed": inv.seed,
        "integrator": m.algorithm.name, "options": m.algorithm.options(),
        "b_range": list(inv.b_range), "lc_range_m": list(inv.lc_range),
        "fit": {"b": f.b, "lc_m": f.lc, "log10_lc": float(np.log10(f.lc)) if f.lc > 0 else None,
                "misfit": f.misfit, "sigma_b": f.sigma_b, "sigma_log10_lc": f.sigma_log10_lc,
                "jacobian": f.jacobian,
                "covariance_b_log10_lc": f.covariance.tolist(), "success": f.success,
                "message": f.message, "n_solves": f.n_solves},
        "profiles": {k: {"low": p.low, "high": p.high, "open_low": p.open_low,
                         "open_high": p.open_high, "n_solves": p.n_solves,
                         "n_points": len(p.table), "resolved": p.resolved,
                         "monotone": p.monotone, "warnings": list(p.warnings),
                         "level": f"Δ misfit ≤ {CHI2_95_1DOF:.3f}"} for k, p in inv.profiles.items()},
        "wall_s": inv.wall_s,
        # every forward solve of the inversion; a failed one (over its budget too) is no cycle
        "solves": m.failures}
    if inv.posterior is None:
        out["posterior"] = None
        out["no_posterior"] = inv.no_posterior
        out["posterior_missed"] = bool(inv.posterior_missed)
    elif isinstance(inv.posterior, GridPosterior):
        p = inv.posterior
        out["posterior"] = {
            "method": "grid", "prior": p.prior, "mean": p.mean, "std": p.std,
            "interval_95": {k: list(v) for k, v in p.interval.items()},
            "edge_mass": p.edge_mass, "levels": p.levels, "settled": p.settled,
            "n_cells": len(p.cells), "n_solves": p.n_solves, "n_failed": p.n_failed,
            "wall_s": p.wall_s, "refinement": p.history}
    else:
        p = inv.posterior
        q = p.samples.quantile([0.025, 0.975])
        out["posterior"] = {
            "method": "emcee", "prior": p.prior, "mean": p.mean, "std": p.std,
            "interval_95": {k: [float(q[k].iloc[0]), float(q[k].iloc[1])] for k in p.mean},
            "acceptance": p.acceptance, "tau": p.tau, "tau_reliable": p.tau_reliable,
            "effective_samples": p.effective_samples, "n_solves": p.n_solves,
            "n_samples": len(p.samples), "wall_s": p.wall_s}
    return _with_route(inv, out)


def _with_route(inv: Inversion, out: dict) -> dict:
    """The summary with the posterior's route and checks (in ``posterior``), every attempt's
    (``posterior_attempts``) and a zoomed grid's frame."""
    out["posterior_attempts"] = inv.attempts
    if out["posterior"] is not None:
        out["posterior"]["route"] = inv.route
        out["posterior"]["checks"] = inv.checks
        frame = getattr(inv.posterior, "frame", None)
        if frame is not None:
            out["posterior"]["frame"] = {
                "centre_b_log10_lc": list(frame.centre), "scale": [list(r) for r in frame.scale],
                "bend_log10_lc_b": None if frame.bend is None else [list(v) for v in frame.bend],
                "half": next((a["frame_half"] for a in reversed(inv.attempts)
                              if a.get("passed") and "frame_half" in a), None),
                "what": "(b, log10 Lc) = centre + scale · z, z in [−half, half]², then b "
                        "moved by the bend (a natural cubic spline through (log10 Lc knots, b "
                        "offsets): the profile of log10 Lc's valley floor less the map's line): "
                        "the grid zoomed on the fit (scale: Cholesky factor of its Gauss–Newton "
                        "covariance, log10 Lc widened to its profile)"}
    return out


def write_inversion(inv: Inversion, out: Path, provenance: dict | None = None,
                    events=None) -> dict:
    """Write the files of the module docstring to ``out``; return the summary (as written to
    ``inversion.json``) with the paths written. ``provenance``: what else to record of the run
    (the command line, the integrator's choice, the observations' file), beside the machine's
    and the packages' (:func:`benchmarks.records.provenance.provenance`); ``events``: the
    observed events drawn in ``fit.png``
    (:func:`benchmarks.inversion.fit_figure.observed_events`; None: the means only)."""
    out = Path(out)
    claim_outputs(inversion_files(out, inv.profiles))
    summary = _summary(inv)
    summary["provenance"] = {"tool": version_line(), **machine(), **(provenance or {})}
    files = {"summary": out / "inversion.json", "fit_starts": out / "fit_starts.csv",
             "profiles_plot": out / "profiles.png"}
    write_table(inv.fit.starts, files["fit_starts"])
    for name, p in inv.profiles.items():
        files[f"profile_{name}"] = out / f"profile_{name}.csv"
        write_table(p.table, files[f"profile_{name}"])
    _plot_profiles(inv, files["profiles_plot"])
    if np.isfinite(inv.fit.misfit):
        files["fit_plot"] = out / "fit.png"
        summary["fit"]["model"] = plot_fit(inv, files["fit_plot"], events)
    if isinstance(inv.posterior, GridPosterior):
        files["posterior_cells"] = out / "posterior_cells.csv"
        write_table(inv.posterior.cells, files["posterior_cells"])
        files["posterior"] = out / "posterior.csv"
        write_table(inv.posterior.sample(MAX_SAMPLES_SAVED, inv.seed), files["posterior"])
        files["corner"] = out / "corner.png"
        _plot_corner(inv, files["corner"])
    elif inv.posterior is not None:
        s = inv.posterior.samples
        stride = max(1, -(-len(s) // MAX_SAMPLES_SAVED))
        files["posterior"] = out / "posterior.csv"
        write_table(s.iloc[::stride][["b", "log10_lc"]], files["posterior"])
        files["corner"] = out / "corner.png"
        _plot_corner(inv, files["corner"])
    for path in inversion_files(out, inv.profiles):   # an earlier run's, of another inversion
        if path not in files.values():
            remove_own(path)
    summary["files"] = {k: str(v) for k, v in files.items()}
    write_output(files["summary"], json.dumps(jsonable(summary), indent=2) + "\n")
    return summary


def inversion_files(out: Path, parameters=("b", "log10_lc")) -> list[Path]:
    """Every file :func:`write_inversion` may write to ``out`` (checked before the work: a
    user's file of one of these names is refused, :func:`benchmarks.records.files.writing`)."""
    out = Path(out)
    return [out / n for n in ("inversion.json", "fit_starts.csv", "profiles.png", "fit.png",
                              "posterior_cells.csv", "posterior.csv", "corner.png")] + [
        out / f"profile_{name}.csv" for name in parameters]


def _plot_profiles(inv: Inversion, path: Path) -> None:
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator
    fig = Figure(figsize=(9, 3.6))
    axes = fig.subplots(1, 2)
    for ax, (name, p) in zip(axes, inv.profiles.items()):
        J = p.table.misfit.to_numpy()
        x = p.table[name].to_numpy()
        finite = np.isfinite(J)
        if finite.any():
            ax.plot(x[finite], J[finite] - J[finite].min(), "o-", ms=3)
            ax.axhline(CHI2_95_1DOF, color="k", lw=0.8, ls="--", label="95 % (Δ misfit = 3.84)")
            if np.isfinite(p.low):
                ax.axvspan(p.low, p.high, color="C1", alpha=0.2, label="95 % interval"
                           + (" (open)" if p.open_low or p.open_high else ""))
            ax.set_ylim(0, max(3 * CHI2_95_1DOF, 1.0))
        else:
            ax.text(0.5, 0.5, "no limit cycle on this profile", ha="center",
                    transform=ax.transAxes)
        ax.xaxis.set_major_locator(MaxNLocator(5))
        ax.set_xlabel("b" if name == "b" else "log10 Lc (m)")
        ax.set_ylabel("misfit − its minimum (profile)")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle(f"{literal(inv.misfit.problem.name)}: profiles ({inv.misfit.algorithm.name})", fontsize=10)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def _plot_corner(inv: Inversion, path: Path) -> None:
    require("corner", "inversion", "the corner plot of a posterior")
    import corner
    from matplotlib.figure import Figure
    s = (inv.posterior.sample(20_000, inv.seed) if isinstance(inv.posterior, GridPosterior)
         else inv.posterior.samples)
    truths = ([inv.fit.b, np.log10(inv.fit.lc)] if np.isfinite(inv.fit.misfit) and inv.fit.lc > 0
              else None)
    # corner's own size for two parameters (it draws into a figure it is given)
    fig = corner.corner(s[["b", "log10_lc"]].to_numpy(), fig=Figure(figsize=(5.5, 5.5)),
                        labels=["b", "log10 Lc (m)"],
                        quantiles=[0.025, 0.5, 0.975], show_titles=True, title_fmt=".4g",
                        truths=truths, truth_color="C3")
    fig.suptitle(f"{literal(inv.misfit.problem.name)}: posterior ({inv.method}, "
                 f"{inv.misfit.algorithm.name}); red: least-squares fit", fontsize=9, y=1.02)
    write_figure(fig, path, dpi=110, bbox_inches="tight")
