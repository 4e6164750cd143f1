"""How good are the gradients, and what do they cost? For the paper's example and W1–W4 under
both laws (b, Lc; short runs of 3–8 events): the worst error of every event's dΔT/dp and dΔμ/dp
against a reference — Rodas5P's forward sensitivities at rtol 1e−12 with their error in the step
control, checked against RadauIIA5's made the same way (an independent method: collocation, its
derivative solved exactly) and against central differences of 1e−12 solves (each agreement
listed) — by each method's own sensitivities (its steps held, and with the sensitivities in the
error test) and by central differences through Rodas5P and RadauIIA5 (relative step √rtol); and
the cost of the sensitivities against the solve alone (2 and 6 parameters, with their error in
the step control and without, both methods; interleaved, the minimum of 5 after a warm-up).
Where JAX and diffrax are installed, diffrax's autodiff through its own solve and events is
the external peer on the same events (:mod:`benchmarks.devtools.diffrax_peer`).
"""

from __future__ import annotations

import importlib.util
import math
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.devtools import diffrax_peer
from benchmarks.physics.metrics import metric_gradients
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study, markdown_file
from integrators import solve
from integrators.own.radau5 import RadauIIA5
from integrators.own.rodas5p import Rodas5P
from problems.presets import paper_example, window
from problems.slider import variant

__all__ = ["STUDY", "gradient_errors", "sensitivity_cost", "cases"]

NAMES = ("b", "lc")
SIX = ("a", "b", "lc", "stiffness", "mass", "normal_force")
#: the targets: 1e−6 at rtol 1e−8; sensitivities of 2 parameters ≤ 2×, of 6 ≤ 3× the solve
TARGET_ERROR, TARGET_TWO, TARGET_SIX = 1e-6, 2.0, 3.0
_T_END = {"W1": 6.0, "W2": 12.0, "W3": 14.0, "W4": 3.0}


def cases() -> list:
    """(label, problem): the paper's example (10 s) and W1–W4 (a few events each), both laws."""
    out = [(f"paper/{law}", variant(paper_example(law=law), t_end=10.0))
           for law in ("slip", "aging")]
    out += [(f"{w}/{law}", variant(window(w, law=law), t_end=_T_END[w]))
            for w in _T_END for law in ("slip", "aging")]
    return out


def _grads(events, d_events, problem) -> np.ndarray:
    """(events − 1) × 2 × parameters: dΔT/dp, dΔμ/dp of every event but the first."""
    return metric_gradients(events, d_events, problem.normal_force, [0.0] * d_events.shape[2])[
        1:, :2]


def _by_sensitivities(problem, tol, error_control: bool, method=Rodas5P):
    alg = method(rtol=tol, atol=tol)
    start = time.perf_counter()
    sol = solve(problem, alg, max_points=2, sensitivity=NAMES, sensitivity_error=error_control)
    wall = time.perf_counter() - start
    return _grads(sol.event_array, sol.sensitivity.events, problem), wall, 1


def _by_differences(problem, method, tol):
    alg = method(rtol=tol, atol=tol)
    rel = math.sqrt(tol)
    start = time.perf_counter()
    base = solve(problem, alg, max_points=2).event_array
    cols = []
    for name in NAMES:
        value = getattr(problem.law, name)
        step = rel * value
        ends = [solve(variant(problem, **{name: value + s}), alg, max_points=2).event_array
                for s in (step, -step)]
        n = min(len(base), len(ends[0]), len(ends[1]))
        cols.append((ends[0][:n] - ends[1][:n]) / (2 * step))
    n = min(len(c) for c in cols)
    wall = time.perf_counter() - start
    d = np.stack([c[:n] for c in cols], axis=2)
    return _grads(base[:n], d, problem), wall, 1 + 2 * len(NAMES)


def _error(g, ref) -> tuple[float, float]:
    """The worst error of dΔT and of dΔμ over the events and parameters, relative to each
    gradient's largest size over the events."""
    n = min(len(g), len(ref))
    if n == 0:
        return math.nan, math.nan
    err = np.abs(g[:n] - ref[:n]).max(axis=0) / np.abs(ref[:n]).max(axis=0)
    return float(err[0].max()), float(err[1].max())


REFERENCE_RADAU = "reference: RadauIIA5 vs Rodas5P"
PEER = "diffrax Kvaerno5, jax.jacfwd"
REFERENCE_DIFFERENCES = "reference vs differences"


def _ways(problem, tol) -> list:
    """(way, the call that gives its gradients, wall time and solves) at ``tol``."""
    out = []
    for method in (Rodas5P, RadauIIA5):
        out += [(f"{method.name} sensitivities",
                 lambda m=method: _by_sensitivities(problem, tol, False, m)),
                (f"{method.name} sensitivities, error-controlled",
                 lambda m=method: _by_sensitivities(problem, tol, True, m))]
    return out + [(f"{method.name} differences",
                   lambda m=method: _by_differences(problem, m, tol))
                  for method in (Rodas5P, RadauIIA5)]


def _peer_row(label, problem, tol, ref) -> dict:
    """The row of the external peer (:mod:`benchmarks.devtools.diffrax_peer`) where JAX and
    diffrax are installed: its gradients of the same events, their errors, its wall time with
    the gradients and alone, its first calls' time and steps."""
    got = diffrax_peer.event_gradients(problem, tol, len(ref) + 1, repeats=2)
    return dict(case=label, way=PEER, rtol=tol,
                **dict(zip(("err_dT", "err_dmu"), _error(got.grads, ref))), wall_s=got.wall_s,
                solves=1, events=len(got.grads) + 1, solve_alone_s=got.solve_s,
                first_s=got.first_s, steps=got.steps, message=got.message)


def gradient_errors(tols=(1e-4, 1e-6, 1e-8, 1e-10), progress: bool = False) -> pd.DataFrame:
    """One row per case, way and tolerance: the worst relative errors of dΔT/dp and dΔμ/dp,
    the wall time (s) and the solves (module docstring); and per case the reference's
    agreement with the differences of 1e−12 solves (way ``reference vs differences``); the
    external peer's rows also carry its solve alone's time, first calls' time and steps."""
    rows, peer = [], diffrax_peer.available()
    for label, problem in cases():
        ref = _by_sensitivities(problem, 1e-12, True)[0]
        for way, check in (
                (REFERENCE_RADAU, _by_sensitivities(problem, 1e-12, True, RadauIIA5)),
                (REFERENCE_DIFFERENCES,     # relative step 1e-6 (√rtol)
                 _by_differences(problem, Rodas5P, 1e-12))):
            rows.append(dict(case=label, way=way, rtol=1e-12,
                             **dict(zip(("err_dT", "err_dmu"), _error(check[0], ref))),
                             wall_s=check[1], solves=check[2], events=len(ref) + 1))
        for tol in tols:
            for way, fn in _ways(problem, tol):
                fn()                    # compiles (and warms) before it is timed
                g, wall, solves = fn()
                rows.append(dict(case=label, way=way, rtol=tol,
                                 **dict(zip(("err_dT", "err_dmu"), _error(g, ref))),
                                 wall_s=wall, solves=solves, events=len(g) + 1))
            if peer:
                rows.append(_peer_row(label, problem, tol, ref))
        if progress:
            print(f"gradients: {label} done")
    return pd.DataFrame(rows)


def sensitivity_cost(tols=(1e-6, 1e-8), repeats: int = 5) -> pd.DataFrame:
    """The wall time of a solve with the sensitivities of 2 and of 6 parameters over the solve
    alone (Rodas5P and RadauIIA5; the paper's example and W2, W4 over 40 s), interleaved, the
    minimum of ``repeats`` after a warm-up; the spread of the solve alone's repeats says the
    noise."""
    problems = [("paper/slip", paper_example(law="slip")),
                ("W2/aging", window("W2", law="aging")), ("W4/slip", window("W4", law="slip"))]
    sets = {"alone": (None, False), "2 held": (NAMES, False), "6 held": (SIX, False),
            "2 controlled": (NAMES, True), "6 controlled": (SIX, True)}
    rows = []
    for method, tol in ((m, t) for m in (Rodas5P, RadauIIA5) for t in tols):
        alg = method(rtol=tol, atol=tol)
        for label, problem in problems:
            times = {k: [] for k in sets}
            for names, control in sets.values():
                solve(problem, alg, max_points=2, sensitivity=names, sensitivity_error=control)
            for _ in range(repeats):
                for k, (names, control) in sets.items():
                    sol = solve(problem, alg, max_points=2, sensitivity=names,
                                sensitivity_error=control)
                    times[k].append(sol.stats.wall_s)
            alone = min(times["alone"])
            rows.append(dict(method=method.name, case=label, rtol=tol, alone_ms=1e3 * alone,
                             **{f"ratio_{k.replace(' ', '_')}": min(times[k]) / alone
                                for k in sets if k != "alone"},
                             noise=(max(times["alone"]) - alone) / alone))
    return pd.DataFrame(rows)


def _figure(rows: pd.DataFrame, path: Path) -> None:
    """Work–precision of the gradients: the worst dΔT error over the cases against the
    summed wall time, one line per way."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.4, 4.6))
    ax = fig.subplots()
    data = rows[~rows.way.isin((REFERENCE_RADAU, REFERENCE_DIFFERENCES))]
    for way, part in data.groupby("way", sort=False):
        agg = part.groupby("rtol").agg(     # a failure anywhere leaves no point
            err=("err_dT", lambda e: e.max(skipna=False)), wall=("wall_s", "sum"))
        ax.loglog(agg.wall, agg.err, "o-", label=way)
        for tol, r in agg.iterrows():
            ax.annotate(f"{tol:g}", (r.wall, r.err), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
    ax.axhline(TARGET_ERROR, color="0.6", ls=":", lw=1)
    ax.set_xlabel("wall time over the 10 cases (s)")
    ax.set_ylabel("worst relative error of dΔT/dp (b, Lc)")
    ax.set_title("Gradients of event times: work against precision (labels: rtol)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def _peer_text(rows: pd.DataFrame) -> str:
    """The external peer's paragraph and table, or why it has none."""
    if not diffrax_peer.available():
        return ("diffrax (the external peer: autodiff through its own event handling) is not "
                "installed here (`pip install .[diffrax]`): no peer row.")
    peer = rows[rows.way == PEER].assign(ratio=lambda d: d.wall_s / d.solve_alone_s)
    failed = peer[peer.err_dT.isna()]
    return ("## The external peer: diffrax\n\n" + diffrax_peer.__doc__.split("\n\n")[0]
            .replace("\n", " ") + " Kvaerno5 with a PID controller, each event a terminating "
            "`diffrax.Event` located by `optimistix.Newton`, `jax.jacfwd` with "
            "`diffrax.ForwardMode` (`benchmarks/devtools/diffrax_peer.py`). `ratio`: its "
            "call with the gradients over its solve alone, each the minimum of 2 after the "
            "first calls (`first_s`: with the compile where the call was not compiled before); "
            "its derivatives are not in its step control (compare the `held` ways).\n\n"
            + markdown_table(peer[["case", "rtol", "err_dT", "err_dmu", "wall_s",
                                   "solve_alone_s", "ratio", "first_s", "steps"]],
                             floatfmt=".3g")
            + f"\nFailed (no gradient; NaN above): {len(failed)} of {len(peer)}."
            + "".join(f"\n- {r.case} at rtol {r.rtol:g}: {r.message}"
                      for r in failed.itertuples()) + "\n")


def run(out: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cost = sensitivity_cost()       # first: JAX's threads idle on after the peer's runs
        rows = gradient_errors(progress=True)
    write_table(rows, out / "gradients.csv")
    write_table(cost, out / "gradients_cost.csv")
    _figure(rows, out / "gradients.png")
    at8 = rows[rows.rtol == 1e-8]
    summary = at8.groupby("way").agg(worst_dT=("err_dT", "max"), worst_dmu=("err_dmu", "max"),
                                     wall_s=("wall_s", "sum")).reset_index()
    ref = rows[rows.way == REFERENCE_DIFFERENCES]
    radau = rows[rows.way == REFERENCE_RADAU]
    text = ("# Gradients of ΔT and Δμ: accuracy and cost\n\n"
            + __doc__.split("\n\n")[0].replace("\n", " ") + "\n\n"
            + "![gradients](gradients.png)\n\n## At rtol 1e-8, worst over the 10 cases\n\n"
            + markdown_table(summary, floatfmt=".3g")
            + f"\nTarget: {TARGET_ERROR:g}. The reference (Rodas5P's at 1e-12) against "
            f"RadauIIA5's at 1e-12: worst {radau.err_dT.max():.2g} (dΔT), "
            f"{radau.err_dmu.max():.2g} (dΔμ); against central differences of 1e-12 solves: "
            f"worst {ref.err_dT.max():.2g} (dΔT), {ref.err_dmu.max():.2g} (dΔμ).\n\n"
            "## Every case and tolerance\n\n" + markdown_table(rows, floatfmt=".3g")
            + "\n## Cost of the sensitivities (40 s runs)\n\n"
            + markdown_table(cost, floatfmt=".3g")
            + f"\nTargets: 2 parameters ≤ {TARGET_TWO:g}×, 6 ≤ {TARGET_SIX:g}×. `held`: the "
            "solve's own steps (`sensitivity_error=False`); `controlled`: the sensitivities in "
            "the error test (the default), which takes more steps. `noise`: the solve alone's "
            "spread over its repeats, (max − min)/min.\n\n" + _peer_text(rows)
            + "\n\nCommand: `rsfbench study gradients`.\n")
    write_output(out / "gradients.md", text)
    print(text)


STUDY = Study("gradients", "Gradients: the error of dΔT/dp and dΔμ/dp and the cost of "
              "sensitivities (`gradients.*`)", 211, run,
              report=markdown_file("gradients.md"),
              timed=True, minutes=13,
              writes=("gradients.csv", "gradients_cost.csv", "gradients.png", "gradients.md"))
