"""The posterior of (b, log10 Lc) on a grid refined where its mass is.

The prior is uniform on the box in (b, log10 Lc); the likelihood is exp(−misfit/2)
(:class:`benchmarks.inversion.Misfit`: J1, plus the curves' χ² when they enter). The box is
tiled by ``n`` × ``n`` equal cells, each evaluated at its centre (one ensemble batch), its
posterior mass the likelihood there times its area (the midpoint rule). Then, level by level,
the cells that hold the most mass — together 1 − :data:`TAIL` of it, at most
:data:`MAX_SPLIT` cells — are each split into 3 × 3 (the centre is kept, eight new centres
evaluated in one batch), until the 95 % marginal intervals move by less than :data:`SETTLED` of
their widths from one level to the next and the 95 % highest-density region holds at least
:data:`MIN_CELLS` cells; or :data:`MAX_LEVELS` levels were made, and the result says it did not
settle.

Reported (:class:`CellPosterior`): the mean and standard deviation of each parameter, the 95 %
equal-tailed marginal intervals (each cell's mass spread evenly over its extent), the mass in the
cells on the box's edge, the number of cells, levels and solves; samples drawn from it (a cell by
its mass, a point uniform in it) serve the corner plot and ``posterior.csv``.

A posterior narrower than the first grid's spacing is found if its cell's centre beats the
others' (the misfit is smooth in the metrics); a narrow region of limit cycles between centres
with no cycle is not, as for any grid: the first grid's size bounds what it can miss.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.grid import cell_mass, cell_quantiles, hpd
from benchmarks.inversion.misfit import Misfit

__all__ = ["CellPosterior", "grid_posterior", "TAIL", "MAX_SPLIT", "SETTLED", "MIN_CELLS",
           "MAX_LEVELS"]

#: the mass left unrefined at each level
TAIL = 1e-3
#: cells split per level at most (each 3 × 3: eight new solves)
MAX_SPLIT = 400
#: a level that moves every 95 % interval's ends by less than this fraction of its width settles
SETTLED = 0.02
#: the 95 % highest-density region spans at least this many cells when settled
MIN_CELLS = 40
#: refinement levels at most (each divides the finest spacing by 3)
MAX_LEVELS = 16
_NAMES = ("b", "log10_lc")


@dataclass
class CellPosterior:
    """The refined grid's cells (``cells``: centre, widths, log-likelihood, misfit, mass) and
    the summaries of the module docstring; ``settled``: the refinement met its rule."""

    cells: pd.DataFrame = field(repr=False)
    mean: dict
    std: dict
    interval: dict
    edge_mass: float
    levels: int
    settled: bool
    n_solves: int
    wall_s: float
    prior: str
    best: tuple                      # (b, Lc in m, misfit) of the best centre
    history: list = field(default_factory=list)
    #: solves that failed or ran out of their budget: cells without mass, never a cycle
    n_failed: int = 0

    def sample(self, n: int, seed: int = 0) -> pd.DataFrame:
        """``n`` draws: a cell by its mass, then a point uniform inside it (``ValueError``
        when no cell has a limit cycle: there is no posterior to draw from)."""
        if not self.cells.mass.sum() > 0:
            raise ValueError("no cell of the grid has a limit cycle: there is no posterior to "
                             "draw from")
        rng = np.random.default_rng(seed)
        c = self.cells
        k = rng.choice(len(c), size=n, p=c.mass.to_numpy())
        u = rng.random((n, 2)) - 0.5
        return pd.DataFrame({"b": c.b.to_numpy()[k] + u[:, 0] * c.width_b.to_numpy()[k],
                             "log10_lc": c.log10_lc.to_numpy()[k]
                             + u[:, 1] * c.width_log10_lc.to_numpy()[k]})


def _summary(cells: pd.DataFrame) -> tuple[dict, dict, dict]:
    mean, std, interval = {}, {}, {}
    m = cells.mass.to_numpy()
    if not m.sum() > 0:                  # no cell with a limit cycle: no posterior, no numbers
        nan = dict.fromkeys(_NAMES, float("nan"))
        return nan, dict(nan), dict.fromkeys(_NAMES, (float("nan"), float("nan")))
    for name in _NAMES:
        x, w = cells[name].to_numpy(), cells[f"width_{name}"].to_numpy()
        mean[name] = float(m @ x)
        # each cell uniform over its width: its own variance w²/12 adds to the spread
        std[name] = float(np.sqrt(max(m @ ((x - mean[name]) ** 2 + w ** 2 / 12.0), 0.0)))
        interval[name] = cell_quantiles(x - w / 2, x + w / 2, m, (0.025, 0.975))
    return mean, std, interval


def grid_posterior(misfit: Misfit, b_range, lc_range, n: int = 33, progress: bool = False,
                   say=None) -> CellPosterior:
    """The refined grid posterior of ``misfit`` on the box ``b_range`` × ``lc_range`` (Lc in m)
    from an ``n`` × ``n`` first grid (module docstring)."""
    say = say or (lambda text: None)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 3 <= n <= 1001:
        raise ValueError(f"the first grid's size must be an integer from 3 to 1001, got {n!r}")
    (b_lo, b_hi), (lc_lo, lc_hi) = b_range, lc_range
    l_lo, l_hi = float(np.log10(lc_lo)), float(np.log10(lc_hi))
    started = time.perf_counter()
    wb, wl = (b_hi - b_lo) / n, (l_hi - l_lo) / n
    bb, ll = np.meshgrid(b_lo + wb * (np.arange(n) + 0.5), l_lo + wl * (np.arange(n) + 0.5),
                         indexing="ij")
    failed_before = _failed(misfit)
    cells = _evaluate(misfit, bb.ravel(), ll.ravel(), np.full(bb.size, wb), np.full(bb.size, wl),
                      progress)
    n_solves = len(cells)
    history, settled, level = [], False, 0
    mean, std, interval = _summary(cells)
    for level in range(1, MAX_LEVELS + 1):
        if not cells.mass.any():
            break
        order = np.argsort(-cells.mass.to_numpy())
        cum = np.cumsum(cells.mass.to_numpy()[order])
        split = order[:min(int(np.searchsorted(cum, 1.0 - TAIL) + 1), MAX_SPLIT)]
        say(f"grid posterior: level {level}, {len(split)} cells split 3 × 3")
        parent = cells.iloc[split]
        kids = []
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                if di == 0 and dj == 0:
                    continue
                kids.append((parent.b.to_numpy() + di * parent.width_b.to_numpy() / 3,
                             parent.log10_lc.to_numpy() + dj * parent.width_log10_lc.to_numpy() / 3,
                             parent.width_b.to_numpy() / 3, parent.width_log10_lc.to_numpy() / 3))
        new = _evaluate(misfit, *(np.concatenate(k) for k in zip(*kids)), progress)
        n_solves += len(new)
        centres = parent.copy()
        centres["width_b"] /= 3
        centres["width_log10_lc"] /= 3
        cells = pd.concat([cells.drop(cells.index[split]), centres, new], ignore_index=True)
        cells["mass"] = cell_mass(cells.log_likelihood.to_numpy(),
                                  (cells.width_b * cells.width_log10_lc).to_numpy())
        before = interval
        mean, std, interval = _summary(cells)
        moved = max(max(abs(interval[k][0] - before[k][0]), abs(interval[k][1] - before[k][1]))
                    / max(interval[k][1] - interval[k][0], 1e-300) for k in _NAMES)
        n_hpd = int(hpd(cells.mass.to_numpy(), 0.95,
                        (cells.width_b * cells.width_log10_lc).to_numpy()).sum())
        history.append({"level": level, "cells": len(cells), "split": len(split),
                        "solves": n_solves, "moved": moved, "hpd_cells": n_hpd})
        if moved < SETTLED and n_hpd >= MIN_CELLS:
            settled = True
            break
    edge = ((cells.b - cells.width_b / 2 <= b_lo + 1e-12 * (b_hi - b_lo))
            | (cells.b + cells.width_b / 2 >= b_hi - 1e-12 * (b_hi - b_lo))
            | (cells.log10_lc - cells.width_log10_lc / 2 <= l_lo + 1e-12 * (l_hi - l_lo))
            | (cells.log10_lc + cells.width_log10_lc / 2 >= l_hi - 1e-12 * (l_hi - l_lo)))
    top = cells.loc[cells.log_likelihood.idxmax()] if np.isfinite(cells.log_likelihood).any() \
        else None
    best = ((float(top.b), float(10.0 ** top.log10_lc), float(top.misfit)) if top is not None
            else (np.nan, np.nan, np.nan))
    return CellPosterior(
        cells=cells, mean=mean, std=std, interval=interval,
        edge_mass=float(cells.mass[edge].sum()) if cells.mass.sum() > 0 else float("nan"),
        levels=len(history), settled=settled,
        n_solves=n_solves, wall_s=time.perf_counter() - started,
        n_failed=_failed(misfit) - failed_before,
        prior=f"uniform in b on [{b_lo:g}, {b_hi:g}] and in log10 Lc on [{l_lo:g}, {l_hi:g}] "
              "(Lc in m)", best=best, history=history)


def _failed(misfit) -> int:
    """The forward solves ``misfit`` saw fail so far (0 for a misfit that does not count them:
    any object with ``evaluate`` serves, as the tests' analytic ones)."""
    return int(getattr(misfit, "failures", {}).get("failed", 0))


def _evaluate(misfit: Misfit, b, log10_lc, width_b, width_l, progress) -> pd.DataFrame:
    table = misfit.evaluate(b, 10.0 ** np.asarray(log10_lc), progress=progress)
    cells = pd.DataFrame({"b": b, "log10_lc": log10_lc, "width_b": width_b,
                          "width_log10_lc": width_l,
                          "log_likelihood": table.log_likelihood.to_numpy(),
                          "misfit": table.misfit.to_numpy(),
                          "failed": ((table.retcode != "Success").to_numpy() if "retcode" in table
                                    else np.zeros(len(table), bool))})
    cells["mass"] = cell_mass(cells.log_likelihood.to_numpy(), width_b * width_l)
    return cells
