"""The fitting functions of a (b, Lc) inversion: J1, J2 and J (Urata et al. 2017, Eqs. 10–12).

    J1 = (ΔTsy − ΔT̄)²/σT² + (Δμsy − Δμ̄)²/σμ²           95 % region: J1 ≤ 5.99146 (χ², 2 dof)
    J2(i) = min over μ0 of Σj (μsy(i, j) − μob(i, j))² / Nj(i)
    J̄2 = mean of J2(i) over the observed events i
    J = J1 + (α1/α2) J̄2                                  possible range: J ≤ 2 α1

α1 is the mean J1 over the grid points inside the 95 % region. α2 is the mean J̄2 over the points
whose J̄2 is below min(J̄2 + σJ), σJ being the standard deviation of J2(i) over the events of
one simulation. The paper's sentence ("J̄2 less than the minimum value of J̄2 + σJ in all
simulations") is read here as the minimum over simulations of J̄2 + σJ.

J1 is the one likelihood of every inversion (Gaussian errors of the stated σ: log L = −J1/2).
A point **without a limit cycle** (failed, not converged, too short, stable sliding, an
oscillation that never locks) cannot make the observed events; :func:`scores` says so three ways,
each for its reader: NaN in a table (``j1``: in no region), a finite penalty for least squares
(``penalised``, ``j1_penalised``: each residual :data:`NO_CYCLE_RESIDUAL` σ, far above any
point that makes stick–slip, so a fit can step away) and −inf for a sampler or a grid posterior
(``log_likelihood``).

The curves J2 compares are those of :mod:`benchmarks.physics.curves`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pandas as pd

__all__ = ["CHI2_95_2DOF", "NO_CYCLE_RESIDUAL", "NO_CYCLE_J1", "Scores", "scores",
           "EventSamples", "event_samples", "offset_residuals", "j2_per_event", "JointFit",
           "joint_fit", "Total", "total", "CHI2_95_1DOF"]

#: the 95 % quantile of χ² with two degrees of freedom: the paper's J1 threshold
CHI2_95_2DOF = 5.99146
#: the 95 % quantile of χ² with one degree of freedom: the level of every profile interval
#: (−2 Δ log L ≤ 3.84, Wilks), the stick–slip inversion's and the laboratory fit's
CHI2_95_1DOF = 3.841458820694124
#: the residual (in σ) of each observation at a point without a limit cycle, for least squares
NO_CYCLE_RESIDUAL = 1e3
#: J1 of a point without a limit cycle, for least squares (both residuals NO_CYCLE_RESIDUAL)
NO_CYCLE_J1 = 2.0 * NO_CYCLE_RESIDUAL ** 2


class Scores(NamedTuple):
    """Eq. 10 at a set of points (module docstring): the residuals (ΔT − ΔT̄)/σT and
    (Δμ − Δμ̄)/σμ, NaN where ``cycle`` is False.

    Parameters
    ----------
    r_recurrence : numpy.ndarray
        (ΔT − ΔT̄)/σT at each point (dimensionless, in σ); NaN without a limit cycle.
    r_drop : numpy.ndarray
        (Δμ − Δμ̄)/σμ at each point (dimensionless, in σ); NaN without a limit cycle.
    cycle : numpy.ndarray
        Whether each point has a limit cycle (bool), of the residuals' shape.
    """

    r_recurrence: np.ndarray
    r_drop: np.ndarray
    cycle: np.ndarray

    @property
    def j1(self) -> np.ndarray:
        """J1; NaN without a limit cycle (a table's view: in no region)."""
        return self.r_recurrence ** 2 + self.r_drop ** 2

    @property
    def penalised(self) -> tuple[np.ndarray, np.ndarray]:
        """The residuals, :data:`NO_CYCLE_RESIDUAL` without a limit cycle (least squares)."""
        return tuple(np.where(self.cycle, r, NO_CYCLE_RESIDUAL)
                     for r in (self.r_recurrence, self.r_drop))

    @property
    def j1_penalised(self) -> np.ndarray:
        """J1; :data:`NO_CYCLE_J1` without a limit cycle (least squares, profiles)."""
        return np.where(self.cycle, self.j1, NO_CYCLE_J1)

    @property
    def log_likelihood(self) -> np.ndarray:
        """−J1/2; −inf without a limit cycle (a sampler, a grid posterior)."""
        return np.where(self.cycle, -0.5 * self.j1, -np.inf)


def scores(recurrence_s, friction_drop, cycle, obs) -> Scores:
    """Eq. 10 of points with limit-cycle metrics ``recurrence_s``, ``friction_drop`` (arrays
    of one shape; a point scores only where ``cycle``) against ``obs`` (an
    :class:`~benchmarks.inversion.observations.Observations`: means and positive σ).

    Parameters
    ----------
    recurrence_s : array_like
        Each point's recurrence interval ΔT (s); read only where ``cycle``.
    friction_drop : array_like
        Each point's friction drop Δμ (dimensionless), of ``recurrence_s``' shape.
    cycle : array_like of bool
        Whether each point has a limit cycle.
    obs : Observations
        The observed means ΔT̄ (s) and Δμ̄ (dimensionless) and their σ (with the model's
        error, when it has one: σ² = σ_obs² + σ_model², ``Observations.sigmas``).

    Returns
    -------
    Scores
        The residuals in σ, NaN where ``cycle`` is False, and ``cycle``.
    """
    cycle = np.asarray(cycle, dtype=bool)
    sigma_t, sigma_mu = getattr(obs, "sigmas", (obs.sigma_recurrence_s, obs.sigma_friction_drop))
    residual = [np.where(cycle, (np.asarray(x, dtype=float) - mean) / sigma, np.nan)
                for x, mean, sigma in ((recurrence_s, obs.recurrence_s, sigma_t),
                                       (friction_drop, obs.friction_drop, sigma_mu))]
    return Scores(*residual, cycle)


class Total(NamedTuple):
    """−2 log L (up to a constant) at a set of points, from :func:`total`."""

    #: the curves' χ²: 0 without curves in the likelihood, NaN without a cycle or its curve
    chi2_curves: np.ndarray
    #: J1 + χ²_curves; :data:`NO_CYCLE_J1` without a cycle or its curve (least squares)
    misfit: np.ndarray
    #: −misfit/2; −inf without a cycle or its curve (a sampler, a grid posterior)
    log_likelihood: np.ndarray


def total(s: Scores, likelihood=None, curve_slip=(), curve_friction=()) -> Total:
    """J1 of the scored points ``s`` plus the curves' χ² under ``likelihood`` (a
    :class:`~benchmarks.inversion.curve_likelihood.CurveLikelihood`, or None: no curves) of
    each point's model curve (``curve_slip``, ``curve_friction``: one array per point, flat in
    the order of ``s.cycle.ravel()``). A cycle whose curve is missing or empty has no χ² and
    scores as a point without a cycle."""
    cycle = s.cycle.ravel()
    chi2 = np.where(cycle, 0.0, np.nan)
    if likelihood is not None:
        chi2 = np.array([likelihood.chi2(x, y) if c else np.nan
                         for c, x, y in zip(cycle, curve_slip, curve_friction)])
    chi2 = chi2.reshape(s.cycle.shape)
    misfit = s.j1 + chi2
    ok = np.isfinite(misfit)
    return Total(np.where(ok, chi2, np.nan), np.where(ok, misfit, NO_CYCLE_J1),
                 np.where(ok, -0.5 * misfit, -np.inf))


class EventSamples(NamedTuple):
    """Every sample of observed curves, flat: its ``slip``, ``friction`` and ``event`` (the
    events indexed in the order they first appear, each one's samples by increasing slip), and
    the events' ``sizes``."""

    slip: np.ndarray
    friction: np.ndarray
    event: np.ndarray
    sizes: np.ndarray


def event_samples(observed: pd.DataFrame) -> EventSamples:
    """The samples of ``observed`` curves (columns ``event_id``, ``slip_m``, ``friction``)."""
    events = [g.sort_values("slip_m") for _, g in observed.groupby("event_id", sort=False)]
    event = np.concatenate([np.full(len(g), i) for i, g in enumerate(events)])
    return EventSamples(np.concatenate([g.slip_m.to_numpy() for g in events]),
                        np.concatenate([g.friction.to_numpy() for g in events]), event,
                        np.bincount(event))


def offset_residuals(curve_slip: np.ndarray, curve_friction: np.ndarray,
                     samples: EventSamples) -> np.ndarray:
    """μsy − μob at every observed sample, less its event's mean: the residuals after each
    event's best offset μ0 (Eq. 11's minimum, in closed form)."""
    r = np.interp(samples.slip, curve_slip, curve_friction) - samples.friction
    return r - (np.bincount(samples.event, r) / samples.sizes)[samples.event]


def j2_per_event(curve_slip: np.ndarray, curve_friction: np.ndarray,
                 observed: pd.DataFrame | EventSamples) -> np.ndarray:
    """Eq. 11: J2(i) for each observed event i (``observed``: the curves, or their
    :func:`event_samples` when one set is scored against many curves) against one synthetic
    curve: the variance of its residuals after the best offset. NaN for every event if there
    is no curve."""
    samples = observed if isinstance(observed, EventSamples) else event_samples(observed)
    curve_slip = np.asarray(curve_slip, dtype=float)
    if len(curve_slip) < 2:
        return np.full(len(samples.sizes), np.nan)
    r = offset_residuals(curve_slip, np.asarray(curve_friction, dtype=float), samples)
    return np.bincount(samples.event, r * r) / samples.sizes


class JointFit(dict):
    """Result of :func:`joint_fit`: columns to add to a sweep table, and the weights α1, α2."""


def joint_fit(J1: np.ndarray, J2_mean: np.ndarray | None = None,
              J2_std: np.ndarray | None = None) -> JointFit:
    """Region, weights, J and the possible range over a grid of points (Eq. 12).

    Without slip-weakening curves (``J2_mean`` None) only the J1 region is returned. Points with
    NaN J1 (stable sliding, failures) are outside every region.
    """
    J1 = np.asarray(J1, dtype=float)
    in_region = J1 <= CHI2_95_2DOF
    fit = JointFit(in_region=in_region, alpha1=float(J1[in_region].mean()) if in_region.any()
                   else np.nan)
    if J2_mean is None:
        return fit
    J2_mean, J2_std = np.asarray(J2_mean, dtype=float), np.asarray(J2_std, dtype=float)
    finite = np.isfinite(J2_mean) & np.isfinite(J2_std)
    if not finite.any():
        fit.update(alpha2=np.nan, J=np.full(J1.shape, np.nan), possible=np.zeros(J1.shape, bool))
        return fit
    threshold = np.min((J2_mean + J2_std)[finite])
    small = finite & (J2_mean < threshold)
    # with a single best point J̄2 < its own J̄2 + σJ only if σJ > 0; keep that point anyway
    alpha2 = float(J2_mean[small].mean()) if small.any() else float(np.min(J2_mean[finite]))
    J = J1 + fit["alpha1"] / alpha2 * J2_mean if alpha2 > 0 else np.full(J1.shape, np.nan)
    fit.update(alpha2=alpha2, j2_threshold=threshold, J=J, possible=J <= 2.0 * fit["alpha1"])
    return fit
