"""Load-point velocity protocols (Urata et al. 2017, Sect. 3; SPEC §4), all one kind of data: a
piecewise-constant load-point history.

* :class:`LoadHistory` — velocities on consecutive time intervals, switching at given times
  (velocity steps up and down; a velocity of 0 is a hold, as in a slide-hold-slide test), plus an
  optional *overshoot*: after each stick–slip event ends the load point runs at another velocity
  for a while (the paper's shaking-table overshoot);
* :class:`ConstantLoading` (one piece) and :class:`TwoSpeedLoading` (one piece and the
  overshoot) are the paper's two protocols under their own names; ``.history`` is the
  :class:`LoadHistory` they are;
* :func:`velocity_step` and :func:`slide_hold_slide` build the laboratory's standard histories.

Every integrator restarts at each switch (a switch time, or the end of an overshoot): the load
point's velocity is discontinuous there, and no method steps across it.

Events are defined relative to the history's reference velocity ``v_slow`` (the slow loading
speed of the paper's protocols; by default the largest velocity of a history): an event starts
when v > 10·v_slow and ends when v ≤ v_slow.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from problems._validate import (check_finite, check_non_negative, check_positive,
                                units_checked_already, warn_implausible)

__all__ = ["ConstantLoading", "TwoSpeedLoading", "LoadHistory", "velocity_step",
           "slide_hold_slide", "EVENT_START_FACTOR", "event_thresholds", "history_vector",
           "load_segment", "LN_E_HOLD", "ln_load_rate"]

#: an event starts when the slip rate exceeds this multiple of the slow loading speed
EVENT_START_FACTOR = 10.0
#: the value of ln E at a hold (E = 0), for the root function u − ln E of the spring force's
#: extrema: a finite stand-in for −inf (at a hold h' = −w < 0, the spring force has no extremum)
LN_E_HOLD = -1e300


def ln_load_rate(e: float) -> float:
    """ln E, or :data:`LN_E_HOLD` at a hold (E = 0)."""
    return math.log(e) if e > 0.0 else LN_E_HOLD


@dataclass(frozen=True)
class LoadHistory:
    """A piecewise-constant load-point velocity (m/s): ``velocities[0]`` from t = 0 to
    ``switch_times[0]``, ``velocities[i]`` from ``switch_times[i-1]`` to ``switch_times[i]``, the
    last one to the end of the run. A velocity of 0 is a hold. Times in s, strictly increasing
    and positive; one more velocity than switch times.

    ``overshoot_velocity``/``overshoot_duration``: after each event ends, the load point runs at
    that velocity for that long (s) instead (0 duration: no overshoot). ``reference_velocity``:
    the event thresholds' v_slow (default: the largest velocity of the history).

    Parameters
    ----------
    velocities : tuple of float
        The load-point velocity of each piece (m/s, ≥ 0, at least one positive).
    switch_times : tuple of float
        The times the velocity switches (s, positive, strictly increasing); one fewer than
        ``velocities``.
    overshoot_velocity : float
        The load point's velocity after each event (m/s; positive when
        ``overshoot_duration`` is).
    overshoot_duration : float
        How long the overshoot lasts (s, ≥ 0; 0 is none).
    reference_velocity : float, optional
        The event thresholds' v_slow (m/s); ``None`` takes the largest of ``velocities``.

    Raises
    ------
    ValueError
        Naming the field that is out of range or inconsistent with the others.
    """

    velocities: tuple[float, ...]
    switch_times: tuple[float, ...] = ()
    overshoot_velocity: float = 0.0
    overshoot_duration: float = 0.0
    reference_velocity: float | None = None

    def __post_init__(self) -> None:
        vel, sw = self.velocities, self.switch_times
        if not isinstance(vel, tuple) or not vel:
            raise ValueError(f"velocities must be a non-empty tuple of numbers (m/s), got {vel!r}")
        if not isinstance(sw, tuple):
            raise ValueError(f"switch_times must be a tuple of numbers (s), got {sw!r}")
        warned = set()
        for i, v in enumerate(vel):
            check_non_negative(f"velocities[{i}]", v)
            if v not in warned:                 # one warning a value, however often it recurs
                warned.add(v)
                warn_implausible(f"velocities[{i}]", v, kind="velocity")
        if not any(v > 0 for v in vel):
            raise ValueError(f"velocities must include a positive one (all holds: nothing "
                             f"ever moves), got {vel!r}")
        if len(vel) != len(sw) + 1:
            raise ValueError(f"a history needs one more velocity than switch times, got "
                             f"{len(vel)} velocities and {len(sw)} switch times")
        for i, t in enumerate(sw):
            warn_implausible(f"switch_times[{i}]", check_positive(f"switch_times[{i}]", t),
                             kind="time")
            if i and not t > sw[i - 1]:
                raise ValueError(f"switch_times must be strictly increasing, got "
                                 f"switch_times[{i - 1}] = {sw[i - 1]!r} and switch_times[{i}] = "
                                 f"{t!r}")
        warn_implausible("overshoot_duration",
                         check_non_negative("overshoot_duration", self.overshoot_duration))
        if self.overshoot_duration > 0:
            warn_implausible("overshoot_velocity",
                             check_positive("overshoot_velocity", self.overshoot_velocity))
        else:
            check_non_negative("overshoot_velocity", self.overshoot_velocity)
        if self.reference_velocity is not None:
            warn_implausible("reference_velocity",
                             check_positive("reference_velocity", self.reference_velocity))

    @property
    def history(self) -> "LoadHistory":
        return self

    @property
    def v_slow(self) -> float:
        """The event thresholds' reference velocity (m/s): ``reference_velocity``, by default the
        largest load-point velocity, so that steady sliding at any piece (10 times slower than
        an event's start) is never an event."""
        if self.reference_velocity is not None:
            return self.reference_velocity
        return max(self.velocities)

    @property
    def v_fast(self) -> float:
        return self.overshoot_velocity if self.two_speed else self.v_slow

    @property
    def fast_duration(self) -> float:
        return self.overshoot_duration if self.two_speed else 0.0

    @property
    def two_speed(self) -> bool:
        """True when events switch the load point to the overshoot velocity."""
        return self.overshoot_duration > 0

    @property
    def overshoots(self) -> bool:
        """True when that switch changes the load point's velocity (an overshoot at the
        velocity of every piece is a switch that changes nothing)."""
        return self.two_speed and any(v != self.overshoot_velocity for v in self.velocities)

    @property
    def holds(self) -> tuple[tuple[float, float], ...]:
        """(start, end) of each hold (s); the end is inf for a hold that lasts to the end."""
        edges = (0.0,) + self.switch_times + (math.inf,)
        return tuple((edges[i], edges[i + 1]) for i, v in enumerate(self.velocities) if v == 0)

    def velocity_at(self, t):
        """The load-point velocity (m/s) at time(s) ``t`` without overshoots (a switch time
        belongs to the piece it starts)."""
        idx = np.searchsorted(np.asarray(self.switch_times, dtype=float), t, side="right")
        return np.asarray(self.velocities, dtype=float)[idx]


@dataclass(frozen=True)
class ConstantLoading:
    """The load point moves at a constant velocity ``vl`` (m/s).

    Parameters
    ----------
    vl : float
        The load-point velocity (m/s, positive).

    Raises
    ------
    ValueError
        For a velocity that is not positive.
    """

    vl: float

    def __post_init__(self) -> None:
        warn_implausible("vl", check_positive("vl", self.vl))

    @functools.cached_property
    def history(self) -> LoadHistory:
        """The :class:`LoadHistory` this loading is (made once: the loading is frozen)."""
        with units_checked_already():       # this loading warned for its values already
            return LoadHistory((self.vl,))

    @property
    def v_slow(self) -> float:
        return self.vl

    @property
    def v_fast(self) -> float:
        return self.vl

    @property
    def fast_duration(self) -> float:
        return 0.0

    @property
    def two_speed(self) -> bool:
        return False


@dataclass(frozen=True)
class TwoSpeedLoading:
    """The shaking-table overshoot: vL = ``vlf`` for ``df`` seconds after each event ends, else ``vls``.

    Velocities in m/s, ``df`` in s (Table 2 of the paper). As a history: one piece at ``vls``
    and an overshoot at ``vlf`` for ``df`` (none when ``df`` is 0). An overshoot at ``vlf`` =
    ``vls`` changes no trajectory but stays a switch, so that the derivatives along ``vls``
    (``vlf`` held) and ``vlf`` are a two-speed loading's.

    Parameters
    ----------
    vls : float
        The slow load-point velocity (m/s, positive).
    vlf : float
        The overshoot's velocity after each event (m/s, positive).
    df : float
        The overshoot's duration (s, ≥ 0).

    Raises
    ------
    ValueError
        Naming a value out of range.
    """

    vls: float
    vlf: float
    df: float

    def __post_init__(self) -> None:
        warn_implausible("vls", check_positive("vls", self.vls))
        warn_implausible("vlf", check_positive("vlf", self.vlf))
        warn_implausible("df", check_non_negative("df", self.df))

    @functools.cached_property
    def history(self) -> LoadHistory:
        """The :class:`LoadHistory` this loading is (made once: the loading is frozen)."""
        with units_checked_already():       # this loading warned for its values already
            if not self.two_speed:
                return LoadHistory((self.vls,))
            return LoadHistory((self.vls,), overshoot_velocity=self.vlf,
                               overshoot_duration=self.df)

    @property
    def v_slow(self) -> float:
        return self.vls

    @property
    def v_fast(self) -> float:
        return self.vlf

    @property
    def fast_duration(self) -> float:
        return self.df

    @property
    def two_speed(self) -> bool:
        return self.df > 0


LOADINGS = (ConstantLoading, TwoSpeedLoading, LoadHistory)


def velocity_step(v1: float, v2: float, t_step: float) -> LoadHistory:
    """The load point at ``v1`` (m/s) until ``t_step`` (s), then at ``v2``: the standard
    velocity-step test (up when v2 > v1, down when v2 < v1).

    Parameters
    ----------
    v1, v2 : float
        The load-point velocities before and after the step (m/s, positive).
    t_step : float
        The time of the step (s, positive).

    Returns
    -------
    LoadHistory
        Two pieces, one switch.

    Raises
    ------
    ValueError
        For a velocity or time that is not positive.
    """
    check_positive("v1", v1)
    check_positive("v2", v2)
    return LoadHistory((float(v1), float(v2)), (float(check_positive("t_step", t_step)),))


def slide_hold_slide(v: float, holds, slide: float, first_slide: float | None = None) -> LoadHistory:
    """A slide-hold-slide sequence: slide at ``v`` (m/s) for ``first_slide`` s (default
    ``slide``), then for each hold time in ``holds`` (s) hold the load point at rest and slide
    again for ``slide`` s. Each reloading's peak spring force against log hold time is the
    healing (:func:`benchmarks.lab.measures.healing`).

    Parameters
    ----------
    v : float
        The sliding velocity (m/s, positive).
    holds : sequence of float
        The hold times (s, positive), in order; at least one.
    slide : float
        The duration of each slide after a hold (s, positive).
    first_slide : float, optional
        The duration of the first slide (s); ``None`` takes ``slide``.

    Returns
    -------
    LoadHistory
        Velocities v, 0, v, 0, …, v switching at each hold's start and end.

    Raises
    ------
    ValueError
        For an empty or non-sequence ``holds``, or a time or velocity that is not positive.
    """
    check_positive("v", v)
    check_positive("slide", slide)
    first = slide if first_slide is None else check_positive("first_slide", first_slide)
    if isinstance(holds, (str, bytes)) or not hasattr(holds, "__iter__"):
        raise ValueError(f"holds must be a sequence of hold times (s), got {holds!r}")
    holds = tuple(holds)
    if not holds:
        raise ValueError("holds must list at least one hold time (s)")
    t, times, vel = float(first), [], [float(v)]
    for i, th in enumerate(holds):
        th = check_finite(f"holds[{i}]", th)
        if th <= 0:
            raise ValueError(f"holds[{i}] must be a positive hold time (s), got {th!r}")
        times += [t, t + th]
        vel += [0.0, float(v)]
        t += th + slide
    return LoadHistory(tuple(vel), tuple(times))


def event_thresholds(loading) -> tuple[float, float]:
    """(start, end) slip-rate thresholds of an event in m/s: (10·vLs, vLs).

    Parameters
    ----------
    loading : ConstantLoading, TwoSpeedLoading or LoadHistory
        The loading whose ``v_slow`` (m/s) is vLs.

    Returns
    -------
    tuple of float
        An event starts when v exceeds the first (m/s) and ends when v falls to the second.
    """
    return EVENT_START_FACTOR * loading.v_slow, loading.v_slow


# --- the history in compiled code ------------------------------------------------------------
#: the flat history vector: the overshoot's E and duration (τ), the number of pieces n, then the
#: n − 1 switch times (τ) and the n piece rates E = vL/v0
H_E_FAST, H_TAU_FAST, H_N = 0, 1, 2
H_HEAD = 3


def history_vector(loading, v0: float, time_scale: float) -> np.ndarray:
    """The compiled form of ``loading``'s history, nondimensional (E = vL/v0, τ = t/time_scale)."""
    hist = loading.history
    n = len(hist.velocities)
    out = np.empty(H_HEAD + 2 * n - 1)
    out[H_E_FAST] = hist.overshoot_velocity / v0
    out[H_TAU_FAST] = hist.overshoot_duration / time_scale
    out[H_N] = n
    out[H_HEAD:H_HEAD + n - 1] = np.asarray(hist.switch_times, dtype=float) / time_scale
    out[H_HEAD + n - 1:] = np.asarray(hist.velocities, dtype=float) / v0
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def load_segment(hist, tau, fast_until, tau_end, tiny):
    """The loading segment that starts at τ: (E, its end). The piece containing τ (a switch
    within ``tiny`` of τ has happened), overridden by the overshoot's E until ``fast_until``; the
    segment ends at the next switch, the overshoot's end or ``tau_end``, whichever is first."""
    n = int(hist[H_N])
    i = 0
    while i < n - 1 and hist[H_HEAD + i] <= tau + tiny:
        i += 1
    e = hist[H_HEAD + n - 1 + i]
    bound = tau_end
    if i < n - 1 and hist[H_HEAD + i] < bound:
        bound = hist[H_HEAD + i]
    if hist[H_TAU_FAST] > 0.0 and fast_until - tau > tiny:
        e = hist[H_E_FAST]
        if fast_until < bound:
            bound = fast_until
    return e, bound
