"""The checks of a laboratory fit: is its integrator accurate enough for this record
(:func:`check_lab_solver`), and does the slider's inertia change the answer
(:func:`inertia_check`)?
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd

from benchmarks.lab.fit import _LOG, LabFit, fit_lab
from benchmarks.lab.independent_model import reference_friction
from benchmarks.lab.model import COMPILED_TOL, LAB_MU0
from integrators import make_algorithm

__all__ = ["check_lab_solver", "inertia_check", "CHECK_REFERENCES"]

#: the reference pair of the solver check of a slider with mass or damping: (name, rtol =
#: atol), two independent libraries; the first also checks a quasi-static one-state slider
CHECK_REFERENCES = (("Rodas5P", 1e-12), ("scipy-Radau", 1e-12))
#: the check's σ is at least this multiple of the references' own disagreement: a record more
#: precise than that (noise-free, made by a model) is judged at what the references resolve
RESOLVED = 100.0
#: quasi-static: the two-state model's rtol and scipy's Radau's on the published equations
TWO_STATE_REFERENCES = (1e-12, 1e-11)


def _references(fit: LabFit, p: dict):
    """μ − μ0 at the best fit by two independent solvers, their names, and why one did not
    finish ("" when both did): each solve has the model's wall budget (the two-state model its
    step budget). A quasi-static slider is checked against scipy's Radau on the published
    equations (:mod:`benchmarks.lab.independent_model`, no code shared) and, with one state,
    the project's slider through :func:`integrators.solve` (Rodas5P at 1e-12), with two the
    two-state model at 1e-12; a slider with mass or damping against :data:`CHECK_REFERENCES`
    (the independent model has neither)."""
    model, rec = fit.model, fit.model.record
    if model.mass > 0 or model.radiation_damping > 0:
        refs, why = [], ""
        for name, tol in CHECK_REFERENCES:
            mu, sol = model.response(**p, algorithm=make_algorithm(name, rtol=tol, atol=tol))
            refs.append(mu)
            if not sol.success and not why:
                why = f"{name} at {tol:g}: {sol.retcode.value}: {sol.message}"
        return refs, [f"{n} at {t:g}" for n, t in CHECK_REFERENCES], why
    own_tol, ref_tol = TWO_STATE_REFERENCES
    ref_name = f"scipy-Radau (an independent model of the published equations) at {ref_tol:g}"
    if model.states == 2:
        names = [f"the two-state model at {own_tol:g}", ref_name]
        own, _ = model.response(**p, rtol=own_tol)
        why = "" if np.isfinite(own).all() else f"{names[0]} failed (its step budget?)"
    else:
        name, tol = CHECK_REFERENCES[0]
        names = [f"{name} at {tol:g} (the project's slider through solve)", ref_name]
        own, sol = model.response(**p, algorithm=make_algorithm(name, rtol=tol, atol=tol))
        why = "" if sol.success else f"{name} at {tol:g}: {sol.retcode.value}: {sol.message}"
    try:
        ref = reference_friction(rec.t, rec.velocities, rec.switch_times, p["a"], p["b"],
                                 p["dc"], p["k"], law=model.law, c=p.get("c", 2.0),
                                 b2=p.get("b2", 0.0), dc2=p.get("dc2", 1.0), mu0=LAB_MU0,
                                 rtol=ref_tol, atol=1e-13,
                                 wall_budget=model.wall_budget) - LAB_MU0
    except RuntimeError as exc:
        ref, why = np.full(len(rec.t), np.nan), why or f"{names[1]}: {exc}"
    return [own, ref], names, why


def check_lab_solver(fit: LabFit) -> dict:
    """Is the fit's integrator accurate enough for this record? μ(t) at the best fit against
    two independent references (:func:`_references`: quasi-static, scipy's Radau on the
    published equations and the project's slider through solve or the two-state model at
    1e-12; with mass or damping :data:`CHECK_REFERENCES`), which must agree to σ/100 of the
    record's noise; the fit's own error must be under σ/10 (σ the fit's residual scatter, or
    :data:`RESOLVED` × the references' disagreement where that is larger: on a noise-free
    record σ is the integrators' own error, and the references cannot judge below it; said in
    ``scale``). Returns the errors (in units of that σ) and ``passed``; a reference pair that does not agree says so
    (``references_agree`` False). A fit that failed is not checked (``checked`` False): its
    failure is the fit's, not the integrator's. A solve that fails or runs out of its budget
    (the model's ``wall_budget``, s per solve) fails the check (``passed`` False, ``reason``
    names it): an unfinished reference vouches for nothing.

    Parameters
    ----------
    fit : LabFit
        The fit whose integrator is checked.

    Returns
    -------
    dict
        The errors (in σ), ``passed``, ``checked``, ``references_agree`` and ``reason``.
    """
    model = fit.model
    options = ({"rtol": COMPILED_TOL, "atol": COMPILED_TOL} if model.compiled
               else model.algorithm.options())
    if not fit.success or not np.isfinite(fit.sigma):
        return {"integrator": model.integrator,
                "checked": False, "passed": False,
                "reason": f"the fit failed ({fit.message}): nothing to check"}
    p = {n: fit.values[n] for n in fit.model.parameters}
    own, own_run = fit.model.response(**p)
    refs, names, failed = _references(fit, p)
    if not np.isfinite(own).all():
        failed = (f"the fit's integrator at the best fit: {own_run.retcode.value}: "
                  f"{own_run.message}" if hasattr(own_run, "retcode") else
                  "the fit's model at the best fit ran out of its wall budget" if own_run == -2
                  else "the fit's model at the best fit failed")
    if failed:
        budget = fit.model.wall_budget
        return {"checked": True, "integrator": model.integrator, "options": options,
                "references": names, "references_disagree_sigma": math.nan,
                "references_agree": False, "error_sigma": math.nan, "passed": False,
                "wall_budget_s": budget,
                "reason": f"a solve of the check did not finish, so nothing is compared: "
                          f"{failed}" + (f" (each solve may take {budget:g} s: --wall-budget)"
                                         if budget is not None else "")}
    gap = float(np.max(np.abs(refs[0] - refs[1])))
    floor = RESOLVED * gap
    sigma = max(fit.sigma, floor)
    agree = gap / sigma
    error = float(np.max(np.abs(own - refs[0]))) / sigma
    agreed = agree <= (1.0 + 1e-9) / RESOLVED
    return {"checked": True, "integrator": model.integrator, "options": options,
            "references": names, "references_disagree_sigma": agree,
            "references_agree": bool(agreed), "error_sigma": error,
            "sigma": sigma, "residual_sigma": fit.sigma,
            "scale": ("the residuals' σ" if fit.sigma >= floor else
                      f"{RESOLVED:g} × the references' disagreement ({gap:.2g} in μ): the "
                      f"residuals' σ, {fit.sigma:.2g}, is below what they resolve (a "
                      "noise-free record)"),
            "passed": bool(error <= 0.1 and agreed)}


def inertia_check(fit: LabFit, mass: float, normal_force: float,
                  radiation_damping: float = 0.0) -> tuple[LabFit, pd.DataFrame]:
    """Refit with the slider's ``mass`` (kg) on ``normal_force`` (N), from the quasi-static
    ``fit`` and from the record's own starts (the better kept: where the inertia matters, the
    quasi-static fit can be far off); per parameter, how far it moved in the quasi-static fit's
    standard errors.

    Parameters
    ----------
    fit : LabFit
        The quasi-static fit.
    mass : float
        The slider's mass (kg).
    normal_force : float
        The normal force (N).
    radiation_damping : float
        ηr (N s/m).

    Returns
    -------
    refit : LabFit
        The better of the two refits with mass.
    moved : pandas.DataFrame
        Per parameter, how far it moved, in the quasi-static fit's standard errors.
    """
    model = dataclasses.replace(fit.model, mass=mass, normal_force=normal_force,
                                radiation_damping=radiation_damping)
    start = {n: fit.values[n] for n in fit.free}
    fits = [fit_lab(model, fixed=fit.fixed, weights=fit.piece_weights, start=start),
            fit_lab(model, fixed=fit.fixed, weights=fit.piece_weights)]
    inertial = min(fits, key=lambda f: f.rss if np.isfinite(f.rss) else np.inf)
    rows = []
    for n in fit.free:
        u0 = math.log(fit.values[n]) if n in _LOG else fit.values[n]
        u1 = math.log(inertial.values[n]) if n in _LOG else inertial.values[n]
        rows.append({"parameter": n, "quasi_static": fit.values[n],
                     "inertial": inertial.values[n], "shift_se": (u1 - u0) / fit.se(n)})
    table = pd.DataFrame(rows)
    return inertial, table
