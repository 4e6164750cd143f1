"""Profile intervals of a laboratory fit: hold one parameter at values on either side of its best
fit, refit the others, and find where the squares have risen by χ²₁(95 %) = 3.84 noise
variances (the fit's f σ², :mod:`benchmarks.lab.fit`).

Each side is the one search of every profile (:mod:`benchmarks.inversion.profile_ends`), in
the fitted coordinate (a, b, c as they are; ln Dc, ln k′): it walks out from the best fit,
starting at one Wald standard error (at most a twentieth of the parameter's range), each refit
started from the one before it; a step grows ×2 while the rise per step is under a quarter of
what is left. A bracket whose rise is over :data:`OVERSHOOT` times the level is halved
(:data:`BISECTIONS` at most) until it is not, and the crossing is interpolated in the signed
root √Δ (linear in the parameter for a quadratic profile). A side that reaches its bound of
:data:`~benchmarks.lab.fit.BOUNDS`, or :data:`MAX_POINTS` points, without the rise is
open (the bound, and ``closed`` False); so is a side where the forward model fails, or where
the squares rise only because another parameter's refit is held at an edge of the box
(:data:`BOX_EDGES`; its end is the last point before: no rise is known past it; Δ is NaN in
``points``). The profile
interval differs from the Wald interval where the squares are not quadratic: Dc of a short
step, a and b when their difference is what the record holds.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.objectives import CHI2_95_1DOF
from benchmarks.inversion.profile_ends import ends, next_point
from benchmarks.lab.fit import (_LOG, LabFit, _Problem, _shown,
                                coordinate_bounds)

__all__ = ["LabProfile", "profile_lab", "MAX_POINTS", "BISECTIONS", "OVERSHOOT", "BOX_EDGES"]

#: points a side of a profile takes at most
MAX_POINTS = 24
#: halvings of a bracket whose rise is over OVERSHOOT times the level, before interpolating in it
BISECTIONS = 12
#: a bracket whose far end rises more than this many times the level is halved
OVERSHOOT = 2.0
_BUDGET = {"walk": MAX_POINTS, "bisect": BISECTIONS}


@dataclass
class LabProfile:
    """The profile of one parameter: ``points`` (value in its own unit, Δ = rise of the squares
    in noise variances), the 95 % ``interval`` and whether each side ``closed``.

    Parameters
    ----------
    parameter : str
        The profiled parameter, one of the fit's ``free``.
    value : float
        Its best-fit value, in its own unit (Dc in m, k in 1/m, the rest dimensionless).
    interval : tuple of float
        (low, high) of the profile interval, in that unit (an open side's end: module
        docstring).
    closed : tuple of bool
        Whether the rise was found below and above the best fit.
    points : pandas.DataFrame
        The profile's points: the parameter's value (its unit) and ``delta``, the rise of the
        squares in noise variances (dimensionless; NaN where no rise is known).
    solves : int
        Forward solves of the refits.
    wall_s : float
        The profile's wall time (s).
    """

    parameter: str
    value: float
    interval: tuple
    closed: tuple
    points: pd.DataFrame = field(repr=False)
    solves: int = 0
    wall_s: float = 0.0

    @property
    def note(self) -> str:
        """What an open side means, or "" when both are closed."""
        sides = [s for s, c in zip(("below", "above"), self.closed) if not c]
        if not sides:
            return ""
        scale, unit = _shown(self.parameter)
        ends = " and ".join(f"{s} (to {e * scale:.4g}{' ' + unit if unit else ''})" for s, e, c in
                            zip(("below", "above"), self.interval, self.closed) if not c)
        return (f"{self.parameter}: no rise of the squares by {CHI2_95_1DOF:.2f} noise variances "
                f"is found {ends} (they stay flat up to a bound, another parameter's refit "
                "reaches its bound, or the model fails beyond): the record does not bound "
                f"{self.parameter} there, whatever its standard error says (a step shorter "
                "than the evolution distance, or parameters that stand in for each other)")


def profile_lab(fit: LabFit, parameter: str, level: float = CHI2_95_1DOF) -> LabProfile:
    """The profile interval of ``parameter`` (one of ``fit.free``) at the Δ of ``level``.

    Parameters
    ----------
    fit : LabFit
        The best fit; the others of its ``free`` are refitted at each point.
    parameter : str
        The profiled parameter.
    level : float
        The rise of the squares that ends the interval, in noise variances (dimensionless).

    Returns
    -------
    LabProfile

    Raises
    ------
    ValueError
        For a ``parameter`` not in ``fit.free``.
    """
    if parameter not in fit.free:
        raise ValueError(f"{parameter!r} was not fitted; the fitted parameters: "
                         f"{', '.join(fit.free)}")
    t0 = time.perf_counter()
    j = fit.free.index(parameter)
    others = tuple(n for n in fit.free if n != parameter)
    best = {n: fit.values[n] for n in fit.free}
    u_best = math.log(best[parameter]) if parameter in _LOG else best[parameter]
    scale = fit.profile_scale(parameter)
    lo_bound, hi_bound = coordinate_bounds(fit.free)
    bounds = (lo_bound[j], hi_bound[j])
    step0 = fit.se(parameter) if math.isfinite(fit.se(parameter)) and fit.se(parameter) > 0 \
        else 0.05 * max(abs(u_best), 1e-3)
    rises, starts = {u_best: 0.0}, {u_best: {n: best[n] for n in others}}
    counter = {"solves": 0}

    def rise(u, start):
        """Δ at the parameter's coordinate u, and the others' refit (from ``start``); NaN where
        the forward model failed at the refit's end (no rise is known there)."""
        fixed = dict(fit.fixed)
        fixed[parameter] = math.exp(u) if parameter in _LOG else u
        prob = _Problem(fit.model, others, fixed, fit.piece_weights)
        x = np.empty(0)
        if others:
            res = prob.solve(prob.coordinates(start), max_nfev=60, trial=True)
            x, start = res.x, prob.params(res.x)
        r = prob.residual(x)
        failed = not np.isfinite(prob.g(x)).all()
        counter["solves"] += prob.solves
        d = math.nan if failed else max((float(r @ r) - fit.rss) / scale, 0.0)
        if others and d >= level and _boxed(prob, x):
            d = math.nan              # a rise made by another parameter's bound, not the data
        return d, start

    first = min(step0, 0.05 * (bounds[1] - bounds[0]))
    for side, limit in ((-1, bounds[0]), (1, bounds[1])):
        taken = {"walk": 0, "bisect": 0}
        while True:
            u = np.array(sorted(rises))
            step = next_point(u, [rises[v] for v in u], level, side, limit,
                              walk=(u_best, first), overshoot=OVERSHOOT)
            if step is None or taken[step.kind] == _BUDGET[step.kind]:
                break
            taken[step.kind] += 1
            rises[step.x], starts[step.x] = rise(step.x, starts[step.origin])
    u = np.array(sorted(rises))
    delta = [rises[v] for v in u]
    # a crossing on the bound itself is the bound's (a refit there can fail), not the data's
    low, high, open_low, open_high, _ = ends(u, delta, level, bounds, root=True,
                                             bound_tol=1e-4 * (bounds[1] - bounds[0]))
    to_unit = (lambda v: math.exp(v)) if parameter in _LOG else (lambda v: v)
    points = pd.DataFrame({parameter: [to_unit(v) for v in u], "delta": delta})
    return LabProfile(parameter=parameter, value=fit.values[parameter],
                      interval=(to_unit(low), to_unit(high)),
                      closed=(not open_low, not open_high), points=points,
                      solves=counter["solves"], wall_s=time.perf_counter() - t0)


#: the bounds that are the box's, not a limit of the physics: the upper ones of a and c, both
#: of b and b2 (Dc → 0 or ∞, k′ → ∞ are limits a refit may rightly reach)
BOX_EDGES = {"a": (False, True), "b": (True, True), "c": (False, True), "b2": (True, True)}


def _boxed(prob, x) -> bool:
    """Is one of the refit's parameters held at an edge of the box (:data:`BOX_EDGES`, within
    the tolerances of :attr:`~benchmarks.lab.fit.LabFit.at_bound`)?"""
    lo, hi = prob.bounds()
    for name, u, l, h in zip(prob.free, x, lo, hi):
        near = (1e-3 if name in _LOG else 1e-6) * (h - l)
        low_edge, high_edge = BOX_EDGES.get(name, (False, False))
        if (low_edge and u - l <= near) or (high_edge and h - u <= near):
            return True
    return False
