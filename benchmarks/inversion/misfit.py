"""The misfit of (b, Lc) as a function, for fits, profiles and samplers (issue 17, item 1).

:class:`Misfit` binds one problem, its observations
(:class:`benchmarks.inversion.observations.Observations`) and one algorithm. It evaluates any batch of (b, Lc) on the ensemble engine
(:func:`benchmarks.ensemble.ensemble`: one compiled batch for the own methods) and returns, per
point, the limit-cycle metrics, the residuals, J1 (Eq. 10), J2 (Eq. 11, when the observations
have slip-weakening curves) and the log-likelihood.

What an optimizer or a sampler sees at a point **without a limit cycle** is defined, never NaN
(:func:`benchmarks.inversion.fitting.scores`): each residual is ``NO_CYCLE_RESIDUAL`` σ and J1
``NO_CYCLE_J1`` (finite, so that least squares can step away), the log-likelihood −inf (a
sampler rejects the move), J2 +inf.

The class and the reason are in the table, so a fit can say why a region is excluded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from benchmarks.ensemble import ensemble
from benchmarks.inversion.fitting import NO_CYCLE_RESIDUAL, j2_per_event, scores
from benchmarks.inversion.observations import MIN_SIGMA_REL, Observations
from benchmarks.physics.metrics import CYCLES
from integrators import Algorithm
from problems import SpringSlider

__all__ = ["Misfit", "NO_CYCLE_RESIDUAL", "synthetic", "MIN_SIGMA_REL"]
@dataclass(frozen=True)
class Misfit:
    """J(b, Lc) of ``problem`` against ``obs`` with ``algorithm`` (module docstring).
    ``wall_budget``: s per forward solve; ``workers``: threads (or processes) of a batch;
    ``curve_dt``: s between saved points of the trajectory J2 compares (with curves only)."""

    problem: SpringSlider
    obs: Observations
    algorithm: Algorithm
    wall_budget: float | None = None
    workers: int | None = None
    curve_dt: float = 5e-5

    def __post_init__(self) -> None:
        for name, value, kind in (("problem", self.problem, SpringSlider),
                                  ("obs", self.obs, Observations),
                                  ("algorithm", self.algorithm, Algorithm)):
            if not isinstance(value, kind):
                raise ValueError(f"{name} must be {kind.__name__}, got {value!r}")

    def evaluate(self, b, lc, progress: bool = False) -> pd.DataFrame:
        """One row per (b, Lc) pair (``b`` and ``lc`` broadcast together; Lc in m): the
        ensemble's columns, then ``r_recurrence``, ``r_drop`` (residuals in σ), ``J1``, ``J2``
        (NaN without curves) and ``log_likelihood``."""
        b, lc = np.broadcast_arrays(np.asarray(b, dtype=float), np.asarray(lc, dtype=float))
        table = ensemble(self.problem, self.algorithm, {"b": b.ravel(), "lc": lc.ravel()},
                         wall_budget=self.wall_budget,
                         workers=1 if b.size == 1 else self.workers,   # no pool for one point
                         curve_dt=self.curve_dt if self.obs.curves is not None else None,
                         progress=progress)
        o = self.obs
        cycle = table.classification.isin(CYCLES).to_numpy()
        s = scores(table.recurrence_s, table.friction_drop, cycle, o)
        table["r_recurrence"], table["r_drop"] = s.penalised
        table["J1"] = s.j1_penalised
        if o.curves is not None:
            table["J2"] = [float(np.mean(j2_per_event(np.asarray(s, dtype=float),
                                                      np.asarray(f, dtype=float), o.curves)))
                           if c else np.inf
                           for c, s, f in zip(cycle, table.curve_slip, table.curve_friction)]
        else:
            table["J2"] = np.nan
        table["log_likelihood"] = s.log_likelihood
        return table

    def residuals(self, b: float, lc: float) -> np.ndarray:
        """(ΔT − ΔT̄)/σ and (Δμ − Δμ̄)/σ at one point, for least squares."""
        row = self.evaluate([b], [lc]).iloc[0]
        return np.array([row.r_recurrence, row.r_drop])

    def __call__(self, b: float, lc: float) -> float:
        """J1 at one point (``NO_CYCLE_J1`` without a limit cycle)."""
        return float(self.evaluate([b], [lc]).J1.iloc[0])

    def log_likelihood(self, b: float, lc: float) -> float:
        """−J1/2 at one point (Gaussian errors of the stated σ), −inf without a limit cycle."""
        return float(self.evaluate([b], [lc]).log_likelihood.iloc[0])


def synthetic(recurrence_s: float, friction_drop: float, sigma_rel: float,
              seed: int) -> Observations:
    """Observations of a limit cycle with true ΔT = ``recurrence_s``, Δμ = ``friction_drop``:
    each plus N(0, σ²) with σ = ``sigma_rel`` × its true value, from ``default_rng(seed)``."""
    if not 0 < sigma_rel < 1:
        raise ValueError(f"sigma_rel must be in (0, 1), got {sigma_rel!r}")
    import warnings

    from problems._validate import UnitWarning
    z = np.random.default_rng(seed).standard_normal(2)
    s_t, s_m = sigma_rel * recurrence_s, sigma_rel * friction_drop
    with warnings.catch_warnings():      # σ is a stated fraction of the truth, not a unit slip:
        warnings.simplefilter("ignore", UnitWarning)     # a study would warn once per seed
        return Observations(recurrence_s + s_t * z[0], s_t, friction_drop + s_m * z[1], s_m)
