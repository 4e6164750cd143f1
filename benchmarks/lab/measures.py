"""What a laboratory user measures on a velocity step or a slide-hold-slide test, from a Solution.

* :func:`step_response`: for each velocity step, the first extreme after it (the peak of a step
  up, the trough of a step down), its time, and the change of steady friction, against the
  analytic (a − b) ln(v2/v1) + ηr (v2 − v1)/Fn;
* :func:`healing`: for each hold, the peak on reloading minus the friction when the hold began,
  against the hold time: the healing Δμ_peak and (:func:`healing_rate`) its rate per decade.

**What is measured** is μ = Fs/Fn, the spring force over the normal force: what the load cell of
an apparatus reads. With mass the friction Ft differs from Fs by m dv/dt (and by ηr v with
radiation damping); a laboratory does not see Ft, and nothing here reports it.

**Where an extreme is.** dFs/dt = k (vL − v), so within a piece of constant vL an extreme of Fs
is exactly where v crosses vL: a peak where v rises through it, a trough where v falls. The
measure is the first such crossing after the switch, located with the run's own method, never
on its saved samples: from the state at the switch, the piece is re-solved over windows that
start at the response's shortest time scale (Lc/v, a Fn/(k v), √(m/k), ηr/k at the faster of v
at the switch and vL) and double, :data:`SAMPLES` samples each, until v crosses vL; the bracket
is re-solved the same way until it is :data:`REFINE` of the time since the switch, and the
crossing time and Fs are interpolated across it (Fs by the cubic whose end slopes are
k (vL − v)). A state at a switch comes from the last saved state at or before it, carried there
by a re-solve. Every re-solve is the run's algorithm with its options, from the run's own state:
a measure carries the method's error, and none of the save grid's.

**Settled.** A measure that reads a steady value reads it at the end of a piece, and that piece
is checked: it has settled when there max(|μ − μss(vL)|, a |ln(v/vL)|) ≤ :data:`SETTLED` ×
the measure's scale (a |ln(v2/v1)| for a step, a for a hold), μss = (Ft,ss(vL) + ηr vL)/Fn. A
step's ``delta_mu_ss`` is NaN unless both the piece before it (its end is the baseline) and the
piece after it (its end is the new steady value) have settled. A hold's ``delta_mu_peak`` is
defined against μ when the hold began, steady or not, and ``settled_before`` says whether it
was. Either way an :class:`UnsettledWarning` names a piece that has not settled.

Histories with an overshoot (two-speed loading) are refused: there vL changes after each event,
not at known times.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pandas as pd

from integrators import make_algorithm, solve
from integrators.core.solution import Solution
from problems import (
    ConstantLoading,
    InitialState,
    LoadHistory,
    balanced_initial_state,
    slide_hold_slide_test,
    steady_initial_state,
    velocity_step_test,
)
from problems._validate import units_checked_already

__all__ = ["healing", "healing_rate", "step_response", "HEALING_COLUMNS", "STEP_COLUMNS",
           "PeakNotReached", "ResolveFailed", "UnsettledWarning", "SAMPLES", "REFINE", "SETTLED",
           "STEP_REFERENCE", "step_reference",
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

#: The first extreme after a velocity step of the laboratory apparatus (problems.velocity_step_test,
#: from steady sliding at 1 µm/s), by (law, mass in kg, v2/v1): (its time after the step in s,
#: μ_extreme − μ_before). The slip law with 1 kg: quasi-static it runs away on a step up.
#: Obtained by :func:`step_reference` (the maximum of ±Fs on 200,001 even samples, refined by the
#: parabola through it: no root finding) with Rodas5P and with SUNDIALS CVODE-BDF at
#: rtol = atol = 1e−10; the two agree to ≤ 3e−10 in μ and ≤ 7.4e−8 relative in time; the
#: Rodas5P values. 1e5 and 1e6 (v2 = 0.1 and 1 m/s) are the examples of the original request.
STEP_REFERENCE = {
    ("aging", 0.0, 1e-3): (165.9446622, -0.006624674353),
    ("aging", 0.0, 1e-2): (54.98419266, -0.006000969864),
    ("aging", 0.0, 0.1): (18.18004696, -0.00425032861),
    ("aging", 0.0, 10.0): (1.294792853, 0.007843756951),
    ("aging", 0.0, 100.0): (0.2328302622, 0.0182692286),
    ("aging", 0.0, 1e3): (0.03457611969, 0.02957465055),
    ("aging", 0.0, 1e5): (0.0005756523143, 0.05256521660),
    ("aging", 0.0, 1e6): (6.907762472e-05, 0.06407762323),
    ("slip", 1.0, 1e-3): (1117.915781, -0.01115813565),
    ("slip", 1.0, 1e-2): (162.5999768, -0.008596784204),
    ("slip", 1.0, 0.1): (27.79873382, -0.005067839329),
    ("slip", 1.0, 10.0): (1.059801907, 0.006964052084),
    ("slip", 1.0, 100.0): (0.1804651401, 0.01551016391),
    ("slip", 1.0, 1e3): (0.02698295071, 0.02504327993)}


def step_reference(law: str, mass: float, ratio: float, t_guess: float, solver: str,
                   tol: float = 1e-10, points: int = 200_001) -> tuple[float, float]:
    """(time after the step, μ_extreme − μ_before) of a step from steady sliding at 1 µm/s to
    ``ratio`` µm/s on the laboratory apparatus, independently of :func:`step_response`: the run
    starts at the step and lasts 2 ``t_guess``; the largest ±μ on ``points`` even samples is
    refined by the parabola through it and its neighbours (:data:`STEP_REFERENCE`).

    Parameters
    ----------
    law : str
        The friction law's short name.
    mass : float
        The slider's mass (kg).
    ratio : float
        The speed after the step over the speed before (dimensionless).
    t_guess : float
        About when the extreme comes (s).
    solver : str
        The registry name of the solver.
    tol : float
        Its rtol and atol.
    points : int
        Even samples searched.

    Returns
    -------
    tuple of float
        The extreme's time after the step (s) and μ_extreme − μ_before.

    Raises
    ------
    PeakNotReached
        When the solve fails or the extreme is at an edge of the run.
    """
    base = velocity_step_test(law, v2=1e-6 * ratio, mass=mass)
    start = steady_initial_state(base.law, base.normal_force, base.mu0, 1e-6)
    p = dataclasses.replace(base, loading=ConstantLoading(1e-6 * ratio), initial=start,
                            t_end=2.0 * t_guess)
    run = solve(p, make_algorithm(solver, tol, tol), max_points=points)
    if not run.success:
        raise ResolveFailed(f"{solver} failed on the reference: {run.message}")
    sign = 1.0 if ratio > 1 else -1.0
    y = sign * run.fs / p.normal_force
    i = int(np.argmax(y))
    if not 0 < i < len(y) - 1:
        raise PeakNotReached(f"the reference's extreme is at an edge of 0–{p.t_end:g} s")
    y0, y1, y2 = y[i - 1:i + 2]
    x = 0.5 * (y0 - y2) / (y0 + y2 - 2.0 * y1)
    return (float(run.t[i] + x * (run.t[i + 1] - run.t[i])),
            float(sign * (y1 - 0.25 * (y0 - y2) * x) - start.fs / p.normal_force))


#: samples per re-solve while a crossing is searched for and refined
SAMPLES = 64
#: a crossing's bracket is refined to this fraction of the time since its switch
REFINE = 1e-10
#: a piece has settled when it is this close to steady sliding, as a fraction of the scale
SETTLED = 1e-3

HEALING_COLUMNS = ("hold_s", "t_hold_start_s", "mu_before", "t_peak_s", "mu_peak",
                   "delta_mu_peak", "settled_before")
STEP_COLUMNS = ("t_step_s", "v_before", "v_after", "mu_before", "mu_extreme", "t_extreme_s",
                "mu_end", "delta_mu_end", "expected_delta_mu_ss", "delta_mu_ss",
                "settled_before", "settled_after", "settled")


class PeakNotReached(ValueError):
    """The extreme after a switch cannot be located in its piece. ``too_short``: the piece ends
    before it (a longer piece would show it); otherwise Fs turns the wrong way at the switch.

    Parameters
    ----------
    message : str
        What was not reached, and where.
    too_short : bool
        Whether the piece ends before the extreme.
    """

    def __init__(self, message: str, too_short: bool = True):
        super().__init__(message)
        self.too_short = too_short


#: a hold after which |ln(v/vL)| is below this barely slowed the slider: the crossing of vL
#: that marks the peak is then at the solver's error (the built-in apparatus: 2e-7 after a
#: 1 µs hold, whose peak is not located; 2e-5 after 0.1 ms, whose is)
UNRESOLVED_SLOWING = 1e-6


class ResolveFailed(PeakNotReached):
    """A re-solve that locates a measure failed (its retcode is in the message). A
    :class:`PeakNotReached`, so that a study which skips an unlocated peak skips this one too."""

    def __init__(self, message: str):
        super().__init__(message, too_short=False)


class UnsettledWarning(UserWarning):
    """A piece whose end a measure reads as steady sliding had not settled."""


@dataclasses.dataclass(frozen=True)
class _State:
    t: float
    v: float
    fs: float
    theta: float


def _checked(solution):
    if not isinstance(solution, Solution):
        raise ValueError(f"solution must be a Solution (integrators.solve), got "
                         f"{type(solution).__name__}")
    if not solution.reached_end:
        raise ValueError(f"the run did not reach its end ({solution.retcode.value}: "
                         f"{solution.message}): no laboratory measure is read off a failed run")
    hist = solution.problem.loading.history
    if hist.overshoots:
        raise ValueError("loading has an overshoot (two-speed loading): the load point's "
                         "velocity changes after each event, not at known times, and no "
                         "laboratory measure is defined on it")
    return hist


def _edges(solution) -> tuple[float, ...]:
    hist = solution.problem.loading.history
    return (0.0,) + hist.switch_times + (solution.problem.t_end,)


# --- re-solves from the run's own states ------------------------------------------------------
def _sub_problem(problem, start: _State, t1: float):
    """The problem from ``start`` to ``t1``: the history's pieces in between, shifted to t = 0."""
    hist = problem.loading.history
    sw = np.asarray(hist.switch_times, dtype=float)
    i0 = int(np.searchsorted(sw, start.t, side="right"))
    i1 = int(np.searchsorted(sw, t1, side="left"))
    span = t1 - start.t
    times = [float(s - start.t) for s in hist.switch_times[i0:i1]]
    vel = list(hist.velocities[i0:i1 + 1])
    while times and times[-1] >= span:          # a switch that rounds onto the end is the end
        times.pop()
        vel.pop()
    with units_checked_already():               # the run's problem has warned once already
        if problem.quasi_static:                # Fs is tied to (v, θ): rebuilt, not carried
            initial = balanced_initial_state(problem.law, problem.normal_force, problem.mu0,
                                             start.v, start.theta, problem.radiation_damping)
        else:
            initial = InitialState(v=start.v, theta=start.theta, fs=start.fs)
        loading = LoadHistory(tuple(vel), tuple(times), reference_velocity=hist.v_slow)
        return dataclasses.replace(problem, loading=loading, initial=initial, t_end=span)


def _resolve(solution, start: _State, t1: float, points: int, what: str) -> list[_State]:
    """The run's algorithm from ``start`` to ``t1``, ``points`` samples (times of the run)."""
    try:
        sub = _sub_problem(solution.problem, start, t1)
    except ValueError as exc:          # the run's own state is not a valid start (a loose run)
        raise ResolveFailed(f"the run's state at t = {start.t:.9g} s cannot start the re-solve "
                            f"that locates {what}: {exc}") from None
    run = solve(sub, solution.algorithm, max_points=points)
    if not run.reached_end:
        raise ResolveFailed(f"re-solving {start.t:.9g}–{t1:.9g} s with {solution.algorithm.name} "
                            f"to locate {what} failed ({run.retcode.value}: {run.message})")
    return [_State(start.t + t, v, fs, th)
            for t, v, fs, th in zip(run.t, run.v, run.fs, run.theta)]


def _state_at(solution, t: float, what: str) -> _State:
    """The state at ``t``: a saved one within 4 ulps, else the last saved one before it carried
    to ``t`` by a re-solve. Inside a hold (no sliding piece to end a sub-problem on) the re-solve
    runs as far again into the next piece and ``t`` is its middle sample."""
    ts = solution.t
    i = int(np.searchsorted(ts, t, side="right")) - 1
    for j in (i, i + 1):
        if 0 <= j < len(ts) and abs(ts[j] - t) <= 4 * np.spacing(t):
            return _State(float(ts[j]), float(solution.v[j]), float(solution.fs[j]),
                          float(solution.theta[j]))
    start = _State(float(ts[i]), float(solution.v[i]), float(solution.fs[i]),
                   float(solution.theta[i]))
    if _pieces_slide(solution.problem.loading.history, start.t, t):
        return _resolve(solution, start, t, 2, what)[-1]
    middle = _resolve(solution, start, t + (t - start.t), 3, what)[1]
    if abs(middle.t - t) > 4 * np.spacing(t):
        raise ResolveFailed(f"{what}: {solution.algorithm.name} saved no state at t = {t:.9g} s "
                            f"(its middle sample is at {middle.t:.9g} s)")
    return middle


def _pieces_slide(hist, t0: float, t1: float) -> bool:
    """Does any piece between t0 and t1 slide?"""
    sw = np.asarray(hist.switch_times, dtype=float)
    i0, i1 = np.searchsorted(sw, t0, side="right"), np.searchsorted(sw, t1, side="left")
    return any(v > 0 for v in hist.velocities[i0:i1 + 1])


def _time_scale(problem, v: float) -> float:
    """The shortest time over which the response at slip rate ~``v`` changes: slipping one Lc,
    the direct effect's relaxation a Fn/(k v), the inertial √(m/k), the damping's ηr/k."""
    scales = [problem.law.lc / v, problem.law.a * problem.normal_force / (problem.stiffness * v)]
    if problem.mass > 0:
        scales.append(math.sqrt(problem.mass / problem.stiffness))
    if problem.radiation_damping > 0:
        scales.append(problem.radiation_damping / problem.stiffness)
    return min(scales)


def _crossing(states: list[_State], vl: float, sign: float) -> int | None:
    """The first index j ≥ 1 where sign·ln(v/vL) is ≥ 0 (it is < 0 at index 0), or None."""
    f = sign * np.log(np.array([s.v for s in states]) / vl)
    hits = np.flatnonzero(f[1:] >= 0.0)
    return int(hits[0]) + 1 if len(hits) else None


def _first_extreme(solution, start: _State, t_stop: float, vl: float, sign: float,
                   what: str) -> tuple[float, float]:
    """(t, Fs) at the first crossing of v through ``vl`` after the switch at ``start`` (upward,
    a peak of Fs, for ``sign`` +1; downward, a trough, for −1), before ``t_stop``."""
    kind = "peak" if sign > 0 else "trough"
    if sign * math.log(start.v / vl) >= 0.0:
        raise PeakNotReached(
            f"no {kind} in {what}: at its start the slip rate ({start.v:.6g} m/s) is already "
            f"{'above' if sign > 0 else 'below'} the load point's {vl:.6g} m/s, so the spring "
            f"force {'falls' if sign > 0 else 'rises'} from there (the piece before has not "
            "settled)", too_short=False)
    # a window shorter than a few ulps of t (a negligible damping or mass) cannot be re-solved
    a, length = start, max(_time_scale(solution.problem, max(start.v, vl)),
                           64 * np.spacing(max(start.t, t_stop)))
    while a.t < t_stop:
        t_b = min(a.t + length, t_stop)
        states = _resolve(solution, a, t_b, SAMPLES + 1, f"the {kind} of {what}")
        j = _crossing(states, vl, sign)
        if j is not None:
            return _refine(solution, states[j - 1], states[j], start.t, t_stop, vl, sign,
                           f"the {kind} of {what}")
        a, length = dataclasses.replace(states[-1], t=t_b), 2.0 * length
    raise PeakNotReached(f"the {kind} of {what} was not reached inside the piece (it ends at "
                         f"t = {t_stop:.9g} s)")


def _refine(solution, a: _State, b: _State, t_switch: float, t_stop: float, vl: float,
            sign: float, what: str) -> tuple[float, float]:
    """Shrink the bracket [a, b] of a crossing (module docstring), then interpolate. Each
    re-solve runs over twice the bracket, so a crossing that moves by the method's error at
    the bracket's end is still inside."""
    for _ in range(64):
        if b.t - a.t <= max(REFINE * (b.t - t_switch), 4 * np.spacing(b.t)):
            break
        states = _resolve(solution, a, min(a.t + 2.0 * (b.t - a.t), t_stop), SAMPLES + 1, what)
        j = _crossing(states, vl, sign)
        if j is None:
            if states[-1].t < t_stop:
                raise ResolveFailed(f"{what}: the crossing of v through {vl:.6g} m/s bracketed "
                                    f"in {a.t:.12g}–{b.t:.12g} s is not there on a re-solve")
            raise PeakNotReached(f"{what} was not reached inside the piece: it is at its end "
                                 f"(t = {t_stop:.9g} s)")
        a, b = states[j - 1], states[j]
    fa, fb = sign * math.log(a.v / vl), sign * math.log(b.v / vl)
    # v at vL at both ends (a step too small to move v off vL): the crossing is the bracket's start
    x = fa / (fa - fb) if fa != fb else 0.0
    k, h = solution.problem.stiffness, b.t - a.t
    da, db = k * (vl - a.v) * h, k * (vl - b.v) * h      # dFs/dx at the ends, x = (t − ta)/h
    fs = ((2 * x**3 - 3 * x**2 + 1) * a.fs + (x**3 - 2 * x**2 + x) * da
          + (-2 * x**3 + 3 * x**2) * b.fs + (x**3 - x**2) * db)
    return a.t + x * h, float(fs)


# --- settling -----------------------------------------------------------------------------------
def _steady_mu(problem, vl: float) -> float:
    return float(problem.law.steady_friction(vl, problem.normal_force, problem.f0)
                 + problem.radiation_damping * vl) / problem.normal_force


def _settled(problem, state: _State, vl: float, scale: float, piece: str,
             warned: set | None = None) -> bool:
    """Is ``state`` (a piece's end) steady sliding at ``vl``, to :data:`SETTLED` × ``scale`` in
    μ? If not, an :class:`UnsettledWarning` names ``piece`` and how far off it is (once a piece:
    not again for an end time in ``warned``, which it joins)."""
    off = max(abs(state.fs / problem.normal_force - _steady_mu(problem, vl)),
              problem.law.a * abs(math.log(state.v / vl)))
    if off <= SETTLED * scale:
        return True
    if warned is not None:
        if state.t in warned:          # the piece after one step is the piece before the next
            return False
        warned.add(state.t)
    warnings.warn(f"{piece} has not settled at its end (t = {state.t:.6g} s): μ is {off:.3g} "
                  f"from steady sliding at {vl:.6g} m/s, more than {SETTLED:g} × {scale:.3g} "
                  "(lengthen the piece)", UnsettledWarning, stacklevel=3)
    return False


# --- the measures -------------------------------------------------------------------------------
def step_response(solution) -> pd.DataFrame:
    """One row per switch between two sliding pieces at different speeds (:data:`STEP_COLUMNS`):
    μ at the step, the first extreme of μ after it and its time (module docstring), μ at the end
    of the piece after it, ``delta_mu_end`` = μ_end − μ_before, the steady-state change it
    should settle to, and ``delta_mu_ss`` (= ``delta_mu_end`` when the pieces before and after
    the step have settled, else NaN).

    Parameters
    ----------
    solution : Solution
        A run that reached its end, without an overshoot.

    Returns
    -------
    pandas.DataFrame
        One row per step, :data:`STEP_COLUMNS` (times in s).

    Raises
    ------
    PeakNotReached
        If a piece ends before its extreme.
    ValueError
        For a run that failed or has two-speed loading.
    """
    hist = _checked(solution)
    p, edges = solution.problem, _edges(solution)
    rows, warned = [], set()
    for i, ts in enumerate(hist.switch_times):
        v1, v2 = hist.velocities[i], hist.velocities[i + 1]
        if v1 == 0.0 or v2 == 0.0 or v1 == v2:
            continue
        what = f"the piece after the step at {ts:g} s"
        before = _state_at(solution, ts, f"the state at the step at {ts:g} s")
        t_ext, fs_ext = _first_extreme(solution, before, edges[i + 2], v2,
                                       1.0 if v2 > v1 else -1.0, what)
        end = _state_at(solution, edges[i + 2], f"the end of {what}")
        scale = p.law.a * abs(math.log(v2 / v1))
        settled_before = _settled(p, before, v1, scale, f"the piece before the step at {ts:g} s",
                                  warned)
        settled_after = _settled(p, end, v2, scale, what, warned)
        mu_before, mu_end = before.fs / p.normal_force, end.fs / p.normal_force
        rows.append({"t_step_s": ts, "v_before": v1, "v_after": v2, "mu_before": mu_before,
                     "mu_extreme": fs_ext / p.normal_force, "t_extreme_s": t_ext,
                     "mu_end": mu_end, "delta_mu_end": mu_end - mu_before,
                     "expected_delta_mu_ss": _steady_mu(p, v2) - _steady_mu(p, v1),
                     "delta_mu_ss": (mu_end - mu_before if settled_before and settled_after
                                     else math.nan),
                     "settled_before": settled_before, "settled_after": settled_after,
                     "settled": settled_before and settled_after})
    return pd.DataFrame(rows, columns=list(STEP_COLUMNS))


def healing(solution) -> pd.DataFrame:
    """One row per hold followed by sliding (:data:`HEALING_COLUMNS`): its duration, μ when it
    began, the peak of μ on reloading (the first, module docstring) and its time, and
    ``delta_mu_peak`` = μ_peak − μ_before, and ``settled_before``: had the slide before the hold
    settled at its speed (a hold that opens the run is judged against the speed after it)? A
    hold that ends the run has no reloading and no row; consecutive holds are one hold.

    Parameters
    ----------
    solution : Solution
        A run that reached its end.

    Returns
    -------
    pandas.DataFrame
        One row per hold, :data:`HEALING_COLUMNS` (times in s).

    Raises
    ------
    PeakNotReached
        If a slide ends before its peak.
    ValueError
        For a run that failed."""
    hist = _checked(solution)
    p, edges, vel = solution.problem, _edges(solution), hist.velocities
    rows = []
    for i, v in enumerate(vel):
        if v != 0.0 or (i > 0 and vel[i - 1] == 0.0):
            continue
        j = i
        while j + 1 < len(vel) and vel[j + 1] == 0.0:
            j += 1
        if j + 1 >= len(vel):
            continue
        start, end, vr = edges[i], edges[j + 1], vel[j + 1]
        what = f"the slide after the hold ending at {end:g} s"
        before = _state_at(solution, start, f"the state at the hold starting at {start:g} s")
        reload = _state_at(solution, end, f"the state at the hold's end at {end:g} s")
        try:
            t_peak, fs_peak = _first_extreme(solution, reload, edges[j + 2], vr, 1.0, what)
        except ResolveFailed:
            slowed = math.log(reload.v / vr)
            if abs(slowed) > UNRESOLVED_SLOWING:
                raise
            raise ResolveFailed(
                f"the hold of {end - start:.3g} s ending at {end:g} s slowed the slider by "
                f"ln(v/vL) = {slowed:.2g} only, within the solver's error: its healing (and the "
                "peak after it) is below what the solve resolves; hold longer") from None
        v_slid = vel[i - 1] if i > 0 else vr
        settled = _settled(p, before, v_slid, p.law.a,
                           f"the slide before the hold starting at {start:g} s")
        mu_before, mu_peak = before.fs / p.normal_force, fs_peak / p.normal_force
        rows.append({"hold_s": end - start, "t_hold_start_s": start, "mu_before": mu_before,
                     "t_peak_s": t_peak, "mu_peak": mu_peak,
                     "delta_mu_peak": mu_peak - mu_before,
                     "settled_before": settled})
    return pd.DataFrame(rows, columns=list(HEALING_COLUMNS))


def healing_rate(table: pd.DataFrame) -> float:
    """The least-squares slope of Δμ_peak against log10(hold time): healing per decade. NaN
    with fewer than two different hold times.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`healing`'s table.

    Returns
    -------
    float
        Δμ_peak per decade of hold time (dimensionless).
    """
    if table.hold_s.nunique() < 2:
        return math.nan
    return float(np.polyfit(np.log10(table.hold_s), table.delta_mu_peak, 1)[0])
