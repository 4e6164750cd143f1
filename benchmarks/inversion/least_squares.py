"""A multi-start least-squares fit of (b, Lc) with its covariance.

The parameters are x = (b, log10 Lc): Lc spans decades, and a step in log10 Lc is a relative
step in Lc. The residuals are :meth:`benchmarks.inversion.Misfit.residuals`' (in units of the
observations' σ), so at the optimum the covariance of x is (JᵀJ)⁻¹ with J the residuals'
Jacobian there (Gauss–Newton; the residuals are already scaled by σ, or whitened for curves).

Starts: the misfit over a coarse grid of the box (one ensemble batch), the ``starts`` best points
with a limit cycle. Each start runs ``scipy.optimize.least_squares`` (trust-region reflective,
within the box) with forward differences of relative step ``diff_step`` (the step must stay well
above the solver's own noise in the metrics, about its tolerance, or the Jacobian is noise), or
with exact Jacobians: each point's residuals and their derivatives from one solve with forward
sensitivities (docs/sensitivities.md). The best end point wins; every start's end point is
reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import Misfit

__all__ = ["fit", "FitResult", "EXACT_RTOL", "exact_jacobian_applies", "ExactResiduals"]


@dataclass
class FitResult:
    """The best fit (b, Lc in m, the misfit there: J1, plus the curves' χ² with curves), the
    covariance of (b, log10 Lc) and the standard
    errors of b and of log10 Lc (NaN where the Jacobian is singular and the covariance has no
    meaning), the number of forward solves, and every start's end point.

    Parameters
    ----------
    b : float
        The best-fit evolution effect (dimensionless).
    lc : float
        The best-fit Lc (m).
    misfit : float
        The misfit there (−2 log L + const, dimensionless).
    covariance : numpy.ndarray
        The 2×2 covariance of (b, log10 Lc) from the Jacobian.
    sigma_b, sigma_log10_lc : float
        The standard errors of b and of log10 Lc (NaN where the covariance has no meaning).
    n_solves : int
        Forward solves, the scan's included.
    starts : pandas.DataFrame
        Each start and where it ended: b_start, lc_start (m), b, lc (m), misfit, status,
        message.
    success : bool
        False for a failed fit (no limit cycle on the scan).
    message : str
        The optimiser's message, or why the fit failed.
    jacobian : str
        How the Jacobian was made: "forward differences" or "exact (forward sensitivities)".
    """

    b: float
    lc: float
    misfit: float
    covariance: np.ndarray
    sigma_b: float
    sigma_log10_lc: float
    n_solves: int
    starts: pd.DataFrame = field(repr=False)
    success: bool = True
    message: str = ""
    jacobian: str = "forward differences"


#: the loosest tolerance at which ``fit`` takes exact Jacobians by itself
#: (:data:`problems.directions.SENSITIVITY_RTOL`)
EXACT_RTOL = 1e-6


def exact_jacobian_applies(misfit: Misfit) -> bool:
    """Does ``fit(..., jacobian="auto")`` take exact Jacobians for ``misfit``?"""
    alg = getattr(misfit, "algorithm", None)         # (a stand-in misfit may have none)
    obs = getattr(misfit, "obs", None)
    return bool(getattr(alg, "sensitive", False) and hasattr(misfit, "residuals_and_jacobian")
                and getattr(obs, "curve_likelihood", None) is None
                and alg.rtol is not None and alg.rtol <= EXACT_RTOL)


def _jacobian_kind(misfit: Misfit, jacobian: str) -> str:
    """``fit``'s ``jacobian`` resolved ("auto"), or ValueError for a value it does not take."""
    if jacobian not in ("differences", "exact", "auto"):
        raise ValueError(f"jacobian must be 'differences', 'exact' or 'auto', got {jacobian!r}")
    if jacobian == "exact" and getattr(misfit.obs, "curve_likelihood", None) is not None:
        raise ValueError("jacobian='exact' covers ΔT and Δμ only: with slip-weakening curves "
                         "use 'differences'")
    if jacobian == "auto":
        return "exact" if exact_jacobian_applies(misfit) else "differences"
    return jacobian


class ExactResiduals:
    """The residuals of x = (b, log10 Lc, θ_1, …) and their Jacobian, one solve with
    sensitivities per point (:meth:`Misfit.residuals_and_jacobian`; the last point's kept:
    least squares asks for both there). ``priors`` (name → (mean, σ), SI) frees those
    constants as θ and adds (θ − mean)/σ to the residuals. ``solves`` counts the solves."""

    def __init__(self, misfit: Misfit, priors: dict | None = None):
        self.misfit, self.priors = misfit, dict(priors or {})
        self.nuisance = tuple(self.priors)
        self.solves, self.last = 0, (None, None, None)

    def values(self, x) -> dict:
        """x as the problem's values by name (Lc in m)."""
        return {"b": x[0], "lc": 10.0 ** x[1], **dict(zip(self.nuisance, x[2:]))}

    def at(self, x):
        """(x, residuals, Jacobian) at x."""
        if self.last[0] is None or not np.array_equal(self.last[0], x):
            self.solves += 1
            values = self.values(x)
            r, jac = self.misfit.residuals_and_jacobian(values)
            jac = jac * np.array([1.0, values["lc"] * np.log(10.0)]     # ∂/∂log10 Lc
                                 + [1.0] * len(self.nuisance))
            if self.nuisance:
                sd = np.array([self.priors[n][1] for n in self.nuisance])
                r = np.concatenate([r, self.prior_residuals(x)])
                jac = np.vstack([jac, np.hstack([np.zeros((len(sd), 2)), np.diag(1.0 / sd)])])
            self.last = (np.array(x, dtype=float), r, jac)
        return self.last

    def prior_residuals(self, x) -> np.ndarray:
        """(θ − mean)/σ of each nuisance constant in x."""
        mean = np.array([self.priors[n][0] for n in self.nuisance])
        sd = np.array([self.priors[n][1] for n in self.nuisance])
        return (np.asarray(x[2:], dtype=float) - mean) / sd

    def residuals(self, x):
        return self.at(x)[1]

    def jacobian(self, x):
        return self.at(x)[2]


def fit(misfit: Misfit, b_range=(0.005, 0.02), lc_range=(1e-8, 1e-5), grid: int = 9,
        starts: int = 3, diff_step: float = 1e-3, max_solves: int = 2000,
        start=None, jacobian: str = "auto") -> FitResult:
    """Fit (b, Lc) within the box ``b_range`` × ``lc_range``, from the ``starts`` best points
    of a ``grid`` × ``grid`` scan (module docstring), or from one ``start`` without a scan. A
    box with no limit cycle on its scan is a failed fit (``success`` False), not a guess.

    Parameters
    ----------
    misfit : Misfit
        The objective.
    b_range, lc_range : tuple of float
        (low, high) of b (dimensionless) and of Lc (m; fitted in log10 Lc).
    grid, starts : int
        Points per axis of the scan; how many of its best points start a fit.
    diff_step : float
        The relative step of the finite-difference Jacobian (scipy's ``diff_step``).
    max_solves : int
        Forward solves per start at most.
    start : tuple of float, optional
        One start (b, Lc in m) instead of the scan.
    jacobian : str
        ``"differences"`` (forward differences of ``diff_step``), ``"exact"`` (the residuals
        and their Jacobian from one solve with forward sensitivities each,
        :meth:`Misfit.residuals_and_jacobian`; ΔT and Δμ only, without curves) or ``"auto"``
        (default): exact when the misfit's method has sensitivities at rtol ≤
        :data:`EXACT_RTOL` and there are no curves, else differences.

    Returns
    -------
    FitResult
        The best of the starts' fits.

    Raises
    ------
    ValueError
        For a box without 0 ≤ b_lo < b_hi and 0 < lc_lo < lc_hi.
    """
    from scipy.optimize import least_squares
    (b_lo, b_hi), (lc_lo, lc_hi) = b_range, lc_range
    if not (0 <= b_lo < b_hi and 0 < lc_lo < lc_hi):
        raise ValueError(f"the box must have 0 ≤ b_lo < b_hi and 0 < lc_lo < lc_hi, got "
                         f"b_range = {b_range!r}, lc_range = {lc_range!r}")
    jacobian = _jacobian_kind(misfit, jacobian)
    lo, hi = np.array([b_lo, np.log10(lc_lo)]), np.array([b_hi, np.log10(lc_hi)])
    if start is not None:
        ok, n_solves = pd.DataFrame({"b": [float(start[0])], "lc": [float(start[1])]}), 0
    else:
        bb, ll = np.meshgrid(np.linspace(b_lo, b_hi, grid), np.geomspace(lc_lo, lc_hi, grid),
                             indexing="ij")
        scan = misfit.evaluate(bb.ravel(), ll.ravel())
        n_solves = len(scan)
        ok = scan[np.isfinite(scan.log_likelihood)].nsmallest(starts, "misfit")
    if ok.empty:
        return FitResult(np.nan, np.nan, np.nan, np.full((2, 2), np.nan), np.nan, np.nan,
                         n_solves, pd.DataFrame(), success=False,
                         message=f"no point of the {grid} × {grid} scan has a limit cycle")
    count = {"n": 0}

    def residuals(x):
        count["n"] += 1
        return misfit.residuals(x[0], 10.0 ** x[1])

    exact = ExactResiduals(misfit)
    how = dict(jac=exact.jacobian) if jacobian == "exact" else dict(diff_step=diff_step)
    rows, best = [], None
    for start in ok.itertuples():
        x0 = np.clip([start.b, np.log10(start.lc)], lo, hi)
        res = least_squares(exact.residuals if jacobian == "exact" else residuals, x0,
                            bounds=(lo, hi), max_nfev=max_solves, x_scale="jac", **how)
        value = float(2.0 * res.cost)
        rows.append({"b_start": start.b, "lc_start": start.lc, "b": res.x[0],
                     "lc": 10.0 ** res.x[1], "misfit": value, "status": res.status,
                     "message": res.message})
        if best is None or value < best[1]:
            best = (res, value)
    res, value = best
    return _result(res, value, n_solves + count["n"] + exact.solves, rows, jacobian)


def _result(res, value: float, n_solves: int, rows: list, jacobian: str) -> FitResult:
    """The :class:`FitResult` of the best start's ``res`` (scipy's), its Gauss–Newton
    covariance from the Jacobian there (made by ``jacobian``: "exact" or "differences")."""
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac)
    except np.linalg.LinAlgError:
        cov = np.full((2, 2), np.inf)
    var = np.diag(cov)                    # a singular JᵀJ can invert to a negative diagonal
    sd = np.where(var >= 0, np.sqrt(np.abs(var)), np.nan)
    return FitResult(b=float(res.x[0]), lc=float(10.0 ** res.x[1]), misfit=value, covariance=cov,
                     sigma_b=float(sd[0]), sigma_log10_lc=float(sd[1]),
                     n_solves=n_solves, starts=pd.DataFrame(rows), success=bool(res.success),
                     message=res.message,
                     jacobian=("exact (forward sensitivities)" if jacobian == "exact"
                               else "forward differences"))
