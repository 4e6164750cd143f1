"""The paper's published fits, and the box around each that its sweeps searched.

Urata et al. (2017) publish the best (b, Lc) of each window for the slip law (Sect. 4.1); the
aging law's is solved from Table 3 and the nucleation lengths (:func:`problems.aging_best_fit`).
The box around a fit is the paper's sweep grid: b on its 1e−4 steps, Lc log-spaced a factor
either side; it is the default prior box of an inversion of a window's means.
"""

from __future__ import annotations

import numpy as np

from problems import WINDOWS, aging_best_fit

__all__ = ["GRID", "T_END", "B_STEP", "best_fit", "grid_around", "prior_box"]

#: grid around a best fit: b ± half_width in steps of 1e-4 (the paper's step), Lc from fit/f to
#: fit·f on n log-spaced values
GRID = {"slip": dict(half_width=0.0008, lc_factor=10.0, n_lc=13),
        "aging": dict(half_width=0.0015, lc_factor=30.0, n_lc=15)}
#: simulated time per point: ≥ 30 cycles at the observed recurrence interval
T_END = {"W1": 40.0, "W2": 40.0, "W3": 40.0, "W4": 15.0}
B_STEP = 1e-4


def best_fit(name: str, law: str) -> tuple[float, float]:
    """The published best (b, Lc in m) of window ``name`` for ``law`` (slip or aging)."""
    w = WINDOWS[name]
    return (w.slip_b, w.slip_lc) if law == "slip" else aging_best_fit(w)


def grid_around(b0: float, lc0: float, half_width: float, lc_factor: float, n_lc: int):
    """b on the paper's 1e−4 grid through b0; Lc log-spaced with lc0 as the middle value."""
    k = int(round(half_width / B_STEP))
    b = np.round(b0 + B_STEP * np.arange(-k, k + 1), 12)
    b = b[b > 0]
    lc = np.geomspace(lc0 / lc_factor, lc0 * lc_factor, n_lc)
    lc[n_lc // 2] = lc0                      # exactly the published value
    return b, lc


def prior_box(name: str, law: str):
    """The paper sweep's box around a window's published fit: ``(b_range, lc_range)``; a law the
    paper did not fit (the Nagata law) has none (``ValueError``)."""
    if law not in GRID:
        raise ValueError(f"law = {law!r}: the paper publishes no fit of it to centre a prior box "
                         f"on (it fits the {' and '.join(GRID)} laws); state the box")
    b, lc = grid_around(*best_fit(name, law), **GRID[law])
    return (float(b.min()), float(b.max())), (float(lc.min()), float(lc.max()))
