"""The forward model on a grid of (b, log10 Lc), and what any set of observations makes of it.

The limit-cycle metrics of a problem do not depend on the observations, so one ensemble over a
grid (:func:`metric_map`) serves every data set scored against it: the published means, a
thousand seeded synthetic sets (calibration), the same data under another solver (the solver's
effect). From a :class:`MetricMap` and an :class:`~benchmarks.inversion.observations.Observations`:

* :meth:`MetricMap.scores`: Eq. 10 on the grid (:func:`benchmarks.inversion.objectives.scores`), and
  :meth:`MetricMap.j1`, J1 with ``NO_CYCLE_J1`` where there is no limit cycle;
* :meth:`MetricMap.posterior`: the posterior under the uniform prior in (b, log10 Lc) on the
  box the grid's cells tile (:func:`box_grid` puts the nodes at the cells' centres;
  :func:`cell_box`): the one grid posterior of :mod:`benchmarks.inversion.adaptive`, with no
  refinement — every node carries the same prior mass and the posterior mass of a node is
  exp(−J1/2) normalised (zero without a cycle). Reported: the marginal means and standard
  deviations, the 95 % highest-posterior-density set of nodes (the fewest nodes holding 95 % of
  the mass), 95 % equal-tailed marginal intervals and the mass on the box's edge nodes (a
  posterior cut by the box says so);
* :meth:`MetricMap.profile`: the profile of b or of log10 Lc, J1 minimised over the other
  parameter on the grid (no refinement between nodes: the grid's spacing bounds its error).

A grid posterior is exact up to its quadrature, has no Monte-Carlo noise and costs one ensemble
for any number of data sets; in two parameters that beats sampling wherever the posterior is
resolved by the grid. Whether it is, is measured against emcee where the two are compared
(:mod:`benchmarks.inversion.calibration`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.ensemble import ensemble
from benchmarks.inversion.adaptive import GridPosterior, centres, posterior_of_cells
from benchmarks.inversion.objectives import Total, scores, total
from benchmarks.inversion.observations import Observations
from benchmarks.physics.metrics import CYCLES
from integrators import Algorithm
from problems import SpringSlider

__all__ = ["MetricMap", "metric_map", "box_grid", "cell_box"]
#: s between saved points of a peer's trajectory when curves are made point by point (the own
#: methods sample theirs from the dense output: :func:`benchmarks.ensemble.ensemble`)
CURVE_DT = 5e-5


def box_grid(b_range, lc_range, n_b: int = 41, n_lc: int = 41, through=None):
    """``(b, log10_lc)``: the centres of ``n_b`` × ``n_lc`` equal cells tiling the box
    ``b_range`` × ``lc_range`` (Lc in m) in (b, log10 Lc), so that the cells are the box and a
    uniform prior on the box gives every node the same mass. With ``through`` = (b, Lc), the
    nodes are shifted by at most half a spacing so that the point is a node (the box moves by as
    much).

    Parameters
    ----------
    b_range : tuple of float
        (low, high) of b (dimensionless).
    lc_range : tuple of float
        (low, high) of Lc (m); the cells are equal in log10 Lc.
    n_b, n_lc : int
        Cells along b and along log10 Lc, each at least 2.
    through : tuple of float, optional
        A point (b, Lc in m) to make a node; a node shifted to b ≤ 0 is dropped.

    Returns
    -------
    b : numpy.ndarray
        The nodes of b (dimensionless), increasing.
    log10_lc : numpy.ndarray
        The nodes of log10 Lc (log10 of m), increasing.

    Raises
    ------
    ValueError
        For a box without 0 ≤ b_lo < b_hi and 0 < lc_lo < lc_hi, or ``n_b`` or ``n_lc`` under 2.
    """
    (b_lo, b_hi), (lc_lo, lc_hi) = b_range, lc_range
    if not (0 <= b_lo < b_hi and 0 < lc_lo < lc_hi):
        raise ValueError(f"the box must have 0 ≤ b_lo < b_hi and 0 < lc_lo < lc_hi, got "
                         f"b_range = {b_range!r}, lc_range = {lc_range!r}")
    if n_b < 2 or n_lc < 2:
        raise ValueError(f"n_b and n_lc must be ≥ 2, got {n_b}, {n_lc}")
    b = centres(b_lo, b_hi, n_b)
    log10_lc = centres(np.log10(lc_lo), np.log10(lc_hi), n_lc)
    if through is not None:
        b = _through(b, through[0])
        log10_lc = _through(log10_lc, np.log10(through[1]))
        b = b[b > 0] if b[0] <= 0 else b
    return b, log10_lc


def cell_box(b: np.ndarray, log10_lc: np.ndarray) -> tuple[tuple, tuple]:
    """The box the cells of uniform nodes ``b`` × ``log10_lc`` tile: ``(b_range, lc_range)``
    (Lc in m), the prior box of their grid posterior."""
    hb, hl = (b[1] - b[0]) / 2, (log10_lc[1] - log10_lc[0]) / 2
    return ((float(b[0] - hb), float(b[-1] + hb)),
            (float(10.0 ** (log10_lc[0] - hl)), float(10.0 ** (log10_lc[-1] + hl))))


def _through(x: np.ndarray, x0: float) -> np.ndarray:
    step = x[1] - x[0]
    k = int(np.argmin(np.abs(x - x0)))
    return x + (x0 - x[k]) if abs(x0 - x[k]) <= step else x


@dataclass
class MetricMap:
    """The limit-cycle metrics of ``problem`` with ``algorithm`` at every node of the grid
    ``b`` × ``log10_lc`` (arrays of shape (n_b, n_lc); the metrics NaN where ``cycle`` is
    False), with the counters of the ensemble that made it: ``n_failed`` solves that did not
    succeed (their nodes have no cycle), ``wall_s`` the sum of the solves' own wall times,
    ``run_wall_s`` the ensemble's wall time.

    Parameters
    ----------
    b : numpy.ndarray
        The n_b nodes of b (dimensionless).
    log10_lc : numpy.ndarray
        The n_lc nodes of log10 Lc (log10 of m).
    recurrence_s : numpy.ndarray
        The limit cycle's recurrence interval ΔT at each node (s), shape (n_b, n_lc).
    friction_drop : numpy.ndarray
        The limit cycle's friction drop Δμ at each node (dimensionless), shape (n_b, n_lc).
    cycle : numpy.ndarray
        Whether each node's solve ended on a limit cycle (bool), shape (n_b, n_lc).
    classification : numpy.ndarray
        Each node's class (str: ``"stick-slip"``, ``"stable sliding"``, ``"failed"``, …).
    algorithm : str
        The name of the algorithm that made the map.
    n_solves : int
        Forward solves, one a node.
    n_failed : int
        Solves whose retcode is not Success.
    nfev : int
        Right-hand-side evaluations, summed over the solves.
    wall_s : float
        The sum of the solves' own wall times (s).
    run_wall_s : float
        The ensemble's wall time (s).
    curve_slip, curve_friction : numpy.ndarray or None
        Object arrays of shape (n_b, n_lc): each node's slip-weakening curve, slip (m) and
        friction Ft/Fn (dimensionless), empty without a cycle; None for a map made without
        curves.
    """

    b: np.ndarray
    log10_lc: np.ndarray
    recurrence_s: np.ndarray = field(repr=False)
    friction_drop: np.ndarray = field(repr=False)
    cycle: np.ndarray = field(repr=False)
    classification: np.ndarray = field(repr=False)
    algorithm: str
    n_solves: int
    n_failed: int
    nfev: int
    wall_s: float
    run_wall_s: float
    #: each node's slip-weakening curve (slip m, friction Ft/Fn; empty without a cycle), when
    #: the map was made with curves
    curve_slip: np.ndarray | None = field(default=None, repr=False)
    curve_friction: np.ndarray | None = field(default=None, repr=False)

    def total(self, obs: Observations) -> Total:
        """J1 + the curves' χ² at every node against ``obs``, and the log-likelihood
        (:func:`benchmarks.inversion.objectives.total`; the curves' χ² 0 everywhere when
        ``obs`` has none)."""
        like = obs.curve_likelihood
        if like is not None and self.curve_slip is None:
            raise ValueError("the observations have slip-weakening curves but this map was "
                             "made without them: make it with metric_map(..., curves=True)")
        curves = (() if like is None else (self.curve_slip.ravel(), self.curve_friction.ravel()))
        return total(self.scores(obs), like, *curves)

    def misfit(self, obs: Observations) -> np.ndarray:
        """J1 + the curves' χ² at every node; :data:`NO_CYCLE_J1` without a limit cycle (or
        a cycle whose curve is missing)."""
        return self.total(obs).misfit

    def log_likelihood(self, obs: Observations) -> np.ndarray:
        """−misfit/2 at every node, −inf without a limit cycle."""
        return self.total(obs).log_likelihood

    def j1(self, obs: Observations) -> np.ndarray:
        """J1 at every node against ``obs``; :data:`NO_CYCLE_J1` without a limit cycle."""
        return self.scores(obs).j1_penalised

    def scores(self, obs: Observations):
        """Eq. 10 at every node (:func:`benchmarks.inversion.objectives.scores`)."""
        if not isinstance(obs, Observations):
            raise ValueError(f"obs must be Observations, got {obs!r}")
        return scores(self.recurrence_s, self.friction_drop, self.cycle, obs)

    def posterior(self, obs: Observations, level: float = 0.95) -> GridPosterior:
        """The grid posterior of ``obs``: the posterior of the cells the nodes are the centres
        of (:func:`benchmarks.inversion.adaptive.posterior_of_cells`), with no refinement;
        ``mass`` and ``hpd`` come in the grid's shape, and its cost is the map's.

        Parameters
        ----------
        obs : Observations
            The data set.
        level : float
            Of the highest-density set and of the marginal intervals.

        Returns
        -------
        GridPosterior
        """
        t = self.total(obs)
        bb, ll = np.meshgrid(self.b, self.log10_lc, indexing="ij")
        cells = pd.DataFrame({
            "b": bb.ravel(), "log10_lc": ll.ravel(), "width_b": self.b[1] - self.b[0],
            "width_log10_lc": self.log10_lc[1] - self.log10_lc[0],
            "log_likelihood": np.ravel(t.log_likelihood), "misfit": np.ravel(t.misfit),
            "failed": np.ravel(self.classification == "failed")})
        b_box, lc_box = cell_box(self.b, self.log10_lc)
        return posterior_of_cells(cells, (b_box, tuple(np.log10(lc_box))), level,
                                  shape=bb.shape, n_solves=self.n_solves,
                                  n_failed=self.n_failed, wall_s=self.run_wall_s)

    def profile(self, obs: Observations, parameter: str) -> tuple[np.ndarray, np.ndarray]:
        """``(values, misfit)``: the grid's values of ``parameter`` (``"b"`` or ``"log10_lc"``)
        and the misfit minimised over the other parameter's nodes at each."""
        if parameter not in ("b", "log10_lc"):
            raise ValueError(f"parameter must be 'b' or 'log10_lc', got {parameter!r}")
        J = self.misfit(obs)
        return (self.b, J.min(axis=1)) if parameter == "b" else (self.log10_lc, J.min(axis=0))


def metric_map(problem: SpringSlider, algorithm: Algorithm, b, log10_lc,
               wall_budget: float | None = None, workers: int | None = None,
               progress: bool = False, curves: bool = False) -> MetricMap:
    """One ensemble over the grid ``b`` × ``log10_lc`` (1-D arrays, Lc in log10 m); with
    ``curves``, each node's slip-weakening curve too (for observations with curves).

    Parameters
    ----------
    problem : SpringSlider
        The forward problem; each node is its variant with b and lc replaced.
    algorithm : Algorithm
        The forward solver and its options.
    b : array_like
        The nodes of b (dimensionless): at least two, finite, increasing.
    log10_lc : array_like
        The nodes of log10 Lc (log10 of m): at least two, finite, increasing.
    wall_budget : float, optional
        Each forward solve's wall-time budget (s).
    workers : int, optional
        Threads (or processes) of the ensemble.
    progress : bool
        Show the ensemble's progress.
    curves : bool
        Also save each node's slip-weakening curve (sampled every :data:`CURVE_DT` s for the
        peers' solvers).

    Returns
    -------
    MetricMap
        The metrics in shape (len(b), len(log10_lc)).

    Raises
    ------
    ValueError
        For ``b`` or ``log10_lc`` not at least two finite increasing values.
    """
    import time
    b = np.asarray(b, dtype=float)
    log10_lc = np.asarray(log10_lc, dtype=float)
    for name, x in (("b", b), ("log10_lc", log10_lc)):
        if x.ndim != 1 or x.size < 2 or not np.isfinite(x).all() or not (np.diff(x) > 0).all():
            raise ValueError(f"{name} must be at least two finite increasing values, got {x!r}")
    bb, ll = np.meshgrid(b, log10_lc, indexing="ij")
    started = time.perf_counter()
    table = ensemble(problem, algorithm, {"b": bb.ravel(), "lc": 10.0 ** ll.ravel()},
                     wall_budget=wall_budget, workers=workers, progress=progress,
                     curve_dt=CURVE_DT if curves else None)
    run_wall = time.perf_counter() - started
    shape = bb.shape
    curve = {}
    if curves:
        for c in ("curve_slip", "curve_friction"):
            curve[c] = np.empty(shape, dtype=object)
            curve[c].ravel()[:] = list(table[c])
    cycle = table.classification.isin(CYCLES).to_numpy().reshape(shape)
    return MetricMap(
        b=b, log10_lc=log10_lc,
        recurrence_s=np.where(cycle, table.recurrence_s.to_numpy().reshape(shape), np.nan),
        friction_drop=np.where(cycle, table.friction_drop.to_numpy().reshape(shape), np.nan),
        cycle=cycle, classification=table.classification.to_numpy().reshape(shape),
        algorithm=algorithm.name, n_solves=len(table),
        n_failed=int((table.retcode != "Success").sum()), nfev=int(table.nfev.sum()),
        wall_s=float(table.wall_s.sum()), run_wall_s=run_wall, **curve)
