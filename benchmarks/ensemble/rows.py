"""One row per point: how an ensemble's solves become a table, whatever ran them.

Two paths give the same columns (:data:`RESULT_COLUMNS`, after the parameter columns):

* :func:`batch_rows`: the project's methods on the compiled engine, a batch of points in one
  numba call (:meth:`integrators.own.compiled.CompiledAlgorithm.solve_batch`), each summarised in
  compiled code; Python only names the classes and writes the messages;
* :func:`point_rows`: any other backend, point by point through :func:`integrators.solve` and
  :func:`benchmarks.physics.metrics.summarize`.

Both classify with :func:`integrators.core.cycles.find_cycle` and word the reasons with
:func:`benchmarks.physics.metrics.cycle_from`, so an own method's rows are the same either way (the
tests check it); with curves, a batch solves each point with a cycle twice and its counters say
so. A point that fails is a row with its retcode and message, never an exception;
only a point with a limit cycle (:data:`benchmarks.physics.metrics.CYCLES`) has metrics.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
import pandas as pd

from benchmarks.physics.curves import event_curve
from benchmarks.physics.metrics import (CLASSIFICATIONS, CYCLES, METRICS, EndState, cycle_from,
                                        summarize)
from integrators import ReturnCode, solve
from integrators.core import cycles
from integrators.own import batch as B
from integrators.own import engine as E
from integrators.own.compiled import CompiledAlgorithm, failure, settled_message
from problems.formulations import from_ode_state
from problems.slider import TAU_END_MAX

__all__ = ["RESULT_COLUMNS", "METRIC_COLUMNS", "COUNTER_COLUMNS", "CURVE_COLUMNS", "CURVE_POINTS",
           "CHAIN_POINTS", "chained_curve", "gradient_columns",
           "batch_rows",
           "point_rows", "failed_rows", "compiled", "columns_of"]

#: the limit-cycle columns, NaN unless the point has a limit cycle
METRIC_COLUMNS = ("period", "recurrence_s", "friction_drop", "slip_m", "peak_velocity_m_s",
                  "cycles_to_converge")
#: the counters of the solve, summed over its restarts (wall_s: the solve's own wall time, s)
COUNTER_COLUMNS = ("nfev", "njev", "steps", "rejected")
RESULT_COLUMNS = ("classification", "retcode", "message", "n_events", *METRIC_COLUMNS, "kappa",
                  *COUNTER_COLUMNS, "wall_s", "integrator")
_TEXT = ("classification", "retcode", "message", "integrator")
#: with ``curve_dt``: the slip-weakening curve of the last complete event (slip in m, friction
#: Ft/Fn; :func:`benchmarks.physics.curves.event_curve`), empty unless the point has a limit cycle
CURVE_COLUMNS = ("curve_slip", "curve_friction")
#: samples of a curve made in a compiled batch: evenly spaced in time over the event, start and
#: end included (a W2 event of 9 ms: one every 36 µs)
CURVE_POINTS = 257
#: samples of a curve made for a measurement chain: CURVE_POINTS over the event and a sixth of
#: the rows (integrators.own.batch.MARGIN_SHARE) either side over the chain's margin
CHAIN_POINTS = 3 * (CURVE_POINTS - 1) // 2 + 1


#: the message of a limit cycle whose gradient is unknown
NO_GRADIENT = ("its cycle has no gradient: an arrest in the run (the engine's limit step "
               "through a deep lock has no derivative), or a period that reaches back to the "
               "first event (whose recurrence time is unknown)")


def gradient_columns(sensitivity) -> list[str]:
    """The columns of the limit cycle's gradient along the parameters ``sensitivity``:
    ``d_<metric>/d_<parameter>`` for each of :data:`benchmarks.physics.metrics.METRICS` (SI
    units per the parameter's SI unit)."""
    return [f"d_{m}/d_{n}" for m in METRICS for n in sensitivity]


def columns_of(names, curves: bool, sensitivity=()) -> list[str]:
    """The columns of an ensemble's table: the parameters, the results, the gradients and the
    curves if any."""
    return [*names, *RESULT_COLUMNS, *gradient_columns(sensitivity),
            *(CURVE_COLUMNS if curves else ())]


def compiled(algorithm) -> bool:
    """Does ``algorithm`` run batches in one compiled call?"""
    return isinstance(algorithm, CompiledAlgorithm)


def _frame(names, values, columns: dict) -> pd.DataFrame:
    """The table: parameter columns, then :data:`RESULT_COLUMNS` with fixed dtypes (so that
    every chunk has the same schema, whatever it holds), then the curves if ``columns`` has
    them."""
    data = {name: values[:, j].astype(float) for j, name in enumerate(names)}
    for c in RESULT_COLUMNS:
        x = columns[c]
        data[c] = (pd.array(x, dtype="str") if c in _TEXT
                   else np.asarray(x, dtype=np.int64 if c in COUNTER_COLUMNS + ("n_events",)
                                   else float))
    for c in columns:
        if c.startswith("d_"):
            data[c] = np.asarray(columns[c], dtype=float)
    for c in CURVE_COLUMNS:
        if c in columns:
            data[c] = pd.Series([np.asarray(x, dtype=float) for x in columns[c]], dtype=object)
    return pd.DataFrame(data)


def batch_rows(problems, algorithm, names, values, wall_budget=None,
               parallel: bool = True, curves: bool = False, chain=None, sensitivity=(),
               sensitivity_error: bool = True, settle: float = 0.0) -> pd.DataFrame:
    """The rows of ``problems`` (the points ``values`` of ``names``) solved in one compiled
    batch of the own ``algorithm``, on numba's threads or (``parallel`` False) on this one;
    with ``curves``, each row with a limit cycle has its slip-weakening curve
    (:data:`CURVE_COLUMNS`) at :data:`CURVE_POINTS` times over its last event, from the
    method's dense output (:mod:`integrators.own.batch`).

    Parameters
    ----------
    problems : list of SpringSlider
        The points' problems.
    algorithm : Algorithm
        An own compiled method.
    names : sequence of str
        The varied fields.
    values : numpy.ndarray
        The points, one row each (SI units).
    wall_budget : float, optional
        Each point's wall-time budget (s).
    parallel : bool
        Spread the points over numba's threads.
    curves : bool
        Add each limit cycle's slip-weakening curve.
    chain : benchmarks.physics.chain.Chain, optional
        The measurement chain each curve is passed through (:func:`chained_curve`): the
        second solve then also covers the chain's margin either side of the event.
    sensitivity : tuple of str
        Parameters to differentiate the limit cycle's metrics by (Rodas5P, RadauIIA5; not with
        ``curves``): :func:`gradient_columns`, NaN without a cycle or without a derivative.
    sensitivity_error : bool
        The sensitivities in the step control (as :func:`integrators.solve`'s).
    settle : float
        Stop each point on its settled cycle (:func:`integrators.solve`'s; 0: run to t_end).

    Returns
    -------
    pandas.DataFrame
        One row per point: its parameters, then :data:`RESULT_COLUMNS` (and the gradients
        with ``sensitivity``, :data:`CURVE_COLUMNS` with ``curves``).
    """
    R, states, grad = _solve_batch(problems, algorithm, wall_budget, parallel, curves, chain,
                                   (sensitivity, sensitivity_error), settle)
    n = len(problems)
    col, metrics = _outcomes(problems, algorithm, R, wall_budget)
    col.update({c: metrics[:, j] for j, c in enumerate(METRIC_COLUMNS)})
    col.update(n_events=R[:, B.R["N_EVENTS"]], kappa=[p.kappa for p in problems],
               nfev=R[:, B.R["NFEV"]], njev=R[:, B.R["NJEV"]], steps=R[:, B.R["STEPS"]],
               rejected=R[:, B.R["REJECTED"]], wall_s=R[:, B.R["WALL_S"]],
               integrator=[algorithm.name] * n)
    if sensitivity:
        flat = grad.reshape(n, 4 * len(sensitivity))
        col.update(zip(gradient_columns(sensitivity), flat.T))
        for i in np.flatnonzero(np.isnan(flat).all(axis=1)):
            if col["classification"][i] in CYCLES:
                col["message"][i] = NO_GRADIENT
    if curves:
        col["curve_slip"], col["curve_friction"] = zip(*_curves(
            problems, states, col["classification"], chain, parallel))
        for i, (what, slip) in enumerate(zip(col["classification"], col["curve_slip"])):
            if what in CYCLES and not len(slip):
                col["message"][i] = " ".join(filter(None, (
                    col["message"][i], "its slip-weakening curve could not be made: the second "
                    "solve over its last event stopped (its wall budget?)")))
    return _frame(names, values, col)


def _outcomes(problems, algorithm, R, wall_budget) -> tuple[dict, np.ndarray]:
    """Each point's class, retcode and message (as :func:`point_rows` words them) and its
    limit-cycle metrics (NaN without a cycle), from the batch's rows ``R``."""
    n = len(problems)
    col = {c: [None] * n for c in ("classification", "retcode", "message")}
    metrics = np.full((n, len(METRIC_COLUMNS)), np.nan)
    F, found = cycles.F, R[:, B.R["FOUND"]:]
    for i, problem in enumerate(problems):
        r, what = R[i], CLASSIFICATIONS[int(R[i, B.R["CLASS"]])]
        n_events = int(r[B.R["N_EVENTS"]])
        if what == "failed" and int(r[B.R["STATUS"]]) == E.DONE:
            # done, but the end was not saved (a restart just short of it): as summarize says
            retcode, message = ReturnCode.SUCCESS, f"stopped at t = 0 s of {problem.t_end:g} s"
        elif what == "failed":
            retcode, message = failure(int(r[B.R["STATUS"]]), r[B.R["T_STOP"]],
                                       algorithm.max_steps, wall_budget, problem.t_end)
        else:
            retcode, message = ReturnCode.SUCCESS, ""
            settled = int(r[B.R["STATUS"]]) == E.SETTLED
            t_end = r[B.R["T_STOP"]] if settled else problem.t_end
            if what in CYCLES:
                p = found[i, F["PERIOD"]]
                metrics[i] = (p, *found[i, F["RECURRENCE"]:F["PEAK_V"] + 1],
                              found[i, F["FIRST"]] + p + 1)
            else:
                end = EndState(log_v=float(r[B.R["LOG_V"]]),
                               state_offset=float(r[B.R["STATE_OFFSET"]]),
                               force_offset=float(r[B.R["FORCE_OFFSET"]]),
                               growth_rate=float(r[B.R["GROWTH"]]),
                               longest_run=TAU_END_MAX * problem.law.lc / problem.law.v0)
                message = cycle_from(found[i], n_events, t_end, B.CYCLE_RTOL,
                                     B.CYCLE_MAX_PERIOD, B.CYCLE_MIN_REPEATS, end).reason
            if settled:
                message = " ".join((settled_message(t_end, problem.t_end), message)).strip()
        col["classification"][i], col["retcode"][i], col["message"][i] = (
            what, retcode.value, message)
    return col, metrics


def _curves(problems, states, classes, chain, parallel: bool) -> list:
    """Each point's curve (:func:`_curve`; empty without a cycle), in as many Python threads
    as numba has when ``parallel``: the chain's filters, interpolation and pooling release the
    GIL for part of their time (a tenth off a chained batch's wall time on 2 cores)."""
    def one(k):
        return (_curve(problems[k], states[k], chain) if classes[k] in CYCLES
                else (np.empty(0), np.empty(0)))
    threads = numba.get_num_threads() if parallel else 1
    if threads < 2 or len(problems) < 2:
        return [one(k) for k in range(len(problems))]
    with ThreadPoolExecutor(threads) as pool:
        return list(pool.map(one, range(len(problems))))


def _solve_batch(problems, algorithm, wall_budget, parallel: bool, curves: bool, chain,
                 sensitive=((), True), settle: float = 0.0):
    """``(R, CURVE, GRAD)`` of the batch: the curves' rows over the event (and the chain's
    margin), None without curves; the cycles' gradients along ``sensitive`` (names, error
    control), None without; each point stopped on its settled cycle with ``settle``."""
    if sensitive[0]:
        R, grad = algorithm.solve_batch(problems, wall_budget, parallel,
                                        sensitivity=sensitive[0],
                                        sensitivity_error=sensitive[1])
        return R, None, grad
    if curves and chain is not None:
        return (*algorithm.solve_batch(problems, wall_budget, parallel, CHAIN_POINTS,
                                       chain.margin_s, settle=settle), None)
    if curves:
        return (*algorithm.solve_batch(problems, wall_budget, parallel, CURVE_POINTS,
                                       settle=settle), None)
    return algorithm.solve_batch(problems, wall_budget, parallel, settle=settle), None, None


def _curve(problem, z: np.ndarray, chain=None) -> tuple[np.ndarray, np.ndarray]:
    """The slip-weakening curve from the rows (τ, h, u, s) of :mod:`integrators.own.batch`'s
    ``CURVE``: as :func:`benchmarks.physics.curves.event_curve` makes it from a trajectory, or
    through ``chain`` (the rows then span its margin: :func:`chained_curve`)."""
    if not np.isfinite(z).all():              # the second solve did not repeat the first
        return np.empty(0), np.empty(0)
    nd = problem.nondimensional()
    h, eta, psi = from_ode_state(nd.law_code, nd.beta, z[:, 1:])
    v, fs, theta = problem.dimensional_state(h, eta, psi)
    t = z[:, 0] * nd.time_scale
    ft = problem.friction(v, theta)
    if chain is not None:
        m = len(t) // B.MARGIN_SHARE
        return chained_curve(problem, chain, t, fs, ft, t[m], t[len(t) - 1 - m])
    slip = problem.loading.v_slow * (t - t[0]) - (fs - fs[0]) / problem.stiffness
    return slip, ft / problem.normal_force


def chained_curve(problem, chain, t, fs, ft, t_start: float, t_end: float):
    """The curve of the event from ``t_start`` to ``t_end`` (s) passed through the measurement
    ``chain`` (:meth:`benchmarks.physics.chain.Chain.model_curve`), from the run's times ``t``
    over the event and the chain's margin, its spring force ``fs`` and friction ``ft`` (N).
    The slip is exact: the load point's travel (vLs, and vLf for its push after the event)
    less the spring's shortening, ΔFs/k."""
    loading = problem.loading
    travel = loading.v_slow * (t - t_start) + (loading.v_fast - loading.v_slow) * np.clip(
        t - t_end, 0.0, loading.fast_duration)
    slip = travel - (fs - fs[0]) / problem.stiffness
    fn = problem.normal_force
    return chain.model_curve(t, slip, fs / fn, ft / fn)


def point_rows(problems, algorithm, names, values, wall_budget=None,
               curve_dt: float | None = None, chain=None, settle=None) -> pd.DataFrame:
    """The rows of ``problems`` solved one by one with :func:`integrators.solve` (any backend),
    as :func:`batch_rows` writes them; with ``curve_dt`` (s) the trajectory is saved that finely
    and each row has its slip-weakening curve (:data:`CURVE_COLUMNS`).

    Parameters
    ----------
    problems : list of SpringSlider
        The points' problems.
    algorithm : Algorithm
        Any registered method.
    names : sequence of str
        The varied fields.
    values : numpy.ndarray
        The points, one row each (SI units).
    wall_budget : float, optional
        Each point's wall-time budget (s).
    curve_dt : float, optional
        The save interval for the curves (s).
    chain : benchmarks.physics.chain.Chain, optional
        The measurement chain each curve is passed through (:func:`chained_curve`, from the
        saved trajectory over the event and the chain's margin).
    settle : float, optional
        Stop each point on its settled cycle (:func:`integrators.solve`'s).

    Returns
    -------
    pandas.DataFrame
        As :func:`batch_rows`; a point whose solve raised is a failed row, and the table's
        ``attrs["transient"]`` is then set (it is not stored).
    """
    save = dict(save_every=curve_dt) if curve_dt else dict(max_points=2)
    rows, crashed = [], False
    for problem in problems:
        try:
            sol = solve(problem, algorithm, wall_budget=wall_budget, settle=settle, **save)
            cycle = summarize(sol)
        except Exception as exc:       # checked before the ensemble started: a bug, or this
            rows.append(_failed(f"{type(exc).__name__}: {exc}", problem, algorithm, curve_dt))
            crashed = True             # machine's environment (a missing library): not stored
            continue
        row = {"classification": cycle.classification, "retcode": sol.retcode.value,
               "message": (" ".join((sol.message, cycle.reason)).strip()
                           if sol.settled_s is not None else sol.message or cycle.reason),
               "n_events": len(sol.events),
               "kappa": problem.kappa, "nfev": sol.stats.nfev, "njev": sol.stats.njev,
               "steps": sol.stats.steps, "rejected": sol.stats.rejected,
               "wall_s": sol.stats.wall_s, "integrator": algorithm.name}
        if curve_dt:
            row.update(curve_slip=[], curve_friction=[])
        if cycle.classification in CYCLES:
            row.update({c: getattr(cycle, c) for c in METRIC_COLUMNS})
            if curve_dt:
                row["curve_slip"], row["curve_friction"] = (
                    event_curve(sol) if chain is None else _saved_chained(sol, chain))
        rows.append(row)
    table = _frame(names, values, _columns(rows, curve_dt))
    if crashed:
        table.attrs["transient"] = True
    return table


def _saved_chained(sol, chain):
    """The last complete event's curve through ``chain`` from the saved trajectory: the last
    that ends two of the chain's margins before the run does, as the compiled batch picks it
    (the run's end would cut its margin short)."""
    events = sol.events
    whole = events[events.t_end + 2.0 * chain.margin_s <= sol.t[-1]]
    ev = (whole if len(whole) else events).iloc[-1]
    inside = (sol.t >= ev.t_start - chain.margin_s) & (sol.t <= ev.t_end + chain.margin_s)
    return chained_curve(sol.problem, chain, sol.t[inside], sol.fs[inside], sol.ft[inside],
                         ev.t_start, ev.t_end)


def _failed(message: str, problem, algorithm, curve_dt=None) -> dict:
    return {"classification": "failed", "retcode": ReturnCode.FAILURE.value, "message": message,
            "n_events": 0, "kappa": problem.kappa, "nfev": 0, "njev": 0, "steps": 0,
            "rejected": 0, "wall_s": np.nan, "integrator": algorithm.name,
            **({"curve_slip": [], "curve_friction": []} if curve_dt else {})}


def failed_rows(problems, algorithm, names, values, message: str,
                curve_dt: float | None = None, sensitivity=()) -> pd.DataFrame:
    """The rows of points that could not be run at all (their workers died): ``Failure`` with
    ``message`` (and NaN gradients along ``sensitivity``)."""
    return _frame(names, values, _columns([_failed(message, p, algorithm, curve_dt)
                                           for p in problems], curve_dt, sensitivity))


def _columns(rows: list[dict], curves, sensitivity=()) -> dict:
    cols = (*RESULT_COLUMNS, *gradient_columns(sensitivity), *(CURVE_COLUMNS if curves else ()))
    return {c: [row.get(c, np.nan) for row in rows] for c in cols}
