"""The ends of a profile interval: the one search every profile of the project makes.

A profile is known at points ``x`` (increasing) with values ``d``: the stick–slip misfit
minimised over the other parameter (:mod:`benchmarks.inversion.profile`), or the rise of a
laboratory fit's squares in noise variances (:mod:`benchmarks.lab.profile_intervals`); ``inf``
where the point is known to be beyond any level (no limit cycle), NaN where nothing is known
(the forward model failed). Its interval at ``level`` is the hull of the points within the
level, and each side of it is searched outward from the minimum, one point at a time
(:func:`next_point`; the caller evaluates it, alone or in a batch with others):

* **walk**: while no point beyond the hull is known on a side and the side's limit is not
  reached, a point one step further: a first step from the start (the best fit), then the last
  step again, doubled while the rise per step is under a quarter of what is left to the level;
* **bisect**: the cell in which the level is crossed is halved while it is too coarse: wider
  than 1/``cells`` of the interval, or its outer value over ``overshoot`` times the level's
  rise above the minimum.

:func:`ends` reads the interval off the points: each end interpolated in its crossing cell
(:func:`level_crossing`, linearly or in the signed root), the inner point where the outer one
is ``inf``; open at the limit where the hull reaches it (or the walk stopped short of it), and
open at the inner point where the outer one is NaN (no rise is known past it).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Step", "next_point", "ends", "hull", "too_coarse", "level_crossing"]


class Step(NamedTuple):
    """A point to evaluate: ``x``, reached from the evaluated point ``origin`` (the inner end
    of its step or cell: a refit there is the one to start from), by a ``walk`` or a
    ``bisect``."""

    x: float
    origin: float
    kind: str


def level_crossing(x0: float, d0: float, x1: float, d1: float, level: float,
                   root: bool = False) -> float:
    """Where a profile's rise ``d`` reaches ``level`` between (``x0``, ``d0``) and (``x1``,
    ``d1``): linearly in d, or with ``root`` in the signed root √d (linear in x for a
    quadratic profile; the rises then are ≥ 0 above the minimum). ``x1`` when the two are
    level."""
    if root:
        d0, d1, level = np.sqrt(d0), np.sqrt(d1), np.sqrt(level)
    if d1 == d0:
        return x1
    return x0 + (x1 - x0) * (level - d0) / (d1 - d0)


def too_coarse(x: np.ndarray, a: int, c: int, width: float, cells: int) -> bool:
    """Whether the cell between points ``a`` and ``c`` is wider than 1/``cells`` of an
    interval ``width`` wide (any width is, for an interval of none; none is, for ``cells``
    0)."""
    if cells == 0:
        return False
    return bool(abs(x[c] - x[a]) > width / cells * (1 + 1e-9) + 1e-12 * max(abs(x[a]), 1.0))


def hull(d: np.ndarray, level: float) -> tuple[int, int]:
    """The first and the last of the points within ``level`` (there must be one)."""
    inside = np.flatnonzero(np.asarray(d) <= level)
    return int(inside[0]), int(inside[-1])


def next_point(x, d, level: float, side: int, limit: float, walk=None, cells: int = 0,
               overshoot: float = np.inf) -> Step | None:
    """The next point of the search for the end on ``side`` (−1: low, +1: high) of the
    interval at ``level`` (module docstring), or None when that end is found.

    Parameters
    ----------
    x, d : array_like
        The profile's points, ``x`` increasing; ``d`` inf beyond any level, NaN unknown.
    level : float
        The level, in ``d``'s terms.
    side : int
        −1 for the low end, +1 for the high one.
    limit : float
        Where the side's walk stops (the box's bound).
    walk : tuple or None
        ``(start, first_step)``: the point the walk starts from (the best fit) and its first
        step; None: no walk (the points reach the limits).
    cells : int
        A crossing cell is at most 1/``cells`` of the interval (0: no such rule).
    overshoot : float
        A crossing cell's outer value rises at most this many times the level's rise.

    Returns
    -------
    Step or None
    """
    x, d = np.asarray(x, dtype=float), np.asarray(d, dtype=float)
    if not (d <= level).any():
        return None
    i, j = hull(d, level)
    inner = j if side > 0 else i
    outer = inner + side
    if not 0 <= outer < len(x):                        # nothing known beyond: walk
        if walk is None or (x[inner] - limit) * side >= 0:
            return None
        start, step = walk
        if x[inner] != start:            # the step before, from the point nearer the start
            step = abs(x[inner] - x[inner - side])
            if d[inner] - d[inner - side] < 0.25 * (level - d[inner]):
                step *= 2.0
        u = x[inner] + side * step
        return Step(float(limit if (u - limit) * side >= 0 else u), float(x[inner]), "walk")
    if np.isnan(d[outer]):                             # the model failed: the end is known
        return None
    floor = np.nanmin(d)
    if (too_coarse(x, min(inner, outer), max(inner, outer), x[j] - x[i], cells)
            or d[outer] - floor > overshoot * (level - floor)):
        return Step(float(0.5 * (x[inner] + x[outer])), float(x[inner]), "bisect")
    return None


def ends(x, d, level: float, limits, root: bool = False, cells: int = 0,
         bound_tol: float = 0.0) -> tuple[float, float, bool, bool, bool]:
    """``(low, high, open_low, open_high, resolved)``: the interval at ``level`` read off the
    profile's points (module docstring).

    Parameters
    ----------
    x, d : array_like
        The profile's points, as for :func:`next_point`.
    level : float
        The level, in ``d``'s terms.
    limits : tuple
        (low, high): an end with no point beyond it is open there.
    root : bool
        Interpolate in the signed root of ``d`` (rises ≥ 0), not in ``d``.
    cells : int
        An end whose crossing cell is over 1/``cells`` of the interval is not resolved; both
        ends are then the points about the interval, not an interpolation (0: always resolved).
    bound_tol : float
        A crossing this close to its limit is the limit's, open (a refit there can fail).

    Returns
    -------
    tuple
        NaN ends, open and not resolved when no point is within the level.
    """
    x, d = np.asarray(x, dtype=float), np.asarray(d, dtype=float)
    if not (d <= level).any():
        return np.nan, np.nan, True, True, False
    i, j = hull(d, level)
    out, is_open, outer_points = [], [], []
    for side, inner, limit in ((-1, i, limits[0]), (1, j, limits[1])):
        outer = inner + side
        if not 0 <= outer < len(x):
            end, opened = limit, True
        elif np.isnan(d[outer]):
            end, opened = x[inner], True
        elif np.isfinite(d[outer]):
            end = level_crossing(x[inner], d[inner], x[outer], d[outer], level, root)
            opened = bound_tol > 0 and abs(end - limit) <= bound_tol
            end = limit if opened else end
        else:
            end, opened = x[inner], False
        out.append(float(end))
        is_open.append(bool(opened))
        outer_points.append(None if not 0 <= outer < len(x) else outer)
    resolved = not any(too_coarse(x, min(k, inner), max(k, inner), x[j] - x[i], cells)
                       for k, inner, opened in zip(outer_points, (i, j), is_open)
                       if k is not None and not opened)
    if not resolved:                     # what the points vouch for, not one cell's guess
        out = [float(lim if k is None else x[k]) for k, lim in zip(outer_points, limits)]
    return out[0], out[1], is_open[0], is_open[1], resolved
