"""The load point's displacement as a record's clock (``rsfbench lab fit --clock displacement``).

xlook and RSFit3000 fit a velocity step in the load point's displacement, not in time: the
model's load point is where the record's displacement sensor says it is. Where the time stamps
are the poorer channel (a clock that runs fast and slow), that is the better clock. Each
sample's displacement says when a load point that keeps the history's speeds exactly would be
there:

    τ = s′_k + (x − X_k) / v_k        in a piece k of speed v_k > 0,
    τ = s′_k + (t − s_k)              in a hold (a load point at rest keeps no time),

with X_k the displacement where piece k starts (at the record's start the median of the
first samples carried back to it at the first speed) and s′_k the
piece's start on the new clock: s′_0 = 0, s′_{k+1} = s′_k + (X_{k+1} − X_k)/v_k after a moving
piece, + (s_{k+1} − s_k) after a hold. Each switch s_k and its X_k are those of a two-line fit
within :data:`LOCAL` samples of the history's switch (a whole piece's line is bent by the
clock's wander). The clock's correction τ − t is then smoothed within each piece (the
displacement's glitches' from their neighbours', then a quadratic Savitzky–Golay filter of
:data:`SMOOTH` samples, which keeps a wander's slope at the piece's ends) and each sample's
model time is
t′ = t + that correction: the displacement corrects the clock's wander, while its own noise,
quantisation and glitches, which would reorder samples or tie them, average out. The
switches move with the clock; the fit runs on t′ as it runs on t, and the record keeps the
file's times (:attr:`~benchmarks.lab.step_data.LabRecord.file_t`) for its outputs.

What it assumes: the displacement measures the load point (not the sample's slip; a
``load_velocity`` column, integrated in time, has no clock of its own and is refused), the
history's speeds (found in the same displacement, or ``--velocities`` as commanded), and a clock
that wanders slowly against :data:`SMOOTH` samples (a faster jitter is not corrected).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from benchmarks.lab.step_data import LabRecord

__all__ = ["displacement_clock", "CLOCKS", "CORNER_SAMPLES", "SMOOTH"]

#: the clocks a fit may run on
CLOCKS = ("time", "displacement")
#: the first samples whose displacement, carried back to the record's start at the first
#: speed, gives the displacement there (their median: a glitch does not move it)
CORNER_SAMPLES = 9
#: samples of the Savitzky–Golay filter (quadratic) that smooths the clock's correction
SMOOTH = 51


def displacement_clock(record: LabRecord, refit: bool = True) -> tuple[LabRecord, list[str]]:
    """``(record on the displacement's clock, notes)``: the samples at the times t′ of the
    module docstring, in t′'s order, the switch times s′ on the same clock, the file's times
    kept in ``file_t``; ``refit`` False keeps the switches where they are (given by hand). A
    ValueError for a record whose load point was given as a velocity."""
    from scipy.signal import savgol_filter
    from benchmarks.lab.history import _glitches
    if "load_velocity" in record.columns:
        raise ValueError("--clock displacement needs a load_point column: a load_velocity "
                         "integrated in time has no clock of its own")
    t, x = record.t, record.load_point
    v = np.asarray(record.velocities, dtype=float)
    # each switch where the displacement bends in a short window about it (a whole piece's
    # line is bent by the clock's wander), and the displacement there; a switch given by
    # hand is kept where it was given
    given = np.asarray(record.switch_times, dtype=float)
    cuts = np.concatenate(([0], np.searchsorted(t, given), [len(t)]))
    corners = [_local_corner(t, x, at, cuts[k], cuts[k + 2]) if refit else
               (at, _corner(t, x, at, v[k], v[k + 1])) for k, at in enumerate(given)]
    recorded = np.concatenate(([0.0], [c for c, _ in corners]))
    if np.any(np.diff(recorded) <= 0):
        raise ValueError("--clock displacement: the switches re-fitted on the displacement do "
                         "not stay in order (a piece too short to hold its own corner); use "
                         "--clock time")
    corner = np.concatenate(([_corner(t, x, 0.0, v[0], v[0])], [X for _, X in corners]))
    # each piece's start on the new clock: the travel between corners at the piece's speed,
    # a hold's duration as recorded
    span = np.where(v[:-1] > 0, np.diff(corner) / np.where(v[:-1] > 0, v[:-1], 1.0),
                    np.diff(recorded))
    begin = np.concatenate(([0.0], np.cumsum(span)))
    piece = np.searchsorted(recorded[1:], t, side="right")
    moving = v[piece] > 0
    tau = begin[piece] + np.where(moving, (x - corner[piece]) / np.where(moving, v[piece], 1.0),
                                  t - recorded[piece])
    correction = np.empty(len(t))
    glitch = _glitches(x)
    for k in range(len(v)):                    # within each piece: a corner is no wander
        inside = np.flatnonzero(piece == k)
        y, good = (tau - t)[inside], ~glitch[inside]
        if 3 <= good.sum() < len(y):           # a glitch's time from its neighbours'
            y[~good] = np.interp(t[inside][~good], t[inside][good], y[good])
        size = min(SMOOTH, len(y) // 2 * 2 - 1)
        correction[inside] = savgol_filter(y, size, 2, mode="interp") if size > 2 else y
    clock = t + correction
    shift = min(float(clock.min()), 0.0)     # the model's time starts at 0
    clock -= shift
    # the samples a switch misplaced in time may overtake their neighbours: put in the clock's
    # order, and counted
    order = np.argsort(clock, kind="stable")
    moved = int((order != np.arange(len(order))).sum())
    if np.any(np.diff(clock[order]) <= 0):
        raise ValueError("--clock displacement: two samples get one time on the displacement's "
                         "clock; use --clock time")
    switches = tuple(float(b - shift) for b in begin[1:])
    notes = [f"the clock is the load point's displacement: the record's time corrected by "
             f"{np.min(correction):+.3g} to {np.max(correction):+.3g} s (the times reported "
             "are the file's; lab_fit_residuals.csv also has the model's, t_clock_s)"]
    if moved:
        notes.append(f"on the displacement's clock {moved} of {len(t)} samples change order "
                     "(near a switch that the displacement and the time stamps place "
                     "differently)")
    edges = (0.0, *switches, float(clock[order][-1]))
    at = np.searchsorted(np.asarray(switches), clock[order], side="right")
    pieces = record.pieces.assign(t_start_s=edges[:-1], t_end_s=edges[1:],
                                  samples=np.bincount(at, minlength=len(v)))
    return dataclasses.replace(record, t=clock[order], mu=record.mu[order],
                               load_point=x[order], switch_times=switches, pieces=pieces,
                               t_offset=record.t_offset + shift,
                               file_t=(t + record.t_offset)[order]), notes


def _corner(t, x, at: float, before: float, after: float) -> float:
    """The displacement at time ``at`` on the history's line: the median of the
    :data:`CORNER_SAMPLES` samples each side carried to it at their piece's speed (``before``,
    ``after``; interpolating across a switch would cut its corner)."""
    j = int(np.searchsorted(t, at))
    left, right = slice(max(j - CORNER_SAMPLES, 0), j), slice(j, j + CORNER_SAMPLES)
    near = np.concatenate([x[left] + before * (at - t[left]), x[right] - after * (t[right] - at)])
    return float(np.median(near))


#: samples either side of a switch in which its corner is fitted again for the clock
LOCAL = 100


def _local_corner(t, x, at: float, first: int, last: int) -> tuple[float, float]:
    """(time, displacement) of the corner of the continuous two-line fit of x(t) within
    :data:`LOCAL` samples of ``at`` and halfway to the switches beside it (samples ``first``
    and ``last``: a window over three lines would settle between their corners), without the
    displacement's glitches."""
    from benchmarks.lab.history import _best_hinge, _glitches, _refined
    j = int(np.searchsorted(t, at))
    lo, hi = max(j - LOCAL, (first + j) // 2), min(j + LOCAL, (j + last) // 2)
    keep = ~_glitches(x[lo:hi])
    tk, xk = t[lo:hi][keep], x[lo:hi][keep]
    c = _refined(tk, xk, 0, _best_hinge(tk, xk, side=3)[0], len(tk))
    a = np.column_stack([np.ones_like(tk), np.minimum(tk - c, 0), np.maximum(tk - c, 0)])
    return c, float(np.linalg.lstsq(a, xk, rcond=None)[0][0])
