"""J (Eq. 12) as a function of (b, Lc), once its weights are fixed.

J = J1 + (α1/α2)·J̄2. The paper's weights are statistics of a grid
(:func:`benchmarks.inversion.objectives.joint_fit`: α1 the mean J1 inside the 95 % region, α2 the mean J̄2 of
the points that match the curves best), so J at one point has no meaning until they are fixed.
Take them from a sweep of the region (its ``table.attrs["alpha1"]`` and ``["alpha2"]``); J is
then a function of (b, Lc) like J1, for a fit or a sampler. A point without a limit cycle has
J = +inf (its J2 is +inf, :class:`~benchmarks.inversion.Misfit`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from benchmarks.inversion.misfit import Misfit

__all__ = ["joint_misfit"]


def joint_misfit(misfit: Misfit, b, lc, alpha1: float, alpha2: float) -> pd.DataFrame:
    """:meth:`Misfit.evaluate`'s table of the points (``b``, ``lc``) with the column ``J`` for the
    fixed weights ``alpha1`` and ``alpha2`` (both positive and finite); the misfit must have
    slip-weakening curves."""
    for name, value in (("alpha1", alpha1), ("alpha2", alpha2)):
        if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    if misfit.obs.curves is None:
        raise ValueError("J needs observed slip-weakening curves: the misfit's observations "
                         "have none (J1 alone is the misfit then)")
    if misfit.obs.curve_likelihood is None:
        raise ValueError("J needs the model's slip-weakening curves, which a misfit makes only "
                         "when the observed curves are in its likelihood: the observations "
                         "have curve_noise 'none'")
    table = misfit.evaluate(b, lc, j2=True)
    table["J"] = table.J1 + alpha1 / alpha2 * table.J2
    return table
