"""Before a stick–slip experiment: how well would the means of its events resolve (b, Lc), and
which change to the apparatus resolves them better?

What it assumes: the record holds ``duration`` s of the settled cycle, so n = ⌊duration/ΔT⌋
events; each event's ΔT and Δμ scatter independently and Gaussian about the cycle's with the
stated relative σ (a real record's scatter: NIED's catalogue, docs/nied-catalogue.md), so their
means have σ/√n; b and log10 Lc are fitted to the two means
(:func:`benchmarks.inversion.least_squares.fit`). The expected standard errors are the
Fisher information's, (JᵀJ)⁻¹ with J = ∂(ΔT̄, Δμ̄)/∂(b, log10 Lc)/σ from one solve with forward
sensitivities (docs/sensitivities.md). Two means fix two parameters exactly, so the errors are
the linear map of the means' errors: they hold while that map is nearly linear over ±2σ, which
:func:`check_stick_slip` tests against the spread of repeated fits.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from integrators import Algorithm, solve
from integrators.own.rodas5p import Rodas5P
from problems import SpringSlider
from problems.slider import variant

__all__ = ["StickSlipPlan", "stick_slip_errors", "compare_stick_slip", "check_stick_slip"]


@dataclass(frozen=True)
class StickSlipPlan:
    """A planned stick–slip record (module docstring).

    Parameters
    ----------
    problem : SpringSlider
        The apparatus and the friction law's guessed (b, Lc); its ``t_end`` must reach the
        settled cycle.
    duration : float
        The seconds of settled cycle recorded (s).
    scatter_recurrence, scatter_drop : float
        One event's relative σ of ΔT and of Δμ (dimensionless; 0.05 is 5 %).
    algorithm : Algorithm
        The forward model (Rodas5P or RadauIIA5: the gradients need sensitivities).
    """

    problem: SpringSlider
    duration: float
    scatter_recurrence: float
    scatter_drop: float
    algorithm: Algorithm = Rodas5P(rtol=1e-8, atol=1e-8)

    def __post_init__(self) -> None:
        for name in ("duration", "scatter_recurrence", "scatter_drop"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive and finite, got {value!r}")
        if not getattr(self.algorithm, "sensitive", False):
            raise ValueError(f"the plan's algorithm must have sensitivities (Rodas5P, "
                             f"RadauIIA5), got {self.algorithm.name}")


def stick_slip_errors(plan: StickSlipPlan) -> dict:
    """The cycle's ΔT (s) and Δμ, the events n, the means' σ, and the Fisher standard errors of b
    and of log10 Lc and their correlation (NaN without a limit cycle: ``reason`` says why)."""
    from benchmarks.physics.metrics import cycle_gradient, summarize
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = solve(plan.problem, plan.algorithm, max_points=2, sensitivity=("b", "lc"))
    cycle = summarize(sol)
    grad = cycle_gradient(sol, cycle)
    out = dict(recurrence_s=cycle.recurrence_s, friction_drop=cycle.friction_drop,
               events=math.nan, sigma_mean_recurrence_s=math.nan,
               sigma_mean_friction_drop=math.nan, se_b=math.nan, se_log10_lc=math.nan,
               correlation=math.nan, reason=cycle.reason or "")
    if not grad:
        return out
    n = max(1, math.floor(plan.duration / cycle.recurrence_s))
    s_t = plan.scatter_recurrence * cycle.recurrence_s / math.sqrt(n)
    s_mu = plan.scatter_drop * cycle.friction_drop / math.sqrt(n)
    lc = plan.problem.law.lc
    jac = np.array([[grad["recurrence_s"]["b"] / s_t,
                     grad["recurrence_s"]["lc"] * lc * math.log(10) / s_t],
                    [grad["friction_drop"]["b"] / s_mu,
                     grad["friction_drop"]["lc"] * lc * math.log(10) / s_mu]])
    cov = np.linalg.inv(jac.T @ jac)
    se = np.sqrt(np.abs(np.diag(cov)))
    out.update(events=n, sigma_mean_recurrence_s=s_t, sigma_mean_friction_drop=s_mu,
               se_b=float(se[0]), se_log10_lc=float(se[1]),
               correlation=float(cov[0, 1] / (se[0] * se[1])))
    return out


def compare_stick_slip(plan: StickSlipPlan, alternatives: dict) -> pd.DataFrame:
    """The plan and each alternative (label → changes: the problem's fields by
    :func:`problems.slider.variant`'s names, or ``duration``, ``scatter_recurrence``,
    ``scatter_drop``), one row each, best resolved log10 Lc first."""
    rows = [dict(plan="as planned", **stick_slip_errors(plan))]
    for label, changes in alternatives.items():
        own = {k: v for k, v in changes.items()
               if k in ("duration", "scatter_recurrence", "scatter_drop")}
        problem = variant(plan.problem, **{k: v for k, v in changes.items() if k not in own})
        rows.append(dict(plan=label, **stick_slip_errors(replace(plan, problem=problem, **own))))
    return pd.DataFrame(rows).sort_values("se_log10_lc", na_position="last",
                                          ignore_index=True)


def check_stick_slip(plan: StickSlipPlan, n: int = 50, seed: int = 0) -> pd.DataFrame:
    """The Fisher errors against the spread of ``n`` fits: each fits (b, log10 Lc) with exact
    Jacobians to the cycle's means plus Gaussian errors of the means' σ (seeds ``seed``…),
    from the truth. One row per coordinate: Fisher se, the fits' spread, their ratio, the mean
    bias in spreads, the fits that ended at an exact fit (χ² < 1) of the ``n`` attempted."""
    from benchmarks.inversion.least_squares import fit
    from benchmarks.inversion.misfit import Misfit
    from benchmarks.inversion.observations import Observations
    errors = stick_slip_errors(plan)
    truth = (plan.problem.law.b, plan.problem.law.lc)
    box = ((0.5 * truth[0], 1.5 * truth[0]), (truth[1] / 30, truth[1] * 30))
    rng = np.random.default_rng(seed)
    est = []
    for _ in range(n):
        obs = Observations(
            recurrence_s=errors["recurrence_s"]
            + errors["sigma_mean_recurrence_s"] * rng.standard_normal(),
            sigma_recurrence_s=errors["sigma_mean_recurrence_s"],
            friction_drop=errors["friction_drop"]
            + errors["sigma_mean_friction_drop"] * rng.standard_normal(),
            sigma_friction_drop=errors["sigma_mean_friction_drop"])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            f = fit(Misfit(plan.problem, obs, plan.algorithm), *box, start=truth,
                    jacobian="exact")
        if f.success and f.misfit < 1.0:     # two means, two parameters: an exact fit
            est.append((f.b, math.log10(f.lc)))
    est = np.array(est).reshape(-1, 2)
    rows = []
    for j, (name, se, true) in enumerate((("b", errors["se_b"], truth[0]),
                                          ("log10_lc", errors["se_log10_lc"],
                                           math.log10(truth[1])))):
        spread = float(np.std(est[:, j], ddof=1)) if len(est) > 1 else math.nan
        rows.append(dict(parameter=name, fisher_se=se, spread=spread, ratio=se / spread,
                         bias=(float(np.mean(est[:, j]) - true) / spread if len(est) > 1
                               else math.nan),
                         fits=len(est), attempts=n))
    return pd.DataFrame(rows)
