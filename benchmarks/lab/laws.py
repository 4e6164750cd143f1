"""Which law, and which trend, fits a record: fits to the same samples, side by side.

Each variant's fit (:func:`benchmarks.lab.fit.fit_lab`: the laws on the same record, trend,
weights and fixed parameters; or one law with each trend) is scored by its residual sum of
squares and by the information criteria of Gaussian residuals with σ² = RSS/n: AIC =
n ln(RSS/n) + 2p and BIC = n ln(RSS/n) + p ln n, p the fitted parameters (the law's and the
linear level and slopes), n the samples (the constants every fit shares are dropped).

**What the criteria assume, and the one that chooses.** Independent residuals. A record's
residuals follow each other (lag-1 ρ of 0.7–0.96 on the five real steps): n samples then carry
about n/f independent ones, f the long-run inflation of the residuals' noise model (the white
+ AR(1) part's long-run variance over its variance, read from the variogram:
:attr:`benchmarks.lab.noise.NoiseModel.inflation`; the lag-1 (1 + ρ)/(1 − ρ) for a fit without
one, which misreads a mixture of white and slow AR(1) noise by up to a factor of 4), and a difference in AIC or BIC overstates the evidence by about f.
The choice is the lowest ``bic_eff`` = n ln(RSS/n)/f + p ln(n/f), the BIC of n/f independent
samples, with one f for all (``inflation``: that of the fit with the smallest squares, whose
residuals are nearest the noise; a law that does not fit has ρ near 1 and no say in it);
``delta_bic_eff`` is each one's difference from the chosen. Laws with as many
parameters (aging, slip) are ranked by their RSS alone either way; a richer trend (a slope per
piece) must lower the squares by more than its parameters' worth in n/f samples, so that a
slope cannot take up an evolution the residuals' correlation does not support.

**Whether a law fits at all** is not a comparison: ``sigma_over_noise`` is the residuals' σ
over the record's own sample-to-sample noise (:func:`benchmarks.lab.fit.sample_noise`), and a
law whose residuals are far above it and follow each other (:data:`~benchmarks.lab.fit.NOT_FIT`,
:data:`~benchmarks.lab.fit.NOT_FIT_RHO`) is said not to fit (``fits`` False), whatever the
others do.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from benchmarks.lab.fit import NOT_FIT, NOT_FIT_RHO

__all__ = ["compare_laws", "LAW_COLUMNS", "parse_laws"]

#: the columns of the comparison (lab_fit_laws.csv); a, b, dc (m), k (1/m) are each law's fit
LAW_COLUMNS = ("law", "success", "n", "parameters", "rss", "sigma", "rho", "noise",
               "sigma_over_noise", "fits", "aic", "bic", "inflation", "bic_eff", "delta_bic",
               "delta_bic_eff", "chosen", "a", "b", "dc", "k", "c")


def parse_laws(text: str, known) -> tuple[str, ...]:
    """The laws of ``--law`` (one, or several separated by commas), each one of ``known``;
    a ValueError naming the bad one otherwise."""
    laws = tuple(s.strip() for s in str(text).split(","))
    for law in laws:
        if law not in known:
            raise ValueError(f"--law {law!r}: expected one of {', '.join(known)}, or several "
                             "separated by commas (aging,slip)")
    if len(set(laws)) != len(laws):
        raise ValueError(f"--law {text!r} names a law twice")
    return laws


def compare_laws(fits: dict, label: str = "law") -> pd.DataFrame:
    """One row per variant of ``fits`` (its name → :class:`~benchmarks.lab.fit.LabFit`), with
    :data:`LAW_COLUMNS` (``label`` naming the first; module docstring); ``chosen`` marks the
    lowest ``bic_eff`` among the fits that succeeded (none when none did)."""
    rows = []
    for law, fit in fits.items():
        p = len(fit.free) + len(fit.linear)
        ok = bool(fit.success and np.isfinite(fit.rss) and fit.rss > 0 and fit.n > p)
        nll = fit.n * math.log(fit.rss / fit.n) if ok else math.nan
        ratio = fit.sigma / fit.noise if fit.noise > 0 else math.nan
        rows.append({label: law, "success": ok, "n": fit.n, "parameters": p, "rss": fit.rss,
                     "sigma": fit.sigma, "rho": fit.rho, "noise": fit.noise,
                     "sigma_over_noise": ratio,
                     "fits": not (ratio > NOT_FIT and fit.rho > NOT_FIT_RHO),
                     "aic": nll + 2 * p, "bic": nll + p * math.log(fit.n),
                     **{k: fit.values.get(k, math.nan) for k in ("a", "b", "dc", "k", "c")}})
    table = pd.DataFrame(rows)
    ok = table[table.success]
    tightest = ok.rss.idxmin() if len(ok) else None         # nearest the noise
    f = _inflation(list(fits.values())[tightest]) if len(ok) else math.nan
    table["inflation"] = f
    table["bic_eff"] = (table.n * np.log(table.rss / table.n) / f
                        + table.parameters * np.log(table.n / f))
    table.loc[~table.success, "bic_eff"] = math.nan
    table["chosen"] = False
    if len(ok):
        best = table.bic_eff[table.success].idxmin()
        table.loc[best, "chosen"] = True
        table["delta_bic"] = table.bic - table.bic[best]
        table["delta_bic_eff"] = table.bic_eff - table.bic_eff[best]
    else:
        table["delta_bic"] = table["delta_bic_eff"] = math.nan
    return table[[label, *LAW_COLUMNS[1:]]]


def _inflation(fit) -> float:
    """f of ``fit``: its noise model's long-run inflation (at least 1), or the lag-1
    (1 + ρ)/(1 − ρ) without a noise model."""
    if fit.noise_model is not None:
        return max(fit.noise_model.inflation, 1.0)
    return (1 + fit.rho) / (1 - fit.rho)
