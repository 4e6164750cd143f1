"""What a laboratory recording says: its stick–slip events, their metrics, the fault's friction
against slip, and the apparatus, measured as Urata et al. (2017, Sect. 2.2) measured them and on
the conventions of the forward model, so that what is measured here is what a simulation is
compared with.

**Events.** Found first from the force alone: the drops of the load cell's force Fs, low-passed
at ``DETECT_HZ``, that exceed a threshold far above the noise (a zigzag with hysteresis, robust
to noise and to a slow drift). Where the slip rate can be had (a slip column, or accelerations),
each event is then timed by the model's rule: it starts when the slip rate exceeds 10·vLs and
ends when it falls back below vLs — or below 3 σ of the slip rate's noise, when that is larger. The
first event (its stick began before the record did) and an event still running at the record's
end are dropped.

**Metrics per event**, as :func:`benchmarks.physics.metrics.event_metrics` defines them: ΔT from
the previous event's start; Δμ = (largest Fs since the previous event ended − smallest Fs during
the event)/Fn, each extremum that of a polynomial of degree ``EXTREMUM_DEGREE`` fitted to the
raw samples around it (those within ``EXTREMUM_BAND`` of the drop from it, or 3 σ of the noise),
so that noise averages out instead of biasing the max and the min apart; slip from the start to
the end (the slip column smoothed at the first of ``TIMING_HZ`` quiet enough to time the events,
or the accelerations integrated twice); the peak slip rate (the largest slope of a quartic fitted
to the slip where its rate is above half its peak).

**Slip from accelerations**: a = a1 − a2 (or a1) low-passed at ``ACCELERATION_HZ`` and
integrated over a window around each event; the drift is removed per event (the slip rate is a
line through its values in the quiet stretches before and after the event, subtracted).

**The fault's friction** Ft = Fs − m·a1 (Eq. 3: the upper specimen's own acceleration a1, not
the slip's a1 − a2, as the upper specimen is what the spring and the fault push), Fs low-passed
at ``FORCE_HZ`` and a1 at
``ACCELERATION_HZ`` (the paper's 400 Hz and 750 Hz), zero phase. Slip-weakening curves, one per
event, are Ft/Fn against the slip since the event started, from its start to its end: the
convention of :func:`benchmarks.physics.curves.event_curve`. A record without accelerations
(or without a mass) has no curves: the load cell's force is not the fault's friction.

**The apparatus**: the stiffness k from Fs against the spring's stretch l − u (the table's
position minus the slip, Eq. 5) when both are recorded, else from dFs/dl during the slow part of
the sticks (the paper's k = Ḟs/vLs, biased low by the creep during the stick), else from Ḟs/vLs
with vLs given; vLs from the table's position over the middle of the sticks, vLf and df from
its speed after each event: above half-way between vLs and its peak for df, its travel beyond
vLs over that pulse (vLf − vLs)·df (Sect. 2.2.2).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit
from scipy.integrate import cumulative_trapezoid

from benchmarks.physics.chain import ACCELERATION_HZ, FORCE_HZ, event_levels
from benchmarks.physics.chain import crossing as _crossing
from benchmarks.physics.chain import lowpass as _lowpass
from benchmarks.physics.chain import smooth as _smooth
from benchmarks.physics.metrics import METRICS
from problems._validate import PLAUSIBLE, check_positive, warn_implausible, warn_unit

__all__ = ["Analysis", "analyse", "DETECT_HZ", "FORCE_HZ", "ACCELERATION_HZ", "EXTREMUM_BAND"]

#: low-pass (Hz) of the force for finding events and of the slip for timing them
DETECT_HZ = 50.0
# FORCE_HZ, ACCELERATION_HZ: the measurement chain's (benchmarks.physics.chain), one for both
# a recording's curves and the model's
#: an extremum is found again on the force smoothed at this (Hz), and a polynomial of degree
#: ``EXTREMUM_DEGREE`` fitted to the samples within ``EXTREMUM_BAND`` of the drop from it
FINE_HZ = 500.0
#: the slip column is smoothed at the first of these (Hz) quiet enough to time the events
TIMING_HZ = (750.0, 300.0, 150.0, DETECT_HZ)
#: the table's position is smoothed at this (Hz) for its speed (the fast loading lasts ~40 ms)
TABLE_HZ = 50.0
EXTREMUM_BAND = 0.002
EXTREMUM_DEGREE = 4
#: a force drop is an event when it exceeds this fraction of the larger drops (their 90th
#: percentile) and many times the noise
DROP_FRACTION = 0.3


@dataclass
class Analysis:
    """The events of a recording (one row each: ``t_start``, ``t_end`` and the four
    :data:`~benchmarks.physics.metrics.METRICS`, NaN where the record cannot give one), the
    slip-weakening curves (``event_id``, ``slip_m``, ``friction``; None without accelerations),
    the apparatus (``stiffness`` N/m, ``vls``, ``vlf`` m/s, ``df`` s, ``normal_force`` N,
    ``mass`` kg, each None where it cannot be read) with how each was had (``how``), and the
    assumptions made (``notes``).

    Parameters
    ----------
    events : pandas.DataFrame
        One row per event: ``t_start``, ``t_end`` (s) and the metrics.
    curves : pandas.DataFrame, optional
        The slip-weakening curves: ``event_id``, ``slip_m`` (m), ``friction``.
    apparatus : dict
        stiffness (N/m), vls, vlf (m/s), df (s), normal_force (N), mass (kg).
    how : dict
        How each apparatus value was had, by name.
    notes : list of str
        The assumptions made.
    noise : dict
        The noise measured on the channels.
    slip_source : str
        Which channel the slip was read from.
    """

    events: pd.DataFrame = field(repr=False)
    curves: pd.DataFrame | None = field(repr=False)
    apparatus: dict
    how: dict
    notes: list[str]
    noise: dict
    slip_source: str


def analyse(rec, mass: float | None = None, vls: float | None = None,
            stiffness: float | None = None) -> Analysis:
    """Measure the recording ``rec`` (:class:`benchmarks.lab.channels.Recording`).

    Parameters
    ----------
    rec : Recording
        The recording.
    mass : float, optional
        The slider's mass (kg), for Ft = Fs − m·a.
    vls, stiffness : float, optional
        The slow load-point speed (m/s) and stiffness (N/m), standing for what the table's
        position would give (and then not measured).

    Returns
    -------
    Analysis

    Raises
    ------
    ValueError
        Naming the record and the check it fails (no event, channels that disagree, …)."""
    mass = None if mass is None else check_positive("mass", mass)
    vls = None if vls is None else check_positive("vls", vls)
    stiffness = None if stiffness is None else check_positive("stiffness", stiffness)
    for name, value in (("mass", mass), ("vls", vls), ("stiffness", stiffness)):
        if value is not None:                 # a unit slip in a given constant: warned
            warn_implausible(name, value)
    notes, how = [], {}
    t, fs = rec.t, rec["shear_force"]
    fs_smooth = _smooth(fs, DETECT_HZ, rec.rate)
    noise = {"shear_force": _noise(fs)}
    drops = _drops(fs_smooth, noise["shear_force"] * math.sqrt(2 * DETECT_HZ / rec.rate), rec)
    _check_slip_against_table(rec)
    acc = _acceleration(rec)
    slip_source = ("slip column" if rec.has("slip") else "accelerations" if acc is not None
                   else "force")
    if vls is not None:
        how["vls"] = "given"
    elif rec.has("table"):
        vls = _slow_speed(rec, drops)
        how["vls"] = f"the slope of {rec.where('table')} over the middle of the sticks"
    elif rec.has("slip"):
        vls = float((rec["slip"][-1] - rec["slip"][0]) / (t[-1] - t[0]))
        how["vls"] = "the record's mean slip rate (no table column, no vls given)"
        notes.append("vLs is the record's mean slip rate (no table column, no vls given): the "
                     "thresholds 10·vLs and vLs that time an event use it")
    events = _events(rec, drops, fs_smooth, acc, vls, slip_source, noise, notes)
    if acc is not None and rec.has("slip"):
        _check_acceleration_against_slip(rec, acc, events)
    if slip_source == "accelerations" and rec.has("table"):
        _check_events_against_table(rec, events)
    if acc is not None and mass is not None:
        _check_inertia(rec, mass, events)
    vlf = df = None
    if rec.has("table") and vls is not None:
        vlf, df = _fast_phase(rec, events, vls)
        how["vlf"] = how["df"] = (f"the speed of {rec.where('table')} after each event: "
                                  "above half-way to its peak for df, its excess travel "
                                  "(vLf − vLs)·df")
    k, how["stiffness"] = _stiffness(rec, fs_smooth, drops, stiffness, vls, how.get("vls"))
    if slip_source == "force" and k is not None and rec.has("table"):
        events["slip_m"] = _force_slip(rec, fs_smooth, events, k)
        notes.append("slip per event from the spring (Δl − ΔFs/k): the record has neither a "
                     "slip column nor accelerations")
    curves = None
    if acc is not None and mass is not None:
        curves = _curves(rec, events, mass)
    elif acc is None:
        notes.append("no slip-weakening curves: the record has no accelerations, and the load "
                     "cell's force is not the fault's friction (Ft = Fs − m·a)")
    else:
        notes.append("no slip-weakening curves: give the slider's mass (Ft = Fs − m·a)")
    apparatus = {"stiffness": k, "vls": vls, "vlf": vlf, "df": df,
                 "normal_force": float(np.median(rec["normal_force"])), "mass": mass}
    keep = events.drop(columns=["_i0", "_i1", "_imax", "_imin", "_drop"])
    keep.attrs = {}
    return Analysis(keep, curves, apparatus, how, notes, noise, slip_source)


# --- signals --------------------------------------------------------------------------------

# _smooth and _lowpass: benchmarks.physics.chain's smooth and lowpass (the measurement chain)


def _noise(x: np.ndarray) -> float:
    """The white noise's σ: the median absolute first difference over 0.6745·√2 (a smooth
    signal sampled fast differs little from sample to sample)."""
    d = np.diff(x)
    return float(np.median(np.abs(d - np.median(d))) / (0.6745 * math.sqrt(2.0)))


def _rate_gain(cutoff: float, rate: float) -> float:
    """How much of a signal's white noise σ its rate carries, smoothed at ``cutoff``
    (:func:`_smooth`, then the centred difference): the norm of that filter."""
    n = int(8 * rate / (2 * math.pi * cutoff)) + 3
    impulse = np.zeros(2 * n + 1)
    impulse[n] = 1.0
    response = np.gradient(_smooth(impulse, cutoff, rate), 1.0 / rate)
    return float(np.sqrt(np.sum(response ** 2)))


def _acceleration(rec):
    """a1 − a2 (or a1), or None."""
    if not rec.has("acceleration"):
        return None
    a = rec["acceleration"]
    return a - rec["acceleration_lower"] if rec.has("acceleration_lower") else a


# --- units: two channels that measure one thing ------------------------------------------------

#: over a record the slider keeps up with the load point: their travels' ratio is near 1, and a
#: ratio beyond these is a unit slip (10³ for mm read as m)
TRAVEL_RATIO = (0.3, 3.0)


def _check_slip_against_table(rec) -> None:
    if not (rec.has("slip") and rec.has("table")):
        return
    slip, table = rec["slip"], rec["table"]
    ratio = (slip[-1] - slip[0]) / (table[-1] - table[0])
    if not TRAVEL_RATIO[0] <= ratio <= TRAVEL_RATIO[1]:
        raise ValueError(f"{rec.source}: over the record {rec.where('slip')} advances "
                         f"{ratio:.3g} times as far as {rec.where('table')}; the slider keeps up "
                         "with the load point, so one of them is in another unit")


def _check_acceleration_against_slip(rec, acc, events) -> None:
    """The accelerations integrated twice over each event against the slip column's change: the
    same slip, unless one of them is in another unit (g read as m/s² is 9.8× off)."""
    t, slip, rate = rec.t, rec["slip"], rec.rate
    acc_f, q = _lowpass(acc, ACCELERATION_HZ, rate), max(int(0.01 * rate), 10)
    ratios = []
    for i0, i1 in zip(events._i0.to_numpy()[:8], events._i1.to_numpy()[:8]):
        a, b = max(int(i0) - q, 0), min(int(i1) + q, len(t))
        if i1 < 0 or b - a < 8 or slip[i1] == slip[i0]:
            continue
        _, u, _ = _integrated(t, acc_f, a, b, int(i0), int(i1))
        ratios.append((u[i1 - a] - u[i0 - a]) / (slip[i1] - slip[i0]))
    if not ratios:
        return
    ratio = float(np.median(ratios))
    if not TRAVEL_RATIO[0] <= ratio <= TRAVEL_RATIO[1]:
        names = rec.where("acceleration") + (f" − {rec.where('acceleration_lower')}"
                                             if rec.has("acceleration_lower") else "")
        raise ValueError(f"{rec.source}: the slip of an event integrated from {names} is "
                         f"{ratio:.3g} times the change of {rec.where('slip')} over it; they "
                         "measure one slip, so one of them is in another unit (an "
                         "acceleration in g read as m/s2 is 9.8 times off)")


#: the inertia m·a of a stick–slip event is of the order of its force drop (0.53–0.57 of it in
#: W1–W4, both laws, measured on the model's recordings): beyond this multiple the mass or the
#: acceleration's unit is wrong
INERTIA_RATIO_MAX = 5.0
#: below this fraction of the drop the inertia is negligible: a mass in the wrong unit (g as
#: kg, or 1 kg for a 1000 kg slider), warned
INERTIA_RATIO_MIN = 1e-3


def _check_inertia(rec, mass: float, events) -> None:
    """Refuse a mass whose m·a dwarfs the force's drops (:data:`INERTIA_RATIO_MAX`)."""
    a1 = _lowpass(rec["acceleration"], ACCELERATION_HZ, rec.rate)
    fs = rec["shear_force"]
    drops = [fs[int(i)] - fs[int(j)] for i, j in zip(events._imax, events._imin)]
    drop = float(np.median(drops))
    inertia = mass * float(np.max(np.abs(a1)))
    if drop > 0 and inertia < INERTIA_RATIO_MIN * drop:
        warn_unit(f"{rec.source}: m·a reaches {inertia:.3g} N with the mass {mass:.6g} kg, "
                  f"{inertia / drop:.2g} of the force's drop in an event ({drop:.3g} N; about "
                  "half of it in the paper's windows): the friction Ft = Fs − m·a and the "
                  "curves are then the load cell's force; is the mass in kg?")
    if drop > 0 and inertia > INERTIA_RATIO_MAX * drop:
        raise ValueError(f"{rec.source}: m·a reaches {inertia:.3g} N with the mass "
                         f"{mass:.6g} kg, {inertia / drop:.3g} times the force's drop in an "
                         f"event ({drop:.3g} N); in stick–slip the inertia is of the order of "
                         f"the drop (half of it in the paper's windows): the mass (kg) or the "
                         f"unit of {rec.where('acceleration')} is wrong")


def _check_events_against_table(rec, events) -> None:
    t, table = rec.t, rec["table"]
    span = np.interp([events.t_start.iloc[0], events.t_start.iloc[-1]], t, table)
    ratio = events.slip_m.iloc[:-1].sum() / (span[1] - span[0])
    if not TRAVEL_RATIO[0] <= ratio <= TRAVEL_RATIO[1]:
        names = rec.where("acceleration") + (f" − {rec.where('acceleration_lower')}"
                                             if rec.has("acceleration_lower") else "")
        raise ValueError(f"{rec.source}: the events' slip integrated from {names} is {ratio:.3g} "
                         f"times the travel of {rec.where('table')} between them; the slider "
                         "keeps up with the load point, so one of them is in another unit")


# --- events -----------------------------------------------------------------------------------

def _drops(fs_smooth: np.ndarray, sigma: float, rec) -> list[tuple[int, int]]:
    """(index of the maximum, index of the minimum) of each large drop of the smoothed force."""
    h = max(10.0 * sigma, 1e-12 * float(np.max(np.abs(fs_smooth))))
    extrema = list(_zigzag(np.ascontiguousarray(fs_smooth), h))
    pairs = [(a, b) for a, b in zip(extrema, extrema[1:]) if fs_smooth[a] > fs_smooth[b]]
    if not pairs:
        raise ValueError(f"{rec.source}: no stick–slip event in {rec.where('shear_force')}: "
                         "the force never drops above its noise")
    size = np.array([fs_smooth[a] - fs_smooth[b] for a, b in pairs])
    big = size >= DROP_FRACTION * np.percentile(size, 90)
    return [p for p, keep in zip(pairs, big) if keep]


@njit(cache=True)
def _zigzag(x: np.ndarray, h: float) -> np.ndarray:
    """Indices of alternating extrema of ``x``, each differing from the last by at least ``h``
    (a reversal smaller than ``h`` is noise)."""
    out = np.empty(len(x), np.int64)
    n, i_ext, up = 0, 0, 0                   # up: 0 undecided, 1 rising, -1 falling
    lo, hi, i_lo, i_hi = x[0], x[0], 0, 0
    for i in range(1, len(x)):
        xi = x[i]
        if up == 0:
            if xi > hi:
                hi, i_hi = xi, i
            if xi < lo:
                lo, i_lo = xi, i
            if hi - lo >= h:                  # the first swing: its start is an extremum
                up = 1 if i_hi > i_lo else -1
                out[n] = i_lo if up == 1 else i_hi
                n += 1
                i_ext = i_hi if up == 1 else i_lo
        elif up == 1:
            if xi > x[i_ext]:
                i_ext = i
            elif xi <= x[i_ext] - h:
                out[n] = i_ext
                n += 1
                up, i_ext = -1, i
        else:
            if xi < x[i_ext]:
                i_ext = i
            elif xi >= x[i_ext] + h:
                out[n] = i_ext
                n += 1
                up, i_ext = 1, i
    return out[:n]


def _extremum(t: np.ndarray, x: np.ndarray, i: int, drop: float, sign: float, lo: int,
              hi: int, rate: float, sigma: float) -> tuple[float, int]:
    """The extreme value of the force ``x`` near index ``i``, and the index of the extreme
    sample (a maximum for ``sign`` +1, a
    minimum for −1), searched within [lo, hi). A model of the samples that cannot overshoot
    them:

    * the fit: found again on ``x`` smoothed at ``FINE_HZ`` within ``DETECT_HZ``'s reach of
      ``i``, then the extreme of a polynomial of degree ``EXTREMUM_DEGREE`` fitted to the raw
      samples whose finely smoothed value is within ``EXTREMUM_BAND`` × ``drop`` (or 3 σ, the
      noise's, if wider) of it: the noise averages out instead of biasing the extreme (a
      stick–slip extreme is lopsided, a slow rise and a fast drop, which a parabola fits badly);
      the lift the noise still gives the fit's extreme is taken off (:func:`_noise_lift`);
    * the bounds, from the samples alone (:func:`_sample_bounds`): between two samples a smooth
      force goes beyond their extreme by at most an eighth of its second difference (the
      three-point parabola's vertex), and noise moves the extreme sample by a few σ. A fit
      beyond them — a polynomial around a corner, or over a few samples of a coarse record —
      overshoots, and the samples' own estimate is taken instead."""
    reach = int(3 * rate / (2 * math.pi * DETECT_HZ)) + 2
    a0, b0 = max(lo, i - reach), min(hi, i + reach + 1)
    fine = sign * _smooth(x[a0:b0], FINE_HZ, rate)
    j = int(np.argmax(fine))
    target = fine[j] - max(EXTREMUM_BAND * drop, 3.0 * sigma)
    a, b = j, j + 1
    while a > 0 and fine[a - 1] >= target:
        a -= 1
    while b < len(fine) and fine[b] >= target:
        b += 1
    if b - a < 2 * EXTREMUM_DEGREE + 1:        # too few samples for the polynomial: widen
        a, b = max(0, j - EXTREMUM_DEGREE), min(len(fine), j + EXTREMUM_DEGREE + 1)
    tt = (t[a0 + a:a0 + b] - t[a0 + j]) * rate              # in samples: well conditioned
    with warnings.catch_warnings():         # a coarse record's few samples: the bounds decide
        warnings.simplefilter("ignore", np.exceptions.RankWarning)
        coef = np.polyfit(tt, sign * x[a0 + a:a0 + b], EXTREMUM_DEGREE)
    grid = np.linspace(tt[0], tt[-1], 8 * len(tt))
    fitted = float(np.max(np.polyval(coef, grid))) - _noise_lift(tt, coef, grid, sigma)
    estimate, low, high = _sample_bounds(sign * x[a0:b0], a, b, sigma)
    extreme = a0 + a + int(np.argmax(sign * x[a0 + a:a0 + b]))
    return float(sign * (fitted if low <= fitted <= high else estimate)), extreme


#: the draws of :func:`_noise_lift`, and its seed (fixed: a record measures the same each time)
LIFT_DRAWS, LIFT_SEED = 256, 20261129


def _noise_lift(tt: np.ndarray, coef: np.ndarray, grid: np.ndarray, sigma: float) -> float:
    """How far white noise of ``sigma`` lifts the largest value of a polynomial fitted to the
    samples at ``tt`` above the largest value of the polynomial it was fitted from (a
    parametric bootstrap: ``coef``'s values at ``tt`` plus :data:`LIFT_DRAWS` draws of the
    noise, refitted). The maximum of a fit is biased up by its noise — by about
    var(slope)/(2 |curvature|) at a smooth peak, 0.16 σ at 5 kHz on W2's force peak — and this
    is that bias, measured on the fit itself (what it leaves is the misfit of the polynomial's
    shape over the band)."""
    if not sigma > 0.0 or len(tt) <= len(coef):
        return 0.0
    draws = np.random.default_rng(LIFT_SEED).standard_normal((len(tt), LIFT_DRAWS))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", np.exceptions.RankWarning)
        noisy = np.polyfit(tt, np.polyval(coef, tt)[:, None] + sigma * draws, len(coef) - 1)
    lifted = np.vander(grid, len(coef)) @ noisy
    return float(np.mean(lifted.max(axis=0)) - np.max(np.polyval(coef, grid)))


#: how far noise moves the extreme sample from the force's extreme, in σ of the noise: the
#: largest of a few dozen normal deviates stays within this but for 1 in 10⁴
NOISE_REACH = 4.0


def _sample_bounds(y: np.ndarray, a: int, b: int, sigma: float) -> tuple[float, float, float]:
    """(an estimate, the lowest, the highest) plausible maximum of the samples ``y`` near the
    largest of ``y[a:b]`` (a maximum: the caller flips a minimum's sign), from the samples
    alone. Near its maximum a force is concave, so between two samples it lies below the
    secants of the neighbouring pairs, extended (:func:`_concave_bound`): at a corner (a slow
    rise, then the drop) that bound is the largest sample itself, where a parabola through the
    three samples would overshoot by an eighth of the drop between them. The estimate is the
    three-point parabola's vertex held under that bound; noise moves the largest sample by up
    to :data:`NOISE_REACH` σ either way."""
    j = a + int(np.argmax(y[a:b]))
    vertex = bound = float(y[j])
    if 0 < j < len(y) - 1:
        y0, y1, y2 = y[j - 1], y[j], y[j + 1]
        curvature = y0 - 2.0 * y1 + y2                      # ≤ 0 at a largest sample
        if curvature < 0:
            vertex = float(y1 - (y2 - y0) ** 2 / (8.0 * curvature))
        bound = _concave_bound(y, j)
    estimate = max(min(vertex, bound), float(y[j]))
    reach = NOISE_REACH * sigma
    return estimate, float(y[j]) - reach, max(estimate, bound) + reach


def _concave_bound(y: np.ndarray, j: int) -> float:
    """The most a concave function through the samples ``y`` reaches between ``j − 1`` and
    ``j + 1``: on each interval [p, p + 1] it lies under the secant through samples p − 1, p
    extended forward and under the one through p + 1, p + 2 extended back; the top of the lower
    of the two lines. Where a secant falls off the record, the larger sample of the interval
    plus the other line's rise over it (no bound tighter than the samples allow)."""
    n, best = len(y), float(y[j])
    for p in (j - 1, j):
        q = p + 1
        if p < 1 or q + 1 >= n:
            continue
        sl, sr = y[p] - y[p - 1], y[q + 1] - y[q]
        if sl <= sr:                        # not concave here (noise): no bound from it
            return math.inf
        t = (y[q] - y[p] + sl * p - sr * q) / (sl - sr)
        t = min(max(t, p), q)
        best = max(best, float(min(y[p] + sl * (t - p), y[q] + sr * (t - q))))
    return best


def _peak_rate(t: np.ndarray, u: np.ndarray, v: np.ndarray, a: int, b: int) -> float:
    """The peak slip rate in [a, b): where ``v`` (a smoothed slip rate) peaks, the largest slope
    of a quartic fitted to the slip ``u`` over the samples where ``v`` is above half its peak
    (and at least 9): the slip's noise averaged over them, not maximised."""
    if b - a < 3:
        return math.nan
    i = a + int(np.argmax(v[a:b]))
    lo, hi = i, i + 1
    while lo > a and v[lo - 1] >= 0.5 * v[i]:
        lo -= 1
    while hi < b and v[hi] >= 0.5 * v[i]:
        hi += 1
    while hi - lo < 9 and (lo > 0 or hi < len(u)):
        lo, hi = max(0, lo - 1), min(len(u), hi + 1)
    if hi - lo < 9:                       # too few samples for the quartic
        return math.nan
    tt = t[lo:hi] - t[i]
    scale = tt[-1] - tt[0]
    coef = np.polyfit(tt / scale, u[lo:hi], 4)
    grid = np.linspace(tt[0], tt[-1], 8 * (hi - lo)) / scale
    return float(np.max(np.polyval(np.polyder(coef), grid)) / scale)


def _integrated(t, acc_f, a: int, b: int, quiet_before: int, quiet_after: int):
    """Slip rate and slip over samples [a, b) from the acceleration, the drift removed: a line
    through the integrated rate's values in [a, quiet_before) and [quiet_after, b) is
    subtracted. Returns (v, u, σ of v in the quiet stretches)."""
    tt = t[a:b]
    v = cumulative_trapezoid(acc_f[a:b], tt, initial=0.0)
    quiet = np.zeros(b - a, bool)
    quiet[:max(quiet_before - a, 2)] = True
    quiet[min(quiet_after - a, b - a - 2):] = True
    c1, c0 = np.polyfit(tt[quiet] - tt[0], v[quiet], 1)
    v = v - (c0 + c1 * (tt - tt[0]))
    sigma = float(np.std(v[quiet]))
    return v, cumulative_trapezoid(v, tt, initial=0.0), sigma


def _slip_rate(rec, vls, noise):
    """The slip column smoothed for timing, its slip rate, a less smoothed rate for the peak,
    and the timing rate's noise; the noises and the smoothing chosen go into ``noise``."""
    t, rate = rec.t, rec.rate
    # the least smoothing whose slip-rate noise is a fifth of the start's threshold: the
    # events are timed as sharply as the noise allows (a heavy smoothing spreads a short
    # event's slip beyond its start and end)
    sigma_u = noise["slip"] = _noise(rec["slip"])
    level = TIMING_HZ[-1]
    for level in TIMING_HZ:
        if sigma_u * _rate_gain(level, rate) <= 2.0 * (vls or 0.0):
            break
    u_s = _smooth(rec["slip"], level, rate)
    v_s = np.gradient(u_s, t)
    v_fast = np.gradient(_smooth(rec["slip"], TABLE_HZ * 4, rate), t)
    sigma_v = sigma_u * _rate_gain(level, rate)
    noise["slip_rate"] = sigma_v
    noise["slip_timing_hz"] = level
    return u_s, v_s, v_fast, sigma_v


def _time_by_rate(rec, imax, v, u, sv, lo, hi, off, vls, peak_of) -> dict:
    """One event's columns from its slip rate ``v`` and slip ``u`` (both from sample ``off``,
    noise ``sv``), searched in ``v[lo:hi]``: it starts above 10·vLs (10·sv without vLs) and
    ends below max(vLs, 3·sv); one reaching the window's edge is open (``_i1`` −1).
    ``peak_of`` is the (t, slip, rate) its peak slip rate is read from."""
    t = rec.t
    start_level, end_level = event_levels(vls, sv)
    peak = lo + int(np.argmax(v[lo:hi]))
    if v[peak] < start_level:           # no event could start: vLs is wrong
        raise ValueError(
            f"{rec.source}: the event at t = {t[imax]:.6g} s slips at "
            f"{v[peak]:.3g} m/s at its fastest, below the rate that starts an event "
            f"(10·vLs = {start_level:.3g} m/s, vLs {vls:.3g} m/s): vLs is the load "
            "point's slow speed in m/s (75 µm/s is 7.5e-05)" if vls else
            f"{rec.source}: the event at t = {t[imax]:.6g} s does not slip above the "
            "noise of the slip rate")
    i0 = peak
    while i0 > lo and v[i0 - 1] >= start_level:
        i0 -= 1
    i1 = peak
    while i1 < hi and v[i1] >= end_level:
        i1 += 1
    if i1 >= hi or i0 <= lo:
        return {"_i0": i0 + off, "_i1": -1}            # not timed: an open event
    ts = _crossing(t[off:], v, start_level, i0)
    te = _crossing(t[off:], v, end_level, i1)
    return {"_i0": i0 + off, "_i1": i1 + off, "t_start": ts, "t_end": te,
            "slip_m": float(np.interp(te, t[off:off + len(u)], u)
                            - np.interp(ts, t[off:off + len(u)], u)),
            "peak_velocity_m_s": _peak_rate(*peak_of, i0, i1 + 1)}


def _drop_columns(rec, fs_smooth, imax, imin, prev_end, next_start, sigma) -> dict:
    """One event's friction drop between its force extremes, the same on the raw samples
    over the whole stick and event, and the samples between the extremes."""
    t, fs, fn, rate = rec.t, rec["shear_force"], rec["normal_force"], rec.rate
    drop = fs_smooth[imax] - fs_smooth[imin]
    fs_max, jmax = _extremum(t, fs, imax, drop, 1.0, prev_end, imin, rate, sigma)
    fs_min, jmin = _extremum(t, fs, imin, drop, -1.0, imax + 1, next_start, rate, sigma)
    fn_event = float(np.median(fn[imax:imin + 1]))
    # the definition on the raw samples alone, over the whole stick and the whole event
    return {"friction_drop": (fs_max - fs_min) / fn_event,
            "friction_drop_raw": (float(np.max(fs[prev_end:imin + 1]))
                                  - float(np.min(fs[imax:next_start]))) / fn_event,
            "drop_samples": jmin - jmax}


def _events(rec, drops, fs_smooth, acc, vls, slip_source, noise, notes) -> pd.DataFrame:
    t, fn, rate = rec.t, rec["normal_force"], rec.rate
    n = len(t)
    if slip_source == "slip column":
        u_s, v_s, v_fast, sigma_v = _slip_rate(rec, vls, noise)
    acc_f = _lowpass(acc, ACCELERATION_HZ, rate) if acc is not None else None
    rows, integrated = [], {}
    quiet = max(int(0.01 * rate), 10)
    for j, (imax, imin) in enumerate(drops):
        prev_end = drops[j - 1][1] if j else 0
        next_start = drops[j + 1][0] if j + 1 < len(drops) else n
        q = max(quiet, imin - imax)
        a, b = max(prev_end, imax - q, 0), min(next_start, imin + q, n)
        row = {"_imax": imax, "_imin": imin, "_drop": j}
        if slip_source == "slip column":
            row.update(_time_by_rate(rec, imax, v_s, u_s, sigma_v, a, b, 0, vls,
                                     (t, rec["slip"], v_fast)))
        elif slip_source == "accelerations":
            v, u, sv = _integrated(t, acc_f, a, b, imax, imin)
            integrated[j] = (a, v, u)
            row.update(_time_by_rate(rec, imax, v, u, sv, 0, b - a, a, vls, (t[a:], u, v)))
        else:
            row.update(_i0=imax, _i1=imin if imin < n - 1 else -1, t_start=float(t[imax]),
                       t_end=float(t[imin]), slip_m=math.nan, peak_velocity_m_s=math.nan)
        row.update(_drop_columns(rec, fs_smooth, imax, imin, prev_end, next_start,
                                 noise["shear_force"]))
        rows.append(row)
    table = pd.DataFrame(rows)
    for column in ("t_start", "t_end", "slip_m", "peak_velocity_m_s"):
        if column not in table:
            table[column] = math.nan
    table["recurrence_s"] = table.t_start.diff()
    # the first event's stick began before the record: dropped; so is one still open at the end
    complete = (table.index > 0) & (table._i1 >= 0) & table.t_end.notna()
    if slip_source == "force":
        notes.append("events timed by the force alone (start at its maximum, end at its "
                     "minimum): the record has neither a slip column nor accelerations")
    table = table[complete].reset_index(drop=True)
    if len(table) < 2:
        raise ValueError(f"{rec.source}: {len(table)} complete stick–slip "
                         f"event{'s' if len(table) != 1 else ''} (the first and any still "
                         "open at the end are partial): a mean and its scatter need at least "
                         "two")
    _check_resolution(rec, table)
    _compare_raw_drop(table, noise["shear_force"] / float(np.median(fn)), notes)
    _note_noise_at_coarse_rate(rec, table, noise["shear_force"] / float(np.median(fn)), notes)
    out = table[["t_start", "t_end", *METRICS, "friction_drop_raw", "drop_samples", "_i0",
                 "_i1", "_imax", "_imin", "_drop"]].copy()
    out.attrs["integrated"] = integrated
    return out


#: the fewest sampling intervals across a drop, from the force's peak to its trough, for the
#: drop to be measured. Measured on docs/examples/apparatus.toml (10–12 ms events) sampled from
#: the run's dense output: every event's Δμ within 0.56 % of the run's at 500 Hz (5 intervals),
#: 0.80 % at 400 Hz (4); 1.3–1.7 % at 250–200 Hz (3), 3.3 % at 100 Hz (1–2)
MIN_DROP_SAMPLES = 4


def _check_resolution(rec, table) -> None:
    """Refuse a record whose events its sampling does not resolve (:data:`MIN_DROP_SAMPLES`),
    naming the rate it needs."""
    across = float(np.median(table.drop_samples))
    if across >= MIN_DROP_SAMPLES:
        return
    # a drop spanning n intervals lasts at least n − 1 of them: the rate that puts the least
    # allowed count across the shortest such drop; under two intervals its length is unknown
    if across >= 2:
        need = f"record at {MIN_DROP_SAMPLES * rec.rate / (across - 1):.3g} Hz or faster"
    else:
        need = (f"the drops last less than {2.0 / rec.rate:.3g} s, so record faster than "
                f"{MIN_DROP_SAMPLES * rec.rate / 2.0:.3g} Hz at the least (their duration is "
                "not in the record)")
    raise ValueError(f"{rec.source}: at {rec.rate:.6g} Hz the force falls from its peak to its "
                     f"trough within {across:g} sampling interval{'s' if across != 1 else ''} "
                     f"(the median event): the drops are not resolved, and their size, timing "
                     f"and slip would be made up; observe needs {MIN_DROP_SAMPLES} intervals "
                     f"across a drop: {need}")


#: below this rate (Hz) a noisy force's extremes carry a bias the fit cannot average out: the
#: few samples at the drop's corner. Measured on docs/examples/apparatus.toml with white noise
#: of 1 % of the drop (`rsfbench study observe`, observe_noise_bias.csv): Δμ off by −0.05 σ at
#: 10 kHz, +0.75 σ at 1 kHz, +2.75 σ at 500 Hz (σ: the noise in μ)
NOISY_RATE = 5_000.0
#: the bias per σ of the noise said at rates below ``NOISY_RATE`` (the 500 Hz figure)
NOISY_BIAS = 2.8


def _note_noise_at_coarse_rate(rec, table, sigma_mu: float, notes: list) -> None:
    """Say the bias a noisy force's drop carries at a coarse rate (:data:`NOISY_RATE`), when it
    exceeds 0.1 % of the drop: not removed, so an inversion is told."""
    drop = float(np.median(table.friction_drop))
    bias = NOISY_BIAS * sigma_mu / drop if drop > 0 else 0.0
    if rec.rate < NOISY_RATE and bias > 1e-3:
        notes.append(f"the force's noise (σ = {sigma_mu:.2g} in μ, {sigma_mu / drop:.2g} of the "
                     f"drop) at {rec.rate:.6g} Hz biases the friction drop high by up to about "
                     f"{100 * bias:.2g} % (the extremes at the drop's corner have few samples "
                     "to average; measured on model recordings): record faster or with less "
                     "noise, or widen σ of Δμ in the inversion")


def _compare_raw_drop(table, sigma_mu: float, notes: list) -> None:
    """Say where the drop from the fitted extremes and the raw samples' (their largest before
    the event less their smallest during it) differ beyond what noise and sampling allow: an
    extreme found in the wrong place (a foreshock, a double peak, a glitch)."""
    raw, fitted = table.friction_drop_raw.to_numpy(), table.friction_drop.to_numpy()
    # noise lifts the raw max and lowers the raw min (NOISE_REACH σ each); sampling misses the
    # extremes by a small fraction of the drop (measured: 0.6 % at 5 intervals across)
    low, high = fitted * (1 - 0.01) - 1e-12, fitted * (1 + 0.01) + 2 * NOISE_REACH * sigma_mu
    bad = np.flatnonzero(~((raw >= low) & (raw <= high)) & np.isfinite(raw) & np.isfinite(fitted))
    if len(bad):
        worst = max(bad, key=lambda k: abs(raw[k] / fitted[k] - 1))
        notes.append(f"the friction drop of {len(bad)} event{'s' if len(bad) > 1 else ''} "
                     f"(event starting at {table.t_start.iloc[worst]:.6g} s: fitted "
                     f"{fitted[worst]:.5g}, raw samples' max − min {raw[worst]:.5g}) differs "
                     "from the raw samples' beyond the noise: an extreme away from the drop "
                     "(a foreshock, a double peak, a glitch); look at observe.png")


# --- the apparatus -----------------------------------------------------------------------------

def _sticks(drops, n: int, rate: float, skip: float = 0.3, tail: float = 0.1):
    """(start, end) of the middle of each stick between two drops: ``skip`` of it after the
    drop (the fast loading, the healing) and ``tail`` before the next one (the creep) left out."""
    out = []
    for (_, imin), (imax, _) in zip(drops, drops[1:]):
        length = imax - imin
        a, b = imin + int(skip * length), imax - int(tail * length)
        if b - a >= max(10, int(0.01 * rate)):
            out.append((a, b))
    return out


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    """The least-squares slope of ``y`` on ``x``."""
    xm = x - x.mean()                    # (elementwise sums: numpy's dot calls BLAS, whose
    return float((xm * (y - y.mean())).sum() / (xm * xm).sum())      # threads cost more here)


def _slow_speed(rec, drops) -> float | None:
    """vLs: the median slope of the table's position over the middle of the sticks."""
    table = _smooth(rec["table"], DETECT_HZ, rec.rate)
    slopes = [_slope(rec.t[a:b], table[a:b]) for a, b in _sticks(drops, len(rec.t), rec.rate)]
    if not slopes:
        return None
    v = float(np.median(slopes))
    if not v > 0:
        raise ValueError(f"{rec.source}: {rec.where('table')} does not advance during the "
                         f"sticks (slope {v:.3g} m/s): the load point's position must increase")
    return v


def _fast_phase(rec, events, vls: float) -> tuple[float, float]:
    """(vLf, df): after each event the table's speed (its position smoothed at ``TABLE_HZ`` and
    differentiated) is above the half-way level between vLs and its peak for df, and its travel
    over that pulse beyond vLs is (vLf − vLs)·df; the medians over the events. (vLs, 0) when no
    pulse stands above the speed's noise."""
    t, rate = rec.t, rec.rate
    x = _smooth(rec["table"], TABLE_HZ, rate)
    w = np.gradient(x, t)
    margin = int(3 * rate / (2 * math.pi * TABLE_HZ)) + 1
    sticks = _sticks_between(events, len(t))
    quiet = np.concatenate([w[(a + b) // 2:b] for a, b in sticks]) if sticks else w
    sigma_w = 1.4826 * float(np.median(np.abs(quiet - np.median(quiet))))
    speeds, durations = [], []
    for e, nxt in sticks:
        a, b = max(e - margin, 0), e + int(0.4 * (nxt - e))
        if b - a < 10:
            continue
        i = a + int(np.argmax(w[a:b]))
        if w[i] - vls < 5.0 * sigma_w:
            continue
        half = vls + 0.5 * (w[i] - vls)
        c0, c1 = i, i
        while c0 > a and w[c0 - 1] >= half:
            c0 -= 1
        while c1 < b - 1 and w[c1 + 1] >= half:
            c1 += 1
        t0, t1 = _crossing(t, w, half, c0), _crossing(t, -w, -half, c1 + 1)
        d = t1 - t0
        lo, hi = max(c0 - margin, 0), min(c1 + 1 + margin, len(t) - 1)
        excess = (x[hi] - x[lo]) - vls * (t[hi] - t[lo])
        if d > 0:
            speeds.append(vls + excess / d)
            durations.append(d)
    if not speeds:
        return vls, 0.0
    return float(np.median(speeds)), float(np.median(durations))


def _sticks_between(events, n: int) -> list[tuple[int, int]]:
    """(end of an event, start of the next) in samples, for each event."""
    ends = events._i1.to_numpy()
    starts = np.append(events._i0.to_numpy()[1:], n)
    return [(int(e), int(s)) for e, s in zip(ends, starts) if s > e]


def _stiffness(rec, fs, drops, given, vls, vls_how) -> tuple[float | None, str]:
    """k (N/m) and how it was had (module docstring); ``vls_how``: how vLs was had."""
    if given is not None:
        return given, "given"
    t, rate = rec.t, rec.rate
    sticks = _sticks(drops, len(t), rate, skip=0.05, tail=0.05)
    middle = _sticks(drops, len(t), rate)
    if not sticks or not middle:
        return None, ("not measured: no stick is long enough (at least 10 samples and 10 ms "
                      "between two drops)")
    if rec.has("table") and rec.has("slip"):
        stretch = _smooth(rec["table"] - rec["slip"], DETECT_HZ, rate)
        k = float(np.median([_slope(stretch[a:b], fs[a:b]) for a, b in sticks]))
        how = (f"Fs against the spring's stretch ({rec.columns['table']!r} − "
               f"{rec.columns['slip']!r}) over the sticks (Eq. 5)")
        names = f"{rec.where('table')} and {rec.where('slip')}"
    elif rec.has("table"):
        table = _smooth(rec["table"], DETECT_HZ, rate)
        k = float(np.median([_slope(table[a:b], fs[a:b]) for a, b in middle]))
        how = (f"dFs/dl over the slow middle of the sticks ({rec.columns['table']!r}; the "
               "paper's Ḟs/vLs: the creep during the stick makes it slightly low)")
        names = rec.where("table")
    elif vls is not None:
        k = float(np.median([_slope(t[a:b], fs[a:b]) for a, b in middle])) / vls
        how = (f"Ḟs/vLs over the slow middle of the sticks (vLs: {vls_how}; the creep makes "
               "it low)")
        names = f"{rec.where('shear_force')} and vLs ({vls_how})"
    else:
        return None, "not measured: the record has no table column and no vls was given"
    plausible = PLAUSIBLE["stiffness"]
    if not plausible.low <= k <= plausible.high:
        raise ValueError(f"{rec.source}: the stiffness from {names} is {k:.4g} N/m, which no "
                         "apparatus has (plausible: "
                         f"{plausible.low:g} to {plausible.high:g} N/m): one of the columns is "
                         "in another unit")
    return k, how


def _force_slip(rec, fs, events, k: float) -> np.ndarray:
    """Slip per event from the spring: Δl − ΔFs/k (``fs`` smoothed) between the event's start
    and end."""
    t = rec.t
    ts, te = events.t_start.to_numpy(), events.t_end.to_numpy()
    table = _smooth(rec["table"], DETECT_HZ, rec.rate)        # the caller's: a table column
    dl = np.interp(te, t, table) - np.interp(ts, t, table)
    return dl - (np.interp(te, t, fs) - np.interp(ts, t, fs)) / k


def _curves(rec, events, mass: float) -> pd.DataFrame:
    """Ft/Fn against the slip since the start of each event, from its start to its end."""
    t, rate = rec.t, rec.rate
    ft = _lowpass(rec["shear_force"], FORCE_HZ, rate) - mass * _lowpass(
        rec["acceleration"], ACCELERATION_HZ, rate)           # a1, not acc = a1 − a2 (Eq. 3)
    mu = ft / rec["normal_force"]
    integrated = events.attrs.get("integrated", {})
    if rec.has("slip") and not integrated:
        slip = _lowpass(rec["slip"], ACCELERATION_HZ, rate)
    parts = []
    for k, ev in events.iterrows():
        i0, i1 = int(ev._i0), int(ev._i1)
        inside = np.arange(i0, i1 + 1)
        if int(ev._drop) in integrated:
            a, _, u = integrated[int(ev._drop)]
            u_at = np.interp(t[inside], t[a:a + len(u)], u)
            u0 = np.interp(ev.t_start, t[a:a + len(u)], u)
        else:
            u_at, u0 = slip[inside], np.interp(ev.t_start, t, slip)
        parts.append(pd.DataFrame({"event_id": k + 1, "slip_m": u_at - u0,
                                   "friction": mu[inside]}))
    return pd.concat(parts, ignore_index=True)
