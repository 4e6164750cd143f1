"""Limit-cycle metrics of a stick–slip run (SPEC §4): per event, and once they converge.

Per event (from ``Solution.events``, whatever the backend):

* recurrence interval ΔT: time between this event's start and the previous one's;
* friction drop Δμ = (max Fs before the event − min Fs during it)/Fn;
* slip per event: slip between the event's start and end;
* peak slip rate.

The limit cycle is found by looking for the shortest period p (in events) for which every metric
repeats, event to event p apart, within ``rtol``; it is summarised by the last complete period.
Classification: ``stick-slip`` (p = 1), ``multiple recurrence`` (p > 1, which the two-speed
loading can cause), ``stable sliding`` (no events, or events that died out) and ``not converged``
(events still changing at the end of the run: run longer).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

__all__ = ["event_metrics", "LimitCycle", "limit_cycle", "METRICS", "CLASSIFICATIONS"]

#: the limit-cycle metrics, in the order tables show them
METRICS = ("recurrence_s", "friction_drop", "slip_m", "peak_velocity_m_s")
CLASSIFICATIONS = ("stick-slip", "multiple recurrence", "stable sliding", "not converged")


def _metric_columns(events: pd.DataFrame, normal_force: float) -> tuple[np.ndarray, np.ndarray]:
    """(t_start, the four METRICS as an (n, 4) array) in numpy: a sweep summarises every point,
    and column arithmetic in pandas costs more than a short solve."""
    col = {c: events[c].to_numpy(dtype=float) for c in ("t_start", "fs_max_before", "fs_min",
                                                         "slip_end", "slip_start", "v_peak")}
    t = col["t_start"]
    recurrence = np.concatenate(([np.nan], np.diff(t))) if len(t) else t
    x = np.column_stack((recurrence, (col["fs_max_before"] - col["fs_min"]) / normal_force,
                         col["slip_end"] - col["slip_start"], col["v_peak"]))
    return t, x


def event_metrics(events: pd.DataFrame, normal_force: float) -> pd.DataFrame:
    """One row per event: its start time and the four metrics (ΔT is NaN for the first event)."""
    t, x = _metric_columns(events, normal_force)
    return pd.DataFrame({"t_start": t, **{name: x[:, i] for i, name in enumerate(METRICS)}})


@dataclass
class LimitCycle:
    """Summary of the cycle a run settles into.

    Metrics are means over the last complete period (for ``multiple recurrence`` the individual
    recurrence intervals of that period are in ``recurrence_values``). ``cycles_to_converge`` is
    the index of the first event from which the metrics repeat within ``rtol``.
    """

    classification: str
    period: int = 0
    recurrence_s: float = float("nan")
    friction_drop: float = float("nan")
    slip_m: float = float("nan")
    peak_velocity_m_s: float = float("nan")
    cycles_to_converge: int | None = None
    n_events: int = 0
    rtol: float = 1e-3
    recurrence_values: list[float] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)


def _repeats(x: np.ndarray, period: int, rtol: float) -> np.ndarray:
    """For each event i ≥ period: do all metrics of event i match those of event i − period?"""
    a, b = x[period:], x[:-period]
    scale = np.maximum(np.abs(a), np.abs(b))
    return np.all(np.abs(a - b) <= rtol * scale, axis=1)


def limit_cycle(events: pd.DataFrame, normal_force: float, t_end: float, rtol: float = 1e-3,
                max_period: int = 4, min_repeats: int = 2) -> LimitCycle:
    """Find the limit cycle of a run from its events table.

    A period p is accepted when the last ``min_repeats``·p events each repeat the event p before
    them within ``rtol``; the smallest such p wins.
    """
    n = len(events)
    if n == 0:
        return LimitCycle("stable sliding", rtol=rtol)
    _, x = _metric_columns(events, normal_force)
    # events that stopped long before the end: the oscillation decayed to steady sliding
    last_interval = x[-1, 0]
    gap = t_end - float(events["t_end"].to_numpy()[-1])
    if n > 1 and np.isfinite(last_interval) and gap > 3.0 * last_interval:
        return LimitCycle("stable sliding", n_events=n, rtol=rtol)
    x = x[1:]                                    # the first event has no recurrence interval
    for p in range(1, max_period + 1):
        need = min_repeats * p
        if len(x) < need + p:
            break
        ok = _repeats(x, p, rtol)
        if not ok[-need:].all():
            continue
        # ok[i] compares event i + p + 1 with event i + 1 (event 0 has no recurrence interval)
        first = len(ok) - int(np.argmin(ok[::-1])) if not ok.all() else 0
        tail = x[-p:]
        return LimitCycle(
            "stick-slip" if p == 1 else "multiple recurrence", period=p,
            recurrence_s=float(tail[:, 0].mean()), friction_drop=float(tail[:, 1].mean()),
            slip_m=float(tail[:, 2].mean()), peak_velocity_m_s=float(tail[:, 3].mean()),
            cycles_to_converge=first + p + 1, n_events=n, rtol=rtol,
            recurrence_values=[float(v) for v in tail[:, 0]])
    return LimitCycle("not converged", n_events=n, rtol=rtol)


def summarize(solution, rtol: float = 1e-3) -> LimitCycle:
    """:func:`limit_cycle` of a Solution."""
    p = solution.problem
    return limit_cycle(solution.events, p.normal_force, p.t_end, rtol=rtol)
