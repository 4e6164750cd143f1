"""Which law fits a record: the fits of several laws to the same samples, side by side.

Each law's fit (:func:`benchmarks.lab.fit.fit_lab`, the same record, trend, weights and fixed
parameters) is scored by its residual sum of squares and by the information criteria of
Gaussian residuals with σ² = RSS/n: AIC = n ln(RSS/n) + 2p and BIC = n ln(RSS/n) + p ln n, p
the fitted parameters (the law's and the linear level and slopes), n the samples (the constants
every law shares are dropped). The lowest BIC is the chosen law.

**What the criteria assume.** Independent residuals. A record's residuals follow each other
(AR(1) ρ of 0.7–0.96 on the five real steps): n samples then carry about n/f independent ones,
f = (1 + ρ)/(1 − ρ), and a difference in AIC or BIC overstates the evidence by about f;
``delta_bic_ar1`` is ΔBIC ÷ f (f of the chosen law's residuals), the difference to read. Laws
with as many parameters (aging, slip) differ in the RSS alone; the Nagata law has one more (c).

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
               "sigma_over_noise", "fits", "aic", "bic", "delta_bic", "delta_bic_ar1", "chosen",
               "a", "b", "dc", "k", "c")


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


def compare_laws(fits: dict) -> pd.DataFrame:
    """One row per law of ``fits`` (law → :class:`~benchmarks.lab.fit.LabFit`), with
    :data:`LAW_COLUMNS` (module docstring); ``chosen`` marks the lowest BIC among the fits
    that succeeded (none when none did)."""
    rows = []
    for law, fit in fits.items():
        p = len(fit.free) + len(fit.linear)
        ok = bool(fit.success and np.isfinite(fit.rss) and fit.rss > 0 and fit.n > p)
        nll = fit.n * math.log(fit.rss / fit.n) if ok else math.nan
        ratio = fit.sigma / fit.noise if fit.noise > 0 else math.nan
        rows.append({"law": law, "success": ok, "n": fit.n, "parameters": p, "rss": fit.rss,
                     "sigma": fit.sigma, "rho": fit.rho, "noise": fit.noise,
                     "sigma_over_noise": ratio,
                     "fits": not (ratio > NOT_FIT and fit.rho > NOT_FIT_RHO),
                     "aic": nll + 2 * p, "bic": nll + p * math.log(fit.n),
                     **{k: fit.values.get(k, math.nan) for k in ("a", "b", "dc", "k", "c")}})
    table = pd.DataFrame(rows)
    ok = table[table.success]
    table["chosen"] = False
    if len(ok):
        best = ok.bic.idxmin()
        table.loc[best, "chosen"] = True
        f = (1 + table.rho[best]) / (1 - table.rho[best])
        table["delta_bic"] = table.bic - table.bic[best]
        table["delta_bic_ar1"] = table.delta_bic / f
    else:
        table["delta_bic"] = table["delta_bic_ar1"] = math.nan
    return table[list(LAW_COLUMNS)]
