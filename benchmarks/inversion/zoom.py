"""A posterior that cannot be confidently wrong: the grid zoomed onto the least-squares fit, the
checks a posterior passes before it is reported, and the route that makes one.

**Why.** With precise observations (σ(ΔT)/ΔT ≈ 5e−4 or less) the posterior of (b, log10 Lc) is
a ridge along the b–Lc valley (correlation 0.999–0.9999 on W2) whose width across it is a
small fraction of the first grid's cells. The midpoint rule then gives mass only to the few
cells whose centres happen to lie on the ridge, and the refinement, which splits only the cells
that hold mass, never finds the rest: the region came out 7–40× narrower than the Gauss–Newton
one, about wherever those centres were (in a case of the issue, excluding the fit and the truth).

**The frame.** The grid is laid in the fit's own coordinates: (b, log10 Lc) = centre + scale · z,
the centre the least-squares fit, the scale the Cholesky factor of its Gauss–Newton covariance.
The grid tiles z ∈ [−:data:`HALF`, :data:`HALF`]² with n × n squares (33 × 33: 0.36 σ a cell)
and is refined as any grid (:func:`benchmarks.inversion.adaptive.grid_posterior`): the ridge is a
round blob there, resolved by the first grid whatever its width in (b, log10 Lc). A point
outside the prior box has prior zero and is not solved.

**The bend.** On the means alone the valley is also *curved*: on a settled recording its floor
(the profile of log10 Lc's b at each log10 Lc) bends away from the Gauss–Newton line by 6e−5 in
b over the box, 200 times the valley's width across (3e−7; correlation 0.99998). A linear frame
then holds a thin arc, not a blob: its refinement split 400 cells a level for six levels and
still failed, and emcee's autocorrelation time was 167 steps. So the frame follows the floor:
after the linear map, each point's b is moved by the floor's offset from the map's line at its
log10 Lc (a natural cubic spline through the profile's points with a cycle, at least
:data:`MIN_BEND_KNOTS`; a line beyond them). The linear map is the Gauss–Newton regression of b
on log10 Lc: its slope and its variance of b across (the valley's width), and log10 Lc's
variance widened to its profile interval's (width / 3.92) where that is wider (a valley longer
than the quadratic model says). Without enough profile points the frame is linear, each
parameter's standard deviation widened to its profile's. Moving b by a function of log10 Lc is
a shear: the map's Jacobian is still a constant, so a cell's mass is its likelihood times its
area in z, and the summaries are read in (b, log10 Lc) (:func:`frame_posterior`). On that
recording the bent grid passed every check at its first level (3,657 solves, 12 s).

**The checks** (:func:`check_posterior`), each recorded with its value:

* the 95 % region contains the fit: the fit lies in a cell of the 95 % highest-density set (for
  samples: fewer than 95 % of them are more likely than the fit, which is what being inside the
  highest-density region means);
* each posterior standard deviation is within :data:`SD_FACTOR` (2) of its reference: the
  Gauss–Newton one where the profile agrees with it (each end of the 95 % profile interval
  within :data:`GAUSSIAN_TOL` of its width from fit ± 1.96 σ_GN: the misfit is quadratic there,
  and for a model linear over the posterior the Gauss–Newton covariance is the posterior's
  exactly); else the range between the Gauss–Newton sd and the profile's width / 3.92 (the
  Gaussian scale of that interval; a uniform posterior cut by the box has 1.13 × it), from
  half the smaller to twice the larger. Where the misfit is not quadratic the two bracket the
  posterior's sd: a valley or a cut by the box widens the profile beyond the posterior's core,
  which Gauss–Newton describes (measured on settled recordings with their curves: the zoomed
  grid's sd 1.3–1.4 × Gauss–Newton's, 0.41–0.44 × the profile's, the truth inside). A factor 2
  leaves room for the quadrature (< 5 % on Gaussians, tests/test_curve_likelihood.py) and
  refuses the spikes of the old grid (7–40× too narrow). Without a closed profile interval
  there is no reference, and the check fails;
* a sampled posterior's chain is at least :data:`MIN_TAU_LENGTH` autocorrelation times long
  after its burn-in: its walkers start from the Gauss–Newton covariance, so a chain that has
  not moved would pass the sd check by construction;
* the grid's best cell is not beaten by a profile's point by more than the 95 % level
  (:func:`posterior_missed`);
* a zoomed grid holds the posterior: less than :data:`EDGE_MASS` of it on the frame's edge.

**The route** (:func:`posterior_route`): the zoomed grid first when the frame's area is smaller
than the prior box's (a narrow posterior, or a thin valley however long: its cells are then the
finer), else the box's grid refined from the first grid (a broad one, cut by the box: the frame
would be mostly outside it), then the other; a zoomed grid whose edge
holds mass is tried once more twice as wide; then emcee, started at the fit with its walkers
drawn from the frame's covariance. The first that passes every check is the posterior; if none
does, there is none, and the reason names each attempt's failed checks.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.adaptive import GridPosterior, grid_posterior, posterior_of_cells
from benchmarks.inversion.objectives import CHI2_95_1DOF
from benchmarks.inversion.profile import lowest_point

__all__ = ["Frame", "frame_of", "frame_posterior", "check_posterior", "reference_sd",
           "posterior_route", "Routed", "frame_map", "frame_moments", "posterior_missed",
           "HALF", "SD_FACTOR", "GAUSSIAN_TOL", "EDGE_MASS", "MIN_TAU_LENGTH", "MIN_BEND_KNOTS",
           "Z95"]

#: the frame's grid spans ± this many (widened) standard deviations
HALF = 6.0
#: a posterior standard deviation must be within this factor of its reference (docstring)
SD_FACTOR = 2.0
#: a profile end within this fraction of its interval's width of fit ± 1.96 σ_GN agrees with GN
GAUSSIAN_TOL = 0.25
#: a sampled posterior's chain after burn-in, in autocorrelation times, at least (docstring)
MIN_TAU_LENGTH = 10
#: the fewest points of the profile of log10 Lc (with a cycle) that bend a frame
MIN_BEND_KNOTS = 4
#: the largest mass on a zoomed grid's edge (inside the prior box) of a posterior it holds
EDGE_MASS = 1e-3
#: the 97.5 % quantile of the standard normal
Z95 = 1.959963984540054
_NAMES = ("b", "log10_lc")


@dataclass(frozen=True)
class Frame:
    """(b, log10 Lc) = bend(``centre`` + ``scale`` · z) over z ∈ [−``half``, ``half``]² (module
    docstring): the linear map, then each point's b moved by the valley's offset at its log10 Lc.

    Parameters
    ----------
    centre : tuple of float
        (b, log10 Lc in log10 m) of z = 0, the least-squares fit.
    scale : tuple of tuple of float
        The 2 × 2 lower-triangular map, a Cholesky factor of the (widened) covariance.
    half : float
        The grid's half-width in z (standard deviations).
    bend : tuple or None
        ``(log10 Lc knots, b offsets)``: where the profile of log10 Lc found the valley's floor,
        less the linear map's line there (a natural cubic spline through them, continued as a
        line beyond the ends); None: a linear frame.
    """

    centre: tuple
    scale: tuple
    half: float = HALF
    bend: tuple | None = None

    def offset(self, log10_lc, derivative: int = 0) -> np.ndarray:
        """The bend's offset in b (or its ``derivative``-th derivative) at ``log10_lc``."""
        log10_lc = np.asarray(log10_lc, dtype=float)
        if self.bend is None:
            return np.zeros_like(log10_lc)
        from scipy.interpolate import CubicSpline
        knots, values = (np.asarray(v, dtype=float) for v in self.bend)
        spline = CubicSpline(knots, values, bc_type="natural")
        lo, hi = knots[0], knots[-1]
        inner = spline(np.clip(log10_lc, lo, hi), derivative)
        if derivative == 0:          # a line beyond the knots (the natural end has no curvature)
            return (inner + np.minimum(log10_lc - lo, 0.0) * spline(lo, 1)
                    + np.maximum(log10_lc - hi, 0.0) * spline(hi, 1))
        if derivative == 1:
            return np.where(log10_lc < lo, spline(lo, 1),
                            np.where(log10_lc > hi, spline(hi, 1), inner))
        return np.where((log10_lc < lo) | (log10_lc > hi), 0.0, inner)

    def to_x(self, z) -> np.ndarray:
        """(b, log10 Lc) of points ``z`` (shape (n, 2))."""
        x = np.asarray(self.centre) + np.atleast_2d(z) @ np.asarray(self.scale).T
        if self.bend is not None:
            x[:, 0] += self.offset(x[:, 1])
        return x

    def to_z(self, x) -> np.ndarray:
        """The frame's coordinates of points ``x`` = (b, log10 Lc) (shape (n, 2))."""
        x = np.array(np.atleast_2d(x), dtype=float)
        if self.bend is not None:
            x[:, 0] -= self.offset(x[:, 1])
        return np.linalg.solve(np.asarray(self.scale), (x - np.asarray(self.centre)).T).T

    def reach(self, z) -> np.ndarray:
        """The extents in b and in log10 Lc of a unit square of the frame about each point ``z``
        (shape (n, 2)): the map's Jacobian there, its rows' absolute sums."""
        scale = np.asarray(self.scale)
        slope = self.offset(self.to_x(z)[:, 1], 1)
        return np.column_stack([np.abs(scale[0] + slope[:, None] * scale[1]).sum(axis=1),
                                np.full(len(slope), np.abs(scale[1]).sum())])

    def extent(self) -> np.ndarray:
        """The half-widths in b and in log10 Lc of the frame's grid (its edge mapped)."""
        t = np.linspace(-self.half, self.half, 201)
        h = np.full_like(t, self.half)
        edge = np.concatenate([np.column_stack(p) for p in ((t, h), (t, -h), (h, t), (-h, t))])
        return np.abs(self.to_x(edge) - np.asarray(self.centre)).max(axis=0)

    def area(self) -> float:
        """The area of the frame's grid in (b, log10 Lc) (the map's Jacobian is a constant)."""
        return float((2 * self.half) ** 2 * abs(np.linalg.det(np.asarray(self.scale))))

    def widened(self, factor: float) -> "Frame":
        """The frame with its grid ``factor`` times as wide."""
        return Frame(self.centre, self.scale, self.half * factor, self.bend)


def frame_of(fit, profiles=None, bend: bool = True) -> Frame | None:
    """The frame of a least-squares ``fit`` (module docstring): bent along the valley that the
    profile of log10 Lc found (``bend`` and at least :data:`MIN_BEND_KNOTS` of its points with a
    cycle), its log10 Lc widened to that profile's interval and b across the valley as
    Gauss–Newton's; else linear, each standard deviation widened to its profile's interval.
    None when the fit failed or its covariance is not a finite positive-definite matrix (a flat
    direction)."""
    cov = np.asarray(fit.covariance, dtype=float)
    if not (np.isfinite(fit.misfit) and np.isfinite(cov).all()):
        return None
    sd = np.sqrt(np.abs(np.diag(cov)))
    widen = np.ones(2)
    for k, name in enumerate(_NAMES):
        p = (profiles or {}).get(name)
        if p is not None and np.isfinite([p.low, p.high]).all() and sd[k] > 0:
            widen[k] = max(1.0, (p.high - p.low) / (2 * Z95) / sd[k])
    centre = (float(fit.b), float(np.log10(fit.lc)))
    valley = _valley(centre, cov, (widen[1] * sd[1]) ** 2,
                     (profiles or {}).get("log10_lc")) if bend else None
    target, knots = valley if valley is not None else (
        widen[:, None] * cov * widen[None, :], None)
    try:
        scale = np.linalg.cholesky(target)
    except np.linalg.LinAlgError:
        return None
    if not (np.isfinite(scale).all() and (np.diag(scale) > 0).all()):
        return None
    return Frame(centre, tuple(map(tuple, scale.tolist())), bend=knots)


def _valley(centre, cov: np.ndarray, var_lc: float, profile) -> tuple | None:
    """The bent frame's covariance and bend (module docstring), or None: the Gauss–Newton
    regression of b on log10 Lc (its slope, and its variance of b across it: det / var), log10
    Lc's variance ``var_lc``, and the offsets of the profile's valley floor from that line."""
    if profile is None or not cov[1, 1] > 0:
        return None
    t = profile.table
    t = t[np.isfinite(t.misfit) & np.isfinite(t.b)].drop_duplicates("log10_lc")
    if len(t) < MIN_BEND_KNOTS:
        return None
    slope, across = cov[0, 1] / cov[1, 1], np.linalg.det(cov) / cov[1, 1]
    if not across > 0:
        return None
    knots = t.log10_lc.to_numpy(dtype=float)
    offsets = t.b.to_numpy(dtype=float) - (centre[0] + slope * (knots - centre[1]))
    target = np.array([[across + slope ** 2 * var_lc, slope * var_lc], [slope * var_lc, var_lc]])
    return target, (tuple(knots.tolist()), tuple(offsets.tolist()))


class _InFrame:
    """``misfit`` in a frame's coordinates, for :func:`grid_posterior`: ``evaluate(z_b,
    10 ** z_log10_lc)`` solves at centre + scale · z; a point outside the prior ``box`` (b,
    log10 Lc) has prior zero and is not solved."""

    def __init__(self, misfit, frame: Frame, box):
        self.misfit, self.frame = misfit, frame
        self.lo, self.hi = np.array([box[0][0], box[1][0]]), np.array([box[0][1], box[1][1]])

    @property
    def failures(self) -> dict:
        """The wrapped misfit's counts of failed solves."""
        return getattr(self.misfit, "failures", {})

    def evaluate(self, z_b, z_lc, progress: bool = False) -> pd.DataFrame:
        """The misfit, log-likelihood and retcode at each point of the frame."""
        x = self.frame.to_x(np.column_stack([np.ravel(z_b), np.log10(np.ravel(z_lc))]))
        inside = ((x >= self.lo) & (x <= self.hi)).all(axis=1)
        out = pd.DataFrame({"misfit": np.full(len(x), np.inf),
                            "log_likelihood": np.full(len(x), -np.inf),
                            "retcode": np.full(len(x), "Success", dtype=object)})
        if inside.any():
            t = self.misfit.evaluate(x[inside, 0], 10.0 ** x[inside, 1], progress=progress)
            for column in out:
                if column in t:
                    out.loc[inside, column] = t[column].to_numpy()
        return out


def frame_posterior(misfit, frame: Frame, b_range, lc_range, n: int = 33,
                    progress: bool = False, say=None) -> tuple[GridPosterior, float]:
    """The grid posterior in ``frame`` within the prior box ``b_range`` × ``lc_range`` (Lc in
    m), refined (:func:`benchmarks.inversion.adaptive.grid_posterior`), and the mass on the
    frame's edge.

    Parameters
    ----------
    misfit : Misfit
        Or any object with ``evaluate(b, lc, progress=...)`` (as :func:`grid_posterior`).
    frame : Frame
        Where the grid lies.
    b_range, lc_range : tuple of float
        The prior box: b (dimensionless) and Lc (m).
    n : int
        The first grid's squares along each side of the frame.
    progress : bool
        Show the ensembles' progress.
    say : callable or None
        Given a line of text as each level starts.

    Returns
    -------
    posterior : GridPosterior
        Its cells' centres and extents in (b, log10 Lc), their squares in the frame (``z_b``,
        ``z_log10_lc``, ``width_z``), ``frame`` set.
    edge_mass : float
        The posterior mass in the cells on the frame's edge.
    """
    box = (tuple(b_range), (float(np.log10(lc_range[0])), float(np.log10(lc_range[1]))))
    k = frame.half
    square = (_InFrame(misfit, frame, box), (-k, k), (10.0 ** -k, 10.0 ** k))
    first = grid_posterior(*square, n=n, progress=progress, say=say, refine=False)
    # a first grid whose edge already holds mass: the frame is too small, and refining it would
    # only be thrown away (on a settled recording with its curves, 4,000 of 13,700 solves)
    inner = first if not first.ok or first.edge_mass > EDGE_MASS else grid_posterior(
        *square, n=n, progress=progress, say=say, first=first)
    c = inner.cells
    z = c[["b", "log10_lc"]].to_numpy()
    x = frame.to_x(z)
    reach = frame.reach(z)                                 # a square's extent per unit side
    w = c.width_b.to_numpy()                               # the squares' side in z
    cells = c.drop(columns="mass").assign(
        z_b=z[:, 0], z_log10_lc=z[:, 1], width_z=w, b=x[:, 0], log10_lc=x[:, 1],
        width_b=w * reach[:, 0], width_log10_lc=w * reach[:, 1])
    post = posterior_of_cells(cells, box, levels=inner.levels, settled=inner.settled,
                              history=inner.history, n_solves=inner.n_solves,
                              n_failed=inner.n_failed, wall_s=inner.wall_s,
                              frame=frame)
    return post, float(inner.edge_mass)


def reference_sd(fit, profiles) -> tuple[dict, dict]:
    """Each parameter's allowed range of posterior standard deviation before the factor, as
    ``(low, high)``, and where it came from (module docstring): ``"Gauss-Newton"`` where the
    profile agrees with it (low = high = σ_GN), else ``"Gauss-Newton–profile"`` (σ_GN and the
    profile's 95 % interval width / 3.92, in order; NaN without a closed interval)."""
    x = {"b": fit.b, "log10_lc": float(np.log10(fit.lc)) if fit.lc > 0 else np.nan}
    gn = {"b": fit.sigma_b, "log10_lc": fit.sigma_log10_lc}
    sd, source = {}, {}
    for name in _NAMES:
        p = profiles.get(name)
        finite = p is not None and np.isfinite([p.low, p.high]).all()
        g = float(gn[name]) if np.isfinite(gn[name]) and gn[name] > 0 else np.nan
        if finite and _agrees(p, x[name], gn[name]):
            sd[name], source[name] = (g, g), "Gauss-Newton"
        elif finite:
            prof = float((p.high - p.low) / (2 * Z95))
            both = [v for v in (g, prof) if np.isfinite(v)]
            sd[name], source[name] = (min(both), max(both)), "Gauss-Newton–profile"
        else:
            sd[name], source[name] = (np.nan, np.nan), "profile"
    return sd, source


def _agrees(p, x: float, s: float) -> bool:
    """Whether profile ``p``'s interval is fit ``x`` ± 1.96 ``s`` within GAUSSIAN_TOL of its
    width at each end (and closed)."""
    if not (np.isfinite(s) and s > 0) or p.open_low or p.open_high:
        return False
    half = Z95 * s
    tol = GAUSSIAN_TOL * 2 * half
    return abs(p.low - (x - half)) <= tol and abs(p.high - (x + half)) <= tol


def check_posterior(post, fit, profiles, edge_mass: float = float("nan")) -> dict:
    """The checks of the module docstring on a grid posterior or a sampled one, each with its
    value; ``passed``: all of them; ``failed``: the failed ones in words.

    Parameters
    ----------
    post : GridPosterior or Posterior
        The posterior (a sampled one's samples carry ``log_likelihood``).
    fit : FitResult
        The least-squares fit, with its Gauss–Newton covariance.
    profiles : dict
        The profiles of ``b`` and ``log10_lc``.
    edge_mass : float
        The mass on a zoomed grid's edge (NaN: not a zoomed grid).

    Returns
    -------
    dict
    """
    ref, source = reference_sd(fit, profiles)
    gn = {"b": fit.sigma_b, "log10_lc": fit.sigma_log10_lc}
    ratio = {k: float(post.std[k] / gn[k]) if gn[k] > 0 else np.nan for k in _NAMES}
    x = {"b": fit.b, "log10_lc": float(np.log10(fit.lc))}
    grid = isinstance(post, GridPosterior)
    inside = _fit_in_hpd(post, x) if grid else _fit_more_likely(post, fit)
    intervals = _intervals(post)
    missed = posterior_missed(post.best[2], profiles) if grid else ""
    failed = []
    if not inside:
        failed.append("the 95 % region does not contain the least-squares fit")
    for k in _NAMES:
        lo, hi = ref[k]
        if not lo / SD_FACTOR <= post.std[k] <= hi * SD_FACTOR:
            failed.append(f"sd of {k} is {post.std[k]:.3g}, outside {lo / SD_FACTOR:.3g}–"
                          f"{hi * SD_FACTOR:.3g} ({_said(lo, hi, source[k])} within "
                          f"{SD_FACTOR:g} ×)")
    short = _short_chain(post) if not grid else ""
    if short:
        failed.append(short)
    if missed:
        failed.append(missed)
    if edge_mass > EDGE_MASS:
        failed.append(f"{edge_mass:.2g} of the mass on the zoomed grid's edge (at most "
                      f"{EDGE_MASS:g})")
    return {"passed": not failed, "failed": failed, "fit_in_region": bool(inside),
            "fit_in_intervals": {k: bool(intervals[k][0] <= x[k] <= intervals[k][1])
                                 for k in _NAMES},
            "sd_ratio": ratio, "sd_reference": ref, "sd_reference_source": source,
            "chain_too_short": bool(short),
            "sd_factor": SD_FACTOR, "best_cell_missed": bool(missed),
            "zoom_edge_mass": edge_mass}


def _said(lo: float, hi: float, source: str) -> str:
    """The reference range of an sd check in words."""
    if source == "Gauss-Newton":
        return f"the Gauss-Newton sd {lo:.3g}"
    if source == "profile":
        return "no closed profile interval: no reference"
    return f"between the Gauss-Newton sd and the profile's, {lo:.3g}–{hi:.3g},"


def _short_chain(post) -> str:
    """Why a sampled posterior's chain is too short to be read (:data:`MIN_TAU_LENGTH`), or
    ""."""
    tau = max(post.tau.values())
    if np.isfinite(tau) and post.kept >= MIN_TAU_LENGTH * tau:
        return ""
    what = f"{tau:.1f} steps" if np.isfinite(tau) else "not estimable"
    return (f"the chain is {post.kept} steps after burn-in, its autocorrelation time {what}: "
            f"at least {MIN_TAU_LENGTH} times that is needed (more --steps)")


def posterior_missed(cell_misfit: float, profiles: dict) -> str:
    """Why a grid posterior is not to be read, or "": its best cell's misfit is higher, by more
    than the 95 % level, than a point one of the profiles found. Its mass then lies about a
    point the data reject against that one: a posterior narrower than the grid's cells, whose
    cell with the best fit was never refined (one of the checks of
    :func:`benchmarks.inversion.zoom.check_posterior`)."""
    found = lowest_point(profiles)
    if found is None or not np.isfinite(cell_misfit):
        return ""
    lowest, at, p = found
    if cell_misfit - lowest <= CHI2_95_1DOF:
        return ""
    return (f"the grid posterior missed the best fit: its best cell has misfit "
            f"{cell_misfit:.4g}, but the profile of {p.parameter} found {lowest:.4g} at "
            f"b = {at['b']:.6g}, log10 Lc = {at['log10_lc']:.4g}: the posterior is narrower than "
            f"the grid's cells and its mass lies elsewhere")



def _intervals(post) -> dict:
    """The 95 % marginal intervals of a grid posterior or of samples."""
    if isinstance(post, GridPosterior):
        return post.interval
    q = post.samples[list(_NAMES)].quantile([0.025, 0.975])
    return {k: (float(q[k].iloc[0]), float(q[k].iloc[1])) for k in _NAMES}


def _fit_in_hpd(post: GridPosterior, x: dict) -> bool:
    """Whether the point ``x`` lies in a cell of the 95 % highest-density set."""
    c = post.cells[np.ravel(post.hpd)]
    if post.frame is not None:
        z = post.frame.to_z([x["b"], x["log10_lc"]])[0]
        d = np.abs(c[["z_b", "z_log10_lc"]].to_numpy() - z)
        half = np.repeat(c.width_z.to_numpy()[:, None] / 2, 2, axis=1)
    else:
        d = np.abs(c[list(_NAMES)].to_numpy() - [x["b"], x["log10_lc"]])
        half = c[["width_b", "width_log10_lc"]].to_numpy() / 2
    return bool((d <= half * (1 + 1e-9)).all(axis=1).any())


def _fit_more_likely(post, fit) -> bool:
    """Samples: fewer than 95 % of them more likely than the fit (it is in the 95 % HPD)."""
    if "log_likelihood" not in post.samples:
        return False
    return bool(np.mean(post.samples.log_likelihood.to_numpy() > -fit.misfit / 2) < 0.95)


@dataclass
class Routed:
    """What :func:`posterior_route` made: the posterior (None when every attempt failed), the
    route that made it (``"zoomed grid"``, ``"box grid"``, ``"sampler"``), its checks, every
    attempt's route and checks, and why there is none.

    Parameters
    ----------
    posterior : GridPosterior or Posterior or None
        The first posterior that passed every check.
    route : str
        Its route ("" without one).
    checks : dict
        Its checks (:func:`check_posterior`; {} without one).
    attempts : list of dict
        Each attempt: ``route``, ``frame_half`` (zoomed grids), ``wall_s`` and its checks.
    reason : str
        Without a posterior: each attempt's failed checks, in words.
    """

    posterior: object
    route: str
    checks: dict = field(default_factory=dict)
    attempts: list = field(default_factory=list)
    reason: str = ""


def posterior_route(misfit, b_range, lc_range, fit, profiles, first: GridPosterior | None,
                    n: int = 33, sampler: dict | None = None, grid: bool = True,
                    progress: bool = False, say=None) -> Routed:
    """The posterior by the route of the module docstring.

    Parameters
    ----------
    misfit : Misfit
        The objective.
    b_range, lc_range : tuple of float
        The prior box: b (dimensionless) and Lc (m).
    fit : FitResult
        The least-squares fit with its Gauss–Newton covariance.
    profiles : dict
        The profiles of ``b`` and ``log10_lc``.
    first : GridPosterior or None
        The box's first grid, unrefined (the box grid refines it).
    n : int
        The first grid's cells along each side (of the box, and of a frame).
    sampler : dict or None
        ``walkers``, ``steps``, ``seed`` of emcee (None: no sampler).
    grid : bool
        Try the grids (False: the sampler alone, ``--method emcee``).
    progress : bool
        Show the ensembles' progress.
    say : callable or None
        Given a line of text as each attempt starts.

    Returns
    -------
    Routed
    """
    say = say or (lambda text: None)
    frame = frame_of(fit, profiles)
    box = (b_range, (np.log10(lc_range[0]), np.log10(lc_range[1])))
    routes = []
    if grid and first is not None and first.ok:
        narrow = frame is not None and frame.area() < np.prod(np.diff(box, axis=1))
        routes = ["zoomed grid", "box grid"] if narrow else ["box grid"]
        routes += ["zoomed grid"] if frame is not None and not narrow else []
    if sampler and np.isfinite(fit.misfit):
        routes.append("sampler")
    attempts = []
    for route in routes:
        for post, checks, record in _attempt(route, misfit, (b_range, lc_range), fit, profiles,
                                             (first, frame, n), sampler, progress, say):
            attempts.append({**record, **checks})
            if checks["passed"]:
                return Routed(post, route, checks, attempts)
    reason = "; ".join(f"{a['route']}: {', '.join(a['failed'])}" for a in attempts)
    return Routed(None, "", {}, attempts, reason or "no route to try (no fit, no first grid)")


def _attempt(route, misfit, box, fit, profiles, grids, sampler, progress, say):
    """The posterior of one route and its checks (a zoomed grid whose edge holds mass: again,
    twice as wide), as ``(posterior, checks, record)``."""
    first, frame, n = grids
    started = time.perf_counter()
    if route == "box grid":
        say("grid posterior over the box, refined where its mass is")
        post = grid_posterior(misfit, *box, n=n, progress=progress, say=say, first=first)
        yield post, check_posterior(post, fit, profiles), {
            "route": route, "wall_s": time.perf_counter() - started}
    elif route == "zoomed grid":
        for f in (frame, frame.widened(2.0)):
            say(f"grid posterior zoomed on the fit (± {f.half:g} σ of its frame)")
            post, edge = frame_posterior(misfit, f, *box, n=n, progress=progress, say=say)
            checks = check_posterior(post, fit, profiles, edge)
            yield post, checks, {"route": route, "frame_half": f.half,
                                 "wall_s": time.perf_counter() - started}
            if checks["passed"] or edge <= EDGE_MASS:
                return
            started = time.perf_counter()
    else:
        from benchmarks.inversion.posterior import sample
        cov = None if frame is None else np.asarray(frame.scale) @ np.asarray(frame.scale).T
        say(f"posterior: {sampler['walkers']} walkers × {sampler['steps']} steps from the fit")
        post = sample(misfit, *box, _inside((fit.b, fit.lc), box), walkers=sampler["walkers"],
                      steps=sampler["steps"], seed=sampler["seed"], progress=progress, cov=cov)
        yield post, check_posterior(post, fit, profiles), {
            "route": route, "wall_s": time.perf_counter() - started}


def _inside(point, box) -> tuple:
    """``point`` (b, Lc in m) moved a hair inside the box (a fit may sit on its edge)."""
    lo = np.array([box[0][0], np.log10(box[1][0])])
    hi = np.array([box[0][1], np.log10(box[1][1])])
    x = np.clip([point[0], np.log10(point[1])], lo + 1e-6 * (hi - lo), hi - 1e-6 * (hi - lo))
    return float(x[0]), float(10.0 ** x[1])


def frame_map(problem, algorithm, frame: Frame, b_range, lc_range, n: int,
              wall_budget: float | None = None, workers: int | None = None):
    """The limit-cycle metrics at the centres of ``n`` × ``n`` equal squares tiling the frame's
    grid: a :class:`~benchmarks.inversion.grid.MetricMap` whose axes are the frame's z (its
    ``b`` and ``log10_lc`` hold z_b and z_log10_lc), so that its posterior of any observations is
    the frame's fixed grid posterior, on the same nodes for every algorithm (mass, overlap and
    highest-density set as in (b, log10 Lc): the map is linear; :func:`frame_moments` reads the
    mean and sd back). A node outside the prior box ``b_range`` × ``lc_range`` (Lc in m) is not
    solved and has no cycle (``"outside the box"``).

    Parameters
    ----------
    problem : SpringSlider
        The forward problem.
    algorithm : Algorithm
        The forward solver and its options.
    frame : Frame
        Where the grid lies.
    b_range, lc_range : tuple of float
        The prior box: b (dimensionless) and Lc (m).
    n : int
        Nodes along each side, at least 2.
    wall_budget : float, optional
        Each forward solve's wall-time budget (s).
    workers : int, optional
        Threads (or processes) of the ensemble.

    Returns
    -------
    MetricMap
    """
    from benchmarks.ensemble import ensemble
    from benchmarks.inversion.adaptive import centres
    from benchmarks.inversion.grid import MetricMap
    from benchmarks.physics.metrics import CYCLES
    z = centres(-frame.half, frame.half, n)
    zz = np.stack(np.meshgrid(z, z, indexing="ij"), axis=-1).reshape(-1, 2)
    x = frame.to_x(zz)
    lo = np.array([b_range[0], np.log10(lc_range[0])])
    hi = np.array([b_range[1], np.log10(lc_range[1])])
    inside = ((x >= lo) & (x <= hi)).all(axis=1)
    metrics = {"recurrence_s": np.full(len(x), np.nan), "friction_drop": np.full(len(x), np.nan)}
    cls = np.full(len(x), "outside the box", dtype=object)
    cost = {"n_failed": 0, "nfev": 0, "wall_s": 0.0}
    started = time.perf_counter()
    if inside.any():
        t = ensemble(problem, algorithm, {"b": x[inside, 0], "lc": 10.0 ** x[inside, 1]},
                     wall_budget=wall_budget, workers=workers)
        for k in metrics:
            metrics[k][inside] = t[k].to_numpy()
        cls[inside] = t.classification.to_numpy()
        cost = {"n_failed": int((t.retcode != "Success").sum()), "nfev": int(t.nfev.sum()),
                "wall_s": float(t.wall_s.sum())}
    cycle = np.isin(cls, list(CYCLES))
    return MetricMap(b=z, log10_lc=z.copy(), **{
        k: np.where(cycle, v, np.nan).reshape(n, n) for k, v in metrics.items()},
        cycle=cycle.reshape(n, n), classification=cls.reshape(n, n), algorithm=algorithm.name,
        n_solves=int(inside.sum()), run_wall_s=time.perf_counter() - started, **cost)


def frame_moments(post: GridPosterior, frame: Frame) -> tuple[dict, dict]:
    """The mean and standard deviation of b and log10 Lc of a posterior on a frame's grid whose
    cells are in the frame's z (:func:`frame_map`), as midpoint moments in (b, log10 Lc)."""
    m = post.cells.mass.to_numpy()
    x = frame.to_x(post.cells[["b", "log10_lc"]].to_numpy())
    mean = np.sum(m[:, None] * x, axis=0)
    sd = np.sqrt(np.maximum(np.sum(m[:, None] * (x - mean) ** 2, axis=0), 0.0))
    return dict(zip(_NAMES, map(float, mean))), dict(zip(_NAMES, map(float, sd)))
