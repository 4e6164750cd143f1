"""A posterior sample of a laboratory fit's parameters with emcee (``rsfbench lab fit
--posterior``).

The likelihood is the fit's: Gaussian noise of variance v = f σ² (σ and f from the least-squares
fit, held fixed: :mod:`benchmarks.lab.fit`), grown by the random walk's share as for the
parameter the walk moves most (:attr:`~benchmarks.lab.fit.LabFit.walk_variance`), so
log L = −RSS/(2 v). The level and the
trend's slopes enter linearly with flat priors, so they are integrated out exactly: the marginal
likelihood of the others is the projected one, up to a constant. The prior is uniform in the
fitted coordinates inside :data:`~benchmarks.lab.fit.BOUNDS` — flat in a, b and c, and
in ln Dc and ln k′, which span decades. Both are stated in the result.

The walkers start in a small ball about the least-squares fit (a hundredth of its covariance);
the first quarter of the steps is dropped. Reported: the acceptance fraction, emcee's
integrated autocorrelation time τ per parameter (``tol=0``) and whether the chain is 50 τ long,
and the effective number of samples.

A Ctrl-C during a step is held until the step ends and then raised as ``KeyboardInterrupt``
from :func:`sample_lab` (as :func:`benchmarks.inversion.posterior.sample` does): emcee wraps the
log-probability in a handler that prints a traceback for any exception, an interruption included.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.posterior import CtrlC, run_sampler
from benchmarks.lab.fit import _LOG, BOUNDS, PARAMETER_UNITS, LabFit, _Problem
from benchmarks.records.optional import require

__all__ = ["LabPosterior", "sample_lab"]


@dataclass
class LabPosterior:
    """Samples (``samples``, the parameters in their own units), their 2.5/50/97.5 %
    ``quantiles``, the chain's diagnostics, its cost and the ``prior``.

    Parameters
    ----------
    samples : pandas.DataFrame
        The chain after burn-in, one column per free parameter (Dc in m, k′ in 1/m; a − b
        added when a and b are free).
    quantiles : dict of str to list of float
        The 2.5, 50 and 97.5 % quantiles of each column.
    acceptance : float
        The walkers' mean acceptance fraction.
    tau : dict of str to float
        The integrated autocorrelation time of each parameter (steps).
    tau_reliable : bool
        Whether the chain is at least 50 τ long after burn-in.
    effective_samples : float
        Independent samples, about (NaN where τ is not finite).
    solves : int
        Forward solves.
    wall_s : float
        The chain's wall time (s).
    prior, likelihood : str
        The prior and the likelihood, in words.
    """

    samples: pd.DataFrame = field(repr=False)
    quantiles: dict
    acceptance: float
    tau: dict
    tau_reliable: bool
    effective_samples: float
    solves: int
    wall_s: float
    prior: str
    likelihood: str


def sample_lab(fit: LabFit, walkers: int = 32, steps: int = 600, seed: int = 0,
               progress: bool = False) -> LabPosterior:
    """emcee over ``fit``'s free parameters (module docstring); ``walkers`` × ``steps`` solves.

    Parameters
    ----------
    fit : LabFit
        The best fit the chain starts about.
    walkers, steps : int
        Walkers (even, ≥ twice the free parameters) and steps (≥ 20): else ValueError.
    seed : int
        The random generator's seed.
    progress : bool
        Show a progress bar.

    Returns
    -------
    LabPosterior
    """
    require("emcee", "inversion", "a posterior sample")
    import emcee
    n = len(fit.free)
    if walkers < 2 * n or walkers % 2:
        raise ValueError(f"walkers must be even and at least {2 * n} (twice the {n} fitted "
                         f"parameters), got {walkers}")
    if steps < 20:
        raise ValueError(f"steps must be at least 20, got {steps}")
    prob = _Problem(fit.model, fit.free, fit.fixed, fit.piece_weights)
    prob.eager = False              # μ only: a sampler needs no Jacobian
    lo, hi = prob.bounds()
    scale = fit.walk_variance
    stopped = CtrlC()

    def log_prob(x):
        if not ((x > lo) & (x < hi)).all():
            return -np.inf
        r = stopped.call(prob.residual, x)
        if r is None:                 # a Ctrl-C: raised after the step (CtrlC)
            return -np.inf
        if not np.isfinite(prob.g(x)).all():
            return -np.inf
        return -0.5 * float(r @ r) / scale

    rng = np.random.default_rng(seed)
    best = prob.coordinates(fit.values)
    cov = fit.covariance if np.isfinite(fit.covariance).all() else np.eye(n) * 1e-6
    p0 = rng.multivariate_normal(best, 0.01 * cov + 1e-18 * np.eye(n), size=walkers)
    p0 = np.clip(p0, lo + 1e-9, hi - 1e-9)
    sampler = emcee.EnsembleSampler(walkers, n, log_prob)
    sampler.random_state = np.random.RandomState(int(rng.integers(2 ** 31))).get_state()
    started = time.perf_counter()
    run_sampler(sampler, p0, steps, progress, stopped)
    wall = time.perf_counter() - started
    burn = steps // 4
    chain = sampler.get_chain(discard=burn, flat=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = sampler.get_autocorr_time(discard=burn, tol=0)
    samples = pd.DataFrame({name: np.exp(chain[:, i]) if name in _LOG else chain[:, i]
                            for i, name in enumerate(fit.free)})
    if {"a", "b"} <= set(samples):
        samples["a_minus_b"] = samples.a - samples.b
    quantiles = {c: [float(samples[c].quantile(q)) for q in (0.025, 0.5, 0.975)]
                 for c in samples}
    kept = steps - burn
    prior = ", ".join(f"uniform in {'ln ' if n in _LOG else ''}{n} on "
                      f"[{BOUNDS[n][0]:g}, {BOUNDS[n][1]:g}]"
                      + ("" if PARAMETER_UNITS[n] == "1" else f" {PARAMETER_UNITS[n]}")
                      for n in fit.free)
    return LabPosterior(
        samples=samples, quantiles=quantiles,
        acceptance=float(np.mean(sampler.acceptance_fraction)),
        tau=dict(zip(fit.free, map(float, tau))),
        tau_reliable=bool(np.isfinite(tau).all() and kept >= 50 * np.max(tau)),
        effective_samples=(float(walkers * kept / np.max(tau)) if np.isfinite(tau).all()
                           else math.nan),
        solves=prob.solves, wall_s=wall, prior=prior,
        likelihood=f"Gaussian noise of variance {scale:.4g} (f σ², σ = {fit.sigma:.4g}, "
                   f"f = {fit.inflation:.3g}, grown by the walk as for the parameter it moves "
                   "most); level and slopes integrated out (flat priors)")
