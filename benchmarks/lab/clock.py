"""The load point's displacement as a record's clock (``rsfbench lab fit --clock displacement``).

xlook and RSFit3000 fit a velocity step in the load point's displacement, not in time: the
model's load point is where the record's displacement sensor says it is. Where the time stamps
are the poorer channel (an irregular or jittery clock, a logger that stamps blocks of samples),
that is the better clock. Here each sample's model time is the time at which a load point that
keeps the history's speeds exactly reaches the sample's measured displacement:

    t′ = s′_k + (x − X_k) / v_k        in a piece k of speed v_k > 0,
    t′ = s′_k + (t − s_k)              in a hold (a load point at rest keeps no time),

with X_k the displacement where piece k starts (at the record's start, then at each switch
s_k: the median of the samples about it carried to it at their piece's speed) and s′_k the piece's start on the new clock: s′_0 = 0,
s′_{k+1} = s′_k + (X_{k+1} − X_k)/v_k after a moving piece, + (s_{k+1} − s_k) after a hold.
The switches are then where the displacement says, whatever the time stamps there. The fit
runs on t′ as it runs on t.

What it assumes: the displacement measures the load point (not the sample's slip), and the
speeds are the history's (found in the same displacement, :mod:`benchmarks.lab.history`). Its
noise becomes the clock's: a displacement noise larger than the travel between two samples
reorders them; they are put in the clock's order, and the record's notes say how many moved.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from benchmarks.lab.step_data import LabRecord

__all__ = ["displacement_clock", "CLOCKS", "CORNER_SAMPLES"]

#: the clocks a fit may run on
CLOCKS = ("time", "displacement")


def displacement_clock(record: LabRecord) -> tuple[LabRecord, list[str]]:
    """``(record on the displacement's clock, notes)``: the samples at the times t′ of the
    module docstring, in t′'s order, with the switch times on the same clock (``t_offset``
    kept: the file's time of the clock's 0 is the first sample's)."""
    t, x = record.t, record.load_point
    v = np.asarray(record.velocities, dtype=float)
    s = np.asarray(record.switch_times, dtype=float)
    recorded = np.concatenate(([0.0], s))
    corner = np.array([_corner(t, x, at, v[max(k - 1, 0)], v[k])
                       for k, at in enumerate(recorded)])
    # each piece's start on the new clock: the travel between corners at the piece's speed,
    # a hold's duration as recorded
    span = np.where(v[:-1] > 0, np.diff(corner) / np.where(v[:-1] > 0, v[:-1], 1.0),
                    np.diff(recorded))
    begin = np.concatenate(([0.0], np.cumsum(span)))
    piece = record.piece_index()
    moving = v[piece] > 0
    clock = begin[piece] + np.where(moving, (x - corner[piece]) / np.where(moving, v[piece], 1.0),
                                    t - recorded[piece])
    departure = float(np.max(np.abs(clock - t)))
    shift = min(float(clock.min()), 0.0)      # the model's time starts at 0
    clock, begin = clock - shift, begin - shift
    order = np.argsort(clock, kind="stable")
    moved = int((order != np.arange(len(order))).sum())
    if np.any(np.diff(clock[order]) <= 0):
        raise ValueError("--clock displacement: two samples are at the same displacement, so "
                         "the displacement gives them one time; use --clock time")
    notes = ["the clock is the load point's displacement (each sample at the time a load point "
             "keeping the history's speeds reaches its displacement; at most "
             f"{departure:.3g} s from the record's time)"]
    if moved:
        notes.append(f"the displacement as the clock puts {moved} of {len(t)} samples in another "
                     "order than the record's time: its noise exceeds the travel between "
                     "samples there, and that noise is now the clock's")
    switches = tuple(map(float, begin[1:]))
    edges = (0.0, *switches, float(clock.max()))
    pieces = record.pieces.assign(t_start_s=edges[:-1], t_end_s=edges[1:])
    return dataclasses.replace(record, t=clock[order], mu=record.mu[order],
                               load_point=x[order], switch_times=switches, pieces=pieces), notes


#: samples either side of a switch whose displacement, carried to it at their piece's speed,
#: gives the displacement there (their median: a glitch does not move it)
CORNER_SAMPLES = 9


def _corner(t, x, at: float, before: float, after: float) -> float:
    """The displacement at time ``at`` on the history's line: the median of the
    :data:`CORNER_SAMPLES` samples each side carried to it at their piece's speed (``before``,
    ``after``; interpolating across a switch would cut its corner)."""
    j = int(np.searchsorted(t, at))
    left, right = slice(max(j - CORNER_SAMPLES, 0), j), slice(j, j + CORNER_SAMPLES)
    near = np.concatenate([x[left] + before * (at - t[left]), x[right] - after * (t[right] - at)])
    return float(np.median(near))
