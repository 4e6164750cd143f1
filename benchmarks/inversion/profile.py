"""Profile likelihoods of b and of log10 Lc (issue 17, item 2, second part).

The profile of b is J1 minimised over log10 Lc at each b of a grid, and the profile of log10 Lc is
J1 minimised over b; a point without a limit cycle everywhere along its line has no finite
profile value (``inf``). The 95 % profile interval is where the profile is within
:data:`CHI2_95_1DOF` of its minimum (−2 Δ log L ≤ 3.84 for one parameter, Wilks), read on the
grid, linearly interpolated at its ends; an interval that reaches the end of the grid says so
(``open_low``/``open_high``): the data do not bound the parameter there.

The lines are first scanned densely (``scan`` points each, every line of the profile in one
ensemble batch: the band of stick–slip along a line can be narrow, and J1 jumps to the
no-cycle value outside it); each line's minimum is then refined by a bounded 1-D minimisation
(``scipy.optimize.minimize_scalar``) between the scan points on either side of its best one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import Misfit

__all__ = ["profile", "Profile", "CHI2_95_1DOF"]

#: the 95 % quantile of χ² with one degree of freedom
CHI2_95_1DOF = 3.841458820694124


@dataclass
class Profile:
    """The profile of ``parameter`` (``"b"`` or ``"log10_lc"``): its grid, the minimum of J1 over
    the other parameter at each value (``J1``) and where (``other``), and the 95 % interval."""

    parameter: str
    table: pd.DataFrame
    low: float
    high: float
    open_low: bool
    open_high: bool
    n_solves: int


def profile(misfit: Misfit, parameter: str, values, other_range, scan: int = 41,
            xatol: float = 1e-4) -> Profile:
    """The profile of ``parameter`` (``"b"``, or ``"log10_lc"`` with ``values`` in log10 m) over
    ``values``, minimising over the other parameter within ``other_range`` (b, or Lc in m)."""
    from scipy.optimize import minimize_scalar
    if parameter not in ("b", "log10_lc"):
        raise ValueError(f"parameter must be 'b' or 'log10_lc', got {parameter!r}")
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size < 2 or not np.isfinite(values).all():
        raise ValueError(f"values must be at least two finite numbers, got {values!r}")
    lo, hi = other_range
    if parameter == "b":                 # the other parameter is log10 Lc
        if not 0 < lo < hi:
            raise ValueError(f"other_range must be 0 < Lc_lo < Lc_hi (m), got {other_range!r}")
        lo, hi = np.log10(lo), np.log10(hi)
    elif not 0 <= lo < hi:
        raise ValueError(f"other_range must be 0 ≤ b_lo < b_hi, got {other_range!r}")

    def point(v, w):                     # (b, Lc) of the profiled value v and the other w
        return (v, 10.0 ** w) if parameter == "b" else (w, 10.0 ** v)

    count = {"n": 0}

    def j1(v, w):
        count["n"] += 1
        return misfit(*point(v, w))

    grid = np.linspace(lo, hi, scan)
    pairs = [point(v, w) for v in values for w in grid]          # every line in one batch
    coarse = misfit.evaluate(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))
    count["n"] += len(coarse)
    J_scan = np.where(np.isfinite(coarse.log_likelihood.to_numpy()), coarse.J1.to_numpy(),
                      np.inf).reshape(len(values), scan)
    rows = []
    for v, line in zip(values, J_scan):
        if not np.isfinite(line).any():
            rows.append({parameter: v, "J1": np.inf, "other": np.nan})
            continue
        k = int(np.argmin(line))
        left, right = grid[max(k - 1, 0)], grid[min(k + 1, scan - 1)]
        res = minimize_scalar(lambda w: j1(v, w), bounds=(left, right), method="bounded",
                              options={"xatol": xatol})
        best_w, best = (res.x, res.fun) if res.fun <= line[k] else (grid[k], line[k])
        rows.append({parameter: v, "J1": float(best), "other": float(best_w)})
    table = pd.DataFrame(rows).rename(columns={"other": "log10_lc" if parameter == "b" else "b"})
    low, high, open_low, open_high = _interval(values, table.J1.to_numpy())
    return Profile(parameter, table, low, high, open_low, open_high, count["n"])


def _interval(x: np.ndarray, J: np.ndarray):
    """The 95 % interval of a profile on its grid: where J − min J ≤ CHI2_95_1DOF, the ends
    interpolated linearly; open where it reaches the grid's end."""
    if not np.isfinite(J).any():
        return np.nan, np.nan, True, True
    inside = J - np.min(J) <= CHI2_95_1DOF
    k = int(np.argmin(J))
    i, j = k, k
    while i > 0 and inside[i - 1]:
        i -= 1
    while j < len(x) - 1 and inside[j + 1]:
        j += 1
    level = np.min(J) + CHI2_95_1DOF

    def cross(a, c):                     # where the line from grid point a to c meets the level
        if not np.isfinite(J[c]):
            return x[a]
        return x[a] + (x[c] - x[a]) * (level - J[a]) / (J[c] - J[a])
    low = x[0] if i == 0 else cross(i, i - 1)
    high = x[-1] if j == len(x) - 1 else cross(j, j + 1)
    return float(low), float(high), i == 0, j == len(x) - 1
