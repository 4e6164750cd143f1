"""The trend of a velocity-step record read where the slider is steady (``detrend="steady"``).

A slope fitted together with the law's parameters trades with the evolution: after a step the
friction's approach to its new steady state and a straight line in displacement look alike over
a few Dc, and a fit can move Dc by tens of percent while the trend takes up the difference. Here
each piece's slope is read only where the friction is at steady state, as Giacomel et al.
(2024)'s ``steadystate`` routine does before RSFit3000's fit, and then held fixed:

* the first piece is steady throughout (the model starts there): its slope is a straight line
  through it, points beyond :data:`OUTLIER` σ of it left out and the line fitted again;
* in each later piece, windows of :data:`WINDOWS` of the piece's travel after its extreme (the
  direct effect's peak) are slid along it: the first window whose slope is that of the piece's
  last window of the same length, within :data:`SLOPE_TOL` (steadystate's 5·10⁻⁷ per µm) or two
  standard errors of their difference, starts the steady part, for each window length; among
  the lengths whose steady point is stable (it moves by at most :data:`STABLE` times the change
  of length) and among the three latest, the shortest window's point is taken (steadystate's
  rule). From there on the piece must be a straight line (its quadratic term within
  :data:`CURVED` standard errors of 0; else the start moves on), and its slope is a line through
  that part. steadystate
  compares each window's slope with the slope before the step instead, which assumes one trend
  for the whole record; comparing with the piece's own end lets each piece have its own (a gouge
  that compacts at a rate of its own).
  Where no steady part is found, the evolution has not ended within the record, and the
  piece's slope is fitted with the rest, as ``detrend="piece"`` does (said in
  :attr:`SteadyTrend.notes`): a slope read off a transient and held would make the fit
  confidently wrong.

A fit then moves each steady part to where a fitted model says the evolution has ended for the
record's noise (:func:`settled_after`; first the fit with a slope per piece, then its own) and
fits again; a slope held with an error several times that of the same slope fitted with the
rest is fitted instead (:func:`benchmarks.lab.fit.fit_lab`).

Each slope's standard error here comes from its line's residuals read by the noise model of
:mod:`benchmarks.lab.noise` (white + AR(1) + a random walk); it decides whether a slope is held
at all. A fit's covariance does not add it to its own: the held slopes are lines through the
samples of :attr:`SteadyTrend.reads`, whose noise also moves the fit, and
:func:`~benchmarks.lab.noise.propagated_covariance` maps that one noise through both (a walk
that tilts a steady part tilts its slope with it, which then takes the tilt off the data the
fit sees; the two errors added would count it twice). The trend, as in ``detrend="piece"``, is continuous at the
switches, and a hold has none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from benchmarks.lab.noise import covariance, drift_covariance, read_noise
from benchmarks.lab.running import running_mean

__all__ = ["SteadyTrend", "steady_trend", "settled_after", "travel_columns",
           "opens_in_transient", "OPENS_CURVED", "SLOPE_TOL", "WINDOWS", "STABLE", "BIAS"]

#: per metre of load-point travel: a window's slope this small is steady whatever its noise
#: (steadystate's threshold, 5·10⁻⁷ per µm)
SLOPE_TOL = 0.5
#: the sliding windows' lengths, fractions of a piece's travel after its extreme (steadystate:
#: 50 to 500 µm by 50, at most half of what follows the step; here at most a quarter, as each
#: window is compared with the piece's last one of its length)
WINDOWS = tuple(np.round(np.linspace(0.05, 0.25, 9), 3))
#: |Δ steady point / Δ window length| at most this for a stable pair (steadystate's rule)
STABLE = 1.5
#: window starts tried per length, evenly along the piece's travel
STARTS = 200
#: a steady part's quadratic term within this many standard errors of 0 is a straight line
CURVED = 2.0
#: samples: a steady part shorter than this gives no slope of its own
FEWEST = 20
#: residuals beyond this many σ are outliers of the first piece's line (steadystate's 3
#: studentised residuals)
OUTLIER = 3.0


@dataclass(frozen=True)
class SteadyTrend:
    """The trend read where the slider is steady (module docstring).

    Parameters
    ----------
    slopes, se : tuple of float
        Each piece's slope of μ per metre of load-point travel and its standard error (0 and 0
        for a hold).
    steady_from : tuple of float
        s from the record's first sample: where each piece's steady part starts (NaN for a
        hold or a piece without one).
    fitted : tuple of bool
        Whether a piece's slope is left to the fit (no steady part found in it; its slope and
        error NaN here).
    columns : numpy.ndarray
        (samples, pieces): each piece's load-point travel at each sample (m), the columns the
        slopes multiply.
    reads : tuple
        Per piece, the indices of the samples its held slope is a line through (None: no held
        slope), so that a fit can follow what their noise does to the slope and to itself at
        once (:meth:`readers`).
    notes : list of str
        What was assumed where the record did not say.
    """

    slopes: tuple
    se: tuple
    steady_from: tuple
    fitted: tuple
    columns: np.ndarray = field(repr=False)
    reads: tuple = field(default=(), repr=False)
    notes: list = field(default_factory=list)

    @property
    def offset(self) -> np.ndarray:
        """The held trend at each sample: the columns times the slopes held."""
        held = np.nan_to_num(np.asarray(self.slopes, dtype=float))
        return self.columns @ held

    def readers(self) -> tuple[list, np.ndarray]:
        """(pieces, L): the pieces with a held slope and, per row, the linear map of the
        samples onto that slope (the line's least-squares slope: L μ is the slope held)."""
        x = self.columns.sum(axis=1)
        pieces, rows = [], []
        for i, idx in enumerate(self.reads):
            if idx is None or self.fitted[i]:
                continue
            u = x[idx] - x[idx].mean()
            row = np.zeros(len(x))
            row[idx] = u / (u @ u)
            pieces.append(i)
            rows.append(row)
        return pieces, np.array(rows).reshape(len(rows), len(x))


def travel_columns(t, velocities, switch_times) -> np.ndarray:
    """(samples, pieces): each piece's load-point travel by time ``t`` (m), by the history."""
    bounds = np.concatenate(([0.0], np.asarray(switch_times, dtype=float), [np.inf]))
    return np.column_stack([np.clip(t - bounds[i], 0.0, bounds[i + 1] - bounds[i]) * v
                            for i, v in enumerate(velocities)])


def _line(x, y) -> tuple[float, float, np.ndarray]:
    """(slope, its standard error, residuals) of a straight line through (x, y), the error
    from the residuals' noise model (white + AR(1) + walk)."""
    design = np.column_stack([np.ones_like(x), x - x.mean()])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    r = y - design @ coef
    q, _ = np.linalg.qr(design)
    noise = read_noise(r, q)
    var = covariance(design, noise.long_run) + drift_covariance(design, noise.walk)
    return float(coef[1]), math.sqrt(max(float(var[1, 1]), 0.0)), r


def _first_piece(x, y) -> np.ndarray:
    """The first piece's samples kept for its line: a line, its outliers out (all kept if
    fewer than :data:`FEWEST` would stay)."""
    design = np.column_stack([np.ones_like(x), x - x.mean()])
    r = y - design @ np.linalg.lstsq(design, y, rcond=None)[0]
    s = math.sqrt(r @ r / max(len(r) - 2, 1))
    keep = np.abs(r) <= OUTLIER * s if s > 0 else np.ones(len(r), bool)
    return np.ones(len(r), bool) if keep.sum() < FEWEST else keep


def _window_sums(x, y) -> tuple:
    """The cumulative sums of 1, x, y, x², xy and y² (x and y centred) that
    :func:`_window_slopes` reads any window's line from."""
    x = x - x.mean()
    y = y - y.mean()
    return tuple(np.concatenate(([0.0], np.cumsum(v)))
                 for v in (np.ones_like(x), x, y, x * x, x * y, y * y))


def _window_slopes(sums, starts, ends):
    """Slopes and their white-noise standard errors of lines through [starts, ends) (index
    ranges), by the cumulative ``sums`` of :func:`_window_sums`."""
    n, sx, sy, sxx, sxy, syy = (c[ends] - c[starts] for c in sums)
    with np.errstate(invalid="ignore", divide="ignore"):
        dxx = sxx - sx * sx / n
        slope = (sxy - sx * sy / n) / dxx
        rss = np.maximum(syy - sy * sy / n - slope * (sxy - sx * sy / n), 0.0)
        se = np.sqrt(rss / np.maximum(n - 2, 1) / dxx)
    return slope, se


def _steady_start(u, y) -> float:
    """The travel after a switch (m) where the piece's steady part starts, or NaN: the search
    of the module docstring on the piece's friction ``y`` against ``u``, its travel since the
    switch."""
    width = max(5, len(y) // 100)
    smooth = running_mean(y, width)
    half = max(len(smooth) // 2, 1)
    first = int(np.argmax(np.abs(smooth[:half] - smooth[0]))) + width // 2
    span = u[-1] - u[first]
    if not span > 0:
        return math.nan
    points, sums = [], _window_sums(u, y)
    for frac in WINDOWS:
        length = frac * span
        # the piece's last window of this length, and the starts that end before it begins
        end_slope, end_se = _window_slopes(sums, *(np.array([np.searchsorted(u, u[-1] - length),
                                                              len(u)]).reshape(2, 1)))
        begin = np.linspace(u[first], u[-1] - 2.0 * length, STARTS)
        i0 = np.searchsorted(u, begin)
        i1 = np.searchsorted(u, begin + length, side="right")
        slope, se = _window_slopes(sums, i0, i1)
        with np.errstate(invalid="ignore"):
            steady = (i1 - i0 >= FEWEST) & (np.abs(slope - end_slope[0]) <= np.maximum(
                SLOPE_TOL, 2.0 * np.sqrt(se ** 2 + end_se[0] ** 2)))
        k = int(np.argmax(steady)) if steady.any() else -1
        # met only at the last start: never met within the record (steadystate's warning)
        points.append(begin[k] if 0 <= k < STARTS - 1 else math.nan)
    return _stable_point(np.asarray(points), np.asarray(WINDOWS) * span)


def _stable_point(points: np.ndarray, lengths: np.ndarray) -> float:
    """steadystate's choice: of the window lengths whose steady point moves by at most
    :data:`STABLE` times the change of length to the next, and whose point is among the three
    latest, the shortest; NaN if none."""
    with np.errstate(invalid="ignore"):
        stable = np.abs(np.diff(points) / np.diff(lengths)) <= STABLE
    found = points[np.isfinite(points)]
    if len(found) == 0:
        return math.nan
    third = np.sort(found)[-min(3, len(found))]
    for j in np.flatnonzero(stable):
        if points[j] >= third:
            return float(points[j])
    return math.nan


#: the first piece's quadratic term beyond this many standard errors: the record opens in a
#: transient (a note; stricter than :data:`CURVED`, which places a start, so that a straight
#: first piece is so called in all but about 1 record in 10⁴)
OPENS_CURVED = 4.0
OPENS_IN_TRANSIENT = ("the first piece is not a straight line in displacement: the record may "
                      "start inside a transient (a --window that starts where the slider is "
                      "steady)")


def opens_in_transient(t, mu, velocities, switch_times) -> bool:
    """Whether the record's first piece (before its first switch) curves in displacement by
    more than :data:`OPENS_CURVED` standard errors: the model starts at steady state, and a
    record that starts inside a transient misleads every trend."""
    t, mu = np.asarray(t, dtype=float), np.asarray(mu, dtype=float)
    end = switch_times[0] if len(switch_times) else np.inf
    inside = np.flatnonzero(t < end)
    if not velocities[0] > 0 or len(inside) < FEWEST:
        return False
    return _curvature(t[inside] * velocities[0], mu[inside]) > OPENS_CURVED


def _curvature(x, y) -> float:
    """|the quadratic term| of (x, y) in its standard errors (by the residuals' noise model)."""
    z = (x - x.mean()) / max(np.ptp(x), 1e-300)
    design = np.column_stack([np.ones_like(z), z, z * z])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    noise = read_noise(y - design @ coef, np.linalg.qr(design)[0])
    var = covariance(design, noise.long_run) + drift_covariance(design, noise.walk)
    return abs(float(coef[2])) / math.sqrt(var[2, 2]) if var[2, 2] > 0 else 0.0


def _straight_from(x, y, first: int) -> int | None:
    """The first index at or after ``first`` from which the rest of (x, y) is a straight line:
    its quadratic term within :data:`CURVED` standard errors of 0 (the errors by the noise
    model of its residuals), tried in steps of a twentieth of what remains; None when under
    :data:`FEWEST` samples would remain."""
    while len(x) - first >= FEWEST:
        if _curvature(x[first:], y[first:]) <= CURVED:
            return first
        first += max(1, (len(x) - first) // 20)
    return None


def steady_trend(t, mu, velocities, switch_times, after=None, fitted=None) -> SteadyTrend:
    """The trend of μ(t) under the load-point history (``velocities`` in m/s between
    ``switch_times`` in s from the first sample) read where the slider is steady (module
    docstring). ``after``: per piece, a time (s) before which it is not steady (a fitted
    model's word, :func:`settled_after`; NaN: none; inf: never); ``fitted``: per piece, True
    to leave its slope to the fit (a held one would be less precise; no note)."""
    t, mu = np.asarray(t, dtype=float), np.asarray(mu, dtype=float)
    cols = travel_columns(t, velocities, switch_times)
    x = cols.sum(axis=1)
    bounds = np.concatenate(([0.0], np.asarray(switch_times, dtype=float), [np.inf]))
    after = np.full(len(velocities), np.nan) if after is None else np.asarray(after, float)
    leave = (False,) * len(velocities) if fitted is None else tuple(map(bool, fitted))
    slopes, ses, starts, fitted, reads, notes = [], [], [], [], [], []
    for i, v in enumerate(velocities):
        inside = np.flatnonzero((t >= bounds[i]) & (t < bounds[i + 1]))
        held, chosen = None, leave[i]
        if chosen:
            pass
        elif v > 0 and len(inside) >= FEWEST and i == 0:
            held = 0           # (a first piece that curves is a fit's note, whatever its trend)
        elif v > 0 and len(inside) >= FEWEST:
            u, ti = cols[inside, i], t[inside]
            found = _steady_start(u, mu[inside])
            if np.isfinite(after[i]) or after[i] == np.inf:
                found = max(found if np.isfinite(found) else 0.0,
                            np.interp(after[i], ti, u, right=np.inf))
            if np.isfinite(found):
                held = _straight_from(x[inside], mu[inside], int(np.searchsorted(u, found)))
        if held is None:
            slopes.append(0.0 if not v > 0 else math.nan)
            ses.append(0.0 if not v > 0 else math.nan)
            starts.append(math.nan)
            fitted.append(bool(v > 0))
            reads.append(None)
            if v > 0 and not chosen:
                notes.append(f"piece {i} (after the switch at {bounds[i]:.6g} s) has no steady "
                             "part long enough to read its slope (the evolution ends late in it, "
                             "or not within the record): its slope is fitted with the rest")
            continue
        part = inside[held:]
        if i == 0:
            part = part[_first_piece(x[part], mu[part])]
        slope, se, _ = _line(x[part], mu[part])
        slopes.append(slope)
        ses.append(se)
        starts.append(float(t[inside[held]]))
        fitted.append(False)
        reads.append(part)
    return SteadyTrend(tuple(slopes), tuple(ses), tuple(starts), tuple(fitted), cols,
                       tuple(reads), notes)


#: the evolution a fitted model leaves in a steady part may bias its slope by at most this
#: many of the slope's standard errors
BIAS = 0.5


def settled_after(trend: SteadyTrend, t, mu, g, velocities, switch_times) -> np.ndarray:
    """Per piece, the time (s) from which a fitted model's rate-and-state part ``g`` (μ − μ0
    at the samples, no trend) changes over the rest of the piece by a slope under :data:`BIAS`
    × that slope's standard error: where the model says the evolution has ended for this
    record's noise. At or after the piece's steady start; inf if never; NaN for the first
    piece, holds and pieces without a steady part. The error at each start is the white-noise error of a line through μ
    there, scaled by the ratio of the steady part's error to its white-noise one."""
    t, mu, g = (np.asarray(v, dtype=float) for v in (t, mu, g))
    x = trend.columns.sum(axis=1)         # the load point's travel, as the trend read it
    bounds = np.concatenate(([0.0], np.asarray(switch_times, dtype=float), [np.inf]))
    out = np.full(len(velocities), np.nan)
    for i in range(1, len(velocities)):
        if not velocities[i] > 0 or trend.fitted[i]:
            continue
        begin = trend.steady_from[i]
        inside = np.flatnonzero((t >= bounds[i]) & (t < bounds[i + 1]))
        xi, ti = x[inside], t[inside]
        first = int(np.searchsorted(ti, begin))
        starts = np.unique(np.linspace(first, len(ti) - FEWEST, STARTS).astype(int))
        starts = starts[starts >= first]
        ends = np.full(len(starts), len(ti))
        slope_g, _ = _window_slopes(_window_sums(xi, g[inside]), starts, ends)
        _, se_white = _window_slopes(_window_sums(xi, mu[inside]), starts, ends)
        scale = trend.se[i] / se_white[0] if len(starts) and se_white[0] > 0 else 1.0
        with np.errstate(invalid="ignore"):
            ok = np.abs(slope_g) <= BIAS * scale * se_white
        out[i] = float(ti[starts[np.argmax(ok)]]) if ok.any() else np.inf
    return out
