"""What a laboratory user measures on a velocity step or a slide-hold-slide test, from a Solution.

* :func:`healing`: for each hold of the load-point history, the peak friction on reloading (the
  spring force, what the apparatus measures, over Fn) minus the friction at the last saved point
  before the hold,
  against the hold time: the healing Δμ_peak and its rate per decade of hold time;
* :func:`step_response`: for each velocity step, the peak excursion after it and the change of
  steady friction at the end of the piece (the analytic (a − b) ln(v2/v1) when it has settled).

Peaks are read off the saved trajectory and refined by the parabola through the largest sample
and its neighbours: save finely (``save_every``) across the reloads. The saved grid never changes
the steps a method takes, so this costs output, not accuracy.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["healing", "healing_rate", "step_response", "HEALING_COLUMNS", "STEP_COLUMNS",
           "PeakNotReached",
           "MARONE_VELOCITY_STEP", "MARONE_SLIDE_HOLD_SLIDE", "marone_problem", "marone_check"]

# μ(t) of Chris Marone's rate-and-state code, as distributed with rsfmodel (J. R. Leeman et al.,
# https://github.com/jrleeman/rsfmodel, cjm_model_comparison/cjm_model.tim and cjm_shs.tim): aging
# law, a = 0.005, b = 0.01, Dc = 10 µm, k = 0.001 µm⁻¹, V0 = 1 µm/s, μ0 = 0.6, quasi-static,
# printed to 9 decimals; a sample of rows. Times after the step, and after the start of the hold.
MARONE_VELOCITY_STEP = {     # steady at 1 µm/s, the load point at 10 µm/s from t = 0
    0.0100001: 0.600089909, 0.1000001: 0.600890435, 0.5000001: 0.604189345,
    1.0000001: 0.607204852, 1.29: 0.607843561, 2.0000001: 0.601866372, 3.0000001: 0.584009097,
    5.0000001: 0.588995429}
MARONE_SLIDE_HOLD_SLIDE = {  # steady at 1 µm/s, a hold from t = 0 to 100 s, then 1 µm/s again
    1.0: 0.599093520, 10.0: 0.595464603, 50.0: 0.593606180, 100.0: 0.593332543,
    110.0: 0.603256162, 132.7: 0.620436068, 150.0: 0.595194064, 178.0: 0.601605796,
    200.0: 0.599523065}


def marone_problem(test: str):
    """(problem, {time after the switch: μ}) of Marone's ``velocity step`` or
    ``slide-hold-slide``; our runs switch at t = 10 s."""
    from problems import slide_hold_slide_test, velocity_step_test
    if test == "velocity step":
        return velocity_step_test(t_step=10.0, t_end=20.0), MARONE_VELOCITY_STEP
    if test == "slide-hold-slide":
        return (slide_hold_slide_test(holds=(100.0,), first_slide=10.0, slide=100.0),
                MARONE_SLIDE_HOLD_SLIDE)
    raise ValueError(f"test must be 'velocity step' or 'slide-hold-slide', got {test!r}")


def marone_check(names=("Rodas5P", "sundials-CVODE-BDF", "sundials-IDA"),
                 tol: float = 1e-11) -> pd.DataFrame:
    """Ours against Marone's rows: per (test, solver), the largest |μ − μ_Marone| and the
    largest difference from the first solver at the same times (NaN for a failed run). Saved
    every 1 ms: his times lie within 1e−7 s of a save point."""
    from integrators import make_algorithm, solve
    rows = []
    for test in ("velocity step", "slide-hold-slide"):
        problem, ref = marone_problem(test)
        times = np.array(sorted(ref))
        first = None
        for name in names:
            sol = solve(problem, make_algorithm(name, tol, tol), save_every=0.001)
            ours = np.interp(10.0 + times, sol.t, sol.fs / problem.normal_force)
            ok = sol.success
            first = ours if first is None and ok else first
            rows.append({"test": test, "integrator": name, "tol": tol,
                         "retcode": sol.retcode.value, "rows": len(times),
                         "max_abs_diff_mu": (float(np.max(np.abs(ours - [ref[t] for t in times])))
                                             if ok else math.nan),
                         f"max_abs_diff_from_{names[0]}": (float(np.max(np.abs(ours - first)))
                                                          if ok and first is not None
                                                          else math.nan)})
    return pd.DataFrame(rows)

HEALING_COLUMNS = ("hold_s", "t_hold_start_s", "mu_before", "t_peak_s", "mu_peak",
                   "delta_mu_peak")
STEP_COLUMNS = ("t_step_s", "v_before", "v_after", "mu_before", "mu_extreme", "t_extreme_s",
                "mu_end", "delta_mu_end", "expected_delta_mu_ss", "settled")


def _checked(solution):
    if not solution.success:
        raise ValueError(f"the run did not reach its end ({solution.retcode.value}: "
                         f"{solution.message}): no laboratory measure is read off a failed run")
    return solution.problem.loading.history


class PeakNotReached(ValueError):
    """The extreme of a piece is at its end: the piece is too short to show it."""


def _extreme(t, y, sign: float, what: str):
    """(t, y) of the largest sign·y, refined by a parabola through it and its neighbours when
    the samples are evenly spaced. :class:`PeakNotReached` if it is the first or last sample
    (the peak lies outside the window: ``what`` says which)."""
    if len(y) < 3:
        raise ValueError(f"too few saved points ({len(y)}) in {what} to find its peak: save "
                         "more often (solve's save_every)")
    i = int(np.argmax(sign * y))
    if i == 0 or i == len(y) - 1:
        raise PeakNotReached(f"the {'peak' if sign > 0 else 'trough'} of {what} is at its "
                             f"{'start' if i == 0 else 'end'} (t = {t[i]:.6g} s): it was not "
                             "reached inside the piece; make the piece longer")
    y0, y1, y2 = y[i - 1], y[i], y[i + 1]
    curv = y0 + y2 - 2.0 * y1
    even = abs((t[i + 1] - t[i]) - (t[i] - t[i - 1])) <= 1e-6 * (t[i + 1] - t[i - 1])
    if curv != 0.0 and even:
        x = 0.5 * (y0 - y2) / curv
        if abs(x) <= 1.0:
            return t[i] + x * (t[i] - t[i - 1]), y1 - 0.25 * (y0 - y2) * x
    return float(t[i]), float(y1)


def _at_or_before(t, y, when: float) -> float:
    """y at the last saved time ≤ ``when``: the value before a switch (after it, the trajectory
    bends, and an interpolation across the switch would mix the two)."""
    return float(y[max(int(np.searchsorted(t, when, side="right")) - 1, 0)])


def healing(solution) -> pd.DataFrame:
    """One row per hold followed by sliding (:data:`HEALING_COLUMNS`): its duration, the
    friction μ = Fs/Fn at the last saved point before it, and the peak of μ in the slide after it
    (before the next switch), located as in the module docstring; ``delta_mu_peak`` =
    μ_peak − μ_before. A hold that ends the run has no reloading and no row;
    :class:`PeakNotReached` if a slide ends before its peak."""
    hist = _checked(solution)
    t, mu = solution.t, solution.fs / solution.problem.normal_force
    edges = (0.0,) + hist.switch_times + (math.inf,)
    rows = []
    for i, v in enumerate(hist.velocities):
        if v != 0.0 or i + 1 >= len(hist.velocities):
            continue
        start, end = edges[i], edges[i + 1]
        reload_end = min(edges[i + 2], solution.t[-1])
        before = _at_or_before(t, mu, start)
        inside = (t >= end) & (t <= reload_end)
        tp, mp = _extreme(t[inside], mu[inside], 1.0,
                          f"the slide after the hold ending at {end:g} s")
        rows.append({"hold_s": end - start, "t_hold_start_s": start, "mu_before": before,
                     "t_peak_s": tp, "mu_peak": mp, "delta_mu_peak": mp - before})
    return pd.DataFrame(rows, columns=list(HEALING_COLUMNS))


def healing_rate(table: pd.DataFrame) -> float:
    """The least-squares slope of Δμ_peak against log10(hold time): healing per decade."""
    if len(table) < 2:
        return math.nan
    return float(np.polyfit(np.log10(table.hold_s), table.delta_mu_peak, 1)[0])


def step_response(solution) -> pd.DataFrame:
    """One row per switch between two sliding pieces (:data:`STEP_COLUMNS`): μ before the step,
    the extreme of μ after it (the peak of a step up, the trough of a step down), μ at the end
    of the piece, the steady-state change (a − b) ln(v2/v1) it should settle to, and whether it
    has: ``settled`` when at the piece's end μ drifts by less than 1e−3 of the direct effect
    a |ln(v2/v1)| per Lc of further slip (|dμ/dt| Lc/v2). :class:`PeakNotReached` if the piece
    ends before its extreme."""
    hist = _checked(solution)
    p = solution.problem
    t, mu = solution.t, solution.fs / p.normal_force
    edges = hist.switch_times + (solution.t[-1],)
    rows = []
    for i, ts in enumerate(hist.switch_times):
        v1, v2 = hist.velocities[i], hist.velocities[i + 1]
        if v1 == 0.0 or v2 == 0.0:
            continue
        inside = (t >= ts) & (t <= edges[i + 1])
        te, me = _extreme(t[inside], mu[inside], 1.0 if v2 > v1 else -1.0,
                          f"the piece after the step at {ts:g} s")
        tw, mw = t[inside], mu[inside]
        before, end = _at_or_before(t, mu, ts), mw[-1]
        drift = abs(mw[-1] - mw[-2]) / (tw[-1] - tw[-2]) * p.law.lc / v2
        rows.append({"t_step_s": ts, "v_before": v1, "v_after": v2, "mu_before": before,
                     "mu_extreme": me, "t_extreme_s": te, "mu_end": end,
                     "delta_mu_end": end - before,
                     "expected_delta_mu_ss": (p.law.a - p.law.b) * math.log(v2 / v1),
                     "settled": bool(drift < 1e-3 * p.law.a * abs(math.log(v2 / v1)))})
    return pd.DataFrame(rows, columns=list(STEP_COLUMNS))
