"""The likelihood of observed slip-weakening curves, beside the means' J1.

The observed curves are friction (Ft/Fn) against the slip since each event started, for n events
(:mod:`benchmarks.physics.curves`); a model point's curve is its last event's. Every event's
curve is compared up to an offset μ0 of its own, as Eq. 11 does (the friction level of a
laboratory event drifts with wear and normal-force control; its shape is what Lc and b set).
Two noise models, each stated in the output (:meth:`CurveLikelihood.describe`):

* ``"scatter"`` (the default; at least :data:`MIN_EVENTS` events): the events scatter about the
  model's curve. Each event is read at K common slips, the (k + ½)/K quantiles of all the
  observed slips up to the shortest event's end — where the samples are: a recorder sampling in
  time puts many at the slow start of an event, where the weakening over a few Lc happens, and
  at its arrest — and projected on the K − 1 contrasts orthogonal to a constant (which removes
  the offsets exactly). The reading at a common slip s is a Gaussian-kernel average of the
  samples' friction, weighted by their slip's distance from s (Nadaraya–Watson; the model's
  curve is read alike, :func:`kernel_read`). Its bandwidth at s is the larger of the slip
  column's noise after the chain's low-pass (where the slip moves less than its noise, as at
  the arrest, samples sorted by slip are in a random order, and a curve interpolated between
  them jumps as the model's parameters move: a χ² that is rough on the scale of the noise) and
  :data:`SPACING_FACTOR` × the observed samples' spacing there (median over the events). The events give a mean ȳ and a covariance of the contrasts; its estimate from
  few events is singular or noisy, so it is shrunk towards a multiple of the identity with Ledoit
  and Wolf's (2004) intensity (:func:`ledoit_wolf`). The curves' χ² of a model curve m is
  (ȳ − m)ᵀ Q S⁻¹ Qᵀ (ȳ − m) with S that covariance (``reading="std"``: the model compared with a
  typical event, as J1 uses the events' standard deviation) or S/n (``"sem"``: with the mean
  curve). The correlation between the slips of one event is the covariance's; the events are
  taken as independent of each other and of the means (their cross-correlation is not modelled);
* ``"sample"``: a σ per sample is given (the friction measurement's noise, in units of μ): the
  samples are independent Gaussian about the model's curve plus the event's offset, so the χ² is
  Σ_i Σ_j (r_ij − r̄_i)² / σ² with r = model − observed at the observed slips (the offsets
  profiled out exactly; this is Σ_i N_i J2(i) / σ², the paper's J2 made a likelihood). It
  assumes that the model makes every event's curve: no event-to-event variability.

Where the chain draws the slip's noise, the model's curve is its phases' samples pooled
(:meth:`benchmarks.physics.chain.Chain.model_curve`); the sample model, J̄2 and the figures read
it as a curve smoothed by a kernel as wide as that noise (:meth:`CurveLikelihood.curve`).

The total misfit of an inversion is −2 log L = J1 + χ²_curves (up to a constant).

**The model's curve goes through the measurement chain** of the observed ones (``chain``, a
:class:`~benchmarks.physics.chain.Chain` from the observations file's ``measurement``): the
model's run is sampled at the record's rate, filtered, timed and read as ``observe`` reads a
recording (:func:`benchmarks.ensemble.rows.chained_curve` makes it, the likelihood names it to
the :class:`~benchmarks.inversion.misfit.Misfit`). Without a chain (a file written before it was
recorded, or curves made by hand) the model's curve is compared as the model makes it.

**The model's error** (``model_error``, σ_model in μ, default 0): added to the covariance of the
contrasts as σ_model²·I (an independent error of the model's friction at each common slip,
its offset removed), or in quadrature to the σ per sample: what the data's spread alone does not
allow for, the model's own distance from a laboratory's events.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit

from benchmarks.inversion.objectives import (EventSamples, event_samples, j2_per_event,
                                             offset_residuals)

__all__ = ["CurveLikelihood", "CURVE_NOISES", "COMMON_SLIPS", "MIN_EVENTS", "MIN_SPREAD",
           "SPACING_FACTOR", "ledoit_wolf", "kernel_read", "bandwidths"]

#: the noise models of the curves (module docstring)
CURVE_NOISES = ("scatter", "sample")
#: the common slips K at which each event is read under the scatter model
COMMON_SLIPS = 12
#: the scatter model's least number of events (a covariance needs a spread of several)
MIN_EVENTS = 3
#: the least spread of the events' shapes (rms, in μ) the scatter model takes as a covariance:
#: below it the curves are noise-free or copies, and their whitening would be round-off
MIN_SPREAD = 1e-7
#: the kernel's least bandwidth in units of the observed samples' spacing at a common slip
SPACING_FACTOR = 2.0
#: the points of a model's curve made from pooled noisy samples (:meth:`CurveLikelihood.curve`)
CURVE_GRID = 400
#: the kernel's reach beyond the nearest sample, in bandwidths: a sample whose z² exceeds the
#: nearest one's by more than this squared weighs under exp(−40.5) = 2.6e−18 of it
KERNEL_REACH = 9.0


def kernel_read(slips: np.ndarray, bandwidth: np.ndarray, slip: np.ndarray,
                friction: np.ndarray) -> np.ndarray:
    """A curve's friction at ``slips`` (m): at each, the mean of the samples (``slip``,
    ``friction``) weighted by a Gaussian of their slip's distance in units of its ``bandwidth``
    (m, one per slip), over the samples within :data:`KERNEL_REACH` bandwidths beyond the
    nearest one (a curve that ends short is read as its last samples' kernel mean); where the
    weights are not finite (a bandwidth of 0), the curve interpolated linearly."""
    slips = np.ascontiguousarray(slips, dtype=float)
    bandwidth = np.ascontiguousarray(np.broadcast_to(bandwidth, slips.shape), dtype=float)
    order = np.argsort(slip, kind="stable")
    xs, ys = np.ascontiguousarray(slip[order]), np.ascontiguousarray(friction[order])
    weighted, total = _kernel_sums(slips, bandwidth, xs, ys)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, weighted / total, np.interp(slips, xs, ys))


@njit(cache=True, error_model="numpy")
def _kernel_sums(slips, bandwidth, xs, ys):
    """Σ w·y and Σ w at each of ``slips`` over the samples (``xs`` sorted), w the Gaussian of
    the distance in bandwidths: only the samples whose z² is within :data:`KERNEL_REACH`² of
    the nearest sample's, found by bisection (the sum is then continuous in the slip, and
    never empty)."""
    weighted = np.zeros(slips.size)
    total = np.zeros(slips.size)
    for i in range(slips.size):
        h = bandwidth[i]
        k = np.searchsorted(xs, slips[i])
        near = np.inf
        if k < xs.size:
            near = xs[k] - slips[i]
        if k > 0:
            near = min(near, slips[i] - xs[k - 1])
        reach = np.sqrt(near * near + (KERNEL_REACH * h) ** 2)
        lo = np.searchsorted(xs, slips[i] - reach)
        hi = np.searchsorted(xs, slips[i] + reach, side="right")
        for j in range(lo, hi):
            z = (xs[j] - slips[i]) / h
            w = np.exp(-0.5 * z * z)
            weighted[i] += w * ys[j]
            total[i] += w
    return weighted, total


def bandwidths(slips: np.ndarray, events: list, chain=None) -> np.ndarray:
    """The kernel's bandwidth (m) at each common slip (module docstring): the larger of the
    slip's noise after ``chain``'s low-pass (0 without a chain or a noisy slip column) and
    :data:`SPACING_FACTOR` × the median over ``events`` (each sorted by slip) of their samples'
    spacing about it."""
    gaps = []
    for g in events:
        x = g.slip_m.to_numpy()
        k = np.clip(np.searchsorted(x, slips), 1, len(x) - 1)
        gaps.append(x[k] - x[k - 1])
    return np.maximum(SPACING_FACTOR * np.median(gaps, axis=0), _filtered_noise(chain))


def _filtered_noise(chain) -> float:
    """The σ (m) of the chain's slip noise after its low-pass (0 if it has none): its white
    noise filtered as observe filters the slip column, measured on a seeded draw."""
    if chain is None or not chain.slip_noise > 0 or chain.slip_from != "slip column":
        return 0.0
    return chain.slip_noise * _unit_filtered_noise(float(chain.slip_hz), float(chain.rate_hz))


@functools.lru_cache(maxsize=16)
def _unit_filtered_noise(cutoff: float, rate: float) -> float:
    """The σ of unit white noise after :func:`benchmarks.physics.chain.lowpass`."""
    from benchmarks.physics.chain import lowpass
    white = np.random.default_rng(0).standard_normal(1 << 15)
    return float(lowpass(white, cutoff, rate)[1024:-1024].std())


def ledoit_wolf(x: np.ndarray) -> tuple[np.ndarray, float]:
    """``(covariance, shrinkage)``: Ledoit and Wolf's (2004, J. Multivariate Anal. 88, 365)
    estimate from the rows of ``x`` (samples × features): the sample covariance (÷ n, about the
    mean) shrunk towards μ·I, μ its mean variance, by the intensity that minimises the expected
    squared Frobenius error; the formula scikit-learn's ``ledoit_wolf`` computes."""
    x = np.asarray(x, dtype=float)
    n, p = x.shape
    x = x - x.mean(axis=0)
    emp = x.T @ x / n
    mu = np.trace(emp) / p
    x2 = x ** 2
    delta_ = np.sum(emp ** 2)
    beta_ = np.sum(x2.T @ x2) / n
    beta = (beta_ - delta_) / (p * n)
    delta = (delta_ - 2.0 * mu * np.trace(emp) + p * mu ** 2) / p
    beta = min(beta, delta)
    shrinkage = 0.0 if beta == 0 else beta / delta
    cov = (1.0 - shrinkage) * emp
    cov.flat[::p + 1] += shrinkage * mu
    return cov, float(shrinkage)


def _contrasts(k: int) -> np.ndarray:
    """An orthonormal basis (k × k−1) of the vectors orthogonal to the constant one."""
    q, _ = np.linalg.qr(np.column_stack([np.ones(k), np.eye(k)[:, :k - 1]]))
    return q[:, 1:]


@dataclass(frozen=True)
class CurveLikelihood:
    """The curves' χ² of a model curve against observed ``curves`` (module docstring):
    :meth:`from_curves` builds it and refuses what it cannot use.

    Parameters
    ----------
    noise : str
        The noise model: ``"scatter"`` or ``"sample"``.
    reading : str
        ``"std"`` (a typical event) or ``"sem"`` (the mean curve).
    n_events : int
        The observed events.
    dof : int
        The χ²'s degrees of freedom.
    sigma : float, optional
        The σ per sample of ``"sample"`` (units of μ, dimensionless).
    slips : numpy.ndarray, optional
        The K common slips of ``"scatter"`` (m).
    mean : numpy.ndarray, optional
        The events' mean curve at ``slips`` (units of μ).
    whiten : numpy.ndarray, optional
        The matrix that whitens the contrasts' residuals (``"scatter"``).
    shrinkage : float, optional
        Ledoit and Wolf's shrinkage intensity (``"scatter"``, in [0, 1]).
    bandwidth : numpy.ndarray, optional
        The kernel's bandwidth at each common slip (``"scatter"``, m).
    observed : EventSamples, optional
        Every observed sample (``"sample"``).
    chain : benchmarks.physics.chain.Chain, optional
        The measurement chain the model's curves go through (None: compared as they are).
    model_error : float
        σ_model, in units of μ (module docstring; 0: none).
    """

    noise: str
    reading: str
    n_events: int
    dof: int
    sigma: float | None = None
    slips: np.ndarray | None = field(default=None, repr=False)
    mean: np.ndarray | None = field(default=None, repr=False)
    whiten: np.ndarray | None = field(default=None, repr=False)
    shrinkage: float | None = None
    bandwidth: np.ndarray | None = field(default=None, repr=False)
    #: every observed sample (the residuals of ``"sample"``, the paper's J̄2)
    observed: EventSamples | None = field(default=None, repr=False)
    #: the measurement chain the model's curves are passed through (None: as they are)
    chain: object = None
    #: σ_model (units of μ) added to the curves' covariance (module docstring)
    model_error: float = 0.0

    @classmethod
    def from_curves(cls, curves: pd.DataFrame, noise: str = "scatter", sigma: float | None = None,
                    reading: str = "std", points: int = COMMON_SLIPS, chain=None,
                    model_error: float = 0.0) -> "CurveLikelihood":
        """The likelihood of ``curves`` (:func:`benchmarks.physics.curves.check_curves`'
        columns) under ``noise``; ``sigma``: the σ per sample of ``"sample"`` (units of μ);
        ``reading``: ``"std"`` or ``"sem"`` (``"scatter"``); ``points``: K; ``chain``: the
        measurement chain of the model's curves; ``model_error``: σ_model (units of μ)."""
        if not (isinstance(model_error, (int, float)) and np.isfinite(model_error)
                and model_error >= 0):
            raise ValueError(f"model_error must be a σ ≥ 0 in units of μ, got {model_error!r}")
        if noise not in CURVE_NOISES:
            raise ValueError(f"curve noise must be one of {CURVE_NOISES}, got {noise!r}")
        if reading not in ("std", "sem"):
            raise ValueError(f"reading must be 'std' or 'sem', got {reading!r}")
        events = [g.sort_values("slip_m") for _, g in curves.groupby("event_id", sort=False)]
        n = len(events)
        observed = event_samples(curves)
        if noise == "sample":
            if sigma is None or not np.isfinite(sigma) or sigma <= 0:
                raise ValueError(f"curve noise 'sample' needs σ per sample > 0 (friction, a "
                                 f"fraction like μ), got {sigma!r}")
            return cls("sample", reading, n, len(observed.slip) - n,
                       sigma=float(np.hypot(sigma, model_error)), observed=observed,
                       chain=chain, model_error=float(model_error))
        if sigma is not None:
            raise ValueError("a σ per sample is for curve noise 'sample'; the 'scatter' model "
                             "estimates its covariance from the events")
        if n < MIN_EVENTS:
            raise ValueError(f"curve noise 'scatter' needs at least {MIN_EVENTS} events to "
                             f"estimate their spread, the curves have {n}: give a σ per sample "
                             "(noise 'sample'; rsfbench invert --curve-noise sample "
                             "--curve-sigma X) or leave the curves out ('none')")
        if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 3:
            raise ValueError(f"points must be an integer ≥ 3, got {points!r}")
        shortest = min(float(g.slip_m.max()) for g in events)
        if not shortest > 0:
            raise ValueError("an observed event has no slip (its slip_m never exceeds 0)")
        pooled = np.concatenate([g.slip_m.to_numpy() for g in events])
        slips = np.quantile(pooled[pooled <= shortest], (np.arange(points) + 0.5) / points)
        if not (np.diff(slips) > 0).all():
            raise ValueError(f"the observed curves have fewer than {points} distinct slips "
                             f"up to the shortest event's end ({shortest:g} m)")
        bandwidth = bandwidths(slips, events, chain)
        y = np.array([kernel_read(slips, bandwidth, g.slip_m.to_numpy(), g.friction.to_numpy())
                      for g in events])
        q = _contrasts(points)
        cov, shrinkage = ledoit_wolf(y @ q)
        spread = float(np.sqrt(np.trace(cov) / (points - 1)))
        if not spread > MIN_SPREAD and model_error == 0:
            raise ValueError(f"the events' curves do not scatter in shape (their spread is "
                             f"{spread:.2g} in μ, below {MIN_SPREAD:g}: noise-free or copies): "
                             "the scatter model has no covariance to use; give a σ per sample "
                             "(noise 'sample'; rsfbench invert --curve-noise sample "
                             "--curve-sigma X)")
        cov *= n / (n - 1.0)                       # the events' spread, as their std is (ddof 1)
        if reading == "sem":
            cov /= n
        cov.flat[::points] += model_error ** 2       # the model's own error: not ÷ n
        # χ² = |L⁻¹ Qᵀ (ȳ − m)|² with S = L Lᵀ: the whitened residuals least squares reads
        whiten = np.linalg.inv(np.linalg.cholesky(cov)) @ q.T
        return cls("scatter", reading, n, points - 1, slips=slips, mean=y.mean(axis=0),
                   whiten=whiten, shrinkage=shrinkage, bandwidth=bandwidth,
                   observed=observed, chain=chain,
                   model_error=float(model_error))

    def curve(self, slip, friction) -> tuple[np.ndarray, np.ndarray]:
        """A model's curve as a curve: the samples of a chain with slip noise (pooled from its
        phases, in a random order where the slip has stopped) read by a Gaussian kernel as
        wide as that noise after the low-pass, at :data:`CURVE_GRID` slips over their range;
        any other curve as it is. What the sample model, J̄2 and the figures read."""
        slip, friction = np.asarray(slip, dtype=float), np.asarray(friction, dtype=float)
        width = _filtered_noise(self.chain)
        if width == 0 or len(slip) < 2:
            return slip, friction
        grid = np.linspace(slip[0], slip[-1], CURVE_GRID)
        return grid, kernel_read(grid, np.full(CURVE_GRID, width), slip, friction)

    def residuals(self, slip: np.ndarray, friction: np.ndarray) -> np.ndarray:
        """The whitened residuals of one model curve, whose squares sum to its χ² (the
        contrasts' for ``"scatter"``, every sample's less its event's mean for ``"sample"``);
        NaN when the curve is empty."""
        slip, friction = np.asarray(slip, dtype=float), np.asarray(friction, dtype=float)
        if len(slip) < 2:
            return np.full(self.dof if self.noise == "scatter" else len(self.observed.slip),
                           np.nan)
        if self.noise == "scatter":
            return self.whiten @ (self.mean - kernel_read(self.slips, self.bandwidth, slip,
                                                          friction))
        return offset_residuals(*self.curve(slip, friction), self.observed) / self.sigma

    def j2(self, slip, friction) -> float:
        """The paper's J̄2 (Eq. 11) of one model curve: the mean over the events of each one's
        residual variance after its best offset (NaN when the curve is empty)."""
        return float(np.mean(j2_per_event(*self.curve(slip, friction), self.observed)))

    def chi2(self, slip, friction) -> float:
        """The curves' χ² of one model curve (NaN when it is empty)."""
        return float(np.sum(self.residuals(slip, friction) ** 2))

    def describe(self) -> str:
        """What the likelihood assumed, in a sentence for the output."""
        return self._noise_text() + self._chain_text()

    def _chain_text(self) -> str:
        c = self.chain
        text = ("; the model's curves as the model makes them (no measurement chain)"
                if c is None else
                f"; the model's curves through the recording's measurement chain "
                f"({c.rate_hz:g} Hz; force {c.force_hz:g} Hz, acceleration "
                f"{c.acceleration_hz:g} Hz, slip {c.slip_hz:g} Hz low-passes; timed on the slip "
                f"smoothed at {c.timing_hz:g} Hz"
                + (f"; the slip's white noise σ = {c.slip_noise:.3g} m drawn on the model's "
                   "samples" if c.slip_noise > 0 and c.slip_from == "slip column" else "")
                + ("" if c.slip_from == "slip column" else
                   "; slip integrated from accelerations: the model's slip is its own") + ")")
        if self.model_error > 0:
            text += f"; model error σ_model = {self.model_error:.3g} in μ added"
        return text

    def _noise_text(self) -> str:
        if self.noise == "sample":
            return (f"curves: {self.n_events} events, σ = {self.sigma:g} per sample (given), "
                    "independent Gaussian about the model's curve with a free offset per event "
                    f"({self.dof} degrees of freedom); no event-to-event variability")
        return (f"curves: {self.n_events} events read at {len(self.slips)} common slips from "
                f"{self.slips[0]:.3g} to {self.slips[-1]:.3g} m by a Gaussian kernel "
                f"({self.bandwidth.min():.2g}–{self.bandwidth.max():.2g} m wide), offsets "
                f"removed ({self.dof} contrasts); their covariance over the events "
                f"(Ledoit–Wolf shrinkage {self.shrinkage:.2f}) "
                + ("as the model's error (the events' spread, as σ = std)"
                   if self.reading == "std" else "÷ n (the mean curve's error, σ = sem)")
                + "; events independent, curves independent of the means")
