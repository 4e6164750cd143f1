"""An independent fit of a velocity step, to hold ``rsfbench lab fit`` against: scipy's
``least_squares`` on :func:`benchmarks.lab.independent_model.reference_friction` (scipy's Radau
on the published equations), sharing no code with :mod:`benchmarks.lab.fit` or
:mod:`benchmarks.lab.model` (a test checks the import graph).

It fits what a laboratory's own script would: a, b, ln Dc and ln k′ by trust-region least
squares with forward differences (``diff_step`` :data:`DIFF_STEP`), the level and the trend
(``none``: a level; ``one``: + a slope in the load point's travel; ``piece``: + a slope per
moving piece) by linear least squares at each trial; on the window, history (velocities and
switch times) and trend it is given: the project's, so that the two differ only in the model
code and the optimiser. Its standard errors are the textbook ones, σ² (JᵀJ)⁻¹ of the full
problem with σ² = RSS/(n − p), inflated by (1 + ρ)/(1 − ρ) for the residuals' lag-1
correlation ρ; Dc's and k′'s on the log scale.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from benchmarks.lab.independent_model import reference_friction

__all__ = ["ReferenceFit", "fit_reference", "DIFF_STEP", "Z95"]

#: least_squares' relative finite-difference step (Radau at rtol 1e-9 is ~1e-9 noisy)
DIFF_STEP = 1e-4
Z95 = 1.959963984540054
_NAMES = ("a", "b", "dc", "k")
_LOG = ("dc", "k")


@dataclass
class ReferenceFit:
    """The independent fit's values (Dc in m, k′ in 1/m), standard errors (of ln Dc and ln k′
    for those), residual σ and lag-1 correlation ρ, forward runs and wall time.

    Parameters
    ----------
    values : dict of str to float
        a, b, dc (m), k (1/m), and a_minus_b.
    se : dict of str to float
        Standard errors (ln Dc, ln k′ for those).
    rss, sigma, rho : float
        Residual sum of squares, σ and lag-1 correlation.
    n : int
        Samples.
    runs : int
        Forward runs.
    wall_s : float
        Wall time (s).
    success : bool
        least_squares' success.
    message : str
        Its message.
    """

    values: dict
    se: dict
    rss: float
    sigma: float
    rho: float
    n: int
    runs: int
    wall_s: float
    success: bool
    message: str = ""
    residuals: np.ndarray = field(default=None, repr=False)

    def interval(self, name: str) -> tuple[float, float]:
        """The 95 % Wald interval in the parameter's own unit."""
        v, s = self.values[name], self.se[name]
        if name in _LOG:
            return v * math.exp(-Z95 * s), v * math.exp(Z95 * s)
        return v - Z95 * s, v + Z95 * s


def _basis(t, velocities, switch_times, detrend: str, more=None) -> np.ndarray:
    bounds = np.array([0.0, *switch_times, np.inf])
    columns = [np.ones(len(t))]
    travel = [np.clip(t - bounds[i], 0.0, bounds[i + 1] - bounds[i]) * v
              for i, v in enumerate(velocities)]
    if detrend == "one":
        columns.append(np.sum(travel, axis=0))
    elif detrend == "piece":
        columns += [x for x, v in zip(travel, velocities) if v > 0]
    elif detrend != "none":
        raise ValueError(f"detrend must be none, one or piece, got {detrend!r}")
    if more is not None and np.size(more):
        columns += list(np.asarray(more, dtype=float).reshape(len(t), -1).T)
    return np.column_stack(columns)


def fit_reference(t, mu, velocities, switch_times, law: str, detrend: str, start: dict,
                  dc_starts=(0.3, 1.0, 3.0), rtol: float = 1e-9, trend_columns=None):
    """Fit ``law`` (aging or slip) to μ(t) under the load-point history (``velocities`` in m/s,
    ``switch_times`` in s from t = 0, the record's first sample) with the trend ``detrend``,
    from ``start`` (a, b, dc in m, k in 1/m) with Dc also at ``dc_starts`` times its start;
    the best of those fits.

    Parameters
    ----------
    t, mu : array_like
        The record's times (s, from 0) and friction.
    velocities, switch_times : sequence of float
        The load point's history.
    law : str
        ``aging`` or ``slip``.
    detrend : str
        ``none``, ``one`` or ``piece``.
    start : dict of str to float
        Starting values.
    dc_starts : sequence of float
        Multiples of the start's Dc also tried.
    rtol : float
        Radau's rtol (atol 1e-3 × rtol).
    trend_columns : numpy.ndarray, optional
        (samples, m): more columns fitted linearly (a held trend's fitted pieces).

    Returns
    -------
    ReferenceFit
    """
    started = time.perf_counter()
    t, mu = np.asarray(t, dtype=float), np.asarray(mu, dtype=float)
    basis = _basis(t, velocities, switch_times, detrend, trend_columns)
    q, _ = np.linalg.qr(basis)
    runs = [0]

    def model(x):
        a, b, lndc, lnk = x
        runs[0] += 1
        try:
            return reference_friction(t, velocities, switch_times, a, b, math.exp(lndc),
                                      math.exp(lnk), law=law, rtol=rtol, atol=1e-3 * rtol,
                                      wall_budget=60.0)
        except (RuntimeError, ValueError, OverflowError, ZeroDivisionError):
            return np.full(len(t), np.nan)

    def residual(x):
        g = model(x)
        if not np.isfinite(g).all():
            return np.full(len(t), 1.0)
        r = mu - g
        return r - q @ (q.T @ r)

    lo = [1e-5, -0.5, math.log(1e-9), math.log(1.0)]
    hi = [0.5, 0.5, math.log(0.1), math.log(1e10)]
    best = None
    for m in dc_starts:
        x0 = np.clip([start["a"], start["b"], math.log(start["dc"] * m), math.log(start["k"])],
                     np.add(lo, 1e-9), np.subtract(hi, 1e-9))
        res = least_squares(residual, x0, bounds=(lo, hi), diff_step=DIFF_STEP, x_scale="jac",
                            xtol=1e-10, ftol=1e-12, gtol=1e-10, max_nfev=200)
        if best is None or res.cost < best.cost:
            best = res
    x = best.x
    g = model(x)
    coef, *_ = np.linalg.lstsq(basis, mu - g, rcond=None)
    r = mu - g - basis @ coef
    n, p = len(t), len(x) + basis.shape[1]
    rss = float(r @ r)
    sigma = math.sqrt(rss / max(n - p, 1))
    rc = r - r.mean()
    rho = float(np.clip((rc[1:] @ rc[:-1]) / (rc @ rc), 0.0, 0.999))
    se, ok = _errors(model, x, g, hi, basis, sigma ** 2 * (1 + rho) / (1 - rho))
    values = {"a": float(x[0]), "b": float(x[1]), "dc": math.exp(x[2]), "k": math.exp(x[3])}
    values["a_minus_b"] = values["a"] - values["b"]
    return ReferenceFit(values=values, se=se, rss=rss, sigma=sigma, rho=rho, n=n,
                        runs=runs[0], wall_s=time.perf_counter() - started,
                        success=bool(best.success) and ok,
                        message=str(best.message) if ok else "a model run at or about the fit "
                        "failed: no standard errors", residuals=r)


def _errors(model, x, g, upper, basis, variance) -> tuple[dict, bool]:
    """The standard errors of a, b, ln Dc, ln k′ and a − b from the full problem's Jacobian
    (the model's columns and the basis'), ``variance`` (JᵀJ)⁻¹; NaN, and False, where a run
    at or about ``x`` failed."""
    full = np.column_stack([_unprojected(model, x, g, upper), basis])
    ok = bool(np.isfinite(full).all() and np.isfinite(g).all())
    size = full.shape[1]
    cov = np.linalg.pinv(full.T @ full) * variance if ok else np.full((size, size), np.nan)
    se = {name: float(math.sqrt(max(cov[i, i], 0.0))) for i, name in enumerate(_NAMES)}
    se["a_minus_b"] = float(math.sqrt(max(cov[0, 0] + cov[1, 1] - 2 * cov[0, 1], 0.0)))
    return se, ok


def _unprojected(model, x, g, upper) -> np.ndarray:
    """∂g/∂x by one-sided differences of :data:`DIFF_STEP` × max(|x|, 1) (backward within a
    step of the ``upper`` bounds)."""
    cols = []
    for j in range(len(x)):
        h = DIFF_STEP * max(abs(x[j]), 1.0)
        if x[j] + h > upper[j]:
            h = -h
        xj = np.array(x, dtype=float)
        xj[j] += h
        cols.append((model(xj) - g) / h)
    return np.column_stack(cols)
