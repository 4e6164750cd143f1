"""Does the inversion with nuisance constants cover its truth? (b, Lc, k, vLs) of W2 under the
slip law from the cycle's ΔT̄ and Δμ̄ with 1 % Gaussian errors, the stiffness and the slow load
speed known to 3 % and 2 % (each prior's mean drawn about the truth with its σ: the
calibration's error), ``fits`` seeds: the gradient fit with exact Jacobians, its Laplace
intervals (±1.96 sd), the nested Laplace sampler's 95 % intervals on every seed (200 draws,
the command's default; :mod:`benchmarks.inversion.nested_laplace`) and, for the first
``sampled`` seeds, the Gauss–Newton-metric Metropolis sampler's 2.5–97.5 % intervals
(:mod:`benchmarks.inversion.nuisance`). The truth's cycle comes from
Rodas5P at rtol 1e−10, the fits' forward model at 1e−8.
"""

from __future__ import annotations

import math
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import Misfit
from benchmarks.inversion.nested_laplace import DRAWS, sample_nested, weighted_summary
from benchmarks.inversion.nuisance import (fit_with_nuisance, integrated_time,
                                           sample_with_nuisance)
from benchmarks.inversion.observations import Observations
from benchmarks.physics.metrics import summarize
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study, markdown_file
from integrators import solve
from integrators.own.rodas5p import Rodas5P
from problems.presets import window
from problems.slider import variant

__all__ = ["STUDY", "nuisance_coverage"]

#: the priors' relative σ, the observations' relative σ, the box
PRIOR_REL = {"stiffness": 0.03, "vls": 0.02}
SIGMA_REL = 0.01
B_RANGE, LC_RANGE = (0.008, 0.012), (3e-8, 3e-6)


def _one(truth, cycle, seed: int, steps: int) -> dict:
    rng = np.random.default_rng(seed)
    values = {"stiffness": truth.stiffness, "vls": truth.loading.vls}
    priors = {n: (v * (1 + PRIOR_REL[n] * rng.standard_normal()), PRIOR_REL[n] * v)
              for n, v in values.items()}
    s_t, s_mu = SIGMA_REL * cycle.recurrence_s, SIGMA_REL * cycle.friction_drop
    obs = Observations(recurrence_s=cycle.recurrence_s + s_t * rng.standard_normal(),
                       sigma_recurrence_s=s_t,
                       friction_drop=cycle.friction_drop + s_mu * rng.standard_normal(),
                       sigma_friction_drop=s_mu)
    start_pb = variant(truth, **{n: m for n, (m, _) in priors.items()})
    misfit = Misfit(start_pb, obs, Rodas5P(rtol=1e-8, atol=1e-8))
    started = time.perf_counter()
    fitted = fit_with_nuisance(misfit, priors, B_RANGE, LC_RANGE)
    row = dict(seed=seed, wall_s=time.perf_counter() - started, solves=fitted.n_solves,
               chi2=fitted.chi2, laplace_check=fitted.laplace_check)
    true_x = [truth.law.b, math.log10(truth.law.lc), *values.values()]
    for name, est, sd, t in zip(fitted.names, fitted.x, fitted.sd, true_x):
        row[f"z_{name}"] = (t - est) / sd
        row[f"laplace_covers_{name}"] = abs(t - est) <= 1.96 * sd
    if steps:
        chain = sample_with_nuisance(misfit, fitted, steps=steps, seed=seed).iloc[steps // 4:]
        for name, t in zip(fitted.names, true_x):
            lo, hi = chain[name].quantile([0.025, 0.975])
            row[f"sampler_covers_{name}"] = bool(lo <= t <= hi)
        row["acceptance"] = float((chain[fitted.names[0]].diff() != 0).mean())
        row["effective_steps"] = len(chain) / max(integrated_time(chain[n].to_numpy())
                                                  for n in fitted.names)
    if np.isfinite(fitted.chi2):        # the command's default sampler, on every seed
        nested = weighted_summary(sample_nested(misfit, fitted, draws=DRAWS, seed=seed),
                                  fitted.names)
        for name, t in zip(fitted.names, true_x):
            lo, hi = nested["interval_95"][name]
            row[f"nested_covers_{name}"] = bool(lo <= t <= hi)
        row["nested_effective_draws"] = nested["effective_draws"]
    return row


def nuisance_coverage(fits: int = 20, sampled: int = 3, steps: int = 1500,
                      progress: bool = False) -> pd.DataFrame:
    """One row per seed (module docstring): z of each parameter's truth, whether the Laplace
    and the sampler's intervals cover it, the fit's wall time, solves, χ² and Laplace check."""
    truth = window("W2", law="slip")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cycle = summarize(solve(truth, Rodas5P(rtol=1e-10, atol=1e-10), max_points=2))
        rows = []
        for seed in range(fits):
            rows.append(_one(truth, cycle, seed, steps if seed < sampled else 0))
            if progress:
                print(f"nuisance: seed {seed}: {rows[-1]['solves']} solves, "
                      f"{rows[-1]['wall_s']:.2f} s")
    return pd.DataFrame(rows)


def run(out: Path, fits: int = 20) -> None:
    rows = nuisance_coverage(fits=fits, progress=True)
    write_table(rows, out / "nuisance.csv")
    names = ("b", "log10_lc", "stiffness", "vls")
    cover = pd.DataFrame({
        "parameter": names,
        "laplace_coverage": [rows[f"laplace_covers_{n}"].mean() for n in names],
        "sampler_coverage": [rows[f"sampler_covers_{n}"].dropna().astype(float).mean()
                             if f"sampler_covers_{n}" in rows else math.nan for n in names],
        "sampled_seeds": [int(rows[f"sampler_covers_{n}"].notna().sum())
                          if f"sampler_covers_{n}" in rows else 0 for n in names],
        "nested_coverage": [rows[f"nested_covers_{n}"].dropna().astype(float).mean()
                            if f"nested_covers_{n}" in rows else math.nan for n in names],
        "z_rms": [float(np.sqrt(np.nanmean(rows[f"z_{n}"] ** 2))) for n in names]})
    text = ("# Inversion with nuisance constants: coverage\n\n"
            + __doc__.split("\n\n")[0].replace("\n", " ") + "\n\n"
            + markdown_table(cover, floatfmt=".3g")
            + f"\nA fit: median {rows.wall_s.median():.2f} s, {rows.solves.median():.0f} "
            f"solves (each with sensitivities), worst {rows.wall_s.max():.2f} s. Laplace "
            f"check (worst |Δχ²/k² − 1| at ±1, ±2 sd; inf: a step leaves the cycles): "
            f"median {rows.laplace_check.median():.3g}.\n\n"
            + markdown_table(rows, floatfmt=".3g")
            + f"\nCommand: `rsfbench study nuisance --set fits={fits}`.\n")
    write_output(out / "nuisance.md", text)
    print(text)


STUDY = Study("nuisance", "Inversion with nuisance constants (b, Lc, k, vL): coverage "
              "(`nuisance.*`)", 212, run, report=markdown_file("nuisance.md"), timed=True,
              settings={"fits": 20}, limits={"fits": (3, 1000)}, minutes=10,
              writes=("nuisance.csv", "nuisance.md"))
