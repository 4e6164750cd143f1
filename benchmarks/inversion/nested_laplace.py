"""The posterior of (b, log10 Lc, nuisance…) where the means are precise: the nuisance constants
drawn from their priors, (b, log10 Lc) fitted exactly for each draw, and the draws weighted by
how well that fit can do — a nested Laplace approximation, sampled by importance.

Why: a settled cycle measures ΔT̄ and Δμ̄ to ~4e−5 and ~1e−3. With k and vL free, those two
numbers fix two combinations of the four parameters, and the posterior is a thin curved sheet
about a two-dimensional manifold. A random walk with the Laplace covariance at one point of it
leaves the sheet at every step (acceptance 0 on 2 of 2 such recordings,
``rsfbench study nuisance-settled``). Here the sheet is followed by construction.

For each draw θ of the constants (their Gaussian priors, cut to ``PRIOR_SPAN`` σ), the
(b, log10 Lc) that best fit the means with θ held (least squares from the fit's point, exact
Jacobians), then

    log w(θ) = −χ²_min(θ)/2 − ½ log det(J_θᵀ J_θ) + log P_θ(box),

the Laplace approximation of p(data | θ) with (b, log10 Lc) flat in the box: J_θ the
residuals' Jacobian in (b, log10 Lc) there, P_θ(box) the mass of N(x*(θ), (J_θᵀJ_θ)⁻¹) inside
the box (without it a θ that leaves (b, Lc) unresolved, det → 0, would take every weight);
(b, log10 Lc) | θ is drawn from that Gaussian cut to the box. Where x*(θ) lies on the box's
edge the squares' slope there is not 0 and the quadratic is only a guide: such draws are
those whose ``inner_converged`` is False, or whose x* is at a bound.

What it assumes beyond :mod:`benchmarks.inversion.nuisance`'s model: that (b, log10 Lc) given
θ is Gaussian (exact in the limit of precise means; the draws' own inner χ² says how far from
it each is) and that the inner fit finds the best (b, log10 Lc)
(a draw whose inner fit ends without a cycle has weight 0). The effective sample size
(Σw)²/Σw² says how many draws the weights leave.
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import NO_CYCLE_RESIDUAL, Misfit

__all__ = ["sample_nested", "weighted_summary", "DRAWS"]

#: draws unless told (``invert --nuisance``'s default, and the studies')
DRAWS = 200
#: least-squares evaluations of each draw's (b, log10 Lc) fit at most
INNER_SOLVES = 50
#: draws of each θ's Gaussian in (b, log10 Lc) that measure its mass in the box
BOX_DRAWS = 4000


def _inner(misfit: Misfit, theta: dict, x0, lo, hi):
    """``(found, solves)``: found is (x*, χ²_min, J at x*, converged) of (b, log10 Lc) with
    ``theta`` held, None without a cycle; solves, the forward solves it took."""
    from scipy.optimize import least_squares
    last, solves = {}, [0]
    here = getattr(type(misfit), "solves_here", None)      # a Misfit counts per thread

    def at(x):
        key = tuple(x)
        if key not in last:
            values = {"b": x[0], "lc": 10.0 ** x[1], **theta}
            before = misfit.solves_here if here is not None else 0
            r, jac = misfit.residuals_and_jacobian(values)
            # a Jacobian by differences (no cycle gradient) takes more than one solve
            solves[0] += misfit.solves_here - before if here is not None else 1
            jac = jac[:, :2] * np.array([1.0, values["lc"] * math.log(10.0)])
            last.clear()
            last[key] = (r, jac)
        return last[key]

    res = least_squares(lambda x: at(x)[0], np.clip(x0, lo, hi), jac=lambda x: at(x)[1],
                        bounds=(lo, hi), x_scale="jac", max_nfev=INNER_SOLVES)
    r, jac = at(res.x)
    if not (abs(r[0]) < NO_CYCLE_RESIDUAL and np.isfinite(r).all() and np.isfinite(jac).all()):
        return None, solves[0]
    return (res.x, float(r @ r), jac, bool(res.success)), solves[0]


def sample_nested(misfit: Misfit, fitted, draws: int = DRAWS, seed: int = 0,
                  progress: bool = False) -> pd.DataFrame:
    """``draws`` weighted draws of (b, log10 Lc, nuisance…) (module docstring): one row per
    draw, ``fitted.names``' columns, ``weight`` (normalised to sum 1), ``inner_chi2`` (χ²_min
    of its θ), ``inner_solves`` and ``inner_converged`` (its least squares' own verdict).
    ``fitted``: a :class:`~benchmarks.inversion.nuisance.NuisanceFit` with a limit cycle
    (its priors, box and point). The draws' fits run side by side on ``misfit.workers``
    threads (all cores unless told: the solves release the GIL); the table does not depend on
    how many."""
    if not np.isfinite(fitted.chi2):
        raise ValueError(f"sample_nested: the fit ended without a limit cycle "
                         f"({fitted.message}); nothing to start from")
    lo, hi = fitted.bounds
    names = list(fitted.priors)
    rng = np.random.default_rng(seed)
    thetas = [_theta(rng, fitted, names) for _ in range(draws)]
    start = np.asarray(fitted.x[:2], dtype=float)
    fits = _side_by_side(lambda theta: _inner(misfit, theta, start, lo[:2], hi[:2]), thetas,
                         getattr(misfit, "workers", None), progress)
    rows = []
    for theta, (found, solves) in zip(thetas, fits):
        if found is None:
            rows.append([*start, *theta.values(), -math.inf, math.inf, solves, False])
            continue
        x, chi2, jac, converged = found
        draw, log_mass = _in_box(rng, x, jac.T @ jac, lo[:2], hi[:2])
        rows.append([*draw, *theta.values(), -0.5 * chi2 + log_mass, chi2, solves, converged])
    table = pd.DataFrame(rows, columns=[*fitted.names, "log_weight", "inner_chi2",
                                        "inner_solves", "inner_converged"])
    logw = np.nan_to_num(table.pop("log_weight").to_numpy(), nan=-math.inf)
    w = np.exp(logw - logw.max()) if np.isfinite(logw).any() else np.zeros(len(logw))
    table.insert(len(fitted.names), "weight", w / w.sum() if w.sum() > 0 else w)
    return table


def _theta(rng, fitted, names) -> dict:
    """One draw of the constants from their priors, each cut to the search's span."""
    lo, hi = fitted.bounds
    theta = {}
    for j, name in enumerate(names):
        mean, sd = fitted.priors[name]
        while True:
            v = mean + sd * rng.standard_normal()
            if lo[2 + j] <= v <= hi[2 + j]:
                break
        theta[name] = float(v)
    return theta


def _side_by_side(work, items, workers, progress: bool) -> list:
    """``[work(item) for item in items]``, in order, on ``workers`` threads (None: all cores)
    through the ensembles' executor (:func:`benchmarks.ensemble.executors.execute`: a Ctrl-C
    drops the items not started), with a progress bar of the items done."""
    import os

    from tqdm.auto import tqdm

    from benchmarks.ensemble.executors import execute
    out = [None] * len(items)
    n = max(1, min(workers or os.cpu_count() or 1, len(items) or 1))
    # a catch_warnings inside a thread (a solve's first compile, say) races on the process's
    # filters: this one, outermost, puts them back as they were
    with warnings.catch_warnings(), tqdm(total=len(items), desc="nested draws", unit="draw",
                                         disable=not progress, file=sys.stderr) as bar:
        for k, result in execute(lambda k: work(items[k]), lambda k: None, None,
                                 list(range(len(items))), n, "threads"):
            out[k] = result
            bar.update(1)
    return out


def _in_box(rng, x, info, lo, hi):
    """A draw of N(x, info⁻¹) within [lo, hi] and the log of that Gaussian's integral over the
    box, ∫ exp(−½ (y−x)ᵀ info (y−x)) dy = (2π)^{d/2} det(info)^{−½} P(box), P(box) the share
    of :data:`BOX_DRAWS` draws inside (its square root from the eigenvalues: an info whose
    condition is 1e7 or worse has no Cholesky factor of its inverse). ``-inf`` where info is
    singular or no draw falls inside."""
    val, vec = np.linalg.eigh(info)
    if not (np.isfinite(val).all() and val.min() > 0):
        return np.asarray(x, dtype=float), -math.inf
    root = vec / np.sqrt(val)                  # root @ rootᵀ = info⁻¹
    ys = x + rng.standard_normal((BOX_DRAWS, len(x))) @ root.T
    inside = np.all((ys >= lo) & (ys <= hi), axis=1)
    if not inside.any():
        return np.asarray(x, dtype=float), -math.inf
    log_mass = (0.5 * len(x) * math.log(2 * math.pi) - 0.5 * float(np.sum(np.log(val)))
                + math.log(inside.mean()))
    return ys[rng.choice(np.flatnonzero(inside))], log_mass


def weighted_summary(table: pd.DataFrame, names) -> dict:
    """Weighted mean, sd and 95 % interval of each of ``names``, and the effective sample
    size (Σw)²/Σw²."""
    w = table.weight.to_numpy()
    ess = float(w.sum() ** 2 / (w ** 2).sum()) if (w > 0).any() else 0.0
    out = {"draws": len(table), "effective_draws": ess, "mean": {}, "sd": {},
           "interval_95": {}}
    for name in names:
        v = table[name].to_numpy()
        mean = float(np.sum(w * v)) if ess else math.nan
        out["mean"][name] = mean
        out["sd"][name] = float(math.sqrt(np.sum(w * (v - mean) ** 2))) if ess else math.nan
        order = np.argsort(v)
        cdf = np.cumsum(w[order])
        out["interval_95"][name] = ([float(np.interp(q, cdf, v[order])) for q in (0.025, 0.975)]
                                    if ess else [math.nan, math.nan])
    return out
