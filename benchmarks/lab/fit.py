"""Fit (a, b, Dc) — and the stiffness, the Nagata law's c — to a velocity-step or slide-hold-slide
record, by least squares on μ(t) with its covariance.

**The model** is :class:`benchmarks.lab.model.LabModel`: the spring-slider on the
record's own load-point history, μ = μ_ref + (rate-and-state response) + a linear trend in the
load point's displacement. The level μ_ref and the trend's slopes enter linearly: they are
eliminated exactly for each trial of the others (variable projection: with a basis that does not
depend on the nonlinear parameters the projected residual P⊥ W (μ − g(θ)) and its Jacobian
−P⊥ W ∂g/∂θ are exact, and (JᵀJ)⁻¹ of the projected problem is the nonlinear parameters' block of
the full covariance). The nonlinear parameters are a, b, ln Dc, ln k′ and c, each fitted unless
given (``fixed``); ∂g/∂θ by forward differences (:data:`FD_STEP`) of runs at rtol = atol = 1e-10,
so a difference is ~10⁻⁵ above the integrator's noise.

**Weights**: one per piece of the history (``weights``, default 1), multiplying its residuals.

**Noise model and uncertainty.** The residuals are read as white + AR(1) + random-walk noise,
fitted to their variogram (:mod:`benchmarks.lab.noise`): σ² = RSS/(n − p), and the covariance is
f σ² (JᵀJ)⁻¹ with f the white + AR(1) part's long-run variance inflation (1 for white noise,
(1 + ρ)/(1 − ρ) for AR(1) alone; a record's unmodelled wiggles make it large, honestly), plus the
walk's share σ²_rw B CᵀC B where the variogram reads one (B = (JᵀJ)⁻¹, C the reverse
cumulative sums of J's rows). With a trend held where the slider is steady
(``detrend="steady"``) the held slopes are lines through the same noisy samples, and the
covariance maps that one noise through the slopes and the fit together
(:func:`benchmarks.lab.noise.propagated_covariance`). Such a trend is first settled
(:func:`_settle`). ρ, the residuals'
lag-1 autocorrelation, is reported beside it.
Intervals: Wald (value ± 1.96 s.e.; Dc and k′ on the log scale) here, profile intervals in
:mod:`benchmarks.lab.profile_intervals` (Δ(RSS)/(f σ²) ≤ 3.84, the unit widened by each
parameter's share of the walk and of a held trend: :meth:`LabFit.profile_scale`). A parameter at a bound of
:data:`BOUNDS` is named (``at_bound``) and its interval is not a confidence interval.

Its checks (the integrator, the inertia) are :mod:`benchmarks.lab.checks`.

**Start.** From the record: for the first step, the jump to the first extreme sets a ln(v2/v1),
the steady change (a − b) ln(v2/v1), the distance to the extreme the stiffness, and the decay
after it Dc; the fit starts from Dc × :data:`DC_STARTS` and keeps the best.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from benchmarks.lab.noise import (RANK_TOL, NoiseModel, covariance, drift_covariance, lag1,
                                   propagated_covariance, read_noise)
from benchmarks.lab.running import running_mean
from benchmarks.lab.squeeze import compress

__all__ = ["LabFit", "fit_lab", "LabFitWarning", "starting_values", "BOUNDS", "FD_STEP",
           "sample_noise", "NOT_FIT", "NOT_FIT_RHO", "TRADES", "drift_covariance",
           "DC_STARTS", "Z95", "SETTLE_DC", "PARAMETER_UNITS", "covariance",
           "RANK_TOL", "DC_LONGEST", "coordinate_bounds", "DERIVED"]

#: each nonlinear parameter's bounds in its own unit (a, b, c dimensionless; dc m; k 1/m); b and
#: b2 may be negative (an evolution that strengthens with slip, as some clays show)
BOUNDS = {"a": (1e-5, 0.5), "b": (-0.5, 0.5), "dc": (1e-9, 0.1), "k": (1.0, 1e10),
          "c": (0.0, 100.0), "b2": (-0.5, 0.5), "dc2": (1e-9, 0.1)}
PARAMETER_UNITS = {"a": "1", "b": "1", "dc": "m", "k": "1/m", "c": "1", "b2": "1", "dc2": "m",
                   "a_minus_b": "1", "mu_ref": "1", "a_minus_b_minus_b2": "1"}
#: the derived parameters, as combinations of the fitted ones: a − b, the steady-state rate
#: dependence of one state, and with two a − b − b2, the whole slider's (a − b alone is then
#: the first state's)
DERIVED = {"a_minus_b": {"a": 1.0, "b": -1.0},
           "a_minus_b_minus_b2": {"a": 1.0, "b": -1.0, "b2": -1.0}}
#: forward-difference step in the fitted coordinates (a, b, ln Dc, ln k′, c)
FD_STEP = 1e-5
#: bytes of solves a fit keeps (μ and its sensitivities per point tried)
CACHE_BYTES = 2 ** 27
#: the starts of Dc, as multiples of the record's own estimate
DC_STARTS = (0.3, 1.0, 3.0)
Z95 = 1.959963984540054
#: a response whose extreme stands less than this many smoothed-noise σ above its settled level
#: has no peak (``starting_values``' ``monotone``)
PEAK_NOISE = 4.0
#: a piece after a step shorter than this many Dc of load-point travel does not show the
#: evolution: the fit warns
SETTLE_DC = 3.0
_LOG = ("dc", "k", "dc2")
#: the second state's starts: b2 as these multiples of b (it may strengthen: negative), Dc2 as
#: this multiple of Dc
B2_STARTS, DC2_START = (0.5, -0.5), 10.0


class LabFitWarning(UserWarning):
    """What a fit wants its user to know: a parameter at a bound, a step shorter than Dc."""


@dataclass
class LabFit:
    """A least-squares fit (module docstring). ``values`` holds every parameter (fitted or
    fixed, and a − b, μ_ref, the trend's slopes); ``free`` the fitted nonlinear ones;
    ``covariance`` is over ``free`` in the fitted coordinates (ln for Dc and k′); ``table()``
    has values, standard errors and 95 % Wald intervals (within the bounds), and whether each
    is fitted, derived (a − b) or fixed.

    Parameters
    ----------
    model : LabModel
        The model and its record.
    free : tuple of str
        The fitted nonlinear parameters.
    values : dict of str to float
        Every parameter's value (Dc in m, k in 1/m, the rest dimensionless).
    covariance : numpy.ndarray
        Over ``free``, in the fitted coordinates (ln Dc, ln k′).
    linear, linear_se : dict of str to float
        The linear parameters (μ_ref, the trend's slopes) and their standard errors.
    residuals, mu_model : numpy.ndarray
        μ observed − model, and the model's μ, at the record's samples.
    rss, sigma, rho : float
        The residual sum of squares, the residuals' σ and their lag-1 correlation.
    n : int
        Samples fitted.
    at_bound : tuple of str
        The parameters at a bound.
    notes : list of str
        What the fit says about itself.
    solves : int
        Forward solves.
    wall_s : float
        The fit's wall time (s).
    weights : numpy.ndarray, optional
        Each sample's weight.
    failed_solves : int
        Solves that failed or ran out of their budget.
    noise : float
        The record's own noise, from its second differences (:func:`sample_noise`).
    trend_rho : float
        The correlation of ln Dc with the trend slope it follows most (:data:`TRADES`).
    drift_sigma : float
        The random walk's σ per sample under the noise (:attr:`noise_model`; 0: none).
    drift_factor : dict of str to float
        Each free parameter's variance with the walk and a held trend's errors ÷ without them
        (≥ 1).
    fixed : dict of str to float
        The parameters held at given values.
    piece_weights : numpy.ndarray, optional
        One weight per piece of the history.
    success : bool
        The optimiser's success.
    message : str
        The optimiser's message.
    noise_model : NoiseModel, optional
        The noise read from the residuals (:mod:`benchmarks.lab.noise`).
    alternatives : dict
        Other trends' values of the law's parameters, by trend: with a held trend, ``piece``
        (every slope fitted with the rest), the fit its steady parts were first settled by.
    """

    model: object
    free: tuple
    values: dict
    covariance: np.ndarray
    linear: dict
    linear_se: dict
    residuals: np.ndarray = field(repr=False)
    mu_model: np.ndarray = field(repr=False)
    rss: float = math.nan
    sigma: float = math.nan
    rho: float = 0.0
    n: int = 0
    at_bound: tuple = ()
    notes: list = field(default_factory=list)
    solves: int = 0
    wall_s: float = 0.0
    weights: np.ndarray | None = field(default=None, repr=False)
    #: solves that failed or ran out of their budget: residuals far from any fit, never μ
    failed_solves: int = 0
    #: the record's own sample-to-sample noise (:func:`sample_noise`), beside σ
    noise: float = math.nan
    #: Dc's correlation with the trend's slope that it follows most (largest in size; NaN:
    #: no trend)
    trend_rho: float = math.nan
    #: the random walk's σ per sample read from the residuals (0: none)
    drift_sigma: float = 0.0
    #: each free parameter's variance with the walk and a held trend's slopes ÷ without them
    #: (≥ 1)
    drift_factor: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)
    piece_weights: np.ndarray | None = None
    success: bool = True
    message: str = ""
    #: the noise read from the residuals (None: AR(1) of ``rho``)
    noise_model: NoiseModel | None = None
    alternatives: dict = field(default_factory=dict)

    @property
    def inflation(self) -> float:
        """f: f σ² is the white + AR(1) noise's long-run variance (:mod:`benchmarks.lab.noise`;
        with a walk, σ² also holds the walk's share, which its own term counts, so f may be
        below 1); (1 + ρ)/(1 − ρ) without a noise model."""
        noise = self.noise_model
        if noise is None:
            return (1.0 + self.rho) / (1.0 - self.rho)
        if noise.walk > 0 and self.sigma > 0:
            return noise.long_run / self.sigma ** 2
        return noise.inflation

    def profile_scale(self, name: str) -> float:
        """The unit of a rise of the squares in ``name``'s profile: f σ² times its variance's
        growth by the drift (:attr:`drift_factor`)."""
        return self.noise_variance * self.drift_factor.get(name, 1.0)

    @property
    def walk_variance(self) -> float:
        """f σ² times the largest of the parameters' variance growths by the walk: the unit of
        a rise of the squares for what is not one parameter (a switch time, the posterior's
        likelihood), the walk's share counted as it counts for the parameter it moves most."""
        return self.noise_variance * max(self.drift_factor.values(), default=1.0)

    @property
    def noise_variance(self) -> float:
        """f σ²: what a change of the squares is measured in (profiles, χ²)."""
        return self.inflation * self.sigma ** 2

    def se(self, name: str) -> float:
        """The standard error in the fitted coordinate (of ln Dc, ln k′ for those)."""
        if name in self.free:
            i = self.free.index(name)
            return float(math.sqrt(max(self.covariance[i, i], 0.0)))
        parts = {n: w for n, w in DERIVED.get(name, {}).items() if n in self.free}
        if parts and (name == "a_minus_b_minus_b2" or {"a", "b"} <= set(parts)):
            weights = np.zeros(len(self.free))
            for n, w in parts.items():
                weights[self.free.index(n)] = w
            used = weights != 0
            c = self.covariance[np.ix_(used, used)]
            if not np.isfinite(c).all():
                return math.inf
            return float(math.sqrt(max(weights[used] @ c @ weights[used], 0.0)))
        return self.linear_se.get(name, 0.0)

    def interval(self, name: str) -> tuple[float, float]:
        """The 95 % Wald interval in the parameter's own unit, within the parameter's bounds
        (:data:`BOUNDS`)."""
        v, s = self.values[name], self.se(name)
        if name in _LOG:
            low, high = v * math.exp(-min(Z95 * s, 700.0)), v * math.exp(min(Z95 * s, 700.0))
        else:
            low, high = v - Z95 * s, v + Z95 * s
        if name in BOUNDS:
            low, high = max(low, BOUNDS[name][0]), min(high, BOUNDS[name][1])
        return low, high

    def table(self) -> pd.DataFrame:
        names = [n for n in ("a", "b", "a_minus_b", "dc", "k", "c", "b2", "dc2",
                             "a_minus_b_minus_b2") if n in self.values]
        names += list(self.linear)
        rows = []
        held = set(self.linear) - set(self.model.linear_names)   # a held trend's slopes
        for n in names:
            low, high = self.interval(n)
            kind = ("held" if n in held else "fitted" if n in self.free or n in self.linear
                    else "derived" if n in DERIVED and set(DERIVED[n]) & set(self.free)
                    else "fixed")
            known = kind != "fixed"
            se = self.se(n) * (self.values[n] if n in _LOG else 1.0)
            rows.append({"parameter": n, "value": self.values[n], "se": se if known else 0.0,
                         "wald_low95": low if known else math.nan,
                         "wald_high95": high if known else math.nan,
                         "unit": PARAMETER_UNITS.get(n, "1/m"), "kind": kind,
                         "at_bound": n in self.at_bound})
        return pd.DataFrame(rows)


class _Problem:
    """The projected least-squares problem of a model, ``free`` parameters and ``fixed``
    values; counts its solves."""

    def __init__(self, model, free, fixed, weights):
        self.model, self.free, self.fixed = model, tuple(free), dict(fixed)
        self.piece_weights = weights
        rec = model.record
        w = np.ones(len(rec.t)) if weights is None else np.asarray(weights, float)[
            rec.piece_index()]
        self.w = w
        self.wmu = w * (rec.mu - model.offset)       # a trend held fixed is taken off
        self.q = np.ascontiguousarray(_orthonormal(w[:, None] * model.linear_basis()))
        self.solves = 0
        self.failed = 0                  # solves that failed or ran out of their budget
        self.cache = {}
        #: the Jacobian from the model's sensitivities (not finite differences)
        self.exact = model.compiled
        self._squeezed = (None, None)    # the last (x, compressed residuals and Jacobian)
        #: with :attr:`exact`, every solve computes them (scipy asks for the Jacobian at
        #: nearly every point it evaluates); a sampler, which never does, sets it False
        self.eager = True

    def params(self, x) -> dict:
        p = dict(self.fixed)
        for name, u in zip(self.free, x):
            p[name] = math.exp(u) if name in _LOG else float(u)
        return p

    def coordinates(self, params: dict) -> np.ndarray:
        return np.array([math.log(params[n]) if n in _LOG else params[n] for n in self.free])

    def bounds(self):
        return coordinate_bounds(self.free)

    def _run(self, x, exact: bool):
        """(g, ∂g/∂x or None) at x, cached: one solve, with the sensitivities if ``exact``."""
        key = tuple(np.round(x, 15))
        hit = self.cache.get(key)
        if hit is not None and (hit[1] is not None or not exact or not np.isfinite(hit[0][0])):
            return hit                      # a failed point is not tried again
        p = self.params(x)
        self.solves += 1
        mu, d = np.full(len(self.w), np.nan), None
        try:
            if exact:
                mu, d, _ = self.model.sensitivities(self.free, **p)
            else:
                mu, _ = self.model.response(**p)
        except ValueError:          # a trial the law refuses (the Nagata law at b = 0)
            pass
        self.failed += not np.isfinite(mu).all()
        if len(self.cache) > 64 or len(self.cache) * mu.nbytes * (1 + len(x)) > CACHE_BYTES:
            self.cache.clear()
        self.cache[key] = (mu, d)
        return mu, d

    def _scales(self, x) -> np.ndarray:
        """∂θ/∂x of each free parameter: θ for ln θ, else 1 (the sensitivities are ∂/∂θ)."""
        return np.array([math.exp(u) if n in _LOG else 1.0 for n, u in zip(self.free, x)])

    def g(self, x) -> np.ndarray:
        return self._run(x, self.exact and self.eager)[0]

    def project(self, v):
        return v - self.q @ (self.q.T @ v)

    def residual(self, x) -> np.ndarray:
        g = self.g(x)
        if not np.isfinite(g).all():            # a failed run: far from any fit
            return np.full(len(g), 1e3 * max(np.std(self.wmu), 1e-6))
        return self.project(self.wmu - self.w * g)

    def jacobian(self, x, projected: bool = True) -> np.ndarray:
        """−W ∂g/∂θ, from the model's sensitivities (:attr:`exact`) or by forward
        differences, projected off the linear basis (the problem's own, :meth:`residual`'s)
        unless ``projected`` is False (the full problem's)."""
        if self.exact:
            g0, d = self._run(x, True)
            jac = -self.w[:, None] * (d * self._scales(x) if d is not None else
                                      np.full((len(g0), len(x)), np.nan))
        else:
            jac = self._differences(x)
        if not np.isfinite(jac).all():
            jac = np.nan_to_num(jac, nan=0.0, posinf=0.0, neginf=0.0)
        return jac - self.q @ (self.q.T @ jac) if projected else jac

    def _differences(self, x) -> np.ndarray:
        g0 = self.g(x)
        lo, hi = self.bounds()
        cols = []
        for j in range(len(x)):
            h = FD_STEP if x[j] + FD_STEP <= hi[j] else -FD_STEP
            xj = np.array(x, dtype=float)
            xj[j] += h
            cols.append(-(self.w * (self.g(xj) - g0)) / h)
        return np.column_stack(cols)

    def linear(self, x):
        """The linear parameters (level, slopes) at x: the least squares of the rest."""
        basis = self.w[:, None] * self.model.linear_basis()
        coef, *_ = np.linalg.lstsq(basis, self.wmu - self.w * self.g(x), rcond=None)
        return coef

    def solve(self, x0, max_nfev=200, tol=1e-10, trial=False):
        """scipy's least_squares from ``x0``; ``tol`` its xtol (ftol 100× finer), or with
        ``trial`` a trial's tolerances (:data:`TRIAL_TOL`, :data:`TRIAL_SQUARES`). With the
        exact Jacobian it sees the residuals compressed (:meth:`_compressed`): the same
        steps, on p + 1 numbers rather than the record's n."""
        ftol = tol * 1e-2
        if trial:
            tol, ftol = TRIAL_TOL, TRIAL_SQUARES / max(int((self.w > 0).sum()), 1)
        lo, hi = self.bounds()
        x0 = np.clip(x0, lo + 1e-12, hi - 1e-12)
        if self.exact:
            fun, jac = (lambda x: self._compressed(x)[0]), (lambda x: self._compressed(x)[1])
        else:
            fun, jac = self.residual, self.jacobian
        return least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                             max_nfev=max_nfev, xtol=tol, ftol=ftol, gtol=1e-10)

    def _compressed(self, x):
        """(r̃, J̃) at x (:func:`benchmarks.lab.squeeze.compress`): ‖r̃‖ = ‖r‖, J̃ᵀr̃ = Jᵀr and
        J̃ᵀJ̃ = JᵀJ, all that scipy's trust region reads of r and J, in p + 1 rows."""
        key = tuple(np.round(x, 15))
        if self._squeezed[0] != key:
            g, d = self._run(x, True)
            if d is None or not (np.isfinite(g).all() and np.isfinite(d).all()):
                r = self.residual(x)                # a failed run: no gradient
                squeezed = (np.append(np.zeros(len(x)), math.sqrt(r @ r)),
                            np.zeros((len(x) + 1, len(x))))
            else:
                squeezed = compress(self.wmu, self.w, g, d, self._scales(x), self.q)[:2]
            self._squeezed = (key, squeezed)
        return self._squeezed[1]


def coordinate_bounds(names) -> tuple[np.ndarray, np.ndarray]:
    """The :data:`BOUNDS` of ``names`` in the fitted coordinates (ln for Dc, k′, Dc2)."""
    lo = [math.log(BOUNDS[n][0]) if n in _LOG else BOUNDS[n][0] for n in names]
    hi = [math.log(BOUNDS[n][1]) if n in _LOG else BOUNDS[n][1] for n in names]
    return np.array(lo), np.array(hi)


def _orthonormal(basis: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the columns' span, whatever their rank (a trend whose piece has
    weight 0 is a zero column)."""
    u, sv, _ = np.linalg.svd(basis, full_matrices=False)
    return u[:, sv > RANK_TOL * max(sv.max(initial=0.0), 1e-300)]


#: a law "does not fit" where its residuals' σ is over this multiple of the record's own
#: sample-to-sample noise and their lag-1 correlation over :data:`NOT_FIT_RHO`
NOT_FIT, NOT_FIT_RHO = 10.0, 0.9


def sample_noise(mu: np.ndarray) -> float:
    """The record's own noise σ, with no model: the robust spread (1.4826 × the median
    absolute deviation) of μ's second differences, ÷ √6 (a second difference of white noise
    has variance 6σ²; a smooth signal's is far smaller, and the few samples of a step's jump
    do not move a median). Correlated noise reads lower than its σ."""
    mu = np.asarray(mu, dtype=float)
    if len(mu) < 5:
        return math.nan
    d2 = mu[2:] - 2.0 * mu[1:-1] + mu[:-2]
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


#: the size of ln Dc's correlation with a trend slope above which the fit says that they trade
TRADES = 0.9


def _trend_correlation(cov: np.ndarray, free, linear_names) -> float:
    """The correlation of ln Dc (``free``'s ``dc``) with the trend slope (a ``trend*`` of
    ``linear_names``, after ``free`` in ``cov``) of the largest size; NaN without both."""
    if "dc" not in free:
        return math.nan
    i = list(free).index("dc")
    best = math.nan
    for j, name in enumerate(linear_names):
        if not name.startswith("trend"):
            continue
        k = len(free) + j
        denom = math.sqrt(max(cov[i, i] * cov[k, k], 0.0))
        if denom > 0 and np.isfinite(denom):
            rho = float(cov[i, k] / denom)
            if not abs(rho) <= abs(best):
                best = rho
    return best


def starting_values(record) -> dict:
    """a, b, Dc and k′ read off the record's first step (module docstring), each piece's drift
    taken out first: the piece before the step by a line through it, the piece after by a line
    through its second half (where it has settled). ``monotone``: the response has no extreme
    before it settles (an evolution that strengthens, b < 0, or a Dc longer than the record
    shows), so that the jump is the whole steady change and a, b are not read apart."""
    t, mu, x = record.t, record.mu, record.load_point
    piece = record.piece_index()
    v1, v2 = record.velocities[0], record.velocities[1]
    if v2 == 0:                        # a hold first: the relaxation sets a/k′ only
        return {"a": 0.01, "b": 0.01, "dc": 1e-5, "k": 1e3}
    before, after = np.flatnonzero(piece == 0), np.flatnonzero(piece == 1)
    x_switch = v1 * record.switch_times[0]
    base = np.polyval(np.polyfit(x[before] - x_switch, mu[before], 1), 0.0)
    late = after[len(after) // 2:]
    slope, end = np.polyfit(x[late] - x_switch, mu[late], 1)
    level = mu[after] - slope * (x[after] - x_switch)           # the step's own response
    k_smooth = max(len(after) // 200, 1)
    smooth = running_mean(level, 2 * k_smooth + 1, "same")
    early = smooth[: max(len(after) // 2, 1)]
    ratio = math.log(v2 / v1)
    i_ext = int(np.argmax(early) if v2 > v1 else np.argmin(early))
    jump = abs(early[i_ext] - base)
    # an extreme that stands no higher above the settled level than the smoothed noise reaches
    # is no peak (a noisy plateau's argmax falls anywhere on it)
    half = len(level) // 2
    smoothed_noise = float(np.std(level[half:] - smooth[half:])) / math.sqrt(2 * k_smooth + 1)
    overshoot = (early[i_ext] - end) * (1.0 if v2 > v1 else -1.0)
    a = float(np.clip(jump / abs(ratio), 1e-3, 0.1))
    b = a - (end - base) / ratio                  # negative: the evolution strengthens
    b = float(np.clip(math.copysign(max(abs(b), 1e-3), b), -0.2, 0.2))
    travel = v2 * (t[after] - record.switch_times[0])
    x_ext = max(travel[i_ext], 1e-7)
    # Dc: the travel from the extreme to 63 % of the way to the new steady value
    target = early[i_ext] + 0.63 * (end - early[i_ext])
    crossed = np.flatnonzero((smooth[i_ext:] - target) * np.sign(early[i_ext] - end) <= 0)
    j = i_ext + (int(crossed[0]) if len(crossed) else len(smooth) - 1 - i_ext)
    dc = max(travel[j] - travel[i_ext], 1e-7)
    k = 2.0 * max(jump, 1e-4) / x_ext
    return {"a": a, "b": b, "dc": float(np.clip(dc, 2e-9, 0.05)),
            "k": float(np.clip(k, 2.0, 5e9)),
            "monotone": bool(i_ext >= 0.9 * (len(early) - 1)
                             or overshoot <= PEAK_NOISE * smoothed_noise)}


def fit_lab(model, fixed: dict | None = None, weights=None, start: dict | None = None,
            dc_starts=DC_STARTS, uncertainty: bool = True) -> LabFit:
    """Least squares of ``model`` (a :class:`~benchmarks.lab.model.LabModel`) to its
    record (``k`` in 1/m: friction per metre of load-point travel; the Nagata law's ``c`` is
    fitted unless fixed).

    Parameters
    ----------
    model : LabModel
        The model and the record it is fitted to.
    fixed : dict of str to float, optional
        Parameters held at given values, in their units (Dc in m, k in 1/m).
    weights : sequence of float, optional
        One non-negative weight per piece of the history.
    start : dict of str to float, optional
        Starting values.
    dc_starts : sequence of float
        The Dc values (m) the fit also starts from.
    uncertainty : bool
        False: the values and squares only (a trial of a search): no covariance (NaN), noise
        model or notes, and a held trend as the model has it (not settled: a trial of a
        settled model's).

    Returns
    -------
    LabFit

    Raises
    ------
    ValueError
        For an unknown or ill-valued fixed parameter, bad weights, or nothing left to fit.
    """
    t0 = time.perf_counter()
    fixed = dict(fixed or {})
    names = model.parameters
    unknown = sorted(set(fixed) - set(names))
    if unknown:
        raise ValueError(f"{unknown[0]!r} is not a parameter of a {model.law}-law fit (its "
                         f"parameters: {', '.join(names)})")
    for name, value in fixed.items():
        lo, hi = BOUNDS[name]
        if not (isinstance(value, (int, float)) and lo <= value <= hi):
            raise ValueError(f"fixed {name} = {value!r} {PARAMETER_UNITS[name]}: expected a "
                             f"number from {lo:g} to {hi:g}")
    weights = _checked_weights(weights, len(model.record.velocities))
    free = tuple(n for n in names if n not in fixed)
    if not free:
        raise ValueError("every parameter is fixed: nothing to fit")
    guess = starting_values(model.record)
    guess.update(c=2.0, b2=0.0, dc2=guess["dc"] * DC2_START)
    guess.update(start or {})
    settle = model.steady is not None and model.steady_after is None and uncertainty
    # a held trend is settled from the fit with a slope per piece (_settle)
    prob = _Problem(dataclasses.replace(model, detrend="piece") if settle else model, free,
                    fixed, weights)
    starts = _starts(guess, free, dc_starts if start is None else None, model.law)
    best = None
    for p0 in starts:
        # each start to the end (a start stopped at a trial's tolerance in a slow valley lost
        # to a worse basin: velstep4 with --states 2 settled at a = 0.5, 3.4 % worse squares)
        res = prob.solve(prob.coordinates({n: p0[n] for n in free}), trial=not uncertainty)
        if best is None or res.cost < best.cost:
            best = res
    alternatives = {}
    if settle:
        alternatives["piece"] = {n: v for n, v in prob.params(best.x).items() if n in names}
        prob, best = _settle(model, prob, best)
    fit = _result(prob, best, time.perf_counter() - t0, uncertainty)
    fit.alternatives.update(alternatives)
    return fit


def _starts(guess: dict, free, dc_starts, law: str) -> list[dict]:
    """The fit's starting points: ``guess`` at each factor of ``dc_starts`` on its Dc (None:
    ``guess`` alone, a start given), each with the :data:`B2_STARTS` of a second state; and
    where the step shows no extreme, each also with an evolution that strengthens."""
    starts = []
    for factor in (dc_starts if "dc" in free and dc_starts is not None else (1.0,)):
        p0 = dict(guess, dc=guess["dc"] * factor)
        if "b2" in free and dc_starts is not None:
            starts += [dict(p0, b2=m * p0["b"], dc2=p0["dc"] * DC2_START) for m in B2_STARTS]
        else:
            starts.append(p0)
    if (guess.get("monotone") and dc_starts is not None and "b" in free and law != "nagata"
            and guess["a"] > guess["b"]):
        # no extreme: also start from an evolution that strengthens, a − b split as 2/3 and −1/3
        starts += [dict(p0, a=2.0 * (p0["a"] - p0["b"]) / 3.0, b=-(p0["a"] - p0["b"]) / 3.0)
                   for p0 in list(starts)]
    return starts


def _checked_weights(weights, n_pieces: int):
    """``weights`` as an array of one non-negative weight per piece (not all 0), or None."""
    if weights is None:
        return None
    weights = np.asarray(weights, dtype=float)
    if weights.shape != (n_pieces,) or not np.all(np.isfinite(weights)) or (weights < 0).any() \
            or not (weights > 0).any():
        raise ValueError(f"weights must be {n_pieces} non-negative numbers, one per piece of "
                         f"the history (not all 0), got {np.atleast_1d(weights).tolist()}")
    return weights


#: a fit's least squares: xtol (ftol 100× finer)
TOL = 1e-10
#: a trial's (of a search, a profile; ``uncertainty=False``): its squares
#: need resolving to a small part of a noise variance only, so it stops once a step changes
#: them by under TRIAL_SQUARES of the mean square (ftol = TRIAL_SQUARES / n), or x by under
#: TRIAL_TOL. On the largest real step (75,220 samples) the trials of its switch and its
#: profiles took 70 % and 83 % of the solves of an ftol of 1e-10, their ends the same to 1e-8
#: (timed by hand, with the commit)
TRIAL_TOL, TRIAL_SQUARES = 1e-6, 1e-3
#: rounds of moving the steady parts to where the fitted model says the evolution has ended
SETTLE_ROUNDS = 3
#: a held slope more uncertain than this many times the same slope fitted with the rest is not
#: held: its steady part is too short to say more than the fit does, and a noisy slope held
#: moves the law's parameters by its noise
HELD_WORSE = 3.0


def _settle(model, prob, best):
    """The held trend's steady parts moved to where a fitted model says each piece's evolution
    has ended (:func:`~benchmarks.lab.steady_trend.settled_after`), first the fit with a slope
    per piece (``prob``, ``best``; a held slope read off a transient makes its own fit say
    that the evolution ended early), then the held fit's own, each fit made again from the
    last; a part only ever moves later, until it stays (at most :data:`SETTLE_ROUNDS`
    rounds). A slope whose held error exceeds :data:`HELD_WORSE` times its error in the fit
    with a slope per piece is fitted instead. The last model keeps its steady parts for the
    profiles and refits."""
    from benchmarks.lab.steady_trend import settled_after
    rec = model.record
    fitted_se = _slope_errors(prob, best.x)
    after, steady = None, model.steady
    # a piece of weight 0 is no data: its slope is free, as with a slope per piece
    forced = (np.zeros(len(rec.velocities), bool) if prob.piece_weights is None
              else np.asarray(prob.piece_weights) == 0)
    for _ in range(SETTLE_ROUNDS):
        g = prob.g(best.x)
        if not np.isfinite(g).all():
            break
        now = settled_after(steady, rec.t, rec.mu, g, rec.velocities, rec.switch_times)
        with np.errstate(invalid="ignore"):
            worse = forced | (np.asarray(steady.se) > HELD_WORSE * fitted_se)
        now = now if after is None else np.fmax(after, now)
        if after is not None and np.array_equal(now, after, equal_nan=True) and \
                np.array_equal(worse, forced):
            break
        after, forced = now, worse
        held = dataclasses.replace(model, steady_after=tuple(map(float, after)),
                                   steady_fitted=tuple(map(bool, forced)))
        steady, counts = held.steady, (prob.solves, prob.failed)
        prob = _Problem(held, prob.free, prob.fixed, prob.piece_weights)
        prob.solves, prob.failed = counts
        best = prob.solve(best.x)
    if prob.model.steady is None:        # the fit with a slope per piece failed: held as read
        counts = (prob.solves, prob.failed)
        prob = _Problem(dataclasses.replace(model, steady_fitted=tuple(map(bool, forced))),
                        prob.free, prob.fixed, prob.piece_weights)
        prob.solves, prob.failed = counts
        best = prob.solve(best.x)
    return prob, best


def _slope_errors(prob, x) -> np.ndarray:
    """Per piece, the standard error of its slope fitted with the rest (``prob`` a fit with a
    slope per piece, at ``x``), by the noise model of its residuals; NaN for a piece without
    one."""
    model = prob.model
    full = np.column_stack([prob.jacobian(x, projected=False),
                            -prob.w[:, None] * model.linear_basis()])
    kept = prob.w > 0
    noise = read_noise(prob.residual(x)[kept], _orthonormal(full[kept]))
    cov = covariance(full, noise.long_run) + drift_covariance(full, noise.walk)
    out = np.full(len(model.record.velocities), np.nan)
    for j, name in enumerate(model.linear_names):
        if name.startswith("trend_"):
            k = len(x) + j
            out[int(name.split("_")[1])] = math.sqrt(max(cov[k, k], 0.0))
    return out


def _result(prob, res, wall_s, uncertainty: bool = True) -> LabFit:
    model = prob.model
    x = res.x
    g = prob.g(x)
    ok = bool(np.isfinite(g).all())
    coef = prob.linear(x) if ok else np.full(len(model.linear_names), np.nan)
    mu_model = g + model.linear_basis() @ coef + model.offset
    r = prob.w * (model.record.mu - mu_model)
    # the samples of weight 0 are no data: they count neither in n nor in ρ
    n, p = int((prob.w > 0).sum()), len(x) + prob.q.shape[1]
    rss = float(r @ r)
    sigma = math.sqrt(rss / max(n - p, 1))
    rho = lag1(r[prob.w > 0])
    if not uncertainty:
        return _values_only(prob, res, wall_s, ok, coef, r, mu_model, rss, sigma, rho, n)
    jac = prob.jacobian(x)
    # the walk is read off the residuals the fit leaves: projected off the linear basis and
    # off the nonlinear parameters' directions
    # (not off a held trend's columns: its slopes were read off their steady parts only, and
    # projecting their whole columns off bends a unit walk's variogram more than they do; on
    # 40 white + walk records the z-scores' spread fell to 0.67–1.02 from 0.81–1.21)
    kept = prob.w > 0
    noise = read_noise(r[kept], _orthonormal(np.column_stack([prob.q, jac])[kept]))
    loads, reads, pieces = _held_maps(model, prob.w)
    walk = noise.walk
    f = noise.long_run / sigma ** 2 if walk > 0 and sigma > 0 else noise.inflation
    # the linear parameters' errors and their correlations with the others: the full
    # problem's covariance, from the unprojected Jacobian (the projected one is orthogonal to
    # the basis, and would leave out what the nonlinear parameters' uncertainty adds)
    full = np.column_stack([prob.jacobian(x, projected=False),
                            -prob.w[:, None] * model.linear_basis()])
    ar1 = covariance(jac, f * sigma ** 2)
    cov, cross, _ = propagated_covariance(jac, f * sigma ** 2, walk, loads, reads)
    with np.errstate(invalid="ignore", divide="ignore"):
        grow = np.diag(cov) / np.diag(ar1)
    drift_factor = {name: float(g) if np.isfinite(g) and g >= 1 else 1.0
                    for name, g in zip(prob.free, grow)}
    full_cov, _, held_cov = propagated_covariance(full, f * sigma ** 2, walk, loads, reads)
    params = prob.params(x)
    values = _derived(dict(params))
    linear = dict(zip(model.linear_names, map(float, coef)))
    linear_se = {k: float(np.sqrt(max(full_cov[len(x) + i, len(x) + i], 0.0)))
                 for i, k in enumerate(model.linear_names)}
    trend_rho = _trend_correlation(full_cov, prob.free, model.linear_names)
    if model.steady is not None:
        for j, i in enumerate(pieces):
            linear[f"trend_{i}"] = float(model.steady.slopes[i])
            linear_se[f"trend_{i}"] = float(np.sqrt(max(held_cov[j, j], 0.0)))
        held_rho = _held_correlation(cov, cross, held_cov, prob.free)
        if not abs(trend_rho) >= abs(held_rho):     # NaN: the other one
            trend_rho = held_rho
    values.update(linear)
    lo, hi = prob.bounds()
    # at a bound: held there by the solver, or within 1e-3 of the log range (Dc, k′ at 1e-9 m
    # is no value) or 1e-6 of a linear one
    near = [(1e-3 if n in _LOG else 1e-6) * (h - l) for n, l, h in zip(prob.free, lo, hi)]
    at_bound = tuple(name for name, u, l, h, tol, act in zip(prob.free, x, lo, hi, near,
                                                             res.active_mask)
                     if act != 0 or u - l <= tol or h - u <= tol)
    fit = LabFit(model=model, free=prob.free, values=values, covariance=cov, linear=linear,
                 linear_se=linear_se, residuals=r, mu_model=mu_model, rss=rss, sigma=sigma,
                 rho=rho, n=n, at_bound=at_bound, solves=prob.solves, wall_s=wall_s,
                 failed_solves=prob.failed, noise=sample_noise(model.record.mu[prob.w > 0]),
                 trend_rho=trend_rho, drift_sigma=math.sqrt(walk), drift_factor=drift_factor,
                 weights=prob.w, fixed=dict(prob.fixed), piece_weights=prob.piece_weights,
                 success=ok and res.status > 0, noise_model=noise,
                 message=res.message if ok else "the forward model failed at the fit's end")
    _notes(fit, lo, hi)
    return fit


def _held_maps(model, w) -> tuple:
    """(loads, reads, pieces) of a trend held fixed (``detrend="steady"``) for
    :func:`~benchmarks.lab.noise.propagated_covariance`: each held slope is a line through
    the samples of its steady part (``reads``, on the residuals' scale: a sample of weight w
    carries w times its noise; weight 0: its own), taken off the data times its travel
    column (``loads``, weighted as the residuals are); None without a held slope."""
    steady = model.steady
    if steady is None:
        return None, None, []
    pieces, rows = steady.readers()
    if not pieces:
        return None, None, []
    loads = w[:, None] * steady.columns[:, pieces]
    return loads, rows / np.where(w > 0, w, 1.0), pieces


def _held_correlation(cov: np.ndarray, cross: np.ndarray, held: np.ndarray, free) -> float:
    """The correlation of ln Dc with the held slope it follows most (largest in size); NaN
    without Dc or a held slope with an error."""
    if "dc" not in free or not cross.size:
        return math.nan
    i = list(free).index("dc")
    best = math.nan
    for j in range(cross.shape[1]):
        if cov[i, i] > 0 and np.isfinite(cov[i, i]) and held[j, j] > 0:
            rho = float(cross[i, j] / math.sqrt(cov[i, i] * held[j, j]))
            if not abs(rho) <= abs(best):
                best = rho
    return best


def _values_only(prob, res, wall_s, ok, coef, r, mu_model, rss, sigma, rho, n) -> LabFit:
    """A fit's values and squares without its uncertainty (``fit_lab(uncertainty=False)``)."""
    model = prob.model
    values = _derived(prob.params(res.x))
    linear = dict(zip(model.linear_names, map(float, coef)))
    if model.steady is not None:
        linear.update({f"trend_{i}": float(s) for i, (s, v, f) in enumerate(
            zip(model.steady.slopes, model.record.velocities, model.steady.fitted))
            if v > 0 and not f})
    values.update(linear)
    size = len(res.x)
    return LabFit(model=model, free=prob.free, values=values,
                  covariance=np.full((size, size), np.nan), linear=linear,
                  linear_se={k: math.nan for k in linear}, residuals=r, mu_model=mu_model,
                  rss=rss, sigma=sigma, rho=rho, n=n, solves=prob.solves, wall_s=wall_s,
                  failed_solves=prob.failed, weights=prob.w, fixed=dict(prob.fixed),
                  piece_weights=prob.piece_weights, success=ok and res.status > 0,
                  message=res.message if ok else "the forward model failed at the fit's end")


def _derived(values: dict) -> dict:
    """``values`` with the :data:`DERIVED` combinations of those it has."""
    for name, parts in DERIVED.items():
        if set(parts) <= set(values):
            values[name] = sum(w * values[n] for n, w in parts.items())
    return values


def _shown(name: str) -> tuple[float, str]:
    """(factor, unit) of a parameter as a laboratory reads it: lengths in µm, k′ per µm."""
    return {"m": (1e6, "µm"), "1/m": (1e-6, "per µm")}.get(PARAMETER_UNITS.get(name, "1"),
                                                          (1.0, ""))


#: m: a fitted Dc longer than this is no laboratory evolution distance (a unit slip)
DC_LONGEST = 1e-3


def _notes(fit: LabFit, lo, hi) -> None:
    """The fit's warnings: a parameter the data do not determine or at a bound, a piece too
    short to show the evolution, a Dc below the sampling."""
    lost = [n for n in fit.free if not np.isfinite(fit.se(n))]
    lost += [n for n in fit.linear if not np.isfinite(fit.linear_se[n])]
    if lost:
        fit.notes.append(f"the record does not determine {', '.join(lost)} (the fit's Jacobian "
                         "is singular there, as where a weight of 0 leaves no data for them): "
                         "their standard errors are infinite")
    for name in fit.at_bound:
        l, h = BOUNDS[name]
        side = "lower" if abs(fit.values[name] - l) <= abs(fit.values[name] - h) else "upper"
        scale, unit = _shown(name)
        fit.notes.append(f"{name} = {fit.values[name] * scale:.4g} {unit} is at its {side} "
                         f"bound ({(l if side == 'lower' else h) * scale:g}): the record does not "
                         f"determine it there; its interval is not a confidence interval")
    rec = fit.model.record
    dc = fit.values["dc"]
    from benchmarks.lab.steady_trend import OPENS_IN_TRANSIENT, opens_in_transient
    if opens_in_transient(rec.t, rec.mu, rec.velocities, rec.switch_times):
        fit.notes.append(OPENS_IN_TRANSIENT)
    if not np.isfinite(fit.sigma):
        fit.notes.append("the forward model failed at the fit's end: if the record opens in a "
                         "transient (just after a step), start it (--window) in steady "
                         "sliding, where the model starts")
    elif not fit.success:
        fit.notes.append(f"the fit did not converge ({fit.message}): its values are where it "
                         "stopped, not a minimum")
    if abs(fit.trend_rho) > TRADES and fit.model.steady is not None:
        fit.notes.append(f"Dc follows a held trend slope's error (correlation "
                         f"{fit.trend_rho:+.3f}): the steady part it was read from is short; a "
                         "longer record after the step would settle it")
    elif abs(fit.trend_rho) > TRADES:
        fit.notes.append(f"Dc and the trend's slope trade (correlation {fit.trend_rho:+.3f}): "
                         "the slope can take up part of the evolution; compare --detrend "
                         "steady, none or one, or --detrend auto, and a window that ends where "
                         "the slider is steady")
    if fit.model.steady is not None:
        fit.notes.extend(fit.model.steady.notes)
    # a record of no sample-to-sample noise (μ made by a model, exactly linear between its
    # transients) has nothing to judge a misfit against here
    if fit.noise > 0 and fit.sigma > NOT_FIT * fit.noise and fit.rho > NOT_FIT_RHO:
        fit.notes.append(f"the {fit.model.law} law does not fit this record: its residuals' σ "
                         f"({fit.sigma:.2g}) is {fit.sigma / fit.noise:.3g} × the record's own "
                         f"sample-to-sample noise ({fit.noise:.2g}) and they follow each other "
                         f"(ρ = {fit.rho:.3f}): compare laws (--law aging,slip) or a second "
                         "state (--states 2)")
    for name in ("dc", "dc2"):
        if fit.values.get(name, 0.0) > DC_LONGEST:
            fit.notes.append(f"{name} = {fit.values[name] * 1e6:.4g} µm is longer than any "
                             f"laboratory evolution distance (under {DC_LONGEST * 1e6:g} µm): "
                             "is the load point's unit right (load_point=COLUMN:um, :mm)?")
    moving = [v for v in rec.velocities if v > 0]
    per_sample = max(moving) * float(np.median(np.diff(rec.t)))
    if dc < per_sample:
        fit.notes.append(f"Dc = {dc * 1e6:.3g} µm is shorter than the load point's travel in one "
                         f"sample at its fastest ({per_sample * 1e6:.3g} µm): the record cannot "
                         "resolve it, and a and b are then known only as a − b (an evolution "
                         "the law cannot make ends here too)")
    bounds = (0.0, *rec.switch_times, float(rec.t[-1]))
    for name in ("dc", "dc2"):
        if name not in fit.values:
            continue
        length = fit.values[name]
        for i in range(1, len(rec.velocities)):
            travel = rec.velocities[i] * (bounds[i + 1] - bounds[i])
            if rec.velocities[i] > 0 and travel < SETTLE_DC * length:
                fit.notes.append(
                    f"the piece after the switch at t = {bounds[i]:.6g} s moves the load point "
                    f"{travel * 1e6:.4g} µm, {travel / length:.2g} {name} ({name} = "
                    f"{length * 1e6:.4g} µm): under {SETTLE_DC:g} {name} the evolution is not "
                    f"seen to its end and {name} is poorly determined")
    for note in fit.notes:
        warnings.warn(note, LabFitWarning, stacklevel=3)
