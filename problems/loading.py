"""Load-point velocity protocols (Urata et al. 2017, Sect. 3; SPEC §4).

Events are defined relative to the slow loading speed: an event starts when v > 10·vLs and ends
when v ≤ vLs. For constant loading vLs = vLf = vL.
"""

from __future__ import annotations

from dataclasses import dataclass

from problems._validate import check_non_negative, check_positive, warn_implausible

__all__ = ["ConstantLoading", "TwoSpeedLoading", "EVENT_START_FACTOR"]

#: an event starts when the slip rate exceeds this multiple of the slow loading speed
EVENT_START_FACTOR = 10.0


@dataclass(frozen=True)
class ConstantLoading:
    """The load point moves at a constant velocity ``vl`` (m/s)."""

    vl: float

    def __post_init__(self) -> None:
        warn_implausible("vl", check_positive("vl", self.vl), stacklevel=4)

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

    Velocities in m/s, ``df`` in s (Table 2 of the paper).
    """

    vls: float
    vlf: float
    df: float

    def __post_init__(self) -> None:
        warn_implausible("vls", check_positive("vls", self.vls), stacklevel=4)
        warn_implausible("vlf", check_positive("vlf", self.vlf), stacklevel=4)
        check_non_negative("df", self.df)

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
        return self.df > 0 and self.vlf != self.vls


def event_thresholds(loading) -> tuple[float, float]:
    """(start, end) slip-rate thresholds of an event in m/s: (10·vLs, vLs)."""
    return EVENT_START_FACTOR * loading.v_slow, loading.v_slow
