"""The switch times of a fit's history where the friction says, not only the displacement.

:func:`benchmarks.lab.history.find_history` places each switch on the load point's displacement
(a continuous piecewise line, its glitches left out). A displacement that does not follow two
straight lines near a switch still pulls the corner: on the basalt step of
``tests/data/lab-velocity-steps`` the displacement lags its line by up to 2.4 µm for 3 s after
the 3 → 10 µm/s switch, the corner lands at 68.44 s after the first sample, where the friction
starts to rise at 68.66–68.68 s, and the fit there has a stiffness k′ less than half the one at
the friction's switch. A switch placed off by a fraction
of a second moves a, Dc and k′ by more than their errors.

:func:`refine_switches` profiles each switch on the friction: the whole fit (warm-started from
the current one) at trial switch times, its squares as a function of the switch time (the
others held), over ± :data:`WINDOW_SAMPLES` samples of the displacement's switch (at most a
quarter of the shorter piece beside it): a scan of :data:`SCAN` points (each trial started
from the nearest one made), then a bounded search about the best to :data:`TOLERANCE` of a
sample (a trial that would leave a piece too short is skipped). A scan whose squares stay
within :data:`FLAT` × 3.84 f σ² of their least over the window places no switch: the
displacement's time is kept with both ends open, and no search is made. The switch's 95 % interval is where the squares
are within 3.84 f σ² of their minimum (f σ² the best fit's noise variance, grown by the walk
as for the parameter it moves most: :attr:`~benchmarks.lab.fit.LabFit.walk_variance`), each end
bisected :data:`BISECT` times; an end that the window does not close is open. Where neither end
closes, or the friction does not reject the displacement's time (its squares' rise there is at
most :data:`REJECTED`), the displacement's time is kept: the friction moves a switch only where
it says the displacement is wrong. The switches are refined one after the other, each with
those before it at their refined times. What the refinement assumes: the load point switches
when the friction responds (no lag of the machine's servo), and one switch's time does not
depend on the next's.

Each switch's row says where the displacement put it, where the friction puts it, its interval,
and how strongly the friction rejects the displacement's time (its squares' rise there, in
units of f σ²), with the range of a, b, Dc and k′ over the switch's interval: the part of
their uncertainty that the switch time carries (the fit's own intervals hold the switch fixed).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pandas as pd

from benchmarks.lab.fit import fit_lab
from benchmarks.lab.history import MIN_SAMPLES, PIECE_COLUMNS, _line
from benchmarks.lab.step_data import LabRecord
from benchmarks.inversion.objectives import CHI2_95_1DOF

__all__ = ["refine_switches", "with_switches", "with_velocities", "SWITCH_COLUMNS", "WINDOW_SAMPLES", "SCAN",
           "TOLERANCE", "BISECT", "REJECTED", "FLAT", "HAND_SPEED"]

#: samples either side of the displacement's switch that the friction's may lie
WINDOW_SAMPLES = 50
#: the trial switch times of the first scan
SCAN = 9
#: the search's tolerance on a switch time, in samples
TOLERANCE = 0.1
#: bisections of each end of a switch's interval (to 1/16 of the scan's spacing, under a
#: sample)
BISECT = 4
#: a scan whose squares vary by less than this share of 3.84 f σ² is flat: no search
FLAT = 0.5
#: the squares' rise (in f σ²) at the displacement's switch above which the two are said to
#: disagree (the 95 % level)
REJECTED = CHI2_95_1DOF
#: the parameters whose range over a switch's interval is reported
RANGED = ("a", "b", "dc", "k")
#: the columns of the switches' table (times in the file's time, s)
SWITCH_COLUMNS = ("switch", "displacement_s", "friction_s", "low95_s", "high95_s",
                  "low_closed", "high_closed", "rise_at_displacement", "disagree", "fits",
                  *(f"{p}_{end}" for p in RANGED for end in ("min", "max")))


def with_switches(record: LabRecord, switches) -> LabRecord:
    """``record`` with its history's switch ``switches`` (s from its first sample, increasing,
    inside it, each piece :data:`~benchmarks.lab.history.MIN_SAMPLES` samples at least): the
    speeds kept when as many switches are given as it had, else each piece's displacement
    slope (a speed within 10 standard errors of 0 is a hold)."""
    s = np.asarray(switches, dtype=float)
    t = record.t
    if s.ndim != 1 or not len(s) or not np.isfinite(s).all() or (np.diff(s) <= 0).any():
        raise ValueError("switch times must be increasing numbers (s, file time), got "
                         + ", ".join(f"{float(v) + record.t_offset:.6g}" for v in s))
    if s[0] <= t[0] or s[-1] >= t[-1]:
        raise ValueError(f"switch times must lie inside the record, from "
                         f"{t[0] + record.t_offset:.6g} to {t[-1] + record.t_offset:.6g} s "
                         f"(file time), got {', '.join(f'{v + record.t_offset:.6g}' for v in s)}")
    cuts = np.searchsorted(t, s, side="left")
    sizes = np.diff(np.concatenate(([0], cuts, [len(t)])))
    if (sizes < MIN_SAMPLES).any():
        raise ValueError(f"each piece between switch times needs {MIN_SAMPLES} samples at "
                         f"least; these make pieces of {', '.join(map(str, sizes))}")
    bounds = np.concatenate(([0], cuts, [len(t)]))
    lines = [_line(t[lo:hi], record.load_point[lo:hi]) for lo, hi in zip(bounds, bounds[1:])]
    if len(s) == len(record.switch_times):
        velocities = tuple(record.velocities)
    else:
        velocities = tuple(float(v) if v > 10.0 * se else 0.0 for v, se, _ in lines)
    edges = (0.0, *map(float, s), float(t[-1]))
    pieces = pd.DataFrame({"t_start_s": edges[:-1], "t_end_s": edges[1:],
                           "velocity_m_s": velocities,
                           "velocity_se_m_s": [se for _, se, _ in lines],
                           "samples": sizes}, columns=list(PIECE_COLUMNS))
    return dataclasses.replace(record, velocities=velocities, switch_times=tuple(map(float, s)),
                               pieces=pieces)


#: a speed given by hand may differ from the displacement's by at most this factor
HAND_SPEED = 1.25


def with_velocities(record: LabRecord, velocities) -> LabRecord:
    """``record`` with its history's speeds ``velocities`` (m/s, one per piece, the first
    moving; 0 a hold) in place of those its displacement gave: the speeds the machine was
    commanded to run at, which a record's clock cannot bias."""
    v = np.asarray(velocities, dtype=float) + 0.0          # (−0 is 0)
    if v.shape != (len(record.velocities),):
        raise ValueError(f"{len(v)} velocities given, but the history has "
                         f"{len(record.velocities)} pieces (one speed each)")
    if not np.isfinite(v).all() or (v < 0).any() or not v[0] > 0:
        raise ValueError("velocities must be speeds of 0 (a hold) or more, the first above 0, "
                         f"got {', '.join(f'{x * 1e6:g}' for x in v)} µm/s")
    found = np.asarray(record.velocities, dtype=float)
    for i, (given, seen) in enumerate(zip(v, found)):
        # a commanded speed differs from the measured one by a calibration, not by a unit or
        # a hold
        if (given > 0) != (seen > 0) or (seen > 0 and not
                                         1 / HAND_SPEED <= given / seen <= HAND_SPEED):
            raise ValueError(f"velocity {i + 1} given as {given * 1e6:g} µm/s, where the "
                             f"displacement moves at {seen * 1e6:.4g} µm/s (a hand speed must "
                             f"be within a factor {HAND_SPEED:g} of it, and 0 only at a hold)")
    return dataclasses.replace(record, velocities=tuple(map(float, v)),
                               pieces=record.pieces.assign(velocity_m_s=v))


def refine_switches(fit) -> tuple[object, pd.DataFrame]:
    """``(fit, table)``: each switch of ``fit``'s history profiled on the friction (module
    docstring), the model's record moved to the friction's switches and refitted (its fixed
    parameters and weights kept); ``table`` has :data:`SWITCH_COLUMNS`, one row per switch."""
    started, first = time.perf_counter(), fit
    rows, trials = [], 0
    for i in range(len(fit.model.record.switch_times)):
        fit, row, solves = _refine(fit, i)
        rows.append(row)
        trials += solves
    final, refit = fit, 0
    if fit is not first:
        # a held trend is settled again at the refined switches (fit_lab's _settle), from the
        # refined fit's values; every switch where the displacement put it: the first fit
        # stands (the same model, fitted again from its own values, changed nothing)
        model = dataclasses.replace(fit.model, steady_after=None, steady_fitted=None)
        final = fit_lab(model, fixed=fit.fixed, weights=fit.piece_weights,
                        start={n: fit.values[n] for n in model.parameters})
        # the refit may stop worse than the refined fit (squares of one trend model: a held
        # trend settled again is another)
        refit = final.solves
        if model.steady is None and not final.rss <= fit.rss:
            final = fit
    # the fit's cost is all of it: the first fit, every trial and the refits
    final = dataclasses.replace(final, solves=first.solves + trials + refit,
                                wall_s=first.wall_s + time.perf_counter() - started)
    return final, pd.DataFrame(rows, columns=list(SWITCH_COLUMNS))


def _refine(fit, i: int):
    """Switch ``i`` profiled and moved (module docstring): the fit there, its row and the
    solves it took."""
    from scipy.optimize import minimize_scalar
    rec = fit.model.record
    dt = float(np.median(np.diff(rec.t)))
    t0 = rec.switch_times[i]
    edges = (float(rec.t[0]), *rec.switch_times, float(rec.t[-1]))
    width = min(WINDOW_SAMPLES * dt, 0.25 * min(t0 - edges[i], edges[i + 2] - t0))
    # a held trend keeps its held and fitted pieces: every trial has the same basis
    fits, held = {}, None if fit.model.steady is None else fit.model.steady.fitted

    def at(ts: float):
        ts = float(ts)
        if ts not in fits:
            times = list(rec.switch_times)
            times[i] = ts
            try:
                model = dataclasses.replace(fit.model, record=with_switches(rec, times),
                                            steady_fitted=held)
            except ValueError:           # a piece too short: no trial there
                fits[ts] = None
                return None
            # from the nearest trial made (the squares' valley moves little between trials)
            near = min((s for s in fits if fits[s] is not None and fits[s].success),
                       key=lambda s: abs(s - ts), default=None)
            source = fit if near is None else fits[near]
            start = {n: source.values[n] for n in model.parameters}
            fits[ts] = fit_lab(model, fixed=fit.fixed, weights=fit.piece_weights, start=start,
                               uncertainty=False)
        return fits[ts]

    def squares(ts: float) -> float:
        # a trial with a failed solve (its budget, say) is no evidence where the switch is:
        # its squares are not those of the model
        f = at(ts)
        return (f.rss if f is not None and f.success and not f.failed_solves
                and np.isfinite(f.rss) else math.inf)

    # the scan from the displacement's time outwards, so that each trial starts next to one
    scan = np.linspace(t0 - width, t0 + width, SCAN)
    values = dict((ts, squares(ts)) for ts in sorted(scan, key=lambda ts: abs(ts - t0)))
    finite = [v for v in values.values() if math.isfinite(v)]
    if finite and max(finite) - min(finite) <= FLAT * CHI2_95_1DOF * fit.walk_variance:
        # flat over the window: the friction places no switch in it (both ends open), and the
        # displacement's time is kept without a search (a shortcut of the rule below, taken
        # with a margin: this unit is the displacement's fit's, and a search between the
        # scan's points may find squares lower than the scan's)
        return (fit, _flat_row(fit, i, fits, squares, t0, (t0 - width, t0 + width)),
                _solves(fits, fit))
    k = int(np.argmin([values[ts] for ts in scan]))
    lo, hi = scan[max(k - 1, 0)], scan[min(k + 1, SCAN - 1)]
    minimize_scalar(squares, bounds=(lo, hi), method="bounded",
                    options={"xatol": TOLERANCE * dt})
    best_t = min(fits, key=lambda ts: squares(ts))
    if not np.isfinite(squares(best_t)):     # no trial fitted: the displacement's switch kept
        best_t = t0
        fits[t0] = fit
    # a trial has no noise model: the best's is refitted from its values (a warm start that
    # stays there)
    trial = fits[best_t]
    best = refit = fit_lab(trial.model, fixed=fit.fixed, weights=fit.piece_weights,
                           start={n: trial.values[n] for n in trial.model.parameters})
    unit = best.walk_variance
    level = squares(best_t) + CHI2_95_1DOF * unit
    ends, closed = _ends(fits, squares, best_t, t0 - width, t0 + width, level)
    rise = (squares(t0) - squares(best_t)) / unit
    if best_t != t0 and (not any(closed) or rise <= REJECTED):
        # the friction does not place the switch, or does not reject the displacement's: the
        # displacement's time is kept
        best_t, best = t0, fit
    within = [fits[ts] for ts in fits if squares(ts) <= level]
    return (best, _row(i, rec.file_time, t0, best_t, ends, closed, rise, len(fits), within),
            _solves(fits, fit) + refit.solves)


def _solves(fits: dict, fit) -> int:
    """The forward solves of a switch's trial fits (``fit``, the one it started from, not
    counted)."""
    return sum(f.solves for f in fits.values() if f is not None and f is not fit)


def _row(i, file_time, t0, best_t, ends, closed, rise, n_fits, within) -> dict:
    """Switch ``i``'s row of the table (times in the file's time: ``file_time`` of the
    record's), the ranges of :data:`RANGED` over the fits ``within`` its interval."""
    row = {"switch": i + 1, "displacement_s": float(file_time(t0)),
           "friction_s": float(file_time(best_t)), "low95_s": float(file_time(ends[0])),
           "high95_s": float(file_time(ends[1])),
           "low_closed": closed[0], "high_closed": closed[1], "rise_at_displacement": rise,
           "disagree": bool(rise > REJECTED), "fits": n_fits}
    for p in RANGED:
        vals = [f.values[p] for f in within]
        row[f"{p}_min"], row[f"{p}_max"] = min(vals), max(vals)
    return row


def _flat_row(fit, i, fits, squares, t0, window) -> dict:
    """The row of a switch whose scan stayed within 3.84 noise variances: the displacement's
    time, the window's ends open, the ranges over every trial that fitted."""
    within = [f for f in fits.values() if f is not None and f.success] or [fit]
    least = min(squares(ts) for ts in fits)
    rise = (squares(t0) - least) / fit.walk_variance if math.isfinite(least) else math.nan
    return _row(i, fit.model.record.file_time, t0, t0, window, (False, False), rise, len(fits),
                within)


def _ends(fits, squares, best_t: float, low: float, high: float, level: float):
    """The switch interval's ends and whether each is closed: from the best time, the nearest
    trial above ``level`` on each side, bisected :data:`BISECT` times; open at ``low`` or
    ``high`` where none is. A trial that failed is no evidence: it closes no end."""
    ends, closed = [], []
    for side, edge in ((-1, low), (1, high)):
        outside = [ts for ts in fits if (ts - best_t) * side > 0
                   and level < squares(ts) < math.inf]
        if not outside:
            ends.append(edge)
            closed.append(False)
            continue
        out = min(outside, key=lambda ts: abs(ts - best_t))
        inside = max((ts for ts in fits if (ts - best_t) * side >= 0
                      and abs(ts - best_t) < abs(out - best_t) and squares(ts) <= level),
                     key=lambda ts: abs(ts - best_t))
        for _ in range(BISECT):
            mid = 0.5 * (inside + out)
            inside, out = (inside, mid) if level < squares(mid) < math.inf else (mid, out)
        ends.append(0.5 * (inside + out))
        closed.append(True)
    return ends, closed
