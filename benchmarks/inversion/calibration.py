"""Do the 95 % regions hold 95 %? Coverage on seeded synthetic data.

Observations are simulated at a known ``truth`` = (b, Lc): the limit cycle's ΔT and Δμ there,
plus Gaussian noise of standard deviation σ = ``sigma_rel`` × the true value, with the seeds
0, 1, …, ``seeds`` − 1 (numpy's ``default_rng(seed)``, one draw of two normals each). The same
algorithm simulates and inverts, so the check is of the statistics, not of the solver (the
solver's effect is :mod:`benchmarks.inversion.solver_effect`'s question).

For every seed, on one :class:`~benchmarks.inversion.grid.MetricMap` through the truth (the
forward model does not depend on the seed, so one ensemble serves all of them), the truth is
checked against:

* the J1 region, J1 ≤ 5.99 (χ²₂ at 95 %, the paper's region);
* the 95 % profile intervals of b and of log10 Lc (the profile at the truth within 3.84 of the
  minimum of J1 on the grid);
* the posterior's 95 % highest-density region, and its 95 % equal-tailed marginal intervals
  (uniform prior in (b, log10 Lc) on the grid's box).

A region's coverage over n seeds is read against Binomial(n, 0.95): it is consistent with 95 %
when the count of covering seeds lies in that binomial's central 95 % interval, and the
Clopper–Pearson 95 % interval of the coverage says what else it is consistent with (80 % must be
outside it, or the seeds were too few).

The grid's answers are checked on ``check_seeds`` seeds (0: none, and the report says the grid
stands unchecked) against the continuous methods: emcee's posterior (mean and standard deviation
of each parameter, in units of the grid posterior's) and the profile intervals of
:func:`benchmarks.inversion.profile` refined between nodes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.stats import beta, binom

from benchmarks.inversion.grid import MetricMap, box_grid, cell_box, metric_map
from benchmarks.inversion.misfit import Misfit, synthetic
from benchmarks.inversion.objectives import CHI2_95_2DOF
from benchmarks.inversion.posterior import sample
from benchmarks.inversion.profile import CHI2_95_1DOF, profile
from benchmarks.inversion.profile_ends import hull
from integrators import Algorithm
from problems import SpringSlider

__all__ = ["coverage", "Calibration", "REGIONS", "binomial_check", "MIN_SIGMA_REL"]

#: the smallest noise σ of a study, as a fraction of the true values: a thousand times the
#: misfit's own floor (:data:`benchmarks.inversion.misfit.MIN_SIGMA_REL`), so that no seed's
#: noisy mean puts its σ below that floor after the work has begun
MIN_SIGMA_REL = 1e-6

#: the regions checked, as the columns of the per-seed table that say whether each covers
REGIONS = {"j1_region": "J1 ≤ 5.99 (χ²₂, 95 %)",
           "profile_b": "profile interval of b (Δ J1 ≤ 3.84)",
           "profile_log10_lc": "profile interval of log10 Lc (Δ J1 ≤ 3.84)",
           "posterior_hpd": "posterior 95 % highest-density region",
           "posterior_b": "posterior 95 % marginal interval of b",
           "posterior_log10_lc": "posterior 95 % marginal interval of log10 Lc"}


def binomial_check(k: int, n: int, level: float = 0.95) -> dict:
    """What ``k`` covering seeds out of ``n`` say: the coverage, its Clopper–Pearson 95 %
    interval, the central 95 % interval of Binomial(n, level) for the count, and whether the
    count is inside it (``consistent``) and 80 % outside the Clopper–Pearson interval."""
    lo = beta.ppf(0.025, k, n - k + 1) if k > 0 else 0.0
    hi = beta.ppf(0.975, k + 1, n - k) if k < n else 1.0
    a, b = binom.interval(0.95, n, level)
    return {"covered": int(k), "n": int(n), "coverage": k / n, "cp_low": float(lo),
            "cp_high": float(hi), "binomial_low": int(a), "binomial_high": int(b),
            "consistent": bool(a <= k <= b), "excludes_80": bool(not lo <= 0.80 <= hi)}


@dataclass
class Calibration:
    """Per seed (``seeds``: the observations, whether each region of :data:`REGIONS` covers
    the truth, the grid posterior's mean and std), the coverage of each region
    (``summary``: :func:`binomial_check`'s columns), the grid and its map, and the check of the
    grid against the continuous methods (``checks``)."""

    truth: tuple
    sigma_rel: float
    seeds: pd.DataFrame = field(repr=False)
    summary: pd.DataFrame
    checks: pd.DataFrame
    grid_map: MetricMap = field(repr=False)
    nodes_per_sigma: dict


def coverage(problem: SpringSlider, truth, algorithm: Algorithm, b_range, lc_range,
             sigma_rel: float = 0.05, seeds: int = 1000, n_b: int = 121, n_lc: int = 121,
             check_seeds: int = 2, check_walkers: int = 32, check_steps: int = 600,
             workers: int | None = None, progress: bool = False) -> Calibration:
    """The coverage study of the module docstring for ``problem`` with (b, Lc) = ``truth``
    inside the prior box ``b_range`` × ``lc_range`` (Lc in m), on an ``n_b`` × ``n_lc`` grid."""
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ValueError(f"seeds must be a positive integer, got {seeds!r}")
    if (isinstance(check_seeds, bool) or not isinstance(check_seeds, int)
            or not 0 <= check_seeds <= seeds):
        raise ValueError(f"check_seeds must be an integer from 0 to seeds = {seeds}, got "
                         f"{check_seeds!r}")
    for name, n in (("n_b", n_b), ("n_lc", n_lc)):
        if isinstance(n, bool) or not isinstance(n, int) or n < 5:
            raise ValueError(f"{name} must be an integer ≥ 5 (grid nodes), got {n!r}")
    if not MIN_SIGMA_REL <= sigma_rel < 1:      # below it a seed's σ could be refused mid-study
        raise ValueError(f"sigma_rel must be in [{MIN_SIGMA_REL:g}, 1), got {sigma_rel!r}")
    b_t, lc_t = float(truth[0]), float(truth[1])
    if not (b_range[0] < b_t < b_range[1] and lc_range[0] < lc_t < lc_range[1]):
        raise ValueError(f"truth = {truth!r} is outside the box {b_range!r} × {lc_range!r}")
    b, log10_lc = box_grid(b_range, lc_range, n_b, n_lc, through=(b_t, lc_t))
    grid_map = metric_map(problem, algorithm, b, log10_lc, workers=workers, progress=progress)
    i, j = int(np.argmin(np.abs(b - b_t))), int(np.argmin(np.abs(log10_lc - np.log10(lc_t))))
    if not grid_map.cycle[i, j]:
        raise ValueError(f"the truth {truth!r} has no limit cycle with {algorithm.name} "
                         f"({grid_map.classification[i, j]}): nothing to observe")
    T0, M0 = float(grid_map.recurrence_s[i, j]), float(grid_map.friction_drop[i, j])
    rows = []
    for seed in range(seeds):
        obs = synthetic(T0, M0, sigma_rel, seed)
        J = grid_map.j1(obs)
        post = grid_map.posterior(obs)
        J_min = J.min()
        (lo_b, hi_b), (lo_l, hi_l) = post.interval["b"], post.interval["log10_lc"]
        rows.append({
            "seed": seed, "obs_recurrence_s": obs.recurrence_s, "obs_friction_drop":
            obs.friction_drop, "J1_truth": J[i, j], "J1_min": J_min,
            "j1_region": J[i, j] <= CHI2_95_2DOF,
            "profile_b": J[i, :].min() - J_min <= CHI2_95_1DOF,
            "profile_log10_lc": J[:, j].min() - J_min <= CHI2_95_1DOF,
            "posterior_hpd": bool(post.hpd[i, j]),
            "posterior_b": lo_b <= b[i] <= hi_b,
            "posterior_log10_lc": lo_l <= log10_lc[j] <= hi_l,
            "mean_b": post.mean["b"], "std_b": post.std["b"],
            "mean_log10_lc": post.mean["log10_lc"], "std_log10_lc": post.std["log10_lc"],
            "edge_mass": post.edge_mass})
    table = pd.DataFrame(rows)
    summary = pd.DataFrame([{"region": k, "what": v, **binomial_check(int(table[k].sum()), seeds)}
                            for k, v in REGIONS.items()])
    spacing = {"b": b[1] - b[0], "log10_lc": log10_lc[1] - log10_lc[0]}
    nodes = {k: float(table[f"std_{k}"].min() / spacing[k]) for k in spacing}
    checks = _checks(problem, algorithm, grid_map, table, check_seeds, T0, M0,
                     sigma_rel, check_walkers, check_steps, workers)
    return Calibration((b_t, lc_t), sigma_rel, table, summary, checks, grid_map, nodes)


def _checks(problem, algorithm, grid_map: MetricMap, table, n, T0, M0, sigma_rel, walkers,
            steps, workers) -> pd.DataFrame:
    """The grid posterior against emcee's, and the grid profiles against the refined ones."""
    b, log10_lc = grid_map.b, grid_map.log10_lc
    b_box, lc_box = cell_box(b, log10_lc)                    # the nodes' cells: the prior box
    rows = []
    for seed in range(n):
        obs = synthetic(T0, M0, sigma_rel, seed)
        misfit = Misfit(problem, obs, algorithm, workers=workers)
        post = grid_map.posterior(obs)
        k = np.unravel_index(np.argmax(post.mass), post.mass.shape)
        mc = sample(misfit, b_box, lc_box, (b[k[0]], 10.0 ** log10_lc[k[1]]), walkers=walkers,
                    steps=steps, seed=seed)
        row = {"seed": seed, "emcee_solves": mc.n_solves, "emcee_tau_max": max(mc.tau.values()),
               "emcee_effective_samples": mc.effective_samples}
        for name in ("b", "log10_lc"):         # a grid on one node has sd 0: no ratio (NaN)
            sd = post.std[name] if post.std[name] > 0 else np.nan
            row[f"mean_{name}_shift_sd"] = (mc.mean[name] - post.mean[name]) / sd
            row[f"std_{name}_ratio"] = mc.std[name] / sd
        grid_x, grid_J = grid_map.profile(obs, "b")
        level = grid_J.min() + CHI2_95_1DOF
        i, j = hull(grid_J, level)                 # the nodes' hull: no interpolation
        refined = profile(misfit, "b", grid_x[::4], lc_box, scan=len(log10_lc) // 4 + 1)
        row.update({"profile_b_grid_low": grid_x[i], "profile_b_grid_high": grid_x[j],
                    "profile_b_grid_nodes": int((grid_J <= level).sum()),
                    "profile_b_refined_resolved":
                    refined.resolved,
                    "profile_b_refined_low": refined.low, "profile_b_refined_high": refined.high})
        rows.append(row)
    return pd.DataFrame(rows)
