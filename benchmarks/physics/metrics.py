"""Limit-cycle metrics of a stick–slip run (SPEC §4): per event, and once they converge.

Per event (from ``Solution.events``, whatever the backend):

* recurrence interval ΔT: time between this event's start and the previous one's;
* friction drop Δμ = (max Fs before the event − min Fs during it)/Fn;
* slip per event: slip between the event's start and end;
* peak slip rate.

The limit cycle is found by looking for the shortest period p (in events) for which every metric
repeats, event to event p apart, within ``rtol``; it is summarised by the last complete period.

Classification (:data:`CLASSIFICATIONS`). Only the first two are limit cycles whose metrics an
inversion may fit (:data:`CYCLES`); every other class has NaN metrics and a ``reason``:

* ``stick-slip`` (p = 1) and ``multiple recurrence`` (p > 1, which the two-speed loading can
  cause): the metrics repeat, and between events the fault is locked;
* ``oscillation about vL``: a slip-rate oscillation that never locks, not stick–slip. Either
  the metrics repeat and the slip rate crosses the event thresholds, but between events the
  fault keeps slipping at a mean rate above :data:`LOCKED_SLIP_RATE` × vLs (the documented
  rule); or, without a cycle of events, the run ended on a small oscillation about vL
  (:func:`integrators.core.cycles.classify`) that the linear stability of steady sliding
  (:func:`problems.stability.growth_rate`, σ) says has settled: steady sliding is unstable and
  :data:`~integrators.core.cycles.SETTLE_EFOLDS` e-folds of growth passed without an event
  (a small limit cycle), or σ is so close to 0 (k = kcr) that no run this problem allows
  would see the oscillation grow or decay (a neutral, steady oscillation);
* ``stable sliding``: no cycle (no events, a transient, or events that died out), the run ended
  close to steady sliding at vLs (:data:`STEADY_LOG_TOLERANCE`) *and* steady sliding is linearly
  stable there (σ < 0);
* ``not converged``: events still changing at the end of the run (run longer);
* ``too short to classify``: no events, or too few to compare, and the end state does not show
  stable sliding nor a settled oscillation (still locked, still decaying, still growing): the
  reason says how long a run needs (the linear decay to within the tolerance, or the growth's
  settling time, :func:`integrators.core.cycles.settle_time`) when the linear analysis knows;
* ``failed``: the solve did not reach t_end (its retcode and message are the reason).

Nothing here divides by σ or takes its logarithm unguarded: σ = 0 (neutral stability) and σ
unknown (NaN: the characteristic roots could not be computed) are reasons, not crashes.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from integrators.core import cycles
from problems import stability
from problems.slider import TAU_END_MAX

__all__ = ["event_metrics", "LimitCycle", "limit_cycle", "cycle_from", "summarize", "EndState",
           "end_state", "METRICS", "metric_gradients", "event_gradients", "cycle_gradient",
           "CLASSIFICATIONS", "CYCLES", "LOCKED_SLIP_RATE", "STEADY_LOG_TOLERANCE"]

#: the limit-cycle metrics, in the order tables show them
METRICS = ("recurrence_s", "friction_drop", "slip_m", "peak_velocity_m_s")
#: the classes of a run, and those with a limit cycle an inversion can fit: only they have
#: metrics and scores (defined with the compiled search, :mod:`integrators.core.cycles`)
CLASSIFICATIONS, CYCLES = cycles.CLASSIFICATIONS, cycles.CYCLES
#: stick–slip needs the mean slip rate between consecutive events (slip between one event's end
#: and the next one's start, over that time) at most this multiple of vLs: the fault locks. The
#: events-table form of "v falls below vLs/10 between events": over 296 runs (the paper's fits,
#: 5×5 sweep subsamples of W1–W4 under both laws, 22 oscillations and 70 runs across the
#: boundary) no run with ratio ≤ 0.3 kept v above vLs/10; the fits sit at 0.005–0.035, the
#: oscillations at 0.33–2.7 (docs/reliability.md; ``rsfbench study classification`` repeats a subset)
LOCKED_SLIP_RATE = cycles.LOCKED_SLIP_RATE
#: a run ended in steady sliding when |ln(v/vLs)|, the state's friction term off its steady value
#: and the spring force off steady friction (both in units of A = a·Fn: (b/a)|ln θ/θss| for the
#: aging law, |θ − θss|/A for the slip law) are all below this: about one e-fold of decay from
#: the presets' start
STEADY_LOG_TOLERANCE = cycles.STEADY_LOG_TOLERANCE


def _metric_columns(events: pd.DataFrame, normal_force: float) -> tuple[np.ndarray, np.ndarray]:
    """(t_start, the four METRICS as an (n, 4) array) in numpy: a sweep summarises every point,
    and column arithmetic in pandas costs more than a short solve."""
    col = {c: events[c].to_numpy(dtype=float) for c in ("t_start", "fs_max_before", "fs_min",
                                                         "slip_end", "slip_start", "v_peak")}
    t = col["t_start"]
    recurrence = np.concatenate(([np.nan], np.diff(t))) if len(t) else t
    x = np.column_stack((recurrence, (col["fs_max_before"] - col["fs_min"]) / normal_force,
                         col["slip_end"] - col["slip_start"], col["v_peak"]))
    return t, x


def event_metrics(events: pd.DataFrame, normal_force: float) -> pd.DataFrame:
    """One row per event: its start time and the four metrics (ΔT is NaN for the first event).

    Parameters
    ----------
    events : pandas.DataFrame
        A run's events, :data:`~integrators.EVENT_COLUMNS` (SI units).
    normal_force : float
        Fn (N), to make the friction drop a coefficient.

    Returns
    -------
    pandas.DataFrame
        ``t_start`` (s), ``recurrence_s`` (s), ``friction_drop`` (dimensionless), ``slip_m``
        (m), ``peak_velocity_m_s`` (m/s).
    """
    t, x = _metric_columns(events, normal_force)
    return pd.DataFrame({"t_start": t, **{name: x[:, i] for i, name in enumerate(METRICS)}})


@dataclass
class LimitCycle:
    """Summary of the cycle a run settles into.

    Metrics are means over the last complete period (for ``multiple recurrence`` the individual
    recurrence intervals of that period are in ``recurrence_values``); they are NaN unless the
    classification is in :data:`CYCLES`, and ``reason`` then says why. ``cycles_to_converge`` is
    the index of the first event from which the metrics repeat within ``rtol``.

    Parameters
    ----------
    classification : str
        One of :data:`CLASSIFICATIONS`.
    period : int
        Events per period (0 without a cycle).
    recurrence_s : float
        The recurrence interval ΔT (s).
    friction_drop : float
        The friction drop Δμ (dimensionless).
    slip_m : float
        The slip per event (m).
    peak_velocity_m_s : float
        The peak slip rate (m/s).
    cycles_to_converge : int, optional
        The first event from which the metrics repeat.
    n_events : int
        The run's events.
    rtol : float
        The relative tolerance of the repetition.
    recurrence_values : list of float
        The period's recurrence intervals (s).
    reason : str
        Why there are no metrics, when there are none.
    """

    classification: str
    period: int = 0
    recurrence_s: float = float("nan")
    friction_drop: float = float("nan")
    slip_m: float = float("nan")
    peak_velocity_m_s: float = float("nan")
    cycles_to_converge: int | None = None
    n_events: int = 0
    rtol: float = 1e-3
    recurrence_values: list[float] = field(default_factory=list)
    reason: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class EndState:
    """How a run ended, against steady sliding at the slow loading speed vLs: the slip rate
    ``log_v`` = ln(v/vLs), and the state's and the spring's distance from steady sliding in
    units of A = a·Fn (``state_offset``, ``force_offset``); whether steady sliding is linearly
    stable (``growth_rate`` σ, the largest real part of the characteristic roots, 1/s, < 0;
    0 at neutral stability, NaN when it could not be computed); ``longest_run``, the longest
    run (s) the problem allows (τ = ``TAU_END_MAX``; NaN when not known), which says whether
    a promise to run longer can be kept.

    Parameters
    ----------
    log_v : float
        ln(v/vLs) (dimensionless).
    state_offset, force_offset : float
        The state's and the spring's distance from steady sliding, in units of A = a·Fn.
    growth_rate : float
        σ (1/s).
    longest_run : float
        The longest run the problem allows (s).
    """

    log_v: float
    state_offset: float
    force_offset: float
    growth_rate: float
    longest_run: float = float("nan")

    @property
    def stable(self) -> bool:
        return self.growth_rate < 0.0

    @property
    def offset(self) -> float:
        """The largest of the three offsets (A; ``|ln v/vLs|`` counts as one)."""
        return max(abs(self.log_v), self.state_offset, self.force_offset)

    @property
    def near_steady(self) -> bool:
        return self.offset < STEADY_LOG_TOLERANCE

    def stability(self) -> str:
        """Steady sliding's linear stability in words (no division by a zero σ)."""
        g = self.growth_rate
        if g < 0.0:
            return f"linearly stable (perturbations decay e-fold in {-1.0 / g:.3g} s)"
        if g > 0.0:
            return f"linearly unstable (perturbations grow e-fold in {1.0 / g:.3g} s)"
        if g == 0.0:
            return "neutrally stable (growth rate 0 to double precision: k = kcr)"
        return "of unknown linear stability (its characteristic roots could not be computed)"

    def describe(self) -> str:
        with np.errstate(over="ignore"):
            v = np.exp(self.log_v)
        return (f"the run ended at v = {v:.3g} vLs (state {self.state_offset:.2g} "
                f"A, spring {self.force_offset:.2g} A from steady sliding); steady sliding is "
                f"{self.stability()}")


def end_state(solution) -> EndState:
    """The :class:`EndState` of a Solution (its last saved state).

    Parameters
    ----------
    solution : Solution

    Returns
    -------
    EndState
    """
    p = solution.problem
    law, fn = p.law, p.normal_force
    log_v, state, force = cycles.end_offsets(
        law.code, law.a, law.b, law.lc, law.v0, fn, p.f0, p.steady_velocity,
        float(solution.v[-1]), float(solution.fs[-1]), float(solution.theta[-1]),
        p.radiation_damping)
    return EndState(log_v=log_v, state_offset=state, force_offset=force,
                    growth_rate=_growth_rate(p), longest_run=TAU_END_MAX * law.lc / law.v0)


def _growth_rate(problem) -> float:
    """σ of ``problem``, NaN when the characteristic roots cannot be computed (coefficients
    beyond the float range: a mass or stiffness near the float limits), so that classifying
    such a run names the fact instead of raising."""
    try:
        with np.errstate(all="ignore"):
            g = stability.growth_rate(problem)   # looked up at the call: tests replace it
    except (ValueError, ArithmeticError):        # numpy's LinAlgError is a ValueError
        return float("nan")
    return g if np.isfinite(g) else float("nan")


def interevent_slip_rate(events: pd.DataFrame) -> np.ndarray:
    """Mean slip rate (m/s) between each event's start and the end of the event before it
    (NaN for the first event): how far from locked the fault is between events."""
    t0, t1 = events["t_start"].to_numpy(float), events["t_end"].to_numpy(float)
    s0, s1 = events["slip_start"].to_numpy(float), events["slip_end"].to_numpy(float)
    rate = np.full(len(events), np.nan)
    if len(events) > 1:
        with np.errstate(divide="ignore", invalid="ignore"):
            rate[1:] = (s0[1:] - s1[:-1]) / (t0[1:] - t1[:-1])
    return rate


def limit_cycle(events: pd.DataFrame, normal_force: float, t_end: float, rtol: float = 1e-3,
                max_period: int = 4, min_repeats: int = 2, v_slow: float | None = None,
                end: EndState | None = None) -> LimitCycle:
    """Find the limit cycle of a run from its events table.

    A period p is accepted when the last ``min_repeats``·p events each repeat the event p before
    them within ``rtol``; the smallest such p wins. ``v_slow`` (the slow loading speed, m/s)
    enables the locking test of stick–slip (:data:`LOCKED_SLIP_RATE`). When no cycle repeats,
    ``end`` (how the run ended) tells stable sliding from a run too short to classify; without
    it such a run is never called stable sliding. The search is
    :func:`integrators.core.cycles.find_cycle`, the one the ensemble kernel runs.

    Parameters
    ----------
    events : pandas.DataFrame
        The run's events, :data:`~integrators.EVENT_COLUMNS` (SI units).
    normal_force : float
        Fn (N).
    t_end : float
        The end of the run (s).
    rtol : float
        The relative tolerance of a repetition.
    max_period : int
        The longest period looked for (events).
    min_repeats : int
        How many times a period must repeat.
    v_slow : float, optional
        The slow loading speed (m/s).
    end : EndState, optional
        How the run ended.

    Returns
    -------
    LimitCycle
    """
    if not 1 <= max_period <= cycles.MAX_PERIOD:
        raise ValueError(f"max_period must be in 1..{cycles.MAX_PERIOD}, got {max_period!r}")
    if not min_repeats >= 1:
        raise ValueError(f"min_repeats must be at least 1, got {min_repeats!r}")
    t, x = _metric_columns(events, normal_force)
    col = {c: events[c].to_numpy(dtype=float) for c in ("t_end", "slip_start", "slip_end")}
    found = np.empty(cycles.N_F)
    cycles.find_cycle(t, col["t_end"], col["slip_start"], col["slip_end"], np.ascontiguousarray(x),
                      float(t_end), float(rtol), int(max_period), int(min_repeats),
                      np.nan if v_slow is None else float(v_slow), found)
    return cycle_from(found, len(events), t_end, rtol, max_period, min_repeats, end)


def cycle_from(found: np.ndarray, n: int, t_end: float, rtol: float, max_period: int,
               min_repeats: int, end: EndState | None) -> LimitCycle:
    """The :class:`LimitCycle` of :func:`integrators.core.cycles.find_cycle`'s output ``found``
    for a run with ``n`` events that reached ``t_end`` (s), classified against its ``end``:
    the reason a reader sees, for one run or for each point of an ensemble."""
    F = cycles.F
    outcome, p = int(found[F["OUTCOME"]]), found[F["PERIOD"]]
    quiet = float(found[F["GAP"]])
    if end is not None:
        growth, offsets = end.growth_rate, (end.log_v, end.state_offset, end.force_offset)
        headroom = end.longest_run - t_end
    else:
        growth, offsets, headroom = np.nan, (np.nan,) * 3, np.nan
    what = CLASSIFICATIONS[cycles.classify(outcome, p, growth, *offsets, quiet, headroom)]
    if what in CYCLES:
        p = int(p)
        return LimitCycle(
            what, period=p, recurrence_s=float(found[F["RECURRENCE"]]),
            friction_drop=float(found[F["DROP"]]), slip_m=float(found[F["SLIP"]]),
            peak_velocity_m_s=float(found[F["PEAK_V"]]),
            cycles_to_converge=int(found[F["FIRST"]]) + p + 1, n_events=n, rtol=rtol,
            recurrence_values=[float(v) for v in found[F["VALUES"]:F["VALUES"] + p]])
    if what == "oscillation about vL" and outcome == cycles.OSCILLATING:
        return LimitCycle(
            what, period=int(p), n_events=n, rtol=rtol,
            reason=f"a periodic slip-rate oscillation (period {int(p)}, ΔT "
                   f"{found[F['RECURRENCE']]:.4g} s), but between events the fault slips at "
                   f"{found[F['RATIO']]:.2g} vLs on average (stick–slip needs ≤ "
                   f"{LOCKED_SLIP_RATE:g} vLs): it never locks")
    if what == "oscillation about vL":
        return LimitCycle(what, n_events=n, rtol=rtol,
                          reason=_settled_reason(end, quiet, headroom, n))
    if what == "stable sliding":
        died = "no events" if n == 0 else f"the {n} events died out"
        return LimitCycle(what, n_events=n, rtol=rtol, reason=f"{died}; {end.describe()}")
    why = end.describe() if end is not None else "no end state to compare with steady sliding"
    longer = _run_longer(end, quiet, headroom, t_end)
    if outcome == cycles.NO_EVENTS:
        reason = f"no event in {t_end:g} s, and {why}: {longer}"
    elif outcome == cycles.STOPPED:
        reason = (f"no event in the last {quiet:.3g} s (more than 3 of its last "
                  f"recurrence intervals), and {why}: {longer}")
    elif outcome == cycles.TOO_FEW:
        reason = (f"{n} events in {t_end:g} s, too few to see a cycle repeat (at least "
                  f"{2 * min_repeats + 1} are needed), and {why}: {longer}")
    else:
        reason = (f"the metrics of the last events do not repeat within {rtol:g} with any "
                  f"period up to {max_period}: run longer")
    return LimitCycle(what, n_events=n, rtol=rtol, reason=reason)


def _settled_reason(end: EndState, quiet: float, headroom: float, n: int) -> str:
    """Why a run without a cycle of events is an oscillation about vL (see
    :func:`integrators.core.cycles.classify`)."""
    g = end.growth_rate
    since = "no event" if n == 0 else f"no event in the last {quiet:.3g} s"
    if g > 0.0 and g * quiet >= cycles.SETTLE_EFOLDS:
        return (f"a small limit cycle about vL, not stick–slip: {since} over {g * quiet:.3g} "
                f"e-folds of the linear growth of steady sliding ({cycles.SETTLE_EFOLDS:g} "
                f"turn any perturbation into an event), the growth has saturated; "
                f"{end.describe()}")
    wait = cycles.settle_time(g, end.offset, quiet)
    return (f"a steady oscillation about vL at neutral stability (k = kcr to within the "
            f"precision of the growth rate): {end.describe()}; it would take {wait:.3g} s "
            f"more to grow or decay measurably, longer than any run of this problem can be "
            f"({end.longest_run:.3g} s, τ = v0 t/Lc at its limit)")


def _run_longer(end: EndState | None, quiet: float, headroom: float, t_end: float) -> str:
    """How much longer to run, as far as the linear stability of steady sliding knows."""
    if end is None or not np.isfinite(headroom) or not cycles.on_oscillation(
            end.log_v, end.state_offset, end.force_offset):
        return "run longer"
    wait = cycles.settle_time(end.growth_rate, end.offset, quiet)
    if not 0.0 < wait <= headroom:
        return "run longer"
    if end.growth_rate < 0.0:
        what = (f"a decaying oscillation is then within {STEADY_LOG_TOLERANCE:g} of steady "
                f"sliding")
    else:
        what = (f"{cycles.SETTLE_EFOLDS:g} e-folds of growth have then passed: it has events "
                f"or has settled as a small limit cycle")
    return f"run to t_end ≥ {_round_up(t_end + wait):.4g} s ({what})"


def _round_up(x: float, digits: int = 4) -> float:
    """``x`` rounded up to ``digits`` significant digits: a promised length printed with
    ``:.4g`` is never shorter than the length computed."""
    scale = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    return math.ceil(x / scale * (1 - 1e-12)) * scale


def summarize(solution, rtol: float = 1e-3) -> LimitCycle:
    """:func:`limit_cycle` of a Solution; a run that did not reach its end is ``failed``, never
    classified as physics, unless it stopped on its settled cycle (``solve(..., settle=)``):
    then its events up to there.

    Parameters
    ----------
    solution : Solution
    rtol : float
        The relative tolerance of a repetition.

    Returns
    -------
    LimitCycle
    """
    p = solution.problem
    events = solution.events
    settled, settle = solution.settled_s, solution.meta.get("settle", 0.0)
    if settled is not None and not rtol >= settle:      # its cycle repeats to settle only
        return LimitCycle("failed", n_events=len(events), rtol=rtol,
                          reason=f"stopped on a cycle settled to {settle:g}, looser than this "
                                 f"search's rtol = {rtol:g}: solve with settle ≤ rtol")
    if settled is not None:             # stopped on its settled cycle: its cycle is read
        return limit_cycle(events, p.normal_force, settled, rtol=rtol,
                           v_slow=p.loading.v_slow, end=end_state(solution))
    if not solution.success or not solution.reached_end:
        why = (f"{solution.retcode.value}: {solution.message}" if not solution.success else
               f"stopped at t = {solution.t_reached:g} s of {p.t_end:g} s")
        return LimitCycle("failed", n_events=len(events), rtol=rtol, reason=why)
    return limit_cycle(events, p.normal_force, p.t_end, rtol=rtol, v_slow=p.loading.v_slow,
                       end=end_state(solution))


def metric_gradients(events: np.ndarray, d_events: np.ndarray, normal_force: float,
                     d_fn: np.ndarray) -> np.ndarray:
    """The derivatives of each event's four :data:`METRICS` (n × 4 × parameters) from the
    events table (n × 8, SI) and its derivatives (n × 8 × parameters; a solve's
    :class:`~integrators.core.solution.Sensitivity`), ``d_fn`` = ∂Fn/∂θ per parameter:
    ΔT_i = t_start,i − t_start,i−1 (NaN for the first), Δμ = (fs_max − fs_min)/Fn,
    slip_end − slip_start, v_peak."""
    out = np.full((len(events), 4, d_events.shape[2]), np.nan)
    if len(events):
        out[1:, 0] = np.diff(d_events[:, 0], axis=0)
        drop = (events[:, 2] - events[:, 3])[:, None]
        out[:, 1] = ((d_events[:, 2] - d_events[:, 3]) / normal_force
                     - drop * np.asarray(d_fn)[None, :] / normal_force ** 2)
        out[:, 2] = d_events[:, 7] - d_events[:, 6]
        out[:, 3] = d_events[:, 4]
    return out


def event_gradients(solution) -> np.ndarray:
    """:func:`metric_gradients` of a solve with sensitivities (events × 4 metrics ×
    parameters), ValueError for one without."""
    sens = solution.sensitivity
    if sens is None:
        raise ValueError("the solve has no sensitivities; solve(..., sensitivity=(...)) with "
                         "Rodas5P")
    d_fn = np.array([1.0 if n == "normal_force" else 0.0 for n in sens.names])
    return metric_gradients(solution.event_array, sens.events, solution.problem.normal_force,
                            d_fn)


def cycle_gradient(solution, cycle: LimitCycle | None = None) -> dict:
    """The gradient of the limit cycle's four :data:`METRICS` (means over its last period)
    from a solve with sensitivities: {metric: {parameter: derivative (SI per unit)}}; empty
    when the run has no cycle or the cycle's derivatives are unknown (after an arrest:
    ``solution.sensitivity.message``) (``cycle``: :func:`summarize`'s, computed if not
    given)."""
    grads = event_gradients(solution)
    cycle = summarize(solution) if cycle is None else cycle
    if cycle.classification not in CYCLES or not cycle.period:
        return {}
    tail = grads[-cycle.period:].mean(axis=0)
    if not np.isfinite(tail).all():     # after an arrest: no derivative (sens.message)
        return {}
    return {m: {n: float(tail[i, j]) for j, n in enumerate(solution.sensitivity.names)}
            for i, m in enumerate(METRICS)}
