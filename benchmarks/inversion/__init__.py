"""Inversions of (b, Lc) a solver can be chosen for (issue 17): the misfit as a function
(:mod:`~benchmarks.inversion.misfit`) and the multi-start least-squares fit with its covariance
(:mod:`~benchmarks.inversion.fit`)."""

from benchmarks.inversion.fit import FitResult, fit
from benchmarks.inversion.misfit import NO_CYCLE_RESIDUAL, Misfit

__all__ = ["Misfit", "NO_CYCLE_RESIDUAL", "fit", "FitResult"]
