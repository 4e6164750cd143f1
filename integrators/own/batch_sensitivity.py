"""Batches that carry forward sensitivities: each point of :mod:`integrators.own.batch` solved
by its method's sensitive kernel (:mod:`integrators.own.sensitivity`), and the gradient of its
limit cycle's four metrics in SI units, all in one compiled call.

The gradient is :func:`benchmarks.physics.metrics.cycle_gradient`'s: the derivatives of each
event's recurrence time, friction drop, slip and peak slip rate
(:func:`benchmarks.physics.metrics.metric_gradients`), averaged over the last period of the
cycle the summary found. Inputs beside the batch's (one row per point): ``D`` (points × n ×
N_DIR) the point's directions (:func:`integrators.own.sensitivity.direction_matrix`), ``X``
(points × n × 4) what turns their derivatives into SI ones
(:func:`integrators.own.sensitivity.si_columns`), ``control`` 1.0 to put the sensitivities in
the step control. Output ``GRAD`` (points × 4 × n): NaN for a point without a limit cycle, or
whose cycle has no derivative (an arrest, a cycle that starts at the first event).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from integrators.core import cycles
from integrators.core.clock import monotonic
from integrators.own import batch as B
from integrators.own import engine as E
from integrators.own.sensitivity import SI, make_arrays

__all__ = ["run_batch", "run_serial", "cycle_gradient"]

_NO_LIMIT = 1 << 62
_DEADLINE, _TAU_END = E.P["DEADLINE"], E.P["TAU_END"]
_BUDGET, _WALL_S, _CLASS = B.C["BUDGET"], B.R["WALL_S"], B.R["CLASS"]
_TS, _F0, _FORCE_H, _V0, _LC, _FN = (B.C[k] for k in ("TS", "F0", "FORCE_H", "V0", "LC", "FN"))
_PERIOD = B.R["FOUND"] + cycles.F["PERIOD"]
_X_TS, _X_FH, _X_FN, _X_LC = SI["LN_TS"], SI["FORCE_H"], SI["FN"], SI["LC"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _run(kernel, workspace, sensitivity_workspace, p, z0, dirs, d, control, grid, saved):
    """One solve with sensitivities along ``d``, as :meth:`integrators.own.compiled.
    CompiledAlgorithm.run` makes it: ``(status, st, ev, sa)``."""
    st, Z, G, ev = B.fresh(z0, saved)
    sa = make_arrays(sensitivity_workspace, d, grid.shape[0], ev.shape[0], control)
    ws, sc = workspace(), E.scratch()
    while True:
        status = kernel(ws, sc, st, p, Z, G, dirs, grid, saved, ev, _NO_LIMIT, sa)
        if status == E.GROW:
            bigger = np.empty((2 * ev.shape[0], 8))
            bigger[:ev.shape[0]] = ev
            ev = bigger
            evs = np.full((ev.shape[0], 8, d.shape[0]), np.nan)
            evs[:sa[9].shape[0]] = sa[9]
            sa = (sa[0], sa[1], sa[2], sa[3], sa[4], sa[5], sa[6], sa[7], sa[8], evs, sa[10],
                  sa[11], sa[12])
        elif status != E.CHUNK:
            break
    return status, st, ev, sa


@njit(cache=True, nogil=True, error_model="numpy")
def cycle_gradient(r, ev, evs, n_ev, c, x, grad):
    """Into ``grad`` (4 × n): the mean over the cycle's last period (``r``, a row of
    :data:`integrators.own.batch.R`) of each event's metrics' derivatives, from the events
    ``ev`` (nondimensional, the engine's) and their derivatives ``evs``; NaN without a cycle
    or where one is not finite."""
    grad[:, :] = np.nan
    if not r[_CLASS] <= B.LAST_CYCLE or not r[_PERIOD] >= 1.0:
        return
    per = int(r[_PERIOD])
    ts, fh, v0, lc, fn = c[_TS], c[_FORCE_H], c[_V0], c[_LC], c[_FN]
    mu0 = c[_F0] / fn
    first = n_ev - per
    for j in range(grad.shape[1]):
        dts, dfh, dfn, dlc = x[j, _X_TS], x[j, _X_FH], x[j, _X_FN], x[j, _X_LC]
        acc = np.zeros(4)
        for i in range(max(first, 1), n_ev):
            start = (evs[i, 0, j] + ev[i, 0] * dts) * ts
            before = (evs[i - 1, 0, j] + ev[i - 1, 0] * dts) * ts
            acc[0] += start - before
            d_max = evs[i, 2, j] * fh + ev[i, 2] * dfh + mu0 * dfn
            d_min = evs[i, 3, j] * fh + ev[i, 3] * dfh + mu0 * dfn
            acc[1] += (d_max - d_min) / fn - fh * (ev[i, 2] - ev[i, 3]) * dfn / fn ** 2
            acc[2] += (evs[i, 7, j] - evs[i, 6, j]) * lc + (ev[i, 7] - ev[i, 6]) * dlc
            acc[3] += v0 * evs[i, 4, j]
        if first < 1:                   # the first event's recurrence time is unknown
            acc[0] = np.nan
        for m in range(4):
            grad[m, j] = acc[m] / per
    for m in range(4):
        for j in range(grad.shape[1]):
            if not math.isfinite(grad[m, j]):
                grad[:, :] = np.nan     # as cycle_gradient: no derivative, none at all
                return


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _one(kernel, workspace, sensitivity_workspace, p0, z0, c, dirs, d, x, control, r, grad):
    """One point: the solve with its sensitivities (save grid (0, t_end)), its summary into
    ``r`` (:func:`integrators.own.batch.record`) and its cycle's gradient into ``grad``."""
    start = monotonic()
    p = p0.copy()
    p[_DEADLINE] = start + c[_BUDGET]
    grid = np.array([0.0, p[_TAU_END]])
    saved = np.empty((2, 3))
    status, st, ev, sa = _run(kernel, workspace, sensitivity_workspace, p, z0, dirs, d,
                              control, grid, saved)
    n_ev = B.record(status, st, ev, p, c, saved, r)
    cycle_gradient(r, ev, sa[9], n_ev, c, x, grad)
    r[_WALL_S] = monotonic() - start


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def run_batch(kernel, workspace, sensitivity_workspace, P, Z0, C, dirs, D, X, control, R,
              GRAD, order):
    """Every point into its rows of ``R`` and ``GRAD``, in parallel, in the order ``order``
    (as :func:`integrators.own.batch.run_batch`)."""
    for k in prange(P.shape[0]):
        i = order[k]
        _one(kernel, workspace, sensitivity_workspace, P[i], Z0[i], C[i], dirs, D[i], X[i],
             control, R[i], GRAD[i])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def run_serial(kernel, workspace, sensitivity_workspace, P, Z0, C, dirs, D, X, control, R,
               GRAD):
    """:func:`run_batch` on the calling thread, in order (as
    :func:`integrators.own.batch.run_serial`)."""
    for i in range(P.shape[0]):
        _one(kernel, workspace, sensitivity_workspace, P[i], Z0[i], C[i], dirs, D[i], X[i],
             control, R[i], GRAD[i])
