"""The misfit of (b, Lc) as a function, for fits, profiles and samplers.

:class:`Misfit` binds one problem, its observations
(:class:`benchmarks.inversion.observations.Observations`) and one algorithm. It evaluates any batch of (b, Lc) on the ensemble engine
(:func:`benchmarks.ensemble.ensemble`: one compiled batch for the own methods) and returns, per
point, the limit-cycle metrics, the residuals, J1 (Eq. 10), and with slip-weakening curves their
χ² (:mod:`benchmarks.inversion.curve_likelihood`) and, when asked, J2 (Eq. 11, the paper's
score: no fit, profile or sampler reads it, and its smooth reading of a noisy model curve is a
tenth of a curves solve); the misfit J1 + χ²_curves, which fits and profiles minimise, and the
log-likelihood, −misfit/2.

What an optimizer or a sampler sees at a point **without a limit cycle** is defined, never NaN
(:func:`benchmarks.inversion.objectives.scores`): each residual is ``NO_CYCLE_RESIDUAL`` σ and J1
``NO_CYCLE_J1`` (finite, so that least squares can step away), the log-likelihood −inf (a
sampler rejects the move), J2 +inf.

The class and the reason are in the table, so a fit can say why a region is excluded.
"""

from __future__ import annotations

import threading
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.ensemble import ensemble
from benchmarks.inversion.objectives import NO_CYCLE_RESIDUAL, scores, total
from benchmarks.inversion.observations import MIN_SIGMA_REL, Observations
from benchmarks.physics.metrics import CYCLES
from integrators import Algorithm
from problems import SpringSlider
from problems._validate import UnitWarning, units_checked_already

__all__ = ["Misfit", "NO_CYCLE_RESIDUAL", "synthetic", "MIN_SIGMA_REL", "BUDGET_STOPS",
           "sensitive_setting"]

#: the retcodes of a solve stopped by its budget (wall time, steps)
BUDGET_STOPS = ("WallTime", "MaxSteps")
_COUNTS = ("solves", "failed", "over_budget")


@dataclass(frozen=True)
class Misfit:
    """J(b, Lc) of ``problem`` against ``obs`` with ``algorithm`` (module docstring).
    ``wall_budget``: s per forward solve; ``workers``: threads (or processes) of a batch;
    ``curve_dt``: s between saved points of the trajectory J2 compares (with curves only).

    A solve that fails or runs out of its budget is a failed point: no limit cycle is read from
    it (the misfit of a point without one), and :attr:`failures` counts it.

    Parameters
    ----------
    problem : SpringSlider
        The forward problem; each point is its variant with b and lc replaced.
    obs : Observations
        What the points are scored against.
    algorithm : Algorithm
        The forward solver and its options.
    wall_budget : float, optional
        Each forward solve's wall-time budget (s).
    workers : int, optional
        Threads (or processes) of a batch of points.
    curve_dt : float
        The save interval of the trajectory the curves are read from (s).

    Raises
    ------
    ValueError
        For a problem, observations or algorithm of another type.
    """

    problem: SpringSlider
    obs: Observations
    algorithm: Algorithm
    wall_budget: float | None = None
    workers: int | None = None
    curve_dt: float = 5e-5
    _counts: dict = field(default_factory=lambda: dict.fromkeys(_COUNTS, 0), init=False,
                          repr=False, compare=False)
    #: the counts are added to from several threads (a sampler's draws)
    _lock: object = field(default_factory=threading.Lock, init=False, repr=False,
                          compare=False)
    _here: object = field(default_factory=threading.local, init=False, repr=False,
                          compare=False)

    @property
    def failures(self) -> dict:
        """The solves evaluated so far: ``solves``, ``failed`` (any retcode but Success) and,
        of those, ``over_budget`` (WallTime or MaxSteps), and the ``wall_budget_s`` per solve."""
        return {**self._counts, "wall_budget_s": self.wall_budget}

    def _count(self, solves: int, failed: int, over_budget: int) -> None:
        with self._lock:
            for name, n in zip(_COUNTS, (solves, failed, over_budget)):
                self._counts[name] += n
        self._here.solves = self.solves_here + solves

    @property
    def solves_here(self) -> int:
        """The solves evaluated so far on the calling thread (a sampler's draw counts its
        own)."""
        return getattr(self._here, "solves", 0)

    def __post_init__(self) -> None:
        for name, value, kind in (("problem", self.problem, SpringSlider),
                                  ("obs", self.obs, Observations),
                                  ("algorithm", self.algorithm, Algorithm)):
            if not isinstance(value, kind):
                raise ValueError(f"{name} must be {kind.__name__}, got {value!r}")

    def evaluate(self, b, lc, progress: bool = False, j2: bool = False) -> pd.DataFrame:
        """One row per (b, Lc) pair (``b`` and ``lc`` broadcast together; Lc in m): the
        ensemble's columns, then ``r_recurrence``, ``r_drop`` (residuals in σ), ``J1``,
        ``chi2_curves`` (the curves' χ², :mod:`benchmarks.inversion.curve_likelihood`; 0
        without curves), ``misfit`` (−2 log L + const: J1 + χ²_curves), ``J2`` (Eq. 11's mean
        over the events, the paper's score; NaN unless ``j2`` and the curves are in the
        likelihood: only then are the model's curves made) and ``log_likelihood``."""
        b, lc = np.broadcast_arrays(np.asarray(b, dtype=float), np.asarray(lc, dtype=float))
        table = ensemble(self.problem, self.algorithm, {"b": b.ravel(), "lc": lc.ravel()},
                         wall_budget=self.wall_budget,
                         workers=1 if b.size == 1 else self.workers,   # no pool for one point
                         curve_dt=(self.curve_dt if self.obs.curve_likelihood is not None
                                   else None),
                         curve_chain=getattr(self.obs.curve_likelihood, "chain", None),
                         progress=progress)
        o = self.obs
        failed = (table.retcode != "Success").to_numpy()
        self._count(len(table), int(failed.sum()), int(table.retcode.isin(BUDGET_STOPS).sum()))
        cycle = table.classification.isin(CYCLES).to_numpy() & ~failed     # never a cycle
        s = scores(table.recurrence_s, table.friction_drop, cycle, o)
        table["r_recurrence"], table["r_drop"] = s.penalised
        table["J1"] = s.j1_penalised
        like = o.curve_likelihood
        t = total(s, like, table.get("curve_slip", ()), table.get("curve_friction", ()))
        table["J2"] = np.nan if like is None or not j2 else [
            like.j2(x, y) if c else np.inf
            for c, x, y in zip(cycle, table.curve_slip, table.curve_friction)]
        table["chi2_curves"], table["misfit"], table["log_likelihood"] = t
        return table

    def residuals(self, b: float, lc: float) -> np.ndarray:
        """The residuals at one point whose squares sum to its misfit, for least squares:
        (ΔT − ΔT̄)/σ, (Δμ − Δμ̄)/σ and, with curves, the curves' whitened residuals (without a
        limit cycle or its curve: :data:`NO_CYCLE_RESIDUAL` twice, then zeros)."""
        row = self.evaluate([b], [lc]).iloc[0]
        out = [row.r_recurrence, row.r_drop]
        like = self.obs.curve_likelihood
        if like is None:
            return np.array(out)
        r = like.residuals(row.curve_slip, row.curve_friction)
        if not np.isfinite(row.log_likelihood) or not np.isfinite(r).all():
            # the squares sum to NO_CYCLE_J1, the misfit of a point without a cycle
            return np.concatenate([[NO_CYCLE_RESIDUAL] * 2, np.zeros(len(r))])
        return np.concatenate([out, r])

    def residuals_and_jacobian(self, values: dict) -> tuple[np.ndarray, np.ndarray]:
        """The residuals (ΔT, Δμ in σ, :meth:`residuals`) at the problem with ``values``
        (parameter name → value, SI; the others kept) and their derivatives with respect to
        each of ``values``' parameters (2 × len(values)), from one solve with forward
        sensitivities: :meth:`_sensitive_algorithm`'s, at this misfit's tolerance, at most
        :data:`problems.directions.SENSITIVITY_RTOL`. Where a cycle has no derivative
        (an arrest in it), forward differences of relative step 1e−3 instead. Without a limit
        cycle: :data:`NO_CYCLE_RESIDUAL` twice and a zero Jacobian (the misfit's plateau).
        Curves are not differentiated: ValueError with curves."""
        from benchmarks.physics.metrics import cycle_gradient
        from problems.slider import variant
        if self.obs.curve_likelihood is not None:
            raise ValueError("exact Jacobians cover ΔT and Δμ; with slip-weakening curves in "
                             "the likelihood the fit differentiates by differences")
        names = tuple(values)
        problem = variant(self.problem, **{n: float(v) for n, v in values.items()})
        algorithm = self._sensitive_algorithm()
        r, sol, cycle = self._cycle_residuals(problem, algorithm, names)
        if cycle is None:
            return r, np.zeros((2, len(names)))
        grad = cycle_gradient(sol, cycle)
        if grad:
            sigma_t, sigma_mu = getattr(self.obs, "sigmas", (self.obs.sigma_recurrence_s,
                                                             self.obs.sigma_friction_drop))
            return r, np.array([[grad["recurrence_s"][n] / sigma_t for n in names],
                                [grad["friction_drop"][n] / sigma_mu for n in names]])
        jac = np.zeros((2, len(names)))
        for j, name in enumerate(names):
            step = 1e-3 * (abs(float(values[name])) or 1.0)
            moved = variant(problem, **{name: float(values[name]) + step})
            jac[:, j] = (self._cycle_residuals(moved, algorithm, ())[0] - r) / step
        return r, jac

    def residuals_at(self, values: dict) -> np.ndarray:
        """The residuals of :meth:`residuals_and_jacobian` at ``values`` without the Jacobian:
        one plain solve of the same integrator (a sampler's step needs no gradient)."""
        from problems.slider import variant
        problem = variant(self.problem, **{n: float(v) for n, v in values.items()})
        return self._cycle_residuals(problem, self._sensitive_algorithm(), ())[0]

    def _sensitive_algorithm(self):
        """The setting the gradients are solved with: :func:`sensitive_setting` of this
        misfit's algorithm."""
        return sensitive_setting(self.algorithm)

    def _cycle_residuals(self, problem, algorithm, names):
        """(ΔT, Δμ residuals in σ, the solution, its cycle or None) of one solve of
        ``problem`` (with the sensitivities ``names``), counted as this misfit's solves."""
        from benchmarks.physics.metrics import summarize
        from integrators import solve
        with units_checked_already():        # a context variable: safe in a sampler's threads
            sol = solve(problem, algorithm, max_points=2, sensitivity=names or None,
                        wall_budget=self.wall_budget)
        self._count(1, int(not sol.success), int(sol.retcode.value in BUDGET_STOPS))
        cycle = summarize(sol)
        if cycle.classification not in CYCLES:
            return np.full(2, NO_CYCLE_RESIDUAL), sol, None
        s = scores([cycle.recurrence_s], [cycle.friction_drop], [True], self.obs)
        return np.array([s.penalised[0][0], s.penalised[1][0]]), sol, cycle

    def __call__(self, b: float, lc: float) -> float:
        """The misfit at one point (``NO_CYCLE_J1`` without a limit cycle)."""
        return float(self.evaluate([b], [lc]).misfit.iloc[0])

    def log_likelihood(self, b: float, lc: float) -> float:
        """−misfit/2 at one point (Gaussian errors of the stated σ), −inf without a limit
        cycle."""
        return float(self.evaluate([b], [lc]).log_likelihood.iloc[0])


def sensitive_setting(algorithm):
    """``algorithm`` where it has forward sensitivities (Rodas5P, RadauIIA5) with rtol and
    atol ≤ :data:`problems.directions.SENSITIVITY_RTOL`; else its method (Rodas5P for one
    without sensitivities) with each tightened to that."""
    from integrators import make_algorithm
    from problems.directions import SENSITIVITY_RTOL
    rtol = getattr(algorithm, "rtol", None) or SENSITIVITY_RTOL
    atol = getattr(algorithm, "atol", None) or SENSITIVITY_RTOL
    sensitive = getattr(algorithm, "sensitive", False)
    if sensitive and max(rtol, atol) <= SENSITIVITY_RTOL:
        return algorithm
    return make_algorithm(algorithm.name if sensitive else "Rodas5P",
                          rtol=min(rtol, SENSITIVITY_RTOL), atol=min(atol, SENSITIVITY_RTOL))


def synthetic(recurrence_s: float, friction_drop: float, sigma_rel: float,
              seed: int) -> Observations:
    """Observations of a limit cycle with true ΔT = ``recurrence_s``, Δμ = ``friction_drop``:
    each plus N(0, σ²) with σ = ``sigma_rel`` × its true value, from ``default_rng(seed)``.

    Parameters
    ----------
    recurrence_s : float
        The true recurrence interval ΔT (s).
    friction_drop : float
        The true friction drop Δμ (dimensionless).
    sigma_rel : float
        Each σ over its true value (dimensionless, in (0, 1)).
    seed : int
        The random generator's seed.

    Returns
    -------
    Observations

    Raises
    ------
    ValueError
        For ``sigma_rel`` outside (0, 1).
    """
    if not 0 < sigma_rel < 1:
        raise ValueError(f"sigma_rel must be in (0, 1), got {sigma_rel!r}")
    z = np.random.default_rng(seed).standard_normal(2)
    s_t, s_m = sigma_rel * recurrence_s, sigma_rel * friction_drop
    with warnings.catch_warnings():      # σ is a stated fraction of the truth, not a unit slip:
        warnings.simplefilter("ignore", UnitWarning)     # a study would warn once per seed
        return Observations(recurrence_s + s_t * z[0], s_t, friction_drop + s_m * z[1], s_m)
