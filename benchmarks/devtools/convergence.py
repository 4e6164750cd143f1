"""Observed order of convergence of the fixed-step methods on a stick–slip limit cycle.

Every non-adaptive registry entry (the ETD family) runs over a ladder of step factors f applied
to the paper's Δτcnst = 1e−5 and Δτmax = 0.01 together; its errors against the reference
(:mod:`benchmarks.devtools.errors`) are fitted by least squares, log(error) against log(Δτcnst). Only
points whose error is well above the reference's own uncertainty (``FLOOR_FACTOR`` × the two
reference solvers' disagreement) enter the fit, and of those the finest ``fit_points``: the
coarsest steps can be pre-asymptotic.

The project's compiled stiff methods (Rosenbrock23, Rodas5P, RadauIIA5, Exprb32, Exprb43) are
adaptive; their order is measured with the error control off (:func:`fixed_step_orders`): n equal steps of the
method's own step over a stiff stretch of the stick phase, the error of the state at its end
against a tight Radau solution. That is where the paper's ETD loses an order (frozen
coefficients), so it is where a declared order has to be shown.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from tqdm.auto import tqdm

from benchmarks.devtools.errors import errors
from benchmarks.devtools.reference import reference
from benchmarks.devtools.timing import warm_up
from benchmarks.physics.plots import plot_convergence
from benchmarks.records.files import write_figure, write_output, write_table
from benchmarks.records.report import jsonable as _jsonable, markdown_table
from integrators import REGISTRY, solve
from problems import paper_example
from problems.formulations import OdeForm, to_ode_state

__all__ = ["observed_order", "convergence_study", "convergence_summary", "write_convergence",
           "fixed_step_orders", "write_fixed_step_orders",
           "CONVERGENCE_FACTORS", "FLOOR_FACTOR"]

CONVERGENCE_FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25, 0.125, 1 / 16, 1 / 32)
FLOOR_FACTOR = 100.0


def observed_order(steps, errors) -> float:
    """Least-squares slope of log(error) against log(step).

    Parameters
    ----------
    steps, errors : array_like
        The step sizes (any unit) and the errors at them (positive, at least two).

    Returns
    -------
    float
        The observed order (dimensionless).

    Raises
    ------
    ValueError
        For fewer than two points, or a step or error that is not positive.
    """
    steps, errors = np.asarray(steps, float), np.asarray(errors, float)
    if len(steps) < 2 or np.any(errors <= 0) or np.any(steps <= 0):
        raise ValueError(f"need >= 2 positive steps and errors, got {steps!r}, {errors!r}")
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def convergence_study(problem, names=None, factors=CONVERGENCE_FACTORS, fit_points: int = 4,
                      error: str = "err_recurrence", progress: bool = True):
    """Run the ladder; return ``(table, orders)``: one row per (method, factor) with a ``fitted``
    flag, and the observed order of each method (NaN if fewer than two points are usable).

    Parameters
    ----------
    problem : SpringSlider
        The problem (its reference is computed or read from the cache).
    names : list of str, optional
        Fixed-step registry names; ``None`` takes every fixed-step method.
    factors : sequence of float
        The multiples of each method's default ``dtau_cnst`` and ``dtau_max`` (dimensionless).
    fit_points : int
        How many of the smallest usable steps the order is fitted on.
    error : str
        The error column fitted (:data:`ERROR_COLUMNS`).
    progress : bool
        Show a progress bar.

    Returns
    -------
    table : pandas.DataFrame
        One row per (method, factor): steps, retcode, wall_s (s), counters, the errors of
        :data:`ERROR_COLUMNS` and ``fitted``.
    orders : dict of str to float
        The observed order by method name.

    Raises
    ------
    ValueError
        For an adaptive method (its convergence is a work-precision question).
    ReferenceDisagreement
        When the two reference solvers do not agree on the problem.
    """
    names = [n for n in REGISTRY if not REGISTRY[n].adaptive] if names is None else list(names)
    ref = reference(problem)
    floor = FLOOR_FACTOR * ref.agreement["max"]
    rows = []
    jobs = [(n, f) for n in names for f in sorted(factors, reverse=True)]
    for name, f in tqdm(jobs, desc="convergence", unit="run", disable=not progress):
        cls = REGISTRY[name]
        if cls.adaptive:
            raise ValueError(f"{name} is adaptive: its convergence is a work-precision question")
        d = cls()
        algorithm = cls(dtau_cnst=d.dtau_cnst * f, dtau_max=d.dtau_max * f)
        warm_up(problem, algorithm)
        sol = solve(problem, algorithm, save_every=problem.t_end / (len(ref.grid_t) - 1))
        rows.append({"problem": problem.name, "integrator": name, "factor": f,
                     "dtau_cnst": algorithm.dtau_cnst, "dtau_max": algorithm.dtau_max,
                     "retcode": sol.retcode.value, "wall_s": sol.stats.wall_s,
                     "nfev": sol.stats.nfev, "steps": sol.stats.steps, **errors(sol, ref),
                     "reference_agreement": ref.agreement["max"]})
    table = pd.DataFrame(rows)
    table["fitted"] = False
    orders = {}
    for name, g in table.groupby("integrator", sort=False):
        usable = g[(g.retcode == "Success") & (g[error] > floor)].sort_values("dtau_cnst")
        chosen = usable.head(fit_points)
        table.loc[chosen.index, "fitted"] = True
        orders[name] = (observed_order(chosen.dtau_cnst, chosen[error]) if len(chosen) >= 2
                        else float("nan"))
    return table, orders


def convergence_summary(problem, table: pd.DataFrame, orders: dict) -> dict:
    """What ``rsfbench convergence --json`` prints: observed and declared orders, the error at
    the finest step of each method, and the reference's own uncertainty."""
    finest = table.sort_values("dtau_cnst").groupby("integrator", sort=False).first()
    return {"problem": problem.name, "error": "err_recurrence", "orders": orders,
            "finest_error": finest["err_recurrence"].to_dict(),
            "declared": {n: {"order": REGISTRY[n].order, "stiff_order": REGISTRY[n].stiff_order}
                         for n in orders},
            "reference_agreement": float(table.reference_agreement.max())}


def write_convergence(problem, table: pd.DataFrame, orders: dict, out) -> dict:
    """Write ``convergence_<problem>.csv/.json/.png`` to ``out``; return the summary."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = convergence_summary(problem, table, orders)
    stem = out / f"convergence_{problem.name.replace('/', '_')}"
    write_table(table, stem.with_suffix(".csv"))
    write_output(stem.with_suffix(".json"), json.dumps(_jsonable(summary), indent=2) + "\n")
    plot_convergence(table, orders, stem.with_suffix(".png"))
    return summary


# --- the compiled adaptive methods, error control off -----------------------------------------

#: the stick phase of the paper example before its first event, τ ∈ [5, 9]: hD/w grows from
#: 1e5 to 1e7 over it, so the stretch is stiff and any order reduction would show
SEGMENT_START, SEGMENT_SPAN = 5.0, 4.0
SEGMENT_STEPS = (2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128)
SEGMENT_FLOOR = 1e-10        # errors below this are not fitted (the reference: ~3e−13)
SEGMENT_TOL = 1e-13          # scipy Radau's rtol = atol for the segment's start and reference


def fixed_step_orders(names=None, laws=("slip", "aging"), steps=SEGMENT_STEPS,
                      fit_points: int = 4, progress: bool = True):
    """Observed order of each compiled stiff method (``fixed_steps``: its own step, every one
    accepted) on the stiff segment of the paper example under each law: the max-norm error of
    z = (h, ln w, Ψ) at the segment's end against scipy Radau at rtol = atol = 1e−13 (which
    agrees with 4096 Exprb43 steps to 3e−13), fitted by least squares over the ``fit_points``
    finest step counts whose error is above ``SEGMENT_FLOOR``.
    Returns ``(table, orders)`` with orders keyed ``"<name>/<law>"``."""
    from scipy.integrate import solve_ivp

    if names is None:
        names = [n for n, c in REGISTRY.items() if hasattr(c, "fixed_steps") and c.adaptive]
    rows, orders = [], {}
    for law in laws:
        nd = paper_example(law).nondimensional()
        form = OdeForm(nd, nd.e_slow)

        def radau(z, span):
            return solve_ivp(form.f, (0.0, span), z, method="Radau", jac=form.jac,
                             rtol=SEGMENT_TOL, atol=SEGMENT_TOL).y[:, -1]

        z0 = radau(to_ode_state(nd.law_code, nd.beta, nd.x0), SEGMENT_START)
        ref = radau(z0, SEGMENT_SPAN)
        for name in tqdm(names, desc=f"fixed steps, {law} law", disable=not progress):
            cls = REGISTRY[name]
            if not hasattr(cls, "fixed_steps"):
                able = [n for n, c in REGISTRY.items() if hasattr(c, "fixed_steps")]
                raise ValueError(f"{name} has no fixed-step mode; these do: {', '.join(able)}")
            algorithm = cls(rtol=0.5, atol=0.5)        # the tolerances are not used
            for n in steps:
                err = float(np.abs(algorithm.fixed_steps(nd, z0, SEGMENT_SPAN, n) - ref).max())
                rows.append({"integrator": name, "law": law, "n_steps": n,
                             "h_tau": SEGMENT_SPAN / n, "error": err,
                             "declared_order": cls.order})
    table = pd.DataFrame(rows)
    table["fitted"] = False
    for (name, law), g in table.groupby(["integrator", "law"], sort=False):
        g = g[np.isfinite(g.error) & (g.error > SEGMENT_FLOOR)].sort_values("h_tau")
        g = g.head(fit_points)
        table.loc[g.index, "fitted"] = True
        orders[f"{name}/{law}"] = (observed_order(g.h_tau, g.error) if len(g) >= 2
                                   else float("nan"))
    return table, orders


def _fixed_step_markdown(table: pd.DataFrame, orders: dict) -> str:
    rows = []
    for name, g in table.groupby("integrator", sort=False):
        row = {"method": name, "declared order": int(g.declared_order.iloc[0])}
        for law, gl in g.groupby("law", sort=False):
            fit = gl[gl.fitted]
            row[f"observed ({law})"] = f"{orders[f'{name}/{law}']:.2f}"
            row[f"fitted steps ({law})"] = (f"{int(fit.n_steps.min())}–{int(fit.n_steps.max())}"
                                            if len(fit) else "")
        rows.append(row)
    return markdown_table(pd.DataFrame(rows))


def write_fixed_step_orders(table: pd.DataFrame, orders: dict, out) -> dict:
    """``convergence_fixed_steps.csv/.json/.md/.png`` in ``out``; returns the JSON summary."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    declared = table.groupby("integrator", sort=False).declared_order.first().to_dict()
    summary = {"segment": f"paper example, stick phase tau in [{SEGMENT_START:g}, "
                          f"{SEGMENT_START + SEGMENT_SPAN:g}], equal steps, no error control",
               "reference": f"scipy Radau, rtol = atol = {SEGMENT_TOL:g}",
               "orders": orders, "declared": declared}
    write_table(table, out / "convergence_fixed_steps.csv")
    write_output(out / "convergence_fixed_steps.md", _fixed_step_markdown(table, orders))
    write_output(out / "convergence_fixed_steps.json",
                 json.dumps(_jsonable(summary), indent=2) + "\n")
    fig = Figure(figsize=(7.5, 5.5), layout="constrained")
    ax = fig.subplots()
    colour = {name: f"C{i}" for i, name in enumerate(declared)}
    for (name, law), g in table.groupby(["integrator", "law"], sort=False):
        g = g.sort_values("h_tau")
        ax.loglog(g.h_tau, g.error, "-" if law == "slip" else "--", marker="o", mfc="none",
                  color=colour[name], lw=1,
                  label=f"{name} ({law}): {orders[f'{name}/{law}']:.2f} (declared "
                        f"{declared[name]})")
        fit = g[g.fitted]
        ax.loglog(fit.h_tau, fit.error, "o", color=colour[name])
    ax.axhline(SEGMENT_FLOOR, color="0.5", ls=":", lw=1, label="fit threshold")
    ax.set_xlabel(r"step $h$ in $\tau$")
    ax.set_ylabel(r"max error of $z = (h, \ln w, \Psi)$ at the segment's end")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, title="observed order (filled: points fitted)", title_fontsize=8)
    ax.set_title("fixed-step order on a stiff stick-phase segment (paper example)", fontsize=11)
    write_figure(fig, out / "convergence_fixed_steps.png", dpi=110)
    return summary
