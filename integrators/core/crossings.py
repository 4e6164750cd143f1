"""Crossings an adapter locates itself, queued for the segment protocol.

The numbalsoda and CyRK adapters find the crossings of the four root functions after the
library has integrated a stretch (a grid, a block, the steps of a call), all at once, and hand
them out in time order from a queue. What they share: a located crossing kept in time order
among those of its interval (``push_crossing``, compiled), the queue of reported roots with
coincident ones merged (``queue_crossings``), and the restart at a root just reported, which
must not find that crossing again (``carry_last_root``).

A queue entry is (τ, z, kinds, signs): the state at the crossing, the root functions that cross
there and the sign of each after its crossing.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from integrators.core.events import AT_ROOT, H_EXTREMUM, PEAK

__all__ = ["push_crossing", "queue_crossings", "carry_last_root"]


@njit(cache=True, nogil=True, error_model="numpy")
def push_crossing(R, m, first, t, kind, sign, z0, z1, z2):
    """Write the crossing (τ, kind, sign, z) as row ``m`` of R (doubled when full) and move it
    into time order among the rows ``first``..m (one interval's crossings). Returns R."""
    if m == R.shape[0]:
        R = np.concatenate((R, np.empty_like(R)))
    R[m, 0], R[m, 1], R[m, 2], R[m, 3], R[m, 4], R[m, 5] = t, kind, sign, z0, z1, z2
    j = m
    while j > first and R[j - 1, 0] > R[j, 0]:
        for col in range(6):
            R[j - 1, col], R[j, col] = R[j, col], R[j - 1, col]
        j -= 1
    return R


def queue_crossings(queue, rows) -> None:
    """Append crossings (τ, kind, sign, z), in time order, to ``queue``; one within 1e−14
    relative of the last entry joins it (END and H_EXTREMUM coincide when E = E_slow)."""
    for t, kind, sign, z in rows:
        if queue and t - queue[-1][0] <= 1e-14 * max(1.0, abs(t)):
            queue[-1][2].append(int(kind))
            queue[-1][3].append(int(sign))
        else:
            queue.append((float(t), z, [int(kind)], [int(sign)]))


def carry_last_root(last, tau0: float, z0: np.ndarray, g0: np.ndarray, e: float,
                    quasi_static: bool = False) -> None:
    """Restarting at the root just reported, ``last`` = (τ, z, [(kind, sign)], E): put each of
    its root functions that sits on the wrong side by round-off on the side after its crossing
    (±``AT_ROOT``), so that the new scan does not find the same crossing again. A function that
    moves with E only if the loading speed is the same: H_EXTREMUM (u − ln E), and without mass
    PEAK (K (E − w) − β s')."""
    if last is None or last[0] != tau0 or not np.array_equal(last[1], z0):
        return
    for kind, sign in last[2]:
        moves = kind == H_EXTREMUM or (quasi_static and kind == PEAK)
        if (not moves or last[3] == e) and g0[kind] * sign <= 0.0:
            g0[kind] = sign * AT_ROOT
