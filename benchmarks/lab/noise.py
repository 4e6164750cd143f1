"""The noise under a fit's residuals: white + AR(1) + a random walk, read from their variogram.

A laboratory record's noise is rarely white. Its sensors add white noise, the apparatus and the
gouge add wiggles that follow each other for a while (AR(1), correlation φ per sample), and the
record wanders slowly (a random walk, variance σ²_rw per sample). Their sum has the variogram

    γ(ℓ) = ½ E (r[i + ℓ] − r[i])² = σ²_w + σ²_a (1 − φ^ℓ) + σ²_rw ℓ/2     (ℓ ≥ 1),

which :func:`read_noise` fits to the residuals' own variogram at :data:`SHORT_LAGS` lags and
:data:`LONG_POINTS` more spaced in log up to 1/:data:`DRIFT_SPAN` of the record: a search over
the AR(1)'s correlation length 1/(1 − φ) (up to :data:`LONGEST_CORRELATION` of that span, so
that a slow wander is read as the walk and a quick one as AR(1)), and non-negative least squares
for the three variances at each (relative errors: each lag's row divided by its γ), keeping a
white or AR(1) part above 0. A record of fewer than 4 × :data:`DRIFT_SPAN` samples is read as
AR(1) of its lag-1 correlation.

What each part does to a fit's errors (:mod:`benchmarks.lab.fit`):

* white + AR(1): the variances of the parameters are (σ²_w + σ²_a (1 + φ)/(1 − φ)) (JᵀJ)⁻¹,
  the long-run variance; over the variance, the inflation
  f = (σ²_w + σ²_a (1 + φ)/(1 − φ)) / (σ²_w + σ²_a) (the variance of a mean of many samples over
  that of independent ones; (1 + ρ)/(1 − ρ) for AR(1) alone, 1 for white noise). A lag-1
  correlation alone misreads a mixture: white + AR(1) of equal parts and φ = 0.9 has ρ = 0.45,
  and (1 + ρ)/(1 − ρ) = 2.6 where f is 10.
* the walk: its correlation outlives any φ < 1, and it moves every residual after each step:
  σ²_rw B CᵀC B (:func:`drift_covariance`). It is taken as read, with no test: under white + AR(1)
  noise without a walk the reading is 0 in two records of three and small in the rest, which
  errs wide; a test of the block means (the walk taken only where they vary beyond white + AR(1)
  noise, at 1 %) missed a walk that wanders 2 σ over 10⁴ samples under AR(1) noise of φ = 0.9
  in 60 of 100 records, and a − b's 95 % interval then held the truth in 72 (the lab-fit
  study's "white + AR(1) + walk" records).

The residuals are those of the fit, whose levels and slopes per piece have taken out part of a
walk and bent its variogram: the walk's column of the fit is the variogram of a unit walk
projected off those columns (exact, from P⊥ K P⊥ with K the walk's covariance), not ℓ/2, which
would read σ²_rw low.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

__all__ = ["NoiseModel", "read_noise", "lag1", "covariance", "drift_covariance",
           "propagated_covariance", "DRIFT_SPAN",
           "SHORT_LAGS", "LONG_POINTS", "LONGEST_CORRELATION", "RANK_TOL"]

#: the variogram's lags: every one from 1 to SHORT_LAGS, then LONG_POINTS spaced in log up to
#: 1/DRIFT_SPAN of the record
SHORT_LAGS, LONG_POINTS = 16, 24
#: the longest lag read is the record's 1/DRIFT_SPAN
DRIFT_SPAN = 20
#: the AR(1)'s correlation length 1/(1 − φ) searched up to this share of the longest lag: a
#: slower wander is the walk's
LONGEST_CORRELATION = 0.1
#: correlation lengths searched
_SEARCH = 60


@dataclass(frozen=True)
class NoiseModel:
    """White + AR(1) + random-walk noise (module docstring); variances per sample, in the
    residuals' unit squared.

    Parameters
    ----------
    white : float
        σ²_w, the white part's variance.
    correlated : float
        σ²_a, the AR(1) part's variance.
    phi : float
        The AR(1) part's correlation from one sample to the next.
    walk : float
        σ²_rw, the walk's variance per sample (0: none read).
    from_variogram : bool
        False for a record too short for the variogram: AR(1) of its lag-1 correlation.
    """

    white: float = 0.0
    correlated: float = 0.0
    phi: float = 0.0
    walk: float = 0.0
    from_variogram: bool = True

    @property
    def inflation(self) -> float:
        """f, the white + AR(1) noise's long-run variance over its variance (≥ 1)."""
        total = self.white + self.correlated
        if not total > 0:
            return 1.0
        return max(self.long_run / total, 1.0)

    @property
    def long_run(self) -> float:
        """σ²_w + σ²_a (1 + φ)/(1 − φ): the white + AR(1) part's long-run variance."""
        return self.white + self.correlated * (1 + self.phi) / (1 - self.phi)

    @property
    def correlation_length(self) -> float:
        """1/(1 − φ), in samples."""
        return 1.0 / (1.0 - self.phi)

    def describe(self) -> str:
        """The model in words: how it was read, its parts, f and the walk."""
        how = "from their variogram" if self.from_variogram else \
            "from their lag-1 correlation (too short for a variogram)"
        total = self.white + self.correlated
        if self.phi == 0 or not self.correlated > 0 or not total > 0:
            # φ = 0 makes the AR(1) column the white one's: no share of it is correlated
            parts = "white noise (f = 1)"
        else:
            parts = (f"white + AR(1) ({self.correlated / total:.0%} of the variance correlated, "
                     f"φ = {self.phi:.3g}: f = {self.inflation:.3g})")
        walk = f" + a random walk of σ = {math.sqrt(self.walk):.2g} per sample" \
            if self.walk > 0 else ""
        return f"read {how} as {parts}{walk}"


def _variogram(r: np.ndarray, lags: np.ndarray) -> np.ndarray:
    return np.array([0.5 * np.mean((r[k:] - r[:-k]) ** 2) for k in lags])


#: the last walk variograms computed, by (n, lags, basis digest): a search's trials read the
#: noise of the same steady parts again
_WALK_CACHE: dict = {}


def _walk_variogram(basis: np.ndarray | None, n: int, lags: np.ndarray) -> np.ndarray:
    """:func:`_projected_walk_variogram`, remembered for the last few bases."""
    if basis is None or basis.shape[1] == 0:
        return lags / 2.0
    q = np.ascontiguousarray(basis, dtype=float)
    key = (n, lags.tobytes(), q.shape, hashlib.blake2b(q.tobytes(), digest_size=16).digest())
    if key not in _WALK_CACHE:
        if len(_WALK_CACHE) >= 64:
            _WALK_CACHE.clear()
        _WALK_CACHE[key] = _projected_walk_variogram(q, n, lags)
    return _WALK_CACHE[key].copy()


def _projected_walk_variogram(basis: np.ndarray, n: int, lags: np.ndarray) -> np.ndarray:
    """The expected variogram of a unit random walk (w[i] = η[0] + … + η[i], Cov = min + 1)
    projected off the columns of the orthonormal ``basis`` (the fit's levels and slopes take
    out part of a walk, and would bias its reading low); ℓ/2 without a basis. With
    A = K Q and G = Qᵀ K Q, P⊥ K P⊥ = K − Q Aᵀ − A Qᵀ + Q G Qᵀ, read along the lags'
    diagonals."""
    q = basis
    i = np.arange(n, dtype=float)
    # (K q)_i = Σ_j (min(i, j) + 1) q_j = Σ_{j ≤ i} (j + 1) q_j + (i + 1) Σ_{j > i} q_j
    below = np.cumsum((i + 1)[:, None] * q, axis=0)
    above = q.sum(axis=0) - np.cumsum(q, axis=0)
    a = below + (i + 1)[:, None] * above
    h = q @ (q.T @ a)
    diag = -2.0 * np.einsum("ij,ij->i", q, a) + np.einsum("ij,ij->i", h, q)
    sums = np.concatenate(([0.0], np.cumsum(diag)))
    # Σ_i (−q_i a_{i+ℓ} − a_i q_{i+ℓ} + h_i q_{i+ℓ}) for every lag ℓ at once: cross-correlations
    # by FFT, summed over the columns
    # (zero-padded to n + the longest lag: no lag wraps round; a length FFTPACK factors well)
    from scipy import fft
    lags = np.asarray(lags, dtype=int)
    size = fft.next_fast_len(n + int(lags.max(initial=0)), real=True)
    fq, fa, fh = (fft.rfft(m, size, axis=0) for m in (q, a, h))
    corr = fft.irfft((np.conj(fh - fa) * fq - np.conj(fq) * fa).sum(axis=1), size)
    count = n - lags
    mean_diag = (sums[count] + sums[n] - sums[lags]) / count
    return lags / 2.0 + 0.5 * (mean_diag - 2.0 * corr[lags] / count)


def read_noise(r: np.ndarray, basis: np.ndarray | None = None) -> NoiseModel:
    """The noise model of the residuals ``r`` (in time order), fitted to their variogram
    (module docstring); ``basis``: the orthonormal columns the fit projected off (its levels
    and slopes), by which a walk's variogram is bent. White noise for a record too short for
    its lags or not finite."""
    r = np.asarray(r, dtype=float)
    n = len(r)
    last = n // DRIFT_SPAN
    if not np.isfinite(r).all():
        return NoiseModel()
    if last < 4:                       # too short for a variogram: AR(1) of the lag-1 ρ
        return _lag1_model(r)
    short = np.arange(1, min(SHORT_LAGS, last) + 1)
    long_ = np.geomspace(min(SHORT_LAGS, last), last, LONG_POINTS).astype(int)
    lags = np.unique(np.concatenate([short, long_]))
    gamma = _variogram(r, lags)
    if not (gamma > 0).all():
        return NoiseModel()
    scale = 1.0 / gamma
    walk_column = _walk_variogram(basis, n, lags)
    best = None
    lengths = np.geomspace(1.05, max(LONGEST_CORRELATION * last, 1.1), _SEARCH)
    for phi in np.concatenate([[0.0], 1.0 - 1.0 / lengths]):
        design = np.column_stack([np.ones(len(lags)), 1.0 - phi ** lags, walk_column])
        coef, res = nnls(design * scale[:, None], gamma * scale)
        # smooth residuals (a law that misfits) can put every variance in the walk: a noise
        # of no white or AR(1) part would give the fit errors of 0
        if coef[0] + coef[1] > 0 and (best is None or res < best[0]):
            best = (res, float(phi), coef)
    if best is None:
        return _lag1_model(r)
    _, phi, (white, correlated, walk) = best
    return NoiseModel(white=float(white), correlated=float(correlated), phi=phi,
                      walk=float(walk))


def lag1(r: np.ndarray) -> float:
    """The lag-1 autocorrelation of ``r`` (0 if negative or undefined; at most 0.999)."""
    c = np.asarray(r, dtype=float) - np.mean(r)
    d = float(c @ c)
    return 0.0 if d == 0 or len(c) < 3 else float(np.clip((c[1:] @ c[:-1]) / d, 0.0, 0.999))


def _lag1_model(r: np.ndarray) -> NoiseModel:
    """AR(1) noise of the residuals' variance and lag-1 correlation: the reading of a record
    too short for a variogram."""
    return NoiseModel(correlated=float(np.var(r)), phi=lag1(r), from_variogram=False)


#: a singular value of a Jacobian or basis below this share of the largest is a direction the
#: data do not determine
RANK_TOL = 1e-10


def covariance(jac: np.ndarray, scale: float) -> np.ndarray:
    """scale · (JᵀJ)⁻¹, with an infinite variance for each parameter in a direction the data
    do not determine (a singular value of J below :data:`RANK_TOL` of the largest): a
    pseudo-inverse would give such a parameter a variance of 0."""
    n = jac.shape[1]
    if not np.isfinite(jac).all():
        return np.full((n, n), np.nan)
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    keep = sv > RANK_TOL * max(sv.max(initial=0.0), 1e-300)
    cov = (vt[keep].T / sv[keep] ** 2) @ vt[keep] * scale
    lost = (np.abs(vt[~keep]) > 1e-6).any(axis=0)
    cov[lost, :] = np.inf
    cov[:, lost] = np.inf
    return cov


def _solution_map(jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P, ok): the rows of J⁺ (the least-squares solution's map of the residuals, on the
    directions the data determine: singular values above :data:`RANK_TOL` of the largest, as
    :func:`covariance` keeps) of the parameters ``ok`` whose variance is finite. With the full
    rank P = (JᵀJ)⁻¹Jᵀ; with collinear columns the rows of P, not (JᵀJ)⁻¹ over the ok block
    times their columns, map the residuals (that product drops what the lost columns carry)."""
    ok = np.isfinite(np.diag(covariance(jac, 1.0)))
    if not ok.any():
        return np.zeros((0, jac.shape[0])), ok
    return np.linalg.pinv(jac, rcond=RANK_TOL)[ok], ok


def drift_covariance(jac: np.ndarray, variance: float) -> np.ndarray:
    """σ²_rw (P C)(P C)ᵀ over ``jac``'s columns, P the least-squares map of the residuals
    (:func:`_solution_map`; (JᵀJ)⁻¹Jᵀ at full rank) and C the walk's cumulative sums (a walk's
    step at sample j moves every residual after it: P C is the reverse cumulative sums of P's
    columns); σ²_rw B CᵀC B at full rank. 0 where the variance is not finite, and without a
    walk."""
    n = jac.shape[1]
    out = np.zeros((n, n))
    if not variance > 0:
        return out
    m, ok = _solution_map(jac)
    if not ok.any():
        return out
    mc = np.cumsum(m[:, ::-1], axis=1)[:, ::-1]
    out[np.ix_(ok, ok)] = variance * (mc @ mc.T)
    return out


def propagated_covariance(jac: np.ndarray, long_run: float, walk: float, loads=None,
                          reads=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The covariance of a least-squares fit's parameters (``jac`` the residuals' derivative,
    r = data − model) when the residuals' noise η (white +
    AR(1) of long-run variance ``long_run``, a walk of ``walk`` per sample) also made a trend
    that was taken off the data before the fit: h slopes s = R η (``reads``, h × samples)
    times their columns (``loads``, samples × h). The parameters then move by −P (I − loads R) η
    (P = J⁺, :func:`_solution_map`; (JᵀJ)⁻¹Jᵀ at full rank): the trend's error and the fit's
    own share one noise, so their variances are not summed but mapped together. Returns
    (cov over ``jac``'s columns, their covariance with the slopes, the slopes' covariance);
    without ``loads`` this is :func:`covariance` plus :func:`drift_covariance`, and the other
    two are empty."""
    p, h = jac.shape[1], 0 if loads is None else loads.shape[1]
    cov = covariance(jac, long_run)
    cross, slopes = np.full((p, h), np.nan), np.full((h, h), np.nan)
    rc = np.cumsum(reads[:, ::-1], axis=1)[:, ::-1] if h and walk > 0 else None
    if h:                                 # the slopes' own errors do not depend on J
        slopes = long_run * (reads @ reads.T) + (walk * (rc @ rc.T) if walk > 0 else 0.0)
    m, ok = _solution_map(jac)
    if not ok.any():
        return cov, cross, slopes
    if h:
        m = m - (m @ loads) @ reads
        cov[np.ix_(ok, ok)] = long_run * (m @ m.T)
    if walk > 0:
        mc = np.cumsum(m[:, ::-1], axis=1)[:, ::-1]
        cov[np.ix_(ok, ok)] += walk * (mc @ mc.T)
    if h:
        cross[ok] = -(long_run * (m @ reads.T) + (walk * (mc @ rc.T) if walk > 0 else 0.0))
    return cov, cross, slopes
    b = covariance(jac, 1.0)
    ok = np.isfinite(np.diag(b)) & np.isfinite(b).all(axis=0)
    k = jac[:, ok].T
    if h:
        k = k - (k @ loads) @ reads
    m = b[np.ix_(ok, ok)] @ k
    if h:
        cov[np.ix_(ok, ok)] = long_run * (m @ m.T)
    if walk > 0:
        mc = np.cumsum(m[:, ::-1], axis=1)[:, ::-1]
        cov[np.ix_(ok, ok)] += walk * (mc @ mc.T)
    if h:
        rc = np.cumsum(reads[:, ::-1], axis=1)[:, ::-1] if walk > 0 else None
        slopes = long_run * (reads @ reads.T) + (walk * (rc @ rc.T) if walk > 0 else 0.0)
        cross[ok] = -(long_run * (m @ reads.T) + (walk * (mc @ rc.T) if walk > 0 else 0.0))
    return cov, cross, slopes
