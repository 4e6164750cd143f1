"""Inversions of (b, Lc) a solver can be chosen for (issue 17): the misfit as a function
(:mod:`~benchmarks.inversion.misfit`), the multi-start least-squares fit with its covariance
(:mod:`~benchmarks.inversion.fit`), profile likelihoods (:mod:`~benchmarks.inversion.profile`)
and posterior samples with emcee (:mod:`~benchmarks.inversion.posterior`)."""

from benchmarks.inversion.fit import FitResult, fit
from benchmarks.inversion.misfit import NO_CYCLE_RESIDUAL, Misfit
from benchmarks.inversion.posterior import Posterior, sample
from benchmarks.inversion.profile import CHI2_95_1DOF, Profile, profile

__all__ = ["Misfit", "NO_CYCLE_RESIDUAL", "fit", "FitResult", "profile", "Profile",
           "CHI2_95_1DOF", "sample", "Posterior"]
