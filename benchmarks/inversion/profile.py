"""Profile likelihoods of b and of log10 Lc.

The profile of b is the misfit (−2 log L: J1, plus the curves' χ² when they enter;
:class:`benchmarks.inversion.Misfit`) minimised over log10 Lc at each b, and the profile of
log10 Lc is it minimised over b; a value without a limit cycle anywhere along its line has no finite profile
value (``inf``). The 95 % profile interval is where the profile is within :data:`CHI2_95_1DOF` of
its minimum (−2 Δ log L ≤ 3.84 for one parameter, Wilks), its ends interpolated linearly between
profile points; an interval that reaches the end of the grid says so (``open_low``/``open_high``):
the data do not bound the parameter there.

Each line is first scanned densely (``scan`` points, every line of a round in one ensemble
batch: the band of stick–slip along a line can be narrow, and J1 jumps to the no-cycle value
outside it), then minimised by a bounded 1-D search (``scipy.optimize.minimize_scalar``) between
the scan points on either side of its best one, to ``xrtol`` of the other parameter's range: an
absolute tolerance in b once stopped the search of a bracket narrower than it at its start, and
with a small σ the profile of log10 Lc read 55 → 1430 → 55 about a valley it had stepped over.

A computed profile value is an upper bound of the true one (a minimum can be missed, never
undershot). Three things make the interval trustworthy, for any σ and any number of points:

* ``best``, a known point such as the least-squares fit, is a profile point: its value of the
  parameter is profiled and its misfit bounds the profile there, so the fit lies inside its interval;
* a **jagged** profile (rising, then falling again, beyond :data:`NOISE_J1` of the misfit, on either side of
  its minimum) is re-minimised at the high point from the optima of its neighbours along the
  other parameter; what stays jagged is reported (``monotone`` False, a warning), and the interval
  is then the hull of every point within the level, never just the piece about the minimum;
* the interval is **resolved**: the cells in which the level is crossed are bisected (a round of
  new lines at a time, at most ``refine`` rounds) until each is at most 1/:data:`CELLS` of the
  interval's width (the one search of every profile, :mod:`benchmarks.inversion.profile_ends`,
  whose walk the grid makes unneeded: it reaches both ends of the range). An interval that
  stays narrower than that is not reported as if resolved: ``resolved`` is False, a warning
  says so, and its ends are the profile points outside the level about it (what the profile
  can vouch for), not an interpolation inside one cell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import Misfit
from benchmarks.inversion.objectives import CHI2_95_1DOF
from benchmarks.inversion.profile_ends import ends, hull, next_point, too_coarse

__all__ = ["profile", "Profile", "lowest_point", "CHI2_95_1DOF", "NOISE_J1", "CELLS", "SCAN"]

#: a profile falling by less than this (in misfit, plus 1e−3 of the value) where it should rise is
#: noise: it moves an interval's end by a few hundredths of the level at most
NOISE_J1 = 0.05
#: a resolved interval spans at least this many cells at each end (module docstring)
CELLS = 4
#: points of a line's first scan: 21, not 41, since the searches about the scan's best point
#: refine it (on two settled recordings' curves profiles, every profile point within 0.018 of
#: the 41-point scan's, the intervals equal to 5 digits, a third fewer solves)
SCAN = 21


@dataclass
class Profile:
    """The profile of ``parameter`` (``"b"`` or ``"log10_lc"``): its points (``table``: the value,
    the minimum of the misfit over the other parameter there and where, and ``point``: ``grid``, ``best``
    or ``refined``), the 95 % interval, whether it is resolved and the profile monotone about its
    minimum, and the warnings that say what is not.

    Parameters
    ----------
    parameter : str
        ``"b"`` or ``"log10_lc"``.
    table : pandas.DataFrame
        One row a profile point, by increasing value: the ``parameter`` (b dimensionless,
        log10 Lc in log10 of m), ``misfit`` (dimensionless; inf without a limit cycle on its
        line), the other parameter where it is least, and ``point``.
    low, high : float
        The 95 % profile interval's ends, in the parameter's unit.
    open_low, open_high : bool
        Whether the interval reaches that end of the profile's points: the data do not bound
        the parameter there.
    n_solves : int
        Forward solves of the profile.
    resolved : bool
        Whether each end of the interval is resolved to :data:`CELLS` cells.
    monotone : bool
        Whether the profile falls and rises without a jag beyond :data:`NOISE_J1`.
    warnings : list of str
        What is not resolved or not monotone, in words.
    """

    parameter: str
    table: pd.DataFrame
    low: float
    high: float
    open_low: bool
    open_high: bool
    n_solves: int
    resolved: bool = True
    monotone: bool = True
    warnings: list = field(default_factory=list)


def profile(misfit: Misfit, parameter: str, values, other_range, scan: int = SCAN,
            xrtol: float = 1e-6, best=None, refine: int = 12) -> Profile:
    """The profile of ``parameter`` (``"b"``, or ``"log10_lc"`` with ``values`` in log10 m) over
    ``values``, minimising over the other parameter within ``other_range`` (b, or Lc in m), to
    ``xrtol`` of its range.

    Parameters
    ----------
    misfit : Misfit
        The objective.
    parameter : str
        ``"b"`` or ``"log10_lc"``.
    values : array_like
        At least two finite values of it: b (dimensionless) or log10 Lc (log10 of m).
    other_range : tuple of float
        (low, high) of the other parameter: 0 < Lc_lo < Lc_hi (m) when profiling b, else
        0 ≤ b_lo < b_hi (dimensionless).
    scan : int
        Points (at least 2) of each line's first scan, evenly spaced in b or in log10 Lc.
    xrtol : float
        The 1-D search's tolerance, a fraction of the other parameter's range, in (0, 0.1).
    best : tuple of float, optional
        (b, Lc in m, misfit) of a known point (a fit), a profile point if its misfit is finite.
    refine : int
        Rounds of repair and bisection at most, 0 or more (0: the grid only).

    Returns
    -------
    Profile

    Raises
    ------
    ValueError
        For another ``parameter``, ``values`` not two finite numbers, or ``scan``, ``refine``,
        ``xrtol`` or ``other_range`` out of range.
    """
    if parameter not in ("b", "log10_lc"):
        raise ValueError(f"parameter must be 'b' or 'log10_lc', got {parameter!r}")
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size < 2 or not np.isfinite(values).all():
        raise ValueError(f"values must be at least two finite numbers, got {values!r}")
    for name, n, least in (("scan", scan, 2), ("refine", refine, 0)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < least:
            raise ValueError(f"{name} must be an integer ≥ {least}, got {n!r}")
    if not 0 < xrtol < 0.1:
        raise ValueError(f"xrtol must be in (0, 0.1) (a fraction of the range), got {xrtol!r}")
    lo, hi = other_range
    if parameter == "b":                 # the other parameter is log10 Lc
        if not 0 < lo < hi:
            raise ValueError(f"other_range must be 0 < Lc_lo < Lc_hi (m), got {other_range!r}")
        lo, hi = np.log10(lo), np.log10(hi)
    elif not 0 <= lo < hi:
        raise ValueError(f"other_range must be 0 ≤ b_lo < b_hi, got {other_range!r}")
    lines = _Lines(misfit, parameter, np.linspace(lo, hi, scan), xrtol * (hi - lo))
    points = {float(v): (J, w, "grid") for v, (J, w) in zip(values, lines.minimise(values))}
    if best is not None and np.isfinite(best[2]):
        v, w = (best[0], np.log10(best[1])) if parameter == "b" else (np.log10(best[1]), best[0])
        (J, w_line), = lines.minimise([v], [[w]])
        points[float(v)] = (J, w_line, "best") if J <= best[2] else (float(best[2]), w, "best")
    _repair_and_bisect(lines, points, refine)
    x, J, w = _arrays(points)
    kinds = [points[v][2] for v in x]
    other = "b" if parameter == "log10_lc" else "log10_lc"
    table = pd.DataFrame({parameter: x, "misfit": J, other: w, "point": kinds})
    low, high, open_low, open_high, resolved = _interval(x, J)
    jagged = _jagged(J)
    warnings = _warnings("b" if parameter == "b" else "log10 Lc", x, J, jagged,
                         (low, high, resolved), refine)
    return Profile(parameter, table, low, high, open_low, open_high, lines.n_solves,
                   resolved=resolved, monotone=not jagged, warnings=warnings)


class _Lines:
    """Minima of the misfit along lines of the profiled parameter, counting the forward solves."""

    def __init__(self, misfit: Misfit, parameter: str, grid: np.ndarray, xatol: float):
        self.misfit, self.parameter, self.grid, self.xatol = misfit, parameter, grid, xatol
        self.n_solves = 0

    def point(self, v, w):               # (b, Lc) of the profiled value v and the other w
        return (v, 10.0 ** w) if self.parameter == "b" else (w, 10.0 ** v)

    def minimise(self, values, hints=None, scan: bool = True) -> list[tuple[float, float]]:
        """``(misfit, other)`` at the minimum of each line: the scan's best point (``scan``: the
        lines are scanned first, in one batch), refined between its neighbours, and about each of
        the line's ``hints`` (values of the other parameter). Every bracket is searched by
        Brent's bounded method at once, one batch a step (:meth:`_searches`)."""
        grid, n = self.grid, len(self.grid)
        scans = np.full((len(values), n), np.inf)
        if scan:
            pairs = [self.point(v, w) for v in values for w in grid]
            scans = self._misfits([p[0] for p in pairs], [p[1] for p in pairs]).reshape(
                len(values), n)
        step = grid[1] - grid[0]
        found, searches = [], []
        for i, (v, line, extra) in enumerate(zip(values, scans, hints or [[]] * len(values))):
            k = int(np.argmin(line))
            found.append([(line[k], grid[k])] if np.isfinite(line[k]) else [])
            brackets = [(grid[max(k - 1, 0)], grid[min(k + 1, n - 1)])] if found[i] else []
            brackets += [(max(grid[0], h - step), min(grid[-1], h + step))
                         for h in np.clip(extra, grid[0], grid[-1])]
            searches += [(i, v, a, c) for a, c in brackets]
        for i, w, J in self._searches(searches):
            if np.isfinite(J):
                found[i].append((J, w))
        return [min(f) if f else (np.inf, np.nan) for f in found]

    def _misfits(self, b, lc) -> np.ndarray:
        """The misfit at each (b, Lc), inf without a limit cycle (not the finite no-cycle
        value: a line's minimum must be a cycle's)."""
        table = self.misfit.evaluate(np.asarray(b, dtype=float), np.asarray(lc, dtype=float))
        self.n_solves += len(table)
        return np.where(np.isfinite(table.log_likelihood.to_numpy()), table.misfit.to_numpy(),
                        np.inf)

    def _searches(self, searches):
        """``(line, other, misfit)`` of every point that the bounded searches ``searches``
        (``(line, value, low, high)`` of the other parameter) evaluated: each is
        :func:`_bounded`, and each step of all of them is one batch."""
        running = {}
        for j, (i, v, a, c) in enumerate(searches):
            search = _bounded(a, c, self.xatol)
            running[j] = (search, next(search))
        while running:
            keys = list(running)
            pairs = [self.point(searches[j][1], running[j][1]) for j in keys]
            values = self._misfits([p[0] for p in pairs], [p[1] for p in pairs])
            for j, J in zip(keys, values):
                search, w = running.pop(j)
                yield searches[j][0], w, J
                try:       # no cycle is kept apart: the search sees a large number
                    running[j] = (search, search.send(J if np.isfinite(J) else 1e30))
                except StopIteration:
                    pass


def _bounded(a: float, b: float, xatol: float, maxfun: int = 500):
    """Brent's bounded minimisation of a function on [a, b] as a generator: it yields the next
    point and is sent the function's value there, until it returns. The steps of
    ``scipy.optimize.minimize_scalar(method="bounded", options={"xatol": xatol})`` (scipy's
    ``_minimize_scalar_bounded``, the same points in the same order), so that many searches can
    share each batch of solves."""
    sqrt_eps = math.sqrt(2.2e-16)
    golden_mean = 0.5 * (3.0 - math.sqrt(5.0))
    fulc = a + golden_mean * (b - a)
    nfc, xf = fulc, fulc
    rat = e = 0.0
    fx = yield xf
    num = 1
    ffulc = fnfc = fx
    xm = 0.5 * (a + b)
    tol1 = sqrt_eps * abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    while abs(xf - xm) > tol2 - 0.5 * (b - a):
        golden = True
        if abs(e) > tol1:                        # a parabola through the three best points
            golden = False
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            r, e = e, rat
            if abs(p) < abs(0.5 * q * r) and q * (a - xf) < p < q * (b - xf):
                rat = (p + 0.0) / q
                x = xf + rat
                if (x - a) < tol2 or (b - x) < tol2:
                    rat = tol1 * (np.sign(xm - xf) + ((xm - xf) == 0))
            else:
                golden = True
        if golden:                               # a golden-section step
            e = (a - xf) if xf >= xm else (b - xf)
            rat = golden_mean * e
        x = xf + (np.sign(rat) + (rat == 0)) * max(abs(rat), tol1)
        fu = yield x
        num += 1
        if fu <= fx:
            if x >= xf:
                a = xf
            else:
                b = xf
            fulc, ffulc = nfc, fnfc
            nfc, fnfc = xf, fx
            xf, fx = x, fu
        else:
            if x < xf:
                a = x
            else:
                b = x
            if fu <= fnfc or nfc == xf:
                fulc, ffulc = nfc, fnfc
                nfc, fnfc = x, fu
            elif fu <= ffulc or fulc == xf or fulc == nfc:
                fulc, ffulc = x, fu
        xm = 0.5 * (a + b)
        tol1 = sqrt_eps * abs(xf) + xatol / 3.0
        tol2 = 2.0 * tol1
        if num >= maxfun:
            return


def _repair_and_bisect(lines: _Lines, points: dict, refine: int) -> None:
    """At most ``refine`` rounds on ``points`` (value → (misfit, other, kind)), in place: each
    jagged point re-minimised from its neighbours' optima, and new lines where the level is
    crossed too coarsely or a point could not be repaired (module docstring)."""
    tried = set()
    for _ in range(refine):
        x, J, w = _arrays(points)
        jagged = _jagged(J)
        suspects = [i for i in jagged if (x[i], _hints(x, w, i)) not in tried]
        stuck = [i for i in jagged if i not in suspects]
        # a point its neighbours' optima could not repair: come closer to it from either side
        new = {float(0.5 * (x[a] + x[a + 1])) for i in stuck for a in (i - 1, i)
               if 0 <= a < len(x) - 1}
        new = sorted(v for v in new.union(_cells_to_bisect(x, J)) if v not in points)
        if not suspects and not new:
            break
        if suspects:                     # re-minimise a high point from its neighbours' optima
            hints = [_hints(x, w, i) for i in suspects]
            tried.update((x[i], h) for i, h in zip(suspects, hints))
            again = lines.minimise(x[suspects], [list(h) for h in hints], scan=False)
            for i, (Ji, wi) in zip(suspects, again):
                if Ji < J[i]:
                    points[x[i]] = (Ji, wi, points[x[i]][2])
        if new:                          # a new line starts from its neighbours' optima too
            near = [w[max(k - 1, 0):k + 1] for k in np.searchsorted(x, new)]
            hints = [[wk for wk in pair if np.isfinite(wk)] for pair in near]
            for v, (Jv, wv) in zip(new, lines.minimise(new, hints)):
                points[v] = (Jv, wv, "refined")


def _arrays(points: dict):
    x = np.array(sorted(points))
    return x, np.array([points[v][0] for v in x]), np.array([points[v][1] for v in x])


def _hints(x, w, i) -> tuple:
    """The optima (other parameter) of the neighbours of point ``i`` that have one."""
    return tuple(float(w[k]) for k in (i - 1, i + 1) if 0 <= k < len(x) and np.isfinite(w[k]))


def _jagged(J: np.ndarray) -> list[int]:
    """The points where the profile, walking away from its minimum, falls again beyond noise:
    the higher point of each such pair (its minimum is the one likely missed)."""
    if not np.isfinite(J).any():
        return []
    k = int(np.argmin(J))
    out = []
    for i in range(len(J)):
        nearer = i + 1 if i < k else i - 1          # the neighbour towards the minimum
        if i != k and np.isfinite(J[i]) and J[i] < J[nearer] - NOISE_J1 - 1e-3 * J[i]:
            out.append(nearer)
    return sorted(set(out))


def _level(J: np.ndarray) -> float:
    """The profile's 95 % level: its minimum + CHI2_95_1DOF (NaN without a finite point)."""
    return float(np.min(J)) + CHI2_95_1DOF if np.isfinite(J).any() else np.nan


def _cells_to_bisect(x, J) -> list[float]:
    """Midpoints of the cells where the level is crossed (or a cycle's band ends) that are wider
    than 1/CELLS of the interval (:func:`benchmarks.inversion.profile_ends.next_point`), and of
    the cells either side of the minimum that are."""
    level = _level(J)
    if np.isnan(level):
        return []
    out = [step.x for side, limit in ((-1, x[0]), (1, x[-1]))
           if (step := next_point(x, J, level, side, limit, cells=CELLS)) is not None]
    i, j = hull(J, level)
    k = int(np.argmin(J))
    return out + [float(0.5 * (x[a] + x[a + 1])) for a in (k - 1, k)
                  if 0 <= a < len(x) - 1 and too_coarse(x, a, a + 1, x[j] - x[i], CELLS)]


def _warnings(label: str, x, J, jagged: list, interval: tuple, refine: int) -> list[str]:
    """What a profile's reader must know: a minimum that is not monotone about it, an interval
    the points do not resolve, or none at all."""
    low, high, resolved = interval
    warnings = []
    if jagged:
        i = jagged[0]
        warnings.append(f"the profile of {label} is not monotone about its minimum at "
                        f"{label} = {x[i]:.6g} (misfit {_triple(J, i)}) after re-minimising there "
                        "from its neighbours' optima: its interval is the hull of every point "
                        "within the level, and may be wider than the truth")
    if not resolved and not (np.isfinite(low) or np.isfinite(high)):
        warnings.append(f"the profile of {label} has no interval: none of its points is within "
                        "the 95 % level (no point of it has a limit cycle, or none fits)")
    elif not resolved:
        warnings.append(f"the 95 % interval of {label} is not resolved by the profile's points "
                        f"after {refine} rounds of bisection (it is narrower than {CELLS} cells "
                        f"at an end): reported as the points about it, [{low:.6g}, {high:.6g}]")
    return warnings


def _interval(x: np.ndarray, J: np.ndarray):
    """``(low, high, open_low, open_high, resolved)`` of a profile on its points (module
    docstring; :func:`benchmarks.inversion.profile_ends.ends`): the hull of the points within
    the level, its ends interpolated linearly towards the next point out (to that point's side's
    end of the cycle band when it has no cycle)."""
    return ends(x, J, _level(J), (x[0], x[-1]), cells=CELLS)


def _triple(J, i) -> str:
    return " → ".join(f"{J[k]:.3g}" for k in range(max(i - 1, 0), min(i + 2, len(J))))


def lowest_point(profiles: dict):
    """``(misfit, row, profile)`` of the lowest finite point of any of ``profiles`` (name →
    :class:`Profile`), its row of the profile's table; None without a finite point."""
    found = [(float(p.table.misfit.min()), p) for p in profiles.values()
             if np.isfinite(p.table.misfit).any()]
    if not found:
        return None
    lowest, p = min(found, key=lambda f: f[0])
    return lowest, p.table.loc[p.table.misfit.idxmin()], p
