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
its proposal, scaled by 2.38/√d (Gelman et al. 1996), one solve per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.least_squares import ExactResiduals
from benchmarks.inversion.misfit import NO_CYCLE_RESIDUAL, Misfit

__all__ = ["NuisanceFit", "fit_with_nuisance", "sample_with_nuisance", "PRIOR_SPAN"]

#: a nuisance constant is searched within this many prior σ of its stated value
PRIOR_SPAN = 5.0
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
        Forward solves (each with sensitivities).
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
        """χ² at x; inf outside the box and the priors' spans (no solve there)."""
        if not (np.all(x >= self.lo) and np.all(x <= self.hi)):
            return math.inf
        r = self.at(x)[1]
        return float(r @ r) if abs(r[0]) < NO_CYCLE_RESIDUAL else math.inf


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


def sample_with_nuisance(misfit: Misfit, fitted: NuisanceFit, steps: int = 2000,
                         seed: int = 0) -> pd.DataFrame:
    """Random-walk Metropolis from the fit's optimum with its Laplace covariance as the
    proposal's metric (module docstring): one row per step (``names``' columns and χ²).
    A step outside the fit's box and priors' spans is rejected without a solve."""
    if not fitted.success:
        raise ValueError(f"sample_with_nuisance: the fit failed ({fitted.message}); nothing to "
                         "start from")
    post = _Posterior(misfit, fitted.priors, *fitted.bounds)
    rng = np.random.default_rng(seed)
    d = len(fitted.x)
    chol = np.linalg.cholesky(fitted.covariance * (2.38 ** 2 / d))
    x, chi2 = fitted.x.copy(), post.chi2(fitted.x)
    rows = np.empty((steps, d + 1))
    for i in range(steps):
        y = x + chol @ rng.standard_normal(d)
        c = post.chi2(y)
        if math.log(rng.random()) < -0.5 * (c - chi2):
            x, chi2 = y, c
        rows[i, :d], rows[i, d] = x, chi2
    return pd.DataFrame(rows, columns=[*fitted.names, "chi2"])
