"""The fitting functions of a (b, Lc) inversion: J1, J2 and J (Urata et al. 2017, Eqs. 10–12).

    J1 = (ΔTsy − ΔT̄)²/σT² + (Δμsy − Δμ̄)²/σμ²           95 % region: J1 ≤ 5.99146 (χ², 2 dof)
    J2(i) = min over μ0 of Σj (μsy(i, j) − μob(i, j))² / Nj(i)
    J̄2 = mean of J2(i) over the observed events i
    J = J1 + (α1/α2) J̄2                                  possible range: J ≤ 2 α1

α1 is the mean J1 over the grid points inside the 95 % region. α2 is the mean J̄2 over the points
whose J̄2 is below min(J̄2 + σJ), σJ being the standard deviation of J2(i) over the events of
one simulation. The paper's sentence ("J̄2 less than the minimum value of J̄2 + σJ in all
simulations") is read here as the minimum over simulations of J̄2 + σJ.

The curves J2 compares are those of :mod:`benchmarks.physics.curves`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["CHI2_95_2DOF", "j1", "j2_per_event", "JointFit", "joint_fit"]

#: the 95 % quantile of χ² with two degrees of freedom: the paper's J1 threshold
CHI2_95_2DOF = 5.99146


def j1(recurrence_s, friction_drop, obs_recurrence: float, sigma_recurrence: float,
       obs_drop: float, sigma_drop: float):
    """Eq. 10 for one point or arrays of points; NaN where a metric is NaN (no stick–slip)."""
    for name, value in (("sigma_recurrence", sigma_recurrence), ("sigma_drop", sigma_drop)):
        if not value > 0:
            raise ValueError(f"{name} must be positive, got {value!r}")
    dt = (np.asarray(recurrence_s, dtype=float) - obs_recurrence) / sigma_recurrence
    dm = (np.asarray(friction_drop, dtype=float) - obs_drop) / sigma_drop
    return dt * dt + dm * dm


def j2_per_event(curve_slip: np.ndarray, curve_friction: np.ndarray,
                 observed: pd.DataFrame) -> np.ndarray:
    """Eq. 11: J2(i) for each observed event i against one synthetic curve.

    The minimum over the offset μ0 is taken in closed form: it is the variance (over the samples
    of event i) of the residual μsy − μob. Returns NaN for every event if there is no curve.
    """
    groups = [g for _, g in observed.groupby("event_id", sort=False)]
    if len(curve_slip) < 2:
        return np.full(len(groups), np.nan)
    out = np.empty(len(groups))
    for i, g in enumerate(groups):
        synthetic = np.interp(g["slip_m"].to_numpy(), curve_slip, curve_friction)
        residual = synthetic - g["friction"].to_numpy()
        out[i] = np.mean((residual - residual.mean()) ** 2)
    return out


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
