"""The measurement chain of a slip-weakening curve: what ``rsfbench observe`` does to a
recording's channels before a curve is read, as one record and one function, so that the model's
curves can be passed through the very same chain before they are compared.

``observe`` (:mod:`benchmarks.lab.events`) reads a curve from a recording sampled at ``rate_hz``,
in this order:

1. the load cell's force Fs low-passed at ``force_hz`` and the upper specimen's acceleration a1
   at ``acceleration_hz`` (zero-phase 4th-order Butterworth, :func:`lowpass`; the paper's 400 Hz
   and 750 Hz), the fault's friction μ = (Fs − m·a1)/Fn (Eq. 3);
2. the slip column low-passed at ``slip_hz`` (the same Butterworth);
3. the event timed on the slip rate of the slip column smoothed at ``timing_hz`` (near-Gaussian,
   :func:`smooth`; the least smoothing that the slip's noise allows): it starts at the first
   sample at or above ``start_level`` (10·vLs) and ends at the first below ``end_level``
   (max(vLs, 3 σ of the smoothed rate's noise));
4. the curve: μ against the filtered slip since the start (the start's slip interpolated at the
   crossing of the start level), over the samples from the start to the end.

:class:`Chain` holds those numbers; :meth:`Chain.record` is what ``observe`` writes into
observations.json (``measurement``), :meth:`Chain.from_record` reads it back (None from a file
written before it: no chain, the model's curves are compared as they are).
:meth:`Chain.model_curve` applies the chain to a model's run around one event (its dense
output over the event and a margin either side, :attr:`Chain.margin_s`): sampled at the record's
rate at :data:`PHASES` offsets of the sampling grid (a recorder's samples fall anywhere in an
event) and averaged; with the slip's noise (below), :data:`NOISY_PHASES` phases whose samples
are pooled, not averaged.

**The slip column's noise is part of the chain** (``slip_noise``, the white noise's σ that
``observe`` measured on the raw column). A curve is friction against *measured* slip, and where
an event starts the slip moves less per sample than its noise: a recorded curve is the true one
smeared along the slip axis, and its start is placed by a noisy crossing. On a record with slip
noise of a few Lc that smear is most of what the curve's first Lc shows, and a noise-free model
curve misplaces Lc (measured on a W2 recording with 1 % noise: ``docs/inversion.md``).
So each sampling phase gets its own draw of that noise before the slip is filtered, and the
curve is every phase's samples pooled, sorted by their noisy slip: a recording of many events
as ``observe`` would read it. They are not averaged by interpolation: where the slip has
stopped (the arrest's pile of samples) the noise is larger than the slip's change, and a
curve interpolated between samples sorted by noisy slip jumps as the parameters move; the
likelihood reads the pooled samples with the kernel it reads the events with
(:mod:`benchmarks.inversion.curve_likelihood`). The event is
timed on the noise-free slip: ``observe`` times it on a slip smoothed so much (50 Hz at 1 %
noise) that its noise moves the start's crossing by a slip far below the noise itself, and a
noisy timing would walk past the end of a window the run cuts short (the last event of a run
that ends within the margin), losing the point's curve. The draws are fixed: one seeded
stream, laid out sample by sample (sample i of phase k is its (i·phases + k)-th number), so a
sample of the window keeps its noise when b and Lc move the event and the window grows or
shrinks; the model's curve changes with its parameters, not with the draw. The
friction's own noise is left out: it has zero mean along the curve and the likelihood takes it
from the events' spread.

An observed curve whose slip was integrated from accelerations (a record without a slip column)
has its own drift removal per event; the model's side of that chain is not made: its record says
``slip_from = "accelerations"`` and the model's curve gets the friction filters and the sampling,
its slip the model's own (:meth:`Chain.model_curve`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass

import numpy as np
from numba import njit

from benchmarks.physics.pchip import pchip

__all__ = ["Chain", "smooth", "lowpass", "event_levels", "friction", "crossing", "FORCE_HZ",
           "ACCELERATION_HZ", "SLIP_HZ", "PHASES", "NOISY_PHASES", "START_FACTOR"]

#: low-pass (Hz) of the force in the fault's friction (the paper's 400 Hz)
FORCE_HZ = 400.0
#: low-pass (Hz) of the accelerations (the paper's 750 Hz)
ACCELERATION_HZ = 750.0
#: low-pass (Hz) of the slip column a curve is read against
SLIP_HZ = ACCELERATION_HZ
#: an event starts when the slip rate exceeds this multiple of vLs (the model's own rule)
START_FACTOR = 10.0
#: the sampling grid's offsets (fractions of a sample) the model's chained curve is averaged over
#: without slip noise
PHASES = 4
#: the phases averaged over with slip noise (each its own draw of the noise)
NOISY_PHASES = 32
#: the Butterworth filters' order (zero phase: applied forward and back)
ORDER = 4
#: the samples scipy's sosfiltfilt pads each end with for that filter (3 × (2 sections + 1)):
#: a shorter signal cannot be filtered
PADLEN = 3 * (2 * (ORDER // 2) + 1)


def smooth(x: np.ndarray, cutoff: float, rate: float) -> np.ndarray:
    """A near-Gaussian smoothing of standard deviation 1/(2π·``cutoff``) s: three passes of a
    moving average. Its kernel is positive, so it never overshoots a sharp drop (a Butterworth
    filter rings there, and its extremes would be the filter's, not the signal's); O(n).

    Parameters
    ----------
    x : numpy.ndarray
        The signal, sampled at ``rate`` along its last axis.
    cutoff : float
        The smoothing's frequency (Hz).
    rate : float
        The sampling rate (Hz).

    Returns
    -------
    numpy.ndarray
        The smoothed signal (a copy).
    """
    from scipy.ndimage import uniform_filter1d      # scipy's filters load when first used
    sigma = rate / (2.0 * math.pi * cutoff)
    width = max(int(round(math.sqrt(4.0 * sigma * sigma + 1.0))), 1)
    y = np.asarray(x, dtype=float)
    if width < 2:
        return y.copy()
    for _ in range(3):
        y = uniform_filter1d(y, width, axis=-1, mode="nearest")
    return y


def lowpass(x: np.ndarray, cutoff: float, rate: float) -> np.ndarray:
    """Zero-phase 4th-order Butterworth low-pass (unchanged when ``cutoff`` ≥ 0.45 × rate).

    Parameters
    ----------
    x : numpy.ndarray
        The signal, sampled at ``rate`` along its last axis.
    cutoff : float
        The cutoff (Hz).
    rate : float
        The sampling rate (Hz).

    Returns
    -------
    numpy.ndarray
        The filtered signal.
    """
    if cutoff >= 0.45 * rate:
        return np.asarray(x, dtype=float)
    x = np.asarray(x, dtype=float)
    x0 = x[..., :1]
    return _sosfiltfilt(*_butter(float(cutoff), float(rate)), x - x0) + x0


def _sosfiltfilt(sos: np.ndarray, zi: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=-1)`` (its default odd padding of
    :data:`PADLEN` samples), step by step as scipy takes them, with the sections' steady
    state ``zi`` given (scipy solves for it at every call: a third of a model curve's time)."""
    from scipy.signal import sosfilt
    if x.shape[-1] <= PADLEN:
        raise ValueError(f"the signal must be longer than {PADLEN} samples to be filtered, "
                         f"got {x.shape[-1]}")
    left, right = x[..., :1], x[..., -1:]
    ext = np.concatenate([2 * left - x[..., PADLEN:0:-1], x,
                          2 * right - x[..., -2:-(PADLEN + 2):-1]], axis=-1)
    zi = zi.reshape((len(sos),) + (1,) * (x.ndim - 1) + (2,))
    y, _ = sosfilt(sos, ext, axis=-1, zi=zi * ext[..., :1])
    y, _ = sosfilt(sos, y[..., ::-1], axis=-1, zi=zi * y[..., -1:])
    return y[..., ::-1][..., PADLEN:-PADLEN]


@functools.lru_cache(maxsize=64)
def _butter(cutoff: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """The Butterworth sections of :func:`lowpass` and their steady state for a unit step
    (designed once per cutoff and rate: a batch of model curves filters thousands of pieces
    alike; neither is written to)."""
    from scipy import signal
    sos = signal.butter(ORDER, cutoff, fs=rate, output="sos")
    return sos, signal.sosfilt_zi(sos)


def event_levels(vls: float | None, sigma_rate: float) -> tuple[float, float]:
    """The slip rates (m/s) at which an event starts and ends: 10·vLs (10 σ without vLs) and
    max(vLs, 3 σ), σ the noise of the slip rate the event is timed on."""
    start = START_FACTOR * vls if vls else START_FACTOR * sigma_rate
    return start, max(vls or 0.0, 3.0 * sigma_rate)


def friction(fs: np.ndarray, a1: np.ndarray, mass: float, fn, rate: float,
             force_hz: float = FORCE_HZ, acceleration_hz: float = ACCELERATION_HZ) -> np.ndarray:
    """The fault's friction as the chain reads it: (Fs low-passed − m · a1 low-passed)/Fn.

    Parameters
    ----------
    fs, a1 : numpy.ndarray
        The load cell's force (N) and the upper specimen's acceleration (m/s²).
    mass : float
        The slider's mass (kg).
    fn : float or numpy.ndarray
        The normal force (N).
    rate : float
        The sampling rate (Hz).
    force_hz, acceleration_hz : float
        The two low-passes' cutoffs (Hz).

    Returns
    -------
    numpy.ndarray
        Ft/Fn (dimensionless).
    """
    return (lowpass(fs, force_hz, rate) - mass * lowpass(a1, acceleration_hz, rate)) / fn


def crossing(t: np.ndarray, x: np.ndarray, level: float, i: int) -> float:
    """The time where ``x`` crosses ``level`` between samples ``i − 1`` and ``i`` (linear).

    Parameters
    ----------
    t, x : numpy.ndarray
        The samples' times and values.
    level : float
        The level crossed.
    i : int
        The sample after the crossing (0: the first sample's time).

    Returns
    -------
    float
    """
    if i <= 0:
        return float(t[0])
    return float(_between(t[i - 1], t[i], x[i - 1], x[i], level))


@njit(cache=True, nogil=True)
def _between(t0, t1, x0, x1, level):
    """The time in [t0, t1] where the line from (t0, x0) to (t1, x1) meets ``level`` (t0 for a
    flat line; clipped to the interval)."""
    f = 0.0 if x1 == x0 else (level - x0) / (x1 - x0)
    return t0 + min(max(f, 0.0), 1.0) * (t1 - t0)


@njit(cache=True, nogil=True)
def _pooled(ts, rate, u, mu, i0, i1, level):
    """Every phase's (row's) samples from ``i0`` to ``i1`` (both > 0, ``i1`` inside the row)
    as :meth:`Chain._timed` takes them, unsorted and in the phases' order: the slip since
    the start's :func:`crossing` of ``level`` on ``rate``, and the friction."""
    size = 0
    for k in range(len(i0)):
        size += i1[k] - i0[k] + 1
    x, y = np.empty(size), np.empty(size)
    at = 0
    for k in range(len(i0)):
        a, b = i0[k], i1[k]
        tc = _between(ts[k, a - 1], ts[k, a], rate[k, a - 1], rate[k, a], level)
        start = np.interp(tc, ts[k], u[k])
        for j in range(a, b + 1):
            x[at] = u[k, j] - start
            y[at] = mu[k, j]
            at += 1
    return x, y


@dataclass(frozen=True)
class Chain:
    """What ``observe`` did to a recording to read its curves (module docstring).

    Parameters
    ----------
    rate_hz : float
        The recording's sampling rate (Hz).
    timing_hz : float
        The smoothing of the slip the events are timed on (Hz).
    start_level, end_level : float
        The slip rates (m/s) that start and end an event.
    force_hz, acceleration_hz, slip_hz : float
        The low-passes of the force, the acceleration and the slip (Hz).
    slip_from : str
        ``"slip column"`` or ``"accelerations"`` (the model's side then keeps its own slip).
    slip_noise : float
        σ (m) of the white noise on the raw slip column (0: none; the model's curve gets it
        in :data:`NOISY_PHASES` fixed draws).
    """

    rate_hz: float
    timing_hz: float
    start_level: float
    end_level: float
    force_hz: float = FORCE_HZ
    acceleration_hz: float = ACCELERATION_HZ
    slip_hz: float = SLIP_HZ
    slip_from: str = "slip column"
    slip_noise: float = 0.0

    def __post_init__(self) -> None:
        for name in ("rate_hz", "timing_hz", "start_level", "end_level", "force_hz",
                     "acceleration_hz", "slip_hz"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value > 0):
                raise ValueError(f"measurement chain: {name} must be a positive number, got "
                                 f"{value!r}")
        if isinstance(self.slip_noise, bool) or not isinstance(self.slip_noise, (int, float)) \
                or not (math.isfinite(self.slip_noise) and self.slip_noise >= 0):
            raise ValueError("measurement chain: slip_noise must be a number ≥ 0 (m), got "
                             f"{self.slip_noise!r}")
        if self.slip_from not in ("slip column", "accelerations"):
            raise ValueError("measurement chain: slip_from must be 'slip column' or "
                             f"'accelerations', got {self.slip_from!r}")

    def record(self) -> dict:
        """The chain as observations.json keeps it (``measurement``): the numbers, the filters'
        kinds and the order of the steps."""
        butter = {"kind": "butterworth low-pass", "order": ORDER, "zero_phase": True}
        return {**asdict(self), "version": 2,
                "filters": {"force": {**butter, "cutoff_hz": self.force_hz},
                            "acceleration": {**butter, "cutoff_hz": self.acceleration_hz},
                            "slip": {**butter, "cutoff_hz": self.slip_hz},
                            "timing": {"kind": "near-Gaussian (three moving averages)",
                                       "cutoff_hz": self.timing_hz}},
                "steps": ["sampled at rate_hz", "slip_noise (m, white) on the raw slip column",
                          "friction (Fs at force_hz − m·a1 at "
                          "acceleration_hz)/Fn", "slip low-passed at slip_hz",
                          "event timed on the slip smoothed at timing_hz: from its rate's "
                          "first sample ≥ start_level to its first < end_level (m/s)",
                          "curve: friction against the slip since the start's crossing"]}

    @classmethod
    def observed(cls, rate: float, slip_from: str, noise: dict, vls: float | None) -> "Chain":
        """The chain ``observe`` applied to a recording at ``rate`` (Hz) whose slip came from
        ``slip_from``, with the ``noise`` it measured (``slip_timing_hz``, ``slip_rate``) and
        vLs (m/s): a slip column is timed at the smoothing its noise allowed, with the end
        level its rate's noise set; slip integrated from accelerations on their low-pass, with
        the levels of vLs (its per-event noise level is not kept)."""
        if slip_from == "slip column":
            return cls(rate, noise["slip_timing_hz"], *event_levels(vls, noise["slip_rate"]),
                       slip_noise=float(noise["slip"]))
        return cls(rate, ACCELERATION_HZ, *event_levels(vls, 0.0), slip_from=slip_from)

    @classmethod
    def from_record(cls, record) -> "Chain | None":
        """The chain of an observations file's ``measurement`` record; None for a file without
        one (written before it): no chain, the model's curves compared as they are. A record
        of version 1 (before the slip's noise was kept) has ``slip_noise`` 0; version 2 must
        have it; a later version is refused (this code does not know its steps)."""
        if record is None:
            return None
        if not isinstance(record, dict):
            raise ValueError(f"measurement must be a table of the chain's numbers, got {record!r}")
        version = record.get("version", 1)
        if version not in (1, 2):
            raise ValueError(f"measurement version {version!r}: this rsfbench reads versions 1 "
                             "and 2; a newer rsfbench wrote it")
        keys = ("rate_hz", "timing_hz", "start_level", "end_level", "force_hz",
                "acceleration_hz", "slip_hz", "slip_from", *(("slip_noise",) if version == 2
                                                             else ()))
        missing = [k for k in keys if k not in record]
        if missing:
            raise ValueError(f"measurement lacks {', '.join(missing)}")
        return cls(**{k: record[k] for k in keys})

    @property
    def margin_s(self) -> float:
        """How far (s) before and after an event the chain reaches: ten e-foldings of the
        slowest Butterworth pole, the timing's smoothing and its walk to the end level."""
        butter = 10.0 / (2.0 * math.pi * min(self.force_hz, self.acceleration_hz, self.slip_hz)
                         * math.sin(math.pi / 8.0))
        return max(butter, 1.0 / self.timing_hz) + 20.0 / self.rate_hz

    def model_curve(self, t: np.ndarray, slip: np.ndarray, fs: np.ndarray, ft: np.ndarray,
                    phases: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The curve ``observe`` would read from the model's run around one event.

        Parameters
        ----------
        t : numpy.ndarray
            Increasing times (s) over the event and :attr:`margin_s` either side.
        slip : numpy.ndarray
            The slip (m) at ``t`` (any origin).
        fs, ft : numpy.ndarray
            The spring's force and the fault's friction over Fn at ``t`` (dimensionless).
        phases : int, optional
            The sampling grid's offsets averaged over (default :data:`PHASES`, or
            :data:`NOISY_PHASES` with slip noise).

        Returns
        -------
        slip : numpy.ndarray
            The slip since the event's start (m), increasing.
        friction : numpy.ndarray
            The friction (Ft/Fn) there; both empty when the event does not fit the window.
        """
        noisy = self.slip_noise > 0 and self.slip_from == "slip column"
        phases = phases or (NOISY_PHASES if noisy else PHASES)
        dt = 1.0 / self.rate_hz
        n = int((t[-1] - t[0]) / dt - (phases - 1) / phases) + 1       # every phase's length
        if n <= PADLEN:
            return np.empty(0), np.empty(0)
        ts = t[0] + (np.arange(phases)[:, None] / phases + np.arange(n)) * dt   # phase × sample
        u, f, r = np.moveaxis(pchip(t, np.column_stack([slip, fs, ft]), ts), -1, 0)
        mu = lowpass(f, self.force_hz, self.rate_hz) - lowpass(f - r, self.acceleration_hz,
                                                               self.rate_hz)
        rate = np.gradient(smooth(u, self.timing_hz, self.rate_hz), dt, axis=-1)
        if noisy:                  # after the timing (module docstring: the draw's layout)
            u = u + self.slip_noise * np.random.default_rng(47).standard_normal((n, phases)).T
        if self.slip_from == "slip column":
            u = lowpass(u, self.slip_hz, self.rate_hz)
        i0, i1 = self._bounds(rate)
        if (i0 == 0).any() or (i1 >= n).any() or (i1 <= i0).any():   # no event, one that
            return np.empty(0), np.empty(0)                           # runs off the window
        if noisy:                  # every phase's samples, as a recorder's: read as events are
            x, y = _pooled(ts, rate, u, mu, i0, i1, self.start_level)
            order = np.argsort(x, kind="stable")
            return x[order], y[order]
        curves = [self._timed(ts[k], rate[k], u[k], mu[k], i0[k], i1[k])
                  for k in range(phases)]
        grid = np.unique(np.concatenate([x for x, _ in curves]))
        return grid, np.mean([np.interp(grid, x, y) for x, y in curves], axis=0)

    def _bounds(self, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each phase's (row's) event as observe times one: the first sample ``i0`` of the run
        at or above the start level that holds the peak rate, and the first sample ``i1`` after
        the peak below the end level (0 and the row's length: no event, or one that runs off
        the window)."""
        n = rate.shape[-1]
        idx = np.arange(n)
        peak = rate.argmax(axis=-1)[:, None]
        before = (rate < self.start_level) & (idx < peak)
        i0 = np.where(before.any(axis=-1), n - 1 - np.argmax(before[:, ::-1], axis=-1) + 1, 0)
        after = (rate < self.end_level) & (idx >= peak)
        i1 = np.where(after.any(axis=-1), np.argmax(after, axis=-1), n)
        started = rate.max(axis=-1) >= self.start_level
        return np.where(started, i0, 0), np.where(started, i1, n)

    def _timed(self, ts, rate, u, mu, i0, i1):
        """One sampling phase's curve over the event from sample ``i0`` to ``i1``
        (:meth:`_bounds`): its friction ``mu`` against the slip ``u`` since the start's crossing
        of the start level on ``rate``, sorted by slip as the observed curves are read (empty
        when the event runs off the window)."""
        if i0 == 0 or i1 >= len(ts):               # no event, or it runs off the window
            return np.empty(0), np.empty(0)
        x = u[i0:i1 + 1] - np.interp(crossing(ts, rate, self.start_level, i0), ts, u)
        order = np.argsort(x, kind="stable")
        return x[order], mu[i0:i1 + 1][order]
