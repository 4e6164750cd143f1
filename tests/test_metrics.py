"""Limit-cycle metrics and classification on hand-made event tables."""

import numpy as np
import pandas as pd
import pytest

from benchmarks.physics.metrics import EndState, event_metrics, limit_cycle
from integrators.core.solution import EVENT_COLUMNS

FN = 1e6


def _events(starts, drops=None, slips=None, peaks=None, duration=0.01):
    n = len(starts)
    drops = np.full(n, 0.04) if drops is None else np.asarray(drops)
    slips = np.full(n, 3e-4) if slips is None else np.asarray(slips)
    peaks = np.full(n, 0.05) if peaks is None else np.asarray(peaks)
    starts = np.asarray(starts, float)
    slip_start = np.cumsum(np.r_[0.0, slips[:-1]])[:n] + 1e-5
    return pd.DataFrame({
        "t_start": starts, "t_end": starts + duration,
        "fs_max_before": 6e5 + drops * FN, "fs_min": np.full(n, 6e5),
        "v_peak": peaks, "t_peak": starts + duration / 2,
        "slip_start": slip_start, "slip_end": slip_start + slips,
    })[list(EVENT_COLUMNS)]


def test_event_metrics_by_hand():
    m = event_metrics(_events([1.0, 3.5, 6.0], drops=[0.03, 0.04, 0.05], slips=[1e-4, 2e-4, 3e-4]),
                      FN)
    assert np.isnan(m.recurrence_s[0])
    np.testing.assert_allclose(m.recurrence_s[1:], [2.5, 2.5])
    np.testing.assert_allclose(m.friction_drop, [0.03, 0.04, 0.05])
    np.testing.assert_allclose(m.slip_m, [1e-4, 2e-4, 3e-4])


def test_converging_stick_slip():
    # recurrence intervals converging geometrically to 2.0: 3.0, 2.5, 2.25, ... within 1e-3
    intervals = 2.0 + 2.0 ** -np.arange(0, 16)
    starts = np.r_[0.0, np.cumsum(intervals)]
    lc = limit_cycle(_events(starts), FN, t_end=starts[-1] + 1.0, rtol=1e-3)
    assert lc.classification == "stick-slip" and lc.period == 1
    assert lc.recurrence_s == pytest.approx(intervals[-1])
    assert lc.friction_drop == pytest.approx(0.04) and lc.slip_m == pytest.approx(3e-4)
    # event i has interval 2 + 2^-(i-1) and repeats event i − 1 within rtol when
    # 2^-(i-1) <= 1e-3 (2 + 2^-(i-2)): false for i = 9 (3.9e-3 > 2.008e-3), true from i = 10 on
    assert lc.cycles_to_converge == 10


def test_multiple_recurrence_period_two():
    intervals = np.tile([1.0, 2.0], 8)
    starts = np.r_[0.0, np.cumsum(intervals)]
    drops = np.tile([0.02, 0.05], 9)[: len(starts)]
    lc = limit_cycle(_events(starts, drops=drops), FN, t_end=starts[-1] + 1.0)
    assert lc.classification == "multiple recurrence" and lc.period == 2
    assert sorted(lc.recurrence_values) == [1.0, 2.0]
    assert lc.recurrence_s == pytest.approx(1.5)


STEADY_STABLE = EndState(log_v=1e-3, state_offset=1e-3, force_offset=1e-3, growth_rate=-2.0)
LOCKED = EndState(log_v=-6.0, state_offset=4.0, force_offset=1.0, growth_rate=-2.0)
UNSTABLE = EndState(log_v=1e-3, state_offset=1e-3, force_offset=1e-3, growth_rate=0.5)


def test_stable_sliding_needs_a_steady_and_stable_end():
    # no events: stable sliding only if the run ended at steady sliding and it is stable there
    assert limit_cycle(_events([]), FN, 10.0, end=STEADY_STABLE).classification == "stable sliding"
    for end in (LOCKED, UNSTABLE, None):
        lc = limit_cycle(_events([]), FN, 10.0, end=end)
        assert lc.classification == "too short to classify" and "run longer" in lc.reason
    # events that died out: the same rule
    died_out = _events([0.1, 0.3, 0.6])
    assert limit_cycle(died_out, FN, 10.0, end=STEADY_STABLE).classification == "stable sliding"
    assert limit_cycle(died_out, FN, 10.0, end=LOCKED).classification == "too short to classify"


def test_not_converged_and_too_few_events():
    rng = np.random.default_rng(1)
    starts = np.cumsum(1.0 + rng.uniform(0, 1, 12))
    lc = limit_cycle(_events(starts), FN, t_end=starts[-1] + 0.5)
    assert lc.classification == "not converged" and "run longer" in lc.reason
    # three events cannot show a period-1 cycle repeating twice
    assert limit_cycle(_events([1.0, 2.0, 3.0]), FN, t_end=3.5).classification == \
        "too short to classify"


def test_an_oscillation_that_never_locks_is_not_stick_slip():
    starts = np.arange(12) * 2.0
    locked = _events(starts)                 # slip only during events: locked between them
    vl = 1e-4
    assert limit_cycle(locked, FN, 24.5, v_slow=vl).classification == "stick-slip"
    creeping = locked.copy()
    # between events the fault slips at 0.8 vL (the event's own slip is unchanged)
    gap = creeping.t_start.to_numpy()[1:] - creeping.t_end.to_numpy()[:-1]
    shift = np.r_[0.0, np.cumsum(0.8 * vl * gap)]
    creeping["slip_start"] += shift
    creeping["slip_end"] += shift
    lc = limit_cycle(creeping, FN, 24.5, v_slow=vl)
    assert lc.classification == "oscillation about vL" and "0.8 vLs" in lc.reason
    assert np.isnan(lc.recurrence_s)
