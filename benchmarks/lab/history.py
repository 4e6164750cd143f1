"""The load point's history in a laboratory record: piecewise-constant speeds and the times it
switches between them, found in its displacement.

A continuous piecewise-linear fit of the displacement, split where one more piece lowers the
squares most (binary segmentation) as long as the two sides' speeds differ by more than
:data:`MIN_CHANGE` of the faster one and by :data:`SIGNIFICANCE` standard errors, each side
holding :data:`MIN_SAMPLES` samples. A split of a piece that holds several corners lands
between them, so each switch is then moved to its best place between its neighbours, pieces
left shorter than :data:`MIN_SAMPLES` are merged away, and each switch time is refined between
samples (the two pieces' continuous fit, minimised over the switch time). All of it is done
without the samples beyond :data:`GLITCH` robust σ of the displacement's running median (a
sensor's glitches, which pull a least-squares corner and inflate a speed's error until it
reads as a hold). A speed within
:data:`SIGNIFICANCE` standard errors of 0 (or under :data:`HOLD` of the fastest) is a hold (0).

Refused in one line: a record with no step (one speed throughout), one that opens with a hold,
a load point faster than :data:`LAB_FASTEST` (a unit slip), and one that moves back (a piece
whose speed is negative beyond its error, or a jump back beyond :data:`RESET` robust σ: a
sensor's reset). A load point outside :data:`LAB_TYPICAL` is warned
about (a :class:`~problems._validate.UnitWarning`: most likely a unit).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from benchmarks.lab.running import running_median
from problems._validate import warn_unit

__all__ = ["find_history", "MIN_SAMPLES", "MIN_CHANGE", "HOLD", "SIGNIFICANCE", "LAB_FASTEST",
           "PIECE_COLUMNS", "LAB_TYPICAL", "GLITCH", "GLITCH_WIDTH", "RESET", "NOISE_WIDTH"]

#: samples a piece of the history holds at least
MIN_SAMPLES = 20
#: two pieces whose speeds differ by less than this share of the faster are one (drift)
MIN_CHANGE = 0.1
#: a speed within :data:`SIGNIFICANCE` standard errors of 0, or below this share of the fastest
#: piece's (a noise-free record), is a hold
HOLD = 1e-6
#: two pieces' speeds must differ by this many standard errors
SIGNIFICANCE = 10.0
#: m/s: a load point faster than this is a unit slip (a displacement in µm read as m or mm);
#: rate-and-state velocity steps run at 0.01 µm/s to 1 mm/s
LAB_FASTEST = 1e-2
#: m/s: the speeds of most velocity-step tests; a load point outside is warned about (a unit)
LAB_TYPICAL = (1e-9, 3e-4)
#: the columns of the pieces table (:attr:`benchmarks.lab.step_data.LabRecord.pieces`)
PIECE_COLUMNS = ("t_start_s", "t_end_s", "velocity_m_s", "velocity_se_m_s", "samples")


def _hinge_fits(t, x, side: int = MIN_SAMPLES):
    """For every interior sample j as the switch, the continuous two-piece least-squares fit of
    x(t) in ``t`` (centred, scaled), each side holding ``side`` samples at least: its residual
    sum of squares and the two slopes."""
    n = len(t)
    ct = np.concatenate(([0.0], np.cumsum(t)))
    ctt = np.concatenate(([0.0], np.cumsum(t * t)))
    cx = np.concatenate(([0.0], np.cumsum(x)))
    ctx = np.concatenate(([0.0], np.cumsum(t * x)))
    j = np.arange(side, n - side + 1)
    c = t[j - 1]                    # the left piece is [0, j), its last sample at the switch
    nl, nr = j, n - j
    slt, sltt, slx, sltx = ct[j], ctt[j], cx[j], ctx[j]
    srt, srtt, srx, srtx = ct[n] - slt, ctt[n] - sltt, cx[n] - slx, ctx[n] - sltx
    lu, luu, lux = slt - nl * c, sltt - 2 * c * slt + nl * c * c, sltx - c * slx
    ru, ruu, rux = srt - nr * c, srtt - 2 * c * srt + nr * c * c, srtx - c * srx
    m = np.zeros((len(j), 3, 3))
    m[:, 0, 0], m[:, 0, 1], m[:, 0, 2] = n, lu, ru
    m[:, 1, 0], m[:, 1, 1] = lu, luu
    m[:, 2, 0], m[:, 2, 2] = ru, ruu
    rhs = np.stack([np.full(len(j), cx[n]), lux, rux], axis=1)
    beta = np.linalg.solve(m, rhs[..., None])[..., 0]
    rss = float(np.dot(x, x)) - np.einsum("ij,ij->i", beta, rhs)
    return j, rss, beta[:, 1], beta[:, 2], m


def _line(t, x):
    """Slope, its standard error and the residual sum of squares of a straight-line fit."""
    tc = t - t.mean()
    stt = float(np.dot(tc, tc))
    slope = float(np.dot(tc, x - x.mean()) / stt)
    r = x - x.mean() - slope * tc
    rss = float(np.dot(r, r))
    return slope, np.sqrt(rss / max(len(t) - 2, 1) / stt), rss


def _best_hinge(t, x, side: int = MIN_SAMPLES):
    """The best switch j of [0, len(t)) for a continuous two-piece fit, the two speeds and the
    standard error of their difference."""
    scale_t, scale_x = t[-1] - t[0], max(np.ptp(x), 1e-300)
    tt, xx = (t - t[0]) / scale_t, (x - x[0]) / scale_x
    j, rss, left, right, m = _hinge_fits(tt, xx, side)
    k = int(np.argmin(rss))
    cov = np.linalg.inv(m[k]) * max(rss[k], 0.0) / max(len(t) - 3, 1)
    se = np.sqrt(max(cov[1, 1] + cov[2, 2] - 2.0 * cov[1, 2], 0.0))
    speed = scale_x / scale_t
    return int(j[k]), left[k] * speed, right[k] * speed, se * speed


def _split(t, x):
    """The best switch of one piece, or None if no split makes two different speeds."""
    if len(t) < 2 * MIN_SAMPLES:
        return None
    j, v1, v2, se = _best_hinge(t, x)
    change = abs(v2 - v1)
    if change <= MIN_CHANGE * max(abs(v1), abs(v2)) or change <= SIGNIFICANCE * se:
        return None
    return j


def _relocated(t, x, cuts: list) -> list:
    """Each switch moved to the best place between its neighbours, as close to them as 3
    samples (a split of a piece that holds several corners lands between them; moved, it lands
    on one, and the sliver left beside it merges with its neighbour)."""
    for _ in range(3):
        for i in range(1, len(cuts) - 1):
            lo, hi = cuts[i - 1], cuts[i + 1]
            if hi - lo >= 6:
                cuts[i] = lo + _best_hinge(t[lo:hi], x[lo:hi], side=3)[0]
    return cuts


def _without_slivers(t, x, cuts: list) -> list:
    """Pieces of fewer than :data:`MIN_SAMPLES` samples gone: the two switches around one become
    one, at the best place between their neighbours (at the record's ends, the switch goes)."""
    while len(cuts) > 2:
        short = [k for k in range(len(cuts) - 1) if cuts[k + 1] - cuts[k] < MIN_SAMPLES]
        if not short:
            break
        k = short[0]
        if k == 0:
            del cuts[1]
        elif k == len(cuts) - 2:
            del cuts[-2]
        else:
            lo, hi = cuts[k - 1], cuts[k + 2]
            cuts[k:k + 2] = [lo + _best_hinge(t[lo:hi], x[lo:hi], side=3)[0]]
    return cuts


def _refined(t, x, lo, j, hi) -> float:
    """The switch between pieces [lo, j) and [j, hi) as a time, minimising the continuous
    two-piece fit's squares over t[j − 2] .. t[j + 1] (golden section)."""
    tt, xx = t[lo:hi] - t[lo], x[lo:hi] - x[lo]

    def rss(c):
        a = np.column_stack([np.ones_like(tt), np.minimum(tt - c, 0), np.maximum(tt - c, 0)])
        r = xx - a @ np.linalg.lstsq(a, xx, rcond=None)[0]
        return float(r @ r)

    a, b = tt[max(j - lo - 2, 0)], tt[min(j - lo + 1, hi - lo - 1)]
    g = (np.sqrt(5) - 1) / 2
    c1, c2 = b - g * (b - a), a + g * (b - a)
    f1, f2 = rss(c1), rss(c2)
    for _ in range(40):
        if f1 < f2:
            b, c2, f2 = c2, c1, f1
            c1 = b - g * (b - a)
            f1 = rss(c1)
        else:
            a, c1, f1 = c1, c2, f2
            c2 = a + g * (b - a)
            f2 = rss(c2)
    return float(t[lo] + 0.5 * (a + b))


#: a displacement sample further than this many robust σ (1.4826 × the median absolute
#: deviation) from the running median of :data:`GLITCH_WIDTH` samples about it is a glitch
GLITCH = 5.0
#: samples of the running median that glitches are measured from (a glitch spans fewer than
#: half of them)
GLITCH_WIDTH = 9


def _glitches(x: np.ndarray) -> np.ndarray:
    """The samples of the displacement ``x`` that are glitches: beyond :data:`GLITCH` σ of its
    running median, σ the sensor's noise read from the second differences (robustly: a
    straight line has none, and a glitch moves few of them). A monotone record's median is its
    own sample, so a clean corner (or a noise-free record) has none; a quantised sensor's
    flicker by one step is none either."""
    if len(x) < GLITCH_WIDTH:
        return np.zeros(len(x), bool)
    d = x - running_median(x, GLITCH_WIDTH)
    return np.abs(d) > GLITCH * _noise_scale(x)


def _noise_scale(x: np.ndarray) -> np.ndarray:
    """The displacement sensor's noise σ at each sample: the larger of the white noise read
    from the second differences (robustly: a straight line has none, and a glitch or a corner
    moves few of them) and the local spread about a running median of :data:`NOISE_WIDTH`
    samples (noise that follows itself, as a filtered sensor's, has small second differences),
    at least one quantisation step (the smallest change that is not 0) and 1e-9 of the travel
    (round-off)."""
    second = np.diff(x, 2)
    step = np.abs(np.diff(x))
    step = step[step > 1e-12 * max(float(np.ptp(x)), 1e-300)]
    white = max(1.4826 * float(np.median(np.abs(second - np.median(second)))) / math.sqrt(6.0),
                float(step.min()) if len(step) else 0.0, 1e-9 * float(np.ptp(x)))
    width = max(min(NOISE_WIDTH, len(x) // 2 * 2 - 1), 1)
    spread = 1.4826 * running_median(np.abs(x - running_median(x, width)), 4 * width + 1)
    return np.maximum(spread, white)


#: samples of the running median about which the sensor's local noise is read
NOISE_WIDTH = 51
#: a drop of the displacement's running median by more than this many σ of the sensor's noise
#: that stays over the next :data:`NOISE_WIDTH` samples is a jump back (a sensor's reset or
#: re-zero), not noise nor a dropout
RESET = 20.0


def find_history(t: np.ndarray, x: np.ndarray, what: str = "the load point",
                 t_offset: float = 0.0):
    """(velocities, switch_times, pieces) of the displacement ``x`` (m) at times ``t`` (s): see
    the module docstring, found without the displacement's glitches (:func:`_glitches`; each
    piece's ``samples`` counts them too). ``what`` names the channel in a refusal, whose times
    are the file's: ``t`` + ``t_offset`` (what ``--window`` takes)."""
    _refuse_jumps_back(t, x, what, t_offset)
    glitch = _glitches(x)
    if not glitch.any() or (~glitch).sum() < 2 * MIN_SAMPLES:
        return _found(t, x, what, t_offset)
    velocities, switches, pieces = _found(t[~glitch], x[~glitch], what, t_offset)
    cuts = np.searchsorted(t, switches, side="left")
    return velocities, switches, pieces.assign(
        t_end_s=(*switches, float(t[-1])), samples=np.diff(np.concatenate(([0], cuts, [len(t)]))))


def _found(t, x, what: str, t_offset: float = 0.0):
    """:func:`find_history` of samples without glitches."""
    cuts = [0, len(t)]
    while True:
        added = False
        for lo, hi in zip(cuts[:-1], cuts[1:]):
            j = _split(t[lo:hi], x[lo:hi])
            if j is not None:
                cuts = sorted(cuts + [lo + j])
                added = True
                break
        if not added:
            break
    cuts = _without_slivers(t, x, _relocated(t, x, cuts))
    # merge neighbours that do not differ (a split may leave two near-equal speeds behind)
    fits = [_line(t[lo:hi], x[lo:hi]) for lo, hi in zip(cuts[:-1], cuts[1:])]
    i = 1
    while i < len(cuts) - 1:
        v1, v2 = fits[i - 1][0], fits[i][0]
        if abs(v2 - v1) <= MIN_CHANGE * max(abs(v1), abs(v2)):
            del cuts[i]
            fits[i - 1:i + 1] = [_line(t[cuts[i - 1]:cuts[i]], x[cuts[i - 1]:cuts[i]])]
        else:
            i += 1
    speeds = np.array([f[0] for f in fits])
    errors = np.array([f[1] for f in fits])
    floor = SIGNIFICANCE * errors + HOLD * speeds.max(initial=0.0)
    back = speeds < -floor
    if back.any():
        k = int(np.argmax(back))
        raise ValueError(f"{what} moves back at {speeds[k]:.3g} m/s from t = "
                         f"{t[cuts[k]] + t_offset:.9g} s to {t[cuts[k + 1] - 1] + t_offset:.9g}"
                         " s (the file's time): a fit needs a load point that only moves "
                         "forward or holds")
    fastest = speeds.max()
    if fastest <= 0:
        raise ValueError(f"{what} does not move")
    if fastest > LAB_FASTEST:
        raise ValueError(f"{what} moves at up to {fastest:.3g} m/s, faster than a velocity-step "
                         f"test runs (up to {LAB_FASTEST:g} m/s): is its unit right? (a "
                         "displacement in µm is load_point=COLUMN:um)")
    velocities = tuple(float(v) if v > f else 0.0 for v, f in zip(speeds, floor))
    if len(velocities) == 1:
        raise ValueError(f"{what} moves at one speed throughout ({velocities[0]:.4g} m/s): "
                         "the record has no velocity step (a change of speed by more than "
                         f"{MIN_CHANGE:.0%} over {MIN_SAMPLES} samples or more)")
    moving = [v for v in velocities if v > 0]
    if max(moving) > LAB_TYPICAL[1] or min(moving) < LAB_TYPICAL[0]:
        warn_unit(f"{what} moves at {min(moving):.3g} to {max(moving):.3g} m/s, outside the "
                  f"{LAB_TYPICAL[0]:g} to {LAB_TYPICAL[1]:g} m/s of most velocity-step tests: "
                  "is its unit right? (a displacement in µm is load_point=COLUMN:um, in mm :mm)")
    if velocities[0] == 0.0:
        raise ValueError(f"{what} holds from the record's start to t = "
                         f"{t[cuts[1]] + t_offset:.9g} s (the file's time): the "
                         "fit starts from steady sliding; start the record (--window) while "
                         "the load point moves")
    switches = tuple(_refined(t, x, lo, j, hi)
                     for lo, j, hi in zip(cuts[:-2], cuts[1:-1], cuts[2:]))
    bounds = (0.0, *switches, float(t[-1]))
    pieces = pd.DataFrame({"t_start_s": bounds[:-1], "t_end_s": bounds[1:],
                           "velocity_m_s": velocities, "velocity_se_m_s": errors,
                           "samples": np.diff(cuts)}, columns=list(PIECE_COLUMNS))
    return velocities, switches, pieces


def _refuse_jumps_back(t, x, what: str, t_offset: float = 0.0) -> None:
    """A ValueError where the displacement's running median drops by more than :data:`RESET`
    σ of the sensor's noise (:func:`_noise_scale`; a sensor's reset: the fit would read it as
    a speed). A glitch of fewer than half the running median's samples moves it not."""
    if len(x) < GLITCH_WIDTH:
        return
    scale = _noise_scale(x)
    drop = np.diff(running_median(x, GLITCH_WIDTH))
    k = int(np.argmin(drop / scale[1:]))
    w = NOISE_WIDTH
    stays = np.median(x[k + 1:k + 1 + w]) - np.median(x[max(k + 1 - w, 0):k + 1])
    if drop[k] < -RESET * scale[k + 1] and stays < -RESET * scale[k + 1]:
        raise ValueError(f"{what} jumps back by {-drop[k] * 1e6:.3g} µm at t = "
                         f"{t[k + 1] + t_offset:.9g} s (the file's time; a sensor's reset or "
                         "re-zero?): fit a --window on one side of it")
