"""An independent forward model of a laboratory velocity step, for checking the fit: the published
equations integrated with scipy's Radau, sharing no code with :mod:`problems` or
:mod:`integrators` (a test checks the import graph).

The quasi-static spring-slider of Dieterich (1979), Ruina (1983) and Marone (1998, Annu. Rev.
Earth Planet. Sci. 26, Eqs. 2–5), in friction units::

    μ = μ0 + a ln(v/v0) + b ln(v0 θ/Dc) [+ b2 ln(v0 θ2/Dc2)]
    dμ/dt = k′ (vL(t) − v)                         k′ in 1/m (friction per metre of load point)
    aging:  dθ/dt = 1 − v θ/Dc                     slip:  dθ/dt = −(v θ/Dc) ln(v θ/Dc)
    Nagata (Nagata et al. 2012, Eq. 7): dθ/dt = 1 − v θ/Dc − (c/b) θ dμ/dt

solved for (μ, ln θ[, ln θ2]) piece by piece of the load point's history (each switch a restart),
from steady sliding at the first speed, v0 = that speed. :func:`synthetic_record` adds what a
laboratory adds: white noise on μ and on the displacement, and a linear drift of μ with the load
point's displacement.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

__all__ = ["reference_friction", "synthetic_record"]


def _rates(law, a, b, dc, k, c, b2, dc2, mu0, v0, vl):
    """The right-hand side in (μ, ln θ[, ln θ2]) and its Jacobian."""
    bs, dcs = ((b, b2), (dc, dc2)) if b2 else ((b,), (dc,))
    slip = law == "slip"

    def speed(y):
        state = sum(bi * (math.log(v0 / di) + li) for bi, di, li in zip(bs, dcs, y[1:]))
        return v0 * math.exp((y[0] - mu0 - state) / a)

    def rhs(t, y):
        v = speed(y)
        dmu = k * (vl - v)
        out = [dmu]
        for i, (di, li) in enumerate(zip(dcs, y[1:])):
            x = math.log(v / di) + li                          # ln(v θ/Dc)
            out.append(-(v / di) * x if slip else math.exp(-li) - v / di)
        if law == "nagata":
            out[1] -= (c / b) * dmu
        return out

    def jac(t, y):
        v = speed(y)
        n = len(y)
        dv = (v / a) * np.array([1.0, *(-bi for bi in bs)])    # ∂v/∂(μ, ln θ, …)
        j = np.empty((n, n))
        j[0] = -k * dv
        for i, (di, li) in enumerate(zip(dcs, y[1:]), start=1):
            if slip:
                x = math.log(v / di) + li
                j[i] = -(x + 1.0) / di * dv
                j[i, i] -= v / di
            else:
                j[i] = -dv / di
                j[i, i] -= math.exp(-li)
        if law == "nagata":
            j[1] -= (c / b) * j[0]
        return j

    return rhs, jac


class _OutOfTime(Exception):
    """The run's wall budget is used up (raised from the right-hand side, caught below)."""


def reference_friction(t, velocities, switch_times, a, b, dc, k, law="aging", c=0.0,
                       b2=0.0, dc2=1.0, mu0=0.6, rtol=1e-10, atol=1e-12,
                       wall_budget: float | None = None) -> np.ndarray:
    """μ at times ``t`` (s, from 0) of the load point at ``velocities`` (m/s) between
    ``switch_times`` (s); parameters in the module docstring's units. ``wall_budget``: s for the
    whole run (None: none). A run that fails, or runs out of its budget, raises
    ``RuntimeError`` saying which.

    Parameters
    ----------
    t : array_like
        The times (s, from 0).
    velocities, switch_times : sequence of float
        The load point's history: velocities (m/s) between switch times (s).
    a, b : float
        The direct and evolution effects (dimensionless).
    dc : float
        The critical slip distance Dc (m).
    k : float
        The stiffness k′ in friction per metre of load point (1/m).
    law : str
        ``"aging"``, ``"slip"`` or ``"nagata"``.
    c : float
        The Nagata law's stress coefficient (dimensionless).
    b2, dc2 : float
        A second state's b (dimensionless; 0: none) and Dc (m).
    mu0 : float
        The friction at steady sliding at the first speed (dimensionless).
    rtol, atol : float
        Radau's tolerances.
    wall_budget : float, optional
        The run's wall-time budget (s).

    Returns
    -------
    numpy.ndarray
        μ at ``t``.
    """
    if wall_budget is not None and not (math.isfinite(wall_budget) and wall_budget > 0):
        raise ValueError(f"wall_budget must be a positive number of s, got {wall_budget!r}")
    deadline = math.inf if wall_budget is None else time.perf_counter() + wall_budget
    t = np.asarray(t, dtype=float)
    v0 = velocities[0]
    y = [mu0, math.log(dc / v0)] + ([math.log(dc2 / v0)] if b2 else [])
    bounds = [0.0, *switch_times, float(t[-1])]
    mu = np.empty(len(t))
    for i, vl in enumerate(velocities):
        t0, t1 = bounds[i], bounds[i + 1]
        if t1 <= t0:
            continue
        rhs, jac = _rates(law, a, b, dc, k, c, b2, dc2, mu0, v0, vl)

        def timed(t_, y_, rhs=rhs):
            if time.perf_counter() > deadline:
                raise _OutOfTime
            return rhs(t_, y_)
        try:
            sol = solve_ivp(timed, (t0, t1), y, method="Radau", jac=jac, rtol=rtol, atol=atol,
                            dense_output=True)
        except _OutOfTime:
            raise RuntimeError(f"the reference run ran out of its wall budget of {wall_budget:g} "
                               f"s on piece {i} (t = {t0:g} to {t1:g} s)") from None
        if not sol.success:
            raise RuntimeError(f"the reference run failed on piece {i}: {sol.message}")
        inside = (t >= t0) & (t <= t1)
        mu[inside] = sol.sol(t[inside])[0]
        y = sol.y[:, -1]
    return mu


def synthetic_record(t, velocities, switch_times, a, b, dc, k, law="aging", c=0.0, b2=0.0,
                     dc2=1.0, mu0=0.6, noise=6e-4, displacement_noise=0.0, drift=0.0,
                     seed=0, correlated=0.0, phi=0.9, walk=0.0,
                     clean=None) -> pd.DataFrame:
    """A record as a laboratory would write it: columns ``time_s``, ``load_point_um`` and
    ``friction``. ``noise`` is σ of μ's white noise, ``correlated`` σ of an AR(1) part of
    correlation ``phi`` from one sample to the next, ``walk`` σ of a random walk's steps per
    sample, ``displacement_noise`` σ of the load point (m), ``drift`` dμ per metre of
    load-point travel.

    Parameters
    ----------
    t, velocities, switch_times, a, b, dc, k, law, c, b2, dc2, mu0
        As :func:`reference_friction`.
    noise : float
        σ of μ (dimensionless).
    displacement_noise : float
        σ of the load point (m).
    drift : float
        dμ per metre of load-point travel (1/m).
    seed : int
        The random generator's seed.
    correlated, phi : float
        σ of μ's AR(1) noise (its stationary σ; 0: none) and its correlation per sample.
    walk : float
        σ of a random walk's step per sample in μ (0: none).
    clean : numpy.ndarray, optional
        :func:`reference_friction` of these arguments at ``t``, if computed already (records
        that differ only in their noise share it).

    Returns
    -------
    pandas.DataFrame
        Columns ``time_s`` (s), ``load_point_um`` (µm) and ``friction``.

    Raises
    ------
    RuntimeError
        When the forward run fails.
    """
    rng = np.random.default_rng(seed)
    t = np.asarray(t, dtype=float)
    bounds = np.array([0.0, *switch_times])
    piece = np.searchsorted(np.asarray(switch_times), t, side="right")
    start = np.concatenate(([0.0], np.cumsum(np.diff(bounds) * np.asarray(velocities[:-1]))))
    x = start[piece] + (t - bounds[piece]) * np.asarray(velocities)[piece]
    mu = reference_friction(t, velocities, switch_times, a, b, dc, k, law, c, b2, dc2, mu0) \
        if clean is None else np.asarray(clean, dtype=float)
    mu = mu + drift * x + noise * rng.standard_normal(len(t))
    x = x + displacement_noise * rng.standard_normal(len(t))
    if correlated:                     # drawn after the white noise: a seed's white is kept
        from scipy.signal import lfilter
        start = correlated * rng.standard_normal()
        steps = correlated * math.sqrt(1.0 - phi ** 2) * rng.standard_normal(len(t))
        mu = mu + lfilter([1.0], [1.0, -phi], steps, zi=[phi * start])[0]
    if walk:
        mu = mu + np.cumsum(walk * rng.standard_normal(len(t)))
    return pd.DataFrame({"time_s": t, "load_point_um": x * 1e6, "friction": mu})
