"""Inversions of (b, Lc) a solver can be chosen for: one likelihood, J1 of Eq. 10 plus the
slip-weakening curves' χ² under a stated noise model
(:mod:`~benchmarks.inversion.curve_likelihood`), with what a point without a limit cycle is to
each reader (:func:`~benchmarks.inversion.objectives.scores`);
the observations, typed in or read from a file (:mod:`~benchmarks.inversion.observations`;
measured on a recording by :mod:`benchmarks.lab.observe_recording`); the misfit as a function
(:mod:`~benchmarks.inversion.misfit`), the multi-start least-squares fit with its covariance
(:mod:`~benchmarks.inversion.least_squares`), profile likelihoods
(:mod:`~benchmarks.inversion.profile`), the posterior on a grid, refined where its mass is or not
(:mod:`~benchmarks.inversion.adaptive`), or sampled with emcee
(:mod:`~benchmarks.inversion.posterior`), the forward model on a grid and the posteriors and
profiles of any data set on it (:mod:`~benchmarks.inversion.grid`).
Built on them: one inversion end to end (:mod:`~benchmarks.inversion.invert`), the coverage of
the 95 % regions (:mod:`~benchmarks.inversion.calibration`), the solver's effect on the
inference (:mod:`~benchmarks.inversion.solver_effect`) and the reproduce steps' studies
(:mod:`~benchmarks.studies.inversion`). Laboratory velocity steps are fitted in
:mod:`benchmarks.lab`."""

from benchmarks.inversion.adaptive import GridPosterior, grid_posterior
from benchmarks.inversion.curve_likelihood import CurveLikelihood
from benchmarks.inversion.grid import MetricMap, box_grid, metric_map
from benchmarks.inversion.least_squares import FitResult, fit
from benchmarks.inversion.misfit import Misfit, synthetic
from benchmarks.inversion.objectives import NO_CYCLE_J1, NO_CYCLE_RESIDUAL, Scores, scores
from benchmarks.inversion.observations import read_observations, write_observations
from benchmarks.inversion.posterior import Posterior, sample
from benchmarks.inversion.profile import CHI2_95_1DOF, Profile, profile

__all__ = ["Misfit", "NO_CYCLE_RESIDUAL", "synthetic", "fit", "FitResult", "profile", "Profile",
           "CHI2_95_1DOF", "sample", "Posterior", "metric_map", "MetricMap", "GridPosterior",
           "box_grid", "NO_CYCLE_J1", "scores", "Scores", "read_observations",
           "write_observations", "CurveLikelihood", "grid_posterior"]
