"""Error measures of a run against its reference (:mod:`benchmarks.devtools.reference`).

Headline accuracy — relative errors of the limit-cycle metrics, compared on the reference's last
complete event N (for a converged stick–slip cycle these are the limit-cycle values):

* ``err_recurrence``     ``|ΔT_N − ΔT_N,ref| / ΔT_N,ref``
* ``err_drop``           friction drop Δμ, likewise
* ``err_slip``           slip per event, likewise
* ``err_peak_velocity``  peak slip rate, likewise

For reference only (they measure phase, which accumulates over the run and saturates, rather than
the shape of the cycle an inversion fits):

* ``err_event_time``     ``|t_N − t_N,ref| / ΔT_N,ref``: the drift of event N's start, in cycles;
* ``err_trajectory``     max over a uniform grid of ``|μ − μ_ref| / Δμ_ref`` (μ = Fs/Fn linearly
  interpolated from the saved points): of order 1 as soon as the phase drift is comparable to
  the duration of an event.

A failed run, or one without an event N, has NaN errors; its retcode says why.
"""

from __future__ import annotations

import math

import numpy as np

from benchmarks.physics.metrics import event_metrics

__all__ = ["ERROR_COLUMNS", "HEADLINE_ERRORS", "errors"]

HEADLINE_ERRORS = ("err_recurrence", "err_drop", "err_slip", "err_peak_velocity")
ERROR_COLUMNS = HEADLINE_ERRORS + ("err_event_time", "err_trajectory")
_METRIC_OF = dict(zip(HEADLINE_ERRORS, ("recurrence_s", "friction_drop", "slip_m", "peak_velocity_m_s")))


def errors(solution, ref) -> dict[str, float]:
    """The :data:`ERROR_COLUMNS` of ``solution`` against the reference ``ref`` of its problem."""
    out = dict.fromkeys(ERROR_COLUMNS, math.nan)
    if not solution.success:
        return out
    got = event_metrics(solution.events, solution.problem.normal_force)
    want = ref.metrics
    n = ref.event_index
    if len(got) > n:
        g = got.iloc[n]
        for col, metric in _METRIC_OF.items():
            out[col] = abs(g[metric] - want[metric]) / abs(want[metric])
        out["err_event_time"] = abs(g["t_start"] - want["t_start"]) / want["recurrence_s"]
    drop = want["friction_drop"]
    mu = np.interp(ref.grid_t, solution.t, solution.mu)
    out["err_trajectory"] = float(np.max(np.abs(mu - ref.grid_mu)) / drop)
    return {k: float(v) for k, v in out.items()}
