"""(b, Lc) together with apparatus constants a record leaves uncertain (stiffness, load-point
speed, mass, normal force): a gradient fit with stated Gaussian priors, its Laplace covariance,
a check of that Gaussian, and a sampler on the Gauss–Newton metric.

What it assumes: the observed means ΔT̄ and Δμ̄ with Gaussian errors of the stated σ (the
misfit's :class:`~benchmarks.inversion.observations.Observations`); each nuisance constant
θ_j Gaussian about its stated value with its stated σ (the prior: what the apparatus'
calibration says); b and log10 Lc flat within the box. The posterior's −2 log is

    χ²(x) = r_T² + r_μ² + Σ_j ((θ_j − θ̄_j)/σ_j)²,      x = (b, log10 Lc, θ_1, …)

Each residual's Jacobian comes from one solve with forward sensitivities
(:meth:`benchmarks.inversion.misfit.Misfit.residuals_and_jacobian`), never differences. The
fit is ``scipy.optimize.least_squares`` (trust-region reflective, within the box and within
``PRIOR_SPAN`` σ of each prior); the Laplace covariance (JᵀJ)⁻¹ at the optimum. The check: χ²
along ±1 and ±2 standard deviations of each principal axis of that covariance against the
quadratic's 1 and 4 (:attr:`NuisanceFit.laplace_check`: the worst ratio; inf when such a step
leaves the box or the cycles). The sampler:
random-walk Metropolis with the Laplace covariance (the Gauss–Newton metric at the optimum) as
its proposal, scaled by 2.38/√d (Gelman et al. 1996) after the whole covariance is shrunk
until no sd exceeds a tenth of its search span (:func:`proposal_covariance`), and its size
tuned during the burn-in (the first quarter, dropped) towards an acceptance of 0.234, then
held; one plain solve per step.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.inversion.least_squares import ExactResiduals
from benchmarks.inversion.misfit import NO_CYCLE_RESIDUAL, Misfit

__all__ = ["NuisanceFit", "fit_with_nuisance", "sample_with_nuisance", "PRIOR_SPAN",
           "NUISANCE", "priors_of", "nuisance_files", "write_nuisance"]

#: a nuisance constant is searched within this many prior σ of its stated value
PRIOR_SPAN = 5.0
#: a proposal's sd along a parameter at most this fraction of its search span, before the
#: 2.38/√d scaling (:func:`proposal_covariance`)
PROPOSAL_SPAN = 0.1
#: the Metropolis acceptance the burn-in tunes the step's size towards (Roberts et al. 1997)
TARGET_ACCEPTANCE = 0.234
#: the nuisance constants a fit can free (:data:`problems.directions.SENSITIVE` names)
NUISANCE = ("stiffness", "vl", "vls", "mass", "normal_force")


@dataclass
class NuisanceFit:
    """The fit of (b, log10 Lc, nuisance…) (module docstring).

    Parameters
    ----------
    names : tuple of str
        "b", "log10_lc", then the nuisance constants' names.
    x : numpy.ndarray
        The best point, in ``names``' order (log10 of Lc in m; the constants in SI).
    covariance : numpy.ndarray
        The Laplace covariance (JᵀJ)⁻¹ there.
    sd : numpy.ndarray
        Its standard deviations.
    chi2 : float
        χ² at the best point.
    n_solves : int
        Forward solves: the fit's with sensitivities, the Laplace check's plain.
    laplace_check : float
        The worst of |Δχ²/expected − 1| along ±1, ±2 σ of the principal axes (0: Gaussian).
    success : bool
        False when no start found a limit cycle.
    message : str
        The optimiser's message.
    priors : dict
        Name → (mean, σ) of each nuisance constant.
    bounds : tuple of numpy.ndarray
        The search's (lower, upper) bounds of x: the box and ``PRIOR_SPAN`` σ of each prior.
    """

    names: tuple
    x: np.ndarray
    covariance: np.ndarray
    sd: np.ndarray
    chi2: float
    n_solves: int
    laplace_check: float = math.nan
    success: bool = True
    message: str = ""
    priors: dict = field(default_factory=dict)
    bounds: tuple = (None, None)

    def table(self) -> pd.DataFrame:
        """One row per parameter: estimate, standard deviation, prior (NaN for b and Lc)."""
        return pd.DataFrame({
            "parameter": list(self.names), "estimate": self.x, "sd": self.sd,
            "prior_mean": [self.priors.get(n, (math.nan, math.nan))[0] for n in self.names],
            "prior_sd": [self.priors.get(n, (math.nan, math.nan))[1] for n in self.names]})


class _Posterior(ExactResiduals):
    """χ²'s residuals and Jacobian in x (priors among the residuals), and χ² within the box
    and the priors' spans."""

    def __init__(self, misfit: Misfit, priors: dict, lo, hi):
        super().__init__(misfit, priors)
        self.lo, self.hi = lo, hi

    def chi2(self, x) -> float:
        """χ² at x by a plain solve (no sensitivities); inf outside the box and the priors'
        spans (no solve there)."""
        if not (np.all(x >= self.lo) and np.all(x <= self.hi)):
            return math.inf
        self.solves += 1
        r = self.misfit.residuals_at(self.values(x))
        if not abs(r[0]) < NO_CYCLE_RESIDUAL:
            return math.inf
        prior = self.prior_residuals(x)
        return float(r @ r + prior @ prior)


def _check_priors(misfit: Misfit, priors: dict) -> None:
    from problems.directions import sensitivity_names
    names = sensitivity_names(misfit.problem, ("b", "lc", *priors))
    for name, spec in priors.items():
        if name not in NUISANCE:
            raise ValueError(f"nuisance: {name!r} cannot be freed; the constants are "
                             f"{', '.join(NUISANCE)}")
        if not (isinstance(spec, (tuple, list)) and len(spec) == 2
                and all(isinstance(v, (int, float)) for v in spec)):
            raise ValueError(f"nuisance: the prior of {name} must be (mean, σ) in SI, got "
                             f"{spec!r}")
        mean, sd = spec
        if not (np.isfinite(mean) and np.isfinite(sd) and sd > 0 and mean > 0):
            raise ValueError(f"nuisance: the prior of {name} must have a positive mean and "
                             f"σ, got mean {mean!r}, σ {sd!r} (SI)")
    del names


def fit_with_nuisance(misfit: Misfit, priors: dict, b_range, lc_range, start=None,
                      max_solves: int = 200) -> NuisanceFit:
    """Fit (b, log10 Lc) and the nuisance constants ``priors`` (name → (mean, σ), SI) to the
    misfit's observations (module docstring).

    Parameters
    ----------
    misfit : Misfit
        The problem (its constants at anything: the priors' means replace them), the
        observations (ΔT̄, Δμ̄; no curves) and the solver's tolerance.
    priors : dict
        Name (:data:`NUISANCE`) → (mean, σ) in SI.
    b_range, lc_range : tuple of float
        The box of b (dimensionless) and of Lc (m).
    start : tuple of float, optional
        (b, Lc in m) to start from (default: the box's centre, log-centre for Lc).
    max_solves : int
        Solves at most.

    Returns
    -------
    NuisanceFit

    Raises
    ------
    ValueError
        For a constant that cannot be freed, a prior without a positive mean and σ, a box
        without 0 ≤ b_lo < b_hi, 0 < lc_lo < lc_hi.
    """
    from scipy.optimize import least_squares
    _check_priors(misfit, priors)
    (b_lo, b_hi), (lc_lo, lc_hi) = b_range, lc_range
    if not (0 <= b_lo < b_hi and 0 < lc_lo < lc_hi):
        raise ValueError(f"the box must have 0 ≤ b_lo < b_hi and 0 < lc_lo < lc_hi, got "
                         f"b_range = {b_range!r}, lc_range = {lc_range!r}")
    means = np.array([m for m, _ in priors.values()])
    sds = np.array([s for _, s in priors.values()])
    lo = np.concatenate([[b_lo, math.log10(lc_lo)], np.maximum(means - PRIOR_SPAN * sds, 0)])
    hi = np.concatenate([[b_hi, math.log10(lc_hi)], means + PRIOR_SPAN * sds])
    post = _Posterior(misfit, dict(priors), lo, hi)
    b0, lc0 = start if start is not None else (0.5 * (b_lo + b_hi), math.sqrt(lc_lo * lc_hi))
    x0 = np.clip(np.concatenate([[b0, math.log10(lc0)], means]), lo, hi)
    res = least_squares(post.residuals, x0, jac=post.jacobian, bounds=(lo, hi), x_scale="jac",
                        max_nfev=max_solves)
    names = ("b", "log10_lc", *priors)
    if abs(res.fun[0]) >= NO_CYCLE_RESIDUAL:
        return NuisanceFit(names, res.x, np.full((len(names),) * 2, np.nan),
                           np.full(len(names), np.nan), math.inf, post.solves, success=False,
                           message="no limit cycle where the fit ended", priors=dict(priors),
                           bounds=(lo, hi))
    jac = post.at(res.x)[2]
    try:
        cov = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        cov = np.full((len(names),) * 2, np.inf)
    sd = np.sqrt(np.abs(np.diag(cov)))
    chi2 = post.chi2(res.x)
    check = _laplace_check(post, res.x, cov, chi2)
    return NuisanceFit(names, res.x, cov, sd, chi2, post.solves, laplace_check=check,
                       success=bool(res.success), message=res.message, priors=dict(priors),
                       bounds=(lo, hi))


def _laplace_check(post: _Posterior, x, cov, chi2: float) -> float:
    """The worst |Δχ²/k² − 1| at x ± k σ along each principal axis of ``cov``, k = 1, 2."""
    if not np.isfinite(cov).all():
        return math.nan
    val, vec = np.linalg.eigh(cov)
    worst = 0.0
    for i in range(len(val)):
        axis = vec[:, i] * math.sqrt(max(val[i], 0.0))
        for k in (1.0, 2.0):
            for sign in (1.0, -1.0):
                d = post.chi2(x + sign * k * axis) - chi2
                worst = max(worst, abs(d / k ** 2 - 1.0))
    return worst


def proposal_covariance(fitted: NuisanceFit) -> np.ndarray:
    """The Laplace covariance shrunk as a whole until no parameter's sd exceeds
    :data:`PROPOSAL_SPAN` of its search span: where the means leave a direction unresolved (an
    sd of 13 decades of Lc in a box of 2), the unshrunk proposal leaves the box at every step
    and the chain never moves. One factor for every entry keeps the valley's direction; a cap
    per parameter turned a thin valley's long axis off the valley (on W2 with 1 % means the
    chain then covered b and Lc in 0 of 3 seeds, against 3 of 3 before)."""
    lo, hi = fitted.bounds
    sd = np.sqrt(np.clip(np.diag(fitted.covariance), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(sd > 0, PROPOSAL_SPAN * (hi - lo) / sd, np.inf)
    return fitted.covariance * min(1.0, float(np.min(ratio))) ** 2


def sample_with_nuisance(misfit: Misfit, fitted: NuisanceFit, steps: int = 2000,
                         seed: int = 0, progress: bool = False) -> pd.DataFrame:
    """Random-walk Metropolis from the fit's optimum with its Laplace covariance as the
    proposal's metric (module docstring): one row per step (``names``' columns and χ²).
    A step outside the fit's box and priors' spans is rejected without a solve. ``progress``:
    a bar on the standard error. A fit the optimiser left at its budget is a start as good as
    any (the chain forgets it in its burn-in); one without a limit cycle is none."""
    if not np.isfinite(fitted.chi2):
        raise ValueError(f"sample_with_nuisance: the fit ended without a limit cycle "
                         f"({fitted.message}); nothing to start from")
    post = _Posterior(misfit, fitted.priors, *fitted.bounds)
    rng = np.random.default_rng(seed)
    d = len(fitted.x)
    cov = proposal_covariance(fitted) * (2.38 ** 2 / d)
    if not np.isfinite(cov).all():
        raise ValueError("sample_with_nuisance: the fit has no Laplace covariance (JᵀJ is "
                         "singular) to propose steps with")
    val, vec = np.linalg.eigh(cov)                # a square root even where cov is singular
    chol = vec * np.sqrt(np.clip(val, 0.0, None))
    x, chi2 = fitted.x.copy(), post.chi2(fitted.x)
    rows = np.empty((steps, d + 1))
    log_scale, burn_in = 0.0, steps // 4
    from tqdm.auto import tqdm
    for i in tqdm(range(steps), desc="sampler", unit="step", disable=not progress,
                  file=sys.stderr):
        y = x + math.exp(log_scale) * (chol @ rng.standard_normal(d))
        c = post.chi2(y)
        accepted = math.log(rng.random()) < -0.5 * (c - chi2)
        if accepted:
            x, chi2 = y, c
        if i < burn_in:                 # the step's size tuned towards TARGET_ACCEPTANCE, then
            log_scale += (accepted - TARGET_ACCEPTANCE) / math.sqrt(i + 1)     # held
        rows[i, :d], rows[i, d] = x, chi2
    return pd.DataFrame(rows, columns=[*fitted.names, "chi2"])


def priors_of(problem, specs) -> dict:
    """The priors of ``specs`` ((name, σ, relative) each), each about ``problem``'s own value:
    name (:data:`NUISANCE`, or an alias of :data:`problems.directions.ALIASES`) → (mean, σ)
    in SI, σ a fraction of the mean where ``relative``. ValueError naming a constant that
    cannot be freed, one named twice, or a σ not above 0."""
    from problems.directions import ALIASES, fields_of, sensitivity_names, value_of
    priors = {}
    for given, sigma, relative in specs:
        name = ALIASES.get(given, given)
        if name not in NUISANCE:
            raise ValueError(f"--nuisance {given}: not a constant the inversion can free; "
                             f"they are {', '.join(NUISANCE)} (aliases k, m, fn)")
        if name in priors:
            raise ValueError(f"--nuisance: {name} named twice")
        if problem.mass > 0 and name not in fields_of(problem):
            have = [n for n in NUISANCE if n in fields_of(problem)]
            raise ValueError(f"--nuisance {given}: {problem.name!r} has no {name}; the "
                             f"constants it can free are {', '.join(have)}")
        sensitivity_names(problem, (name,))     # with mass, or ValueError
        mean = value_of(problem, name)
        sd = sigma * mean if relative else sigma
        if not (math.isfinite(sd) and sd > 0 and mean > 0):
            raise ValueError(f"--nuisance {given}: the prior needs a σ above 0 about a "
                             f"positive value; the problem's {name} is {mean:g} (SI), σ "
                             f"{sd:g}")
        priors[name] = (mean, sd)
    return priors


def nuisance_files(out: Path) -> list[Path]:
    """Every file :func:`write_nuisance` may write to ``out``."""
    return [Path(out) / n for n in ("nuisance.json", "nuisance_parameters.csv",
                                    "nuisance_samples.csv", "nuisance.png")]


def write_nuisance(fitted: NuisanceFit, samples, out: Path, record: dict) -> dict:
    """``nuisance.json`` (the summary, with ``record``'s provenance), the parameters' table,
    the sampler's steps (if any) and the figure (each parameter's sampled histogram over the
    Laplace Gaussian and the prior) to ``out``; the summary with the paths written."""
    from benchmarks.records.files import claim_outputs, write_output, write_table
    from benchmarks.records.provenance import provenance as machine, version_line
    from benchmarks.records.report import jsonable
    out = Path(out)
    claim_outputs(nuisance_files(out))
    table = fitted.table()
    files = {"summary": out / "nuisance.json", "parameters": out / "nuisance_parameters.csv"}
    summary = {"names": list(fitted.names), "success": fitted.success,
               "message": fitted.message, "chi2": fitted.chi2, "solves": fitted.n_solves,
               "laplace_check": fitted.laplace_check,
               "laplace_check_is": "the worst |Δχ²/k² − 1| at ±1, ±2 sd along the Laplace "
                                   "covariance's principal axes (0: Gaussian); null: such a "
                                   "step left the box, the priors' spans or the cycles",
               "parameters": table.to_dict("records"),
               "covariance": fitted.covariance.tolist(),
               "assumed": "ΔT̄ and Δμ̄ Gaussian with the observations' σ; each constant "
                          "Gaussian about the problem's value with its --nuisance σ; b and "
                          "log10 Lc flat in the box; Laplace: (JᵀJ)⁻¹ at the fit",
               "provenance": {"tool": version_line(), **machine(), **record}}
    if samples is not None and len(samples):
        summary["sampler"] = _sampler_summary(fitted, samples)
        files["figure"] = out / "nuisance.png"
        _plot(fitted, samples, files["figure"])       # first: a figure that fails stops all
        files["samples"] = out / "nuisance_samples.csv"
        write_table(samples, files["samples"])
    write_table(table, files["parameters"])
    from benchmarks.records.files import remove_own
    for path in nuisance_files(out):               # an earlier run's this one did not make
        if path not in files.values():
            remove_own(path)
    summary["files"] = {k: str(v) for k, v in files.items()}
    write_output(files["summary"], json.dumps(jsonable(summary), indent=2) + "\n")
    return summary


def _sampler_summary(fitted: NuisanceFit, samples: pd.DataFrame) -> dict:
    """The nested sampler's weighted summary (a ``weight`` column), or the Metropolis
    chain's with its first quarter dropped (burn-in)."""
    if "weight" in samples:
        from benchmarks.inversion.nested_laplace import weighted_summary
        return {"method": "nested Laplace (benchmarks/inversion/nested_laplace.py)",
                **weighted_summary(samples, fitted.names),
                "inner_fits_not_converged": int((~samples.inner_converged.astype(bool)).sum())}
    kept = samples.iloc[len(samples) // 4:]
    tau = max(integrated_time(kept[n].to_numpy()) for n in fitted.names)
    return {"method": "Metropolis on the Gauss–Newton metric", "steps": len(samples),
            "burn_in": len(samples) - len(kept), "tau_steps": tau,
            "effective_steps": len(kept) / tau,
            "acceptance": float((samples[fitted.names[0]].diff().iloc[1:] != 0).mean()),
            "mean": {n: float(kept[n].mean()) for n in fitted.names},
            "sd": {n: float(kept[n].std()) for n in fitted.names},
            "interval_95": {n: [float(v) for v in kept[n].quantile([0.025, 0.975])]
                            for n in fitted.names}}


def integrated_time(x: np.ndarray, window: float = 5.0) -> float:
    """The chain's integrated autocorrelation time in steps, 1 + 2 Σ ρ_k summed up to the
    first lag M ≥ ``window`` × the sum so far (Sokal's window; emcee's estimator); 1 for a
    chain too short or constant."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = len(x)
    if n < 4 or not np.any(x):
        return 1.0
    f = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n]
    acf /= acf[0]
    taus = 2.0 * np.cumsum(acf) - 1.0
    past = np.arange(n) >= window * taus
    return float(max(taus[int(np.argmax(past))] if past.any() else taus[-1], 1.0))


def _plot(fitted: NuisanceFit, samples, path: Path) -> None:
    """Each parameter: the sampler's histogram (weighted, or the chain after its burn-in), the
    Laplace Gaussian, the prior's."""
    from matplotlib.figure import Figure

    from benchmarks.records.files import write_figure
    weights = samples.weight if "weight" in samples else None
    kept = samples if weights is not None else samples.iloc[len(samples) // 4:]
    fig = Figure(figsize=(3.0 * len(fitted.names), 3.0))
    for j, name in enumerate(fitted.names):
        ax = fig.add_subplot(1, len(fitted.names), j + 1)
        ax.hist(kept[name], bins=40, density=True, weights=weights, color="0.7",
                label="sampler")
        grid = np.linspace(*np.quantile(kept[name], [0.001, 0.999]), 200)
        for mean, sd, style, label in ((fitted.x[j], fitted.sd[j], "-", "Laplace"),
                                       (*fitted.priors.get(name, (math.nan, math.nan)), "--",
                                        "prior")):
            if np.isfinite(sd) and sd > 0:
                ax.plot(grid, np.exp(-0.5 * ((grid - mean) / sd) ** 2) / (sd * math.sqrt(
                    2 * math.pi)), ls=style, color="C3" if style == "-" else "C0", lw=1.2,
                    label=label)
        ax.set_xlabel(name, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)
