"""The posterior of (b, log10 Lc) on a grid of cells: one, refined where its mass is or not.

The prior is uniform on the box in (b, log10 Lc); the likelihood is exp(−misfit/2)
(:class:`benchmarks.inversion.Misfit`: J1, plus the curves' χ² when they enter). The box is
tiled by cells, each evaluated at its centre, its posterior mass the likelihood there times its
area (the midpoint rule, :func:`cell_mass`). From the cells (:func:`posterior_of_cells`,
:class:`GridPosterior`): the mean and standard deviation of each parameter (the midpoint rule's
moments: each cell's mass at its centre), the 95 % equal-tailed marginal intervals (each cell's
mass spread evenly over its extent, :func:`cell_quantiles`), the 95 % highest-density set of
cells (:func:`hpd`), the mass in the cells on the box's edge and on each of its sides, and the
best cell; samples drawn from it (a cell by its mass, a point uniform in it) serve the corner
plot and ``posterior.csv``.

A fixed grid is this posterior with no refinement:
:meth:`benchmarks.inversion.grid.MetricMap.posterior` takes the cells of a map's nodes.
:func:`grid_posterior` starts from ``n`` × ``n`` equal cells
(one ensemble batch) and refines: level by level, the cells that hold the most mass — together
1 − :data:`TAIL` of it, at most :data:`MAX_SPLIT` cells — are each split into 3 × 3 (the centre
is kept, eight new centres evaluated in one batch), until the 95 % marginal intervals move by
less than :data:`SETTLED` of their widths from one level to the next and the 95 %
highest-density region holds at least :data:`MIN_CELLS` cells; or :data:`MAX_LEVELS` levels
were made, and the result says it did not settle.

A posterior narrower than the first grid's spacing is found if its cell's centre beats the
others' (the misfit is smooth in the metrics); a narrow region of limit cycles between centres
with no cycle is not, as for any grid: the first grid's size bounds what it can miss.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import Misfit

__all__ = ["GridPosterior", "grid_posterior", "posterior_of_cells", "centres", "cell_mass",
           "cell_quantiles", "hpd", "TAIL", "MAX_SPLIT", "SETTLED", "MIN_CELLS", "MAX_LEVELS"]

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
_SIDES = ("b_low", "b_high", "lc_low", "lc_high")


def centres(lo: float, hi: float, n: int) -> np.ndarray:
    """The centres of ``n`` equal cells tiling [``lo``, ``hi``]."""
    h = (hi - lo) / n
    return lo + h * (np.arange(n) + 0.5)


def cell_mass(log_l: np.ndarray, area=1.0) -> np.ndarray:
    """The posterior mass of cells with log-likelihood ``log_l`` at their centres and ``area``
    (the midpoint rule under a uniform prior), summing to one; all zero when no cell has a
    finite log-likelihood."""
    finite = np.isfinite(log_l)
    if not finite.any():
        return np.zeros(np.shape(log_l))
    w = np.where(finite, np.exp(log_l - np.max(log_l[finite])), 0.0) * area
    return w / w.sum()


def cell_quantiles(lo: np.ndarray, hi: np.ndarray, mass: np.ndarray, qs) -> tuple[float, ...]:
    """Quantiles of a density uniform over each cell [``lo``, ``hi``] with ``mass``: the
    cumulative mass is piecewise linear between the cells' ends (swept once, in order: the
    density steps up by mass/width where a cell begins and down where it ends)."""
    x, at = np.unique(np.concatenate([lo, hi]), return_inverse=True)
    rate = mass / (hi - lo)
    steps = np.zeros(len(x))
    np.add.at(steps, at, np.concatenate([rate, -rate]))
    cdf = np.concatenate([[0.0], np.cumsum(np.cumsum(steps)[:-1] * np.diff(x))])
    return tuple(float(np.interp(q, cdf, x)) for q in qs)


def hpd(mass: np.ndarray, level: float, area=1.0) -> np.ndarray:
    """The highest-posterior-density set of cells (a mask of ``mass``' shape): the fewest
    cells by decreasing density ``mass``/``area`` that hold ``level`` of the mass, the cell
    that crosses the level included."""
    order = np.argsort(mass / area, axis=None)[::-1]
    n_in = int(np.searchsorted(np.cumsum(mass.ravel()[order]), level) + 1)
    inside = np.zeros(mass.size, bool)
    inside[order[:n_in]] = True
    return inside.reshape(mass.shape)


@dataclass
class GridPosterior:
    """The posterior on a grid of cells (module docstring).

    ``cells``: each cell's centre (``b``, ``log10_lc``), widths, log-likelihood, misfit,
    ``failed`` (its solve did not succeed) and ``mass`` (summing to one; all zero, and ``ok``
    False, when no cell has a cycle); ``hpd``: the highest-density cells; ``interval``: the
    equal-tailed marginal intervals (both at the posterior's level, 95 % unless asked);
    ``edge_mass``: the mass in the cells on the box's edge, ``side_mass`` on each side
    (``b_low``, ``b_high``, ``lc_low``, ``lc_high``); ``best``: (b, Lc in m, misfit) of the
    best cell. A grid not refined has its ``shape`` (n_b, n_lc), and ``mass`` and ``hpd`` come
    in that shape, node by node; a refined one's, cell by cell. ``levels``, ``settled`` and
    ``history`` are the refinement's (0, False and empty without one); ``n_solves``,
    ``n_failed`` and ``wall_s``, what the grid cost.

    Parameters
    ----------
    cells : pandas.DataFrame
        One row a cell: ``b`` (dimensionless) and ``log10_lc`` (log10 of m) of its centre,
        ``width_b``, ``width_log10_lc``, ``log_likelihood``, ``misfit``, ``failed`` and
        ``mass`` (dimensionless).
    hpd : numpy.ndarray
        Whether each cell is in the highest-density set (bool), in ``shape`` when not refined.
    mean, std : dict of str to float
        Each parameter's posterior mean and standard deviation, keyed ``"b"``
        (dimensionless) and ``"log10_lc"`` (log10 of m); NaN without a posterior.
    interval : dict of str to tuple of float
        Each parameter's equal-tailed marginal interval (low, high), keyed as ``mean``.
    edge_mass : float
        The mass in the cells on the box's edge (dimensionless).
    side_mass : dict of str to float
        The mass in the cells on each side: ``b_low``, ``b_high``, ``lc_low``, ``lc_high``.
    best : tuple of float
        (b, Lc in m, misfit) at the centre of the cell of highest likelihood.
    prior : str
        The prior in words: the box, uniform in b and log10 Lc.
    shape : tuple of int or None
        (n_b, n_lc) of a grid not refined; None for a refined one.
    levels : int
        Refinement levels made (0 without refinement).
    settled : bool
        Whether the refinement settled before :data:`MAX_LEVELS`.
    n_solves : int
        Forward solves the grid cost.
    n_failed : int
        Of those, the solves that did not succeed.
    wall_s : float
        The grid's wall time (s).
    history : list of dict
        One a level: ``level``, ``cells``, ``split``, ``solves``, ``moved`` (the intervals'
        largest move, as a fraction of the width) and ``hpd_cells``.
    frame : Frame or None
        The frame of a grid laid in one (:class:`benchmarks.inversion.zoom.Frame`): each cell is
        the square of ``z_b``, ``z_log10_lc`` (its centre) and ``width_z`` (its side) mapped by
        ``frame.to_x`` (a map of constant Jacobian, so that a cell's mass is its likelihood
        times ``width_z`` squared), and ``width_b``, ``width_log10_lc`` are its extents; None
        for cells that are rectangles in (b, log10 Lc).
    """

    cells: pd.DataFrame = field(repr=False)
    hpd: np.ndarray = field(repr=False)
    mean: dict
    std: dict
    interval: dict
    edge_mass: float
    side_mass: dict
    best: tuple
    prior: str
    shape: tuple | None = None
    levels: int = 0
    settled: bool = False
    n_solves: int = 0
    n_failed: int = 0
    wall_s: float = 0.0
    history: list = field(default_factory=list)
    frame: object = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        """Whether some cell has a limit cycle: else there is no posterior."""
        return bool(self.cells.mass.sum() > 0)

    @property
    def mass(self) -> np.ndarray:
        """The cells' mass, in the grid's ``shape`` when it was not refined."""
        m = self.cells.mass.to_numpy()
        return m if self.shape is None else m.reshape(self.shape)

    def sample(self, n: int, seed: int = 0) -> pd.DataFrame:
        """``n`` draws: a cell by its mass, then a point uniform inside it.

        Raises
        ------
        ValueError
            When no cell has a limit cycle: there is no posterior to draw from.
        """
        if not self.ok:
            raise ValueError("no cell of the grid has a limit cycle: there is no posterior to "
                             "draw from")
        rng = np.random.default_rng(seed)
        c = self.cells
        k = rng.choice(len(c), size=n, p=c.mass.to_numpy())
        u = rng.random((n, 2)) - 0.5
        if self.frame is not None:       # uniform in the cell's square in the frame
            w = c.width_z.to_numpy()[k]
            z = np.column_stack([c.z_b.to_numpy()[k], c.z_log10_lc.to_numpy()[k]]) + u * w[:, None]
            x = self.frame.to_x(z)
            return pd.DataFrame({"b": x[:, 0], "log10_lc": x[:, 1]})
        return pd.DataFrame({"b": c.b.to_numpy()[k] + u[:, 0] * c.width_b.to_numpy()[k],
                             "log10_lc": c.log10_lc.to_numpy()[k]
                             + u[:, 1] * c.width_log10_lc.to_numpy()[k]})


def posterior_of_cells(cells: pd.DataFrame, box, level: float = 0.95, shape=None,
                       **cost) -> GridPosterior:
    """The posterior of the cells that tile ``box`` (module docstring).

    Parameters
    ----------
    cells : pandas.DataFrame
        One row a cell: ``b``, ``log10_lc`` (its centre), ``width_b``, ``width_log10_lc``,
        ``log_likelihood``, ``misfit`` and ``failed``; its ``mass`` is (re)computed.
    box : tuple
        ``((b_lo, b_hi), (log10_lc_lo, log10_lc_hi))``, the prior box the cells tile.
    level : float
        Of the highest-density set and of the marginal intervals.
    shape : tuple or None
        (n_b, n_lc) of a grid not refined, its cells in ``meshgrid(..., indexing="ij")`` order.
    **cost
        ``levels``, ``settled``, ``history``, ``n_solves``, ``n_failed``, ``wall_s`` and
        ``frame``, as :class:`GridPosterior` holds them.

    Returns
    -------
    GridPosterior
        NaN summaries, no ``hpd`` cell and ``ok`` False when no cell has a limit cycle.
    """
    # a frame's cells: its map's Jacobian is a constant, the squares' areas in z are as good
    area = (cells.width_z ** 2 if "width_z" in cells
            else cells.width_b * cells.width_log10_lc).to_numpy()
    cells = cells.assign(mass=cell_mass(cells.log_likelihood.to_numpy(), area))
    (b_lo, b_hi), (l_lo, l_hi) = box
    prior = (f"uniform in b on [{b_lo:g}, {b_hi:g}] and in log10 Lc on [{l_lo:g}, {l_hi:g}] "
             "(Lc in m)")
    m = cells.mass.to_numpy()
    nan = float("nan")
    if not m.sum() > 0:                  # no cell with a limit cycle: no posterior, no numbers
        return GridPosterior(cells, np.zeros(shape or len(cells), bool),
                             dict.fromkeys(_NAMES, nan), dict.fromkeys(_NAMES, nan),
                             dict.fromkeys(_NAMES, (nan, nan)), nan, dict.fromkeys(_SIDES, nan),
                             (nan, nan, nan), prior, shape, **cost)
    mean, std, interval, sides = {}, {}, {}, {}
    for name, (lo, hi), side in zip(_NAMES, box, ("b", "lc")):
        x, w = cells[name].to_numpy(), cells[f"width_{name}"].to_numpy()
        # sums, not BLAS's dot: its threads cost milliseconds a call on a busy machine
        mean[name] = float(np.sum(m * x))
        std[name] = float(np.sqrt(max(np.sum(m * (x - mean[name]) ** 2), 0.0)))
        interval[name] = cell_quantiles(x - w / 2, x + w / 2, m, ((1 - level) / 2,
                                                                  (1 + level) / 2))
        tol = 1e-12 * (hi - lo)
        sides[f"{side}_low"] = x - w / 2 <= lo + tol
        sides[f"{side}_high"] = x + w / 2 >= hi - tol
    edge = np.logical_or.reduce(list(sides.values()))
    top = cells.loc[cells.log_likelihood.idxmax()]
    inside = hpd(m, level, area)
    return GridPosterior(cells, inside if shape is None else inside.reshape(shape), mean, std,
                         interval, float(m[edge].sum()),
                         {k: float(m[s].sum()) for k, s in sides.items()},
                         (float(top.b), float(10.0 ** top.log10_lc), float(top.misfit)), prior,
                         shape, **cost)


def grid_posterior(misfit: Misfit, b_range, lc_range, n: int = 33, progress: bool = False,
                   say=None, refine: bool = True, first: GridPosterior | None = None
                   ) -> GridPosterior:
    """The refined grid posterior of ``misfit`` (module docstring).

    Parameters
    ----------
    misfit : Misfit
        Or any object with ``evaluate(b, lc, progress=...)`` giving ``misfit`` and
        ``log_likelihood`` (and ``retcode``, optional) columns.
    b_range, lc_range : tuple
        The prior box, b × Lc (m).
    n : int
        The first grid's cells along each side, 3 to 1001.
    progress : bool
        Show the ensembles' progress.
    say : callable or None
        Given a line of text as each level starts.
    refine : bool
        Refine (False: the first grid alone).
    first : GridPosterior, optional
        The first grid already evaluated (an unrefined grid posterior of the same box, ``n``
        × ``n``), refined instead of solving it again; its solves and wall time are counted.

    Returns
    -------
    GridPosterior

    Raises
    ------
    ValueError
        For a first grid's size out of range.
    """
    say = say or (lambda text: None)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 3 <= n <= 1001:
        raise ValueError(f"the first grid's size must be an integer from 3 to 1001, got {n!r}")
    box = (tuple(b_range), (float(np.log10(lc_range[0])), float(np.log10(lc_range[1]))))
    started = time.perf_counter()
    failed_before = _failed(misfit)
    if first is None:
        (b_lo, b_hi), (l_lo, l_hi) = box
        bb, ll = np.meshgrid(centres(b_lo, b_hi, n), centres(l_lo, l_hi, n), indexing="ij")
        cells = _evaluate(misfit, bb.ravel(), ll.ravel(), np.full(bb.size, (b_hi - b_lo) / n),
                          np.full(bb.size, (l_hi - l_lo) / n), progress)
    else:                                # its solves and time are counted below
        cells = first.cells.drop(columns="mass")
        failed_before -= first.n_failed
        started -= first.wall_s
    post = posterior_of_cells(cells, box)
    history, settled, n_solves = [], False, len(cells)
    for level in range(1, (MAX_LEVELS if refine else 0) + 1):
        if not post.ok:
            break
        before = post.interval
        cells, split, new = _refine(misfit, post.cells, progress, lambda k: say(
            f"grid posterior: level {level}, {k} cells split 3 × 3"))
        n_solves += new
        post = posterior_of_cells(cells, box)
        moved = max(max(abs(post.interval[k][0] - before[k][0]),
                        abs(post.interval[k][1] - before[k][1]))
                    / max(post.interval[k][1] - post.interval[k][0], 1e-300) for k in _NAMES)
        history.append({"level": level, "cells": len(cells), "split": split,
                        "solves": n_solves, "moved": moved, "hpd_cells": int(post.hpd.sum())})
        if moved < SETTLED and history[-1]["hpd_cells"] >= MIN_CELLS:
            settled = True
            break
    return posterior_of_cells(post.cells, box, levels=len(history), settled=settled,
                              history=history, n_solves=n_solves,
                              n_failed=_failed(misfit) - failed_before,
                              wall_s=time.perf_counter() - started)


def _refine(misfit: Misfit, cells: pd.DataFrame, progress,
            say) -> tuple[pd.DataFrame, int, int]:
    """One level: the cells holding 1 − TAIL of the mass (MAX_SPLIT at most) split 3 × 3, the
    centre kept (``say`` is given their number first); ``(cells, cells split, new solves)``."""
    order = np.argsort(-cells.mass.to_numpy())
    cum = np.cumsum(cells.mass.to_numpy()[order])
    split = order[:min(int(np.searchsorted(cum, 1.0 - TAIL) + 1), MAX_SPLIT)]
    say(len(split))
    parent = cells.iloc[split]
    b, l = parent.b.to_numpy(), parent.log10_lc.to_numpy()
    wb, wl = parent.width_b.to_numpy() / 3, parent.width_log10_lc.to_numpy() / 3
    kids = [(b + di * wb, l + dj * wl, wb, wl)
            for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj]
    new = _evaluate(misfit, *(np.concatenate(k) for k in zip(*kids)), progress)
    kept = parent.assign(width_b=wb, width_log10_lc=wl)
    return (pd.concat([cells.drop(cells.index[split]), kept, new], ignore_index=True),
            len(split), len(new))


def _failed(misfit) -> int:
    """The forward solves ``misfit`` saw fail so far (0 for a misfit that does not count them:
    any object with ``evaluate`` serves, as the tests' analytic ones)."""
    return int(getattr(misfit, "failures", {}).get("failed", 0))


def _evaluate(misfit: Misfit, b, log10_lc, width_b, width_l, progress) -> pd.DataFrame:
    table = misfit.evaluate(b, 10.0 ** np.asarray(log10_lc), progress=progress)
    return pd.DataFrame({"b": b, "log10_lc": log10_lc, "width_b": width_b,
                         "width_log10_lc": width_l,
                         "log_likelihood": table.log_likelihood.to_numpy(),
                         "misfit": table.misfit.to_numpy(),
                         "failed": ((table.retcode != "Success").to_numpy() if "retcode" in table
                                    else np.zeros(len(table), bool))})
