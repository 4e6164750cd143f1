"""``solve(problem, algorithm) -> Solution``: the one entry point.

Common checks, timing, budgets and failure handling live here once; each backend only maps the
problem onto its method (``Algorithm.run``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from integrators.core.registry import Algorithm
from integrators.core.solution import EVENT_COLUMNS, Output, RawRun, ReturnCode, Solution, Stats
from problems._validate import check_positive, units_checked_already
from problems.slider import SpringSlider

__all__ = ["solve", "Budget", "compile_ahead", "short_piece", "check_settle", "settle_refusal",
           "SETTLE_MAX"]


@dataclass
class Budget:
    """Wall-time budget of one solve (``None``: unlimited), checked by the backends as they go.

    Parameters
    ----------
    wall_s : float, optional
        The budget (s); ``None`` is unlimited.
    start : float
        The ``time.perf_counter()`` value the budget counts from (s).
    """

    wall_s: float | None = None
    start: float = 0.0

    def exceeded(self) -> bool:
        return self.wall_s is not None and time.perf_counter() - self.start > self.wall_s

    def deadline(self) -> float:
        """The ``time.perf_counter()`` at which the budget runs out (inf: none), for compiled
        code that reads the same clock (:func:`integrators.core.clock.monotonic`)."""
        return math.inf if self.wall_s is None else self.start + self.wall_s


def _check_arguments(problem, algorithm, wall_budget) -> None:
    """Refuse what :func:`solve` cannot take: a wrong type, a bad budget, a problem the method
    cannot integrate (:class:`ProblemNotSupported`)."""
    if not isinstance(problem, SpringSlider):
        raise ValueError(f"problem must be a SpringSlider, got {type(problem).__name__}")
    if not isinstance(algorithm, Algorithm):
        raise ValueError(f"algorithm must be an Algorithm instance, got {algorithm!r}")
    if wall_budget is not None:
        check_positive("wall_budget", wall_budget)
    algorithm.check_problem(problem)


def solve(problem: SpringSlider, algorithm: Algorithm, *, save_every: float | None = None,
          max_points: int | None = None, save_at=None, wall_budget: float | None = None,
          progress: bool = False, sensitivity=None,
          sensitivity_error: bool = True, settle: float | None = None) -> Solution:
    """Integrate ``problem`` with ``algorithm`` from t = 0 to ``problem.t_end``.

    The saved grid never changes the steps a method takes, and events are recorded exactly
    whatever is saved. How each backend fills the grid:

    * the own adaptive methods: from the step's dense output, inside the compiled solve; steps
      land only on the end of a loading segment;
    * the ETD family: its fixed rule (Eq. 53) sets every step; a save time takes the state at
      the first step end at or after it (``Solution.t`` holds those step times);
    * scipy: its ``dense_output``; CVODE/IDA (scikits-odes: CV_NORMAL with tstop at the segment
      end only; scikit-SUNDAE: one step at a time): SUNDIALS' interpolation; assimulo: its
      ``interpolate``; numbalsoda: LSODA's own interpolation at the requested times.

    Parameters
    ----------
    problem : SpringSlider
        The problem to integrate.
    algorithm : Algorithm
        The method and its options, e.g. ``Rodas5P(rtol=1e-6, atol=1e-6)``.
    save_every : float, optional
        Save the trajectory every ``save_every`` s (without it or ``save_at``: ``max_points``).
    max_points : int, optional
        The saved points in all (default 20,000); with ``save_every``, a cap on them (default
        10⁷, see :class:`~integrators.core.solution.Output`).
    save_at : array_like, optional
        An increasing array of times (s) to save at exactly, from each method's dense output
        (the ETD family, which saves at its own step ends, refuses it).
    wall_budget : float, optional
        Stop a run that takes longer (s; retcode ``WallTime``). It counts the run, never the
        compiling: a method's first budgeted solve in a process runs a short piece first
        (:func:`compile_ahead`, its running bounded by a tenth of the budget), then the clock.
    progress : bool
        Show a progress bar.
    sensitivity : str or sequence of str, optional
        Parameters to differentiate by (``("b", "lc")``): ``Solution.sensitivity`` holds the
        derivatives of the saved states and events (Rodas5P, RadauIIA5; docs/sensitivities.md).
    sensitivity_error : bool
        Put the sensitivities' error in the step control (default True; False: the steps
        taken without them, the derivatives of that solution).
    settle : float, optional
        Stop at the end of the event where the cycle has settled to this relative tolerance,
        in (0, 1e−3] (:func:`integrators.core.cycles.settled`; ``Solution.settled_s``; own
        compiled methods, no speed switch, no ``sensitivity``; default None: run to t_end).

    Returns
    -------
    Solution
        Always; a numerical failure comes back with its retcode (``reached_end`` false).

    Raises
    ------
    ValueError
        On misuse, before any work (bad arguments, ``save_at`` without dense output).
    ProblemNotSupported
        When the method cannot integrate the problem at all (the paper's ETD without mass),
        before any work; a ``ValueError`` too.
    """
    _check_arguments(problem, algorithm, wall_budget)
    output = Output(save_every=save_every, max_points=max_points, save_at=save_at)
    if save_at is not None and not algorithm.saves_at_times:
        raise ValueError(f"{algorithm.name} saves at its own step ends: save_at needs a method "
                         "with dense output")
    output.times(problem.t_end)             # validates the decimation now, not mid-run
    directions, control = _directions(problem, algorithm, sensitivity, sensitivity_error)
    settle = check_settle(algorithm, settle, bool(directions), problem)
    if wall_budget is not None:
        _compile_once(problem, algorithm, wall_budget, bool(directions))
    budget = Budget(wall_s=wall_budget, start=time.perf_counter())
    bar = _progress_bar(problem, algorithm) if progress else None
    try:
        raw = _run(problem, algorithm, output, budget, bar, directions, control, settle)
    finally:
        if bar:
            bar.close()
    raw.stats = dataclasses.replace(raw.stats, wall_s=time.perf_counter() - budget.start)
    return _solution(problem, algorithm, raw, directions, control, settle)


def _run(problem, algorithm, output, budget, bar, directions, sensitivity_error,
         settle=0.0) -> RawRun:
    """The backend's run; a library failure is a result (a FAILURE RawRun), not a crash."""
    try:
        # trial steps of adaptive methods overflow exp(ln v) before being rejected: expected,
        # and a run that ends non-finite is a retcode anyway
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            update = bar.update_to if bar else None
            if settle:
                return algorithm.run(problem, output, budget, update, settle=settle)
            if not directions:
                return algorithm.run(problem, output, budget, update)
            return algorithm.run(problem, output, budget, update, sensitivity=directions,
                                 sensitivity_error=sensitivity_error)
    except Exception as exc:  # a library failure is a result, not a crash of the caller
        return RawRun(t=np.empty(0), y=np.empty((0, 3)),
                      events=np.empty((0, len(EVENT_COLUMNS))), stats=Stats(),
                      retcode=ReturnCode.FAILURE, message=f"{type(exc).__name__}: {exc}")


#: the loosest ``settle`` taken: the limit-cycle search's own tolerance (``summarize``'s
#: rtol, the batch's CYCLE_RTOL), so that a run stopped on its cycle is found to have one
SETTLE_MAX = 1e-3


def check_settle(algorithm: Algorithm, settle, sensitive: bool = False,
                 problem: SpringSlider | None = None) -> float:
    """``solve``'s ``settle`` as a float (0.0: run to t_end), or ValueError before any work: a
    value outside (0, :data:`SETTLE_MAX`], a method that cannot stop on a settled cycle, with
    sensitivities, or a ``problem`` whose loading switches speed before its end
    (:func:`settle_refusal`)."""
    if settle is None:
        return 0.0
    if isinstance(settle, bool) or not isinstance(settle, (int, float, np.integer,
                                                          np.floating)):
        raise ValueError(f"settle must be a relative tolerance (a number), got {settle!r}")
    if not 0.0 < settle <= SETTLE_MAX:
        raise ValueError(f"settle must be a relative tolerance in (0, {SETTLE_MAX:g}] "
                         f"(dimensionless), got {settle!r}")
    if not algorithm.settles:
        raise ValueError(f"settle: {algorithm.name} runs to t_end; only the project's compiled "
                         "adaptive methods (Rodas5P, RadauIIA5, Rosenbrock23, CashKarp45, "
                         "Exprb32, Exprb43) stop on a settled cycle")
    if sensitive:
        raise ValueError("settle: a solve with sensitivities runs to t_end; ask for one or "
                         "the other")
    why = settle_refusal(problem) if problem is not None else ""
    if why:
        raise ValueError(why)
    return float(settle)


def settle_refusal(problem: SpringSlider) -> str:
    """Why ``settle`` cannot apply to ``problem`` ("" if it can): its loading switches speed
    before its end, and a cycle settled before a switch is not the run's."""
    early = [t for t in problem.loading.history.switch_times if t < problem.t_end]
    if not early:
        return ""
    return (f"settle: the loading switches speed at t = {early[0]:g} s, before t_end = "
            f"{problem.t_end:g} s; a cycle settled before a switch is not the run's (solve "
            "without settle)")


def _directions(problem: SpringSlider, algorithm: Algorithm, sensitivity, control) -> tuple:
    """The :class:`problems.directions.Direction` objects of ``sensitivity`` (empty: none) and
    the error control as a bool, or ValueError for a method without forward sensitivities or a
    name the problem lacks."""
    from problems.directions import direction, sensitive_request, sensitivity_names, warn_loose
    control = sensitive_request(algorithm, sensitivity, control)
    if sensitivity is None:
        return (), control
    names = sensitivity_names(problem, sensitivity)
    warn_loose(algorithm, 2)
    return tuple(direction(problem, n) for n in names), control


def short_piece(problem: SpringSlider, fraction: float = 1e-3) -> SpringSlider:
    """The first ``fraction`` of ``problem``'s run: the same slider, law, start and loading
    up to the shortened end (a history's switches after it dropped, its event thresholds kept),
    so that it runs every kernel the whole problem runs."""
    t_end = problem.t_end * fraction
    hist = problem.loading.history
    kept = sum(1 for t in hist.switch_times if t < t_end)
    # the user's values were judged already; the short end time is not theirs
    with units_checked_already():
        if kept == len(hist.switch_times):
            return dataclasses.replace(problem, t_end=t_end)
        velocities = hist.velocities[:kept + 1]
        if not any(v > 0 for v in velocities):       # a run that opens with a hold
            velocities = velocities[:-1] + (hist.v_slow,)
        loading = dataclasses.replace(hist, velocities=velocities,
                                      switch_times=hist.switch_times[:kept],
                                      reference_velocity=hist.v_slow)
        return dataclasses.replace(problem, loading=loading, t_end=t_end)


def compile_ahead(problem: SpringSlider, algorithm: Algorithm, fraction: float = 1e-3,
                  wall_budget: float | None = None, sensitivity=None) -> None:
    """Run ``algorithm`` on :func:`short_piece` of ``problem``, unsaved, so that numba has
    compiled (or loaded from its cache) every kernel the run needs: the warm-up before any clock
    is read (three saved points: one between steps, from the dense output). ``wall_budget``
    bounds the piece's run, not its compiling (a budget is first checked after the kernels
    ran), so a setting that crawls cannot hang the warm-up. Its outcome is not looked at: the
    real run reports its own.

    Parameters
    ----------
    problem : SpringSlider
        The problem the real run will solve.
    algorithm : Algorithm
        The method and options the real run will use.
    fraction : float
        The part of the run the piece covers (dimensionless, default 1e-3).
    wall_budget : float, optional
        Bounds the piece's run, not its compiling (s).
    sensitivity : sequence of str, optional
        Compile the kernel with forward sensitivities too (as :func:`solve`'s).

    Raises
    ------
    ValueError
        As :func:`solve`, for arguments it refuses.
    """
    with warnings.catch_warnings():
        if sensitivity is not None:         # the real run says so, if its tolerance is loose
            warnings.filterwarnings("ignore", "sensitivity at rtol", UserWarning)
        solve(short_piece(problem, fraction), algorithm, max_points=3, wall_budget=wall_budget,
              sensitivity=sensitivity)


#: (method, its right-hand-side tier, law, with or without mass) compiled in this process by a
#: budgeted solve
_COMPILED: set = set()


#: the part of a run's wall budget its warm-up may spend running (not compiling)
WARM_UP_SHARE = 0.1


def _compile_once(problem: SpringSlider, algorithm: Algorithm, wall_budget: float,
                  sensitive: bool = False) -> None:
    key = (type(algorithm), getattr(algorithm, "rhs", None), type(problem.law),
           problem.quasi_static, sensitive)
    if key not in _COMPILED:
        _COMPILED.add(key)              # first: the warm-up's own budgeted solve skips this
        compile_ahead(problem, algorithm, wall_budget=WARM_UP_SHARE * wall_budget,
                      sensitivity=("b",) if sensitive else None)


def _solution(problem: SpringSlider, algorithm: Algorithm, raw: RawRun, directions=(),
              sensitivity_error: bool = True, settle: float = 0.0) -> Solution:
    """The Solution of ``raw``; a repeat of the run (``rerun``) takes its sensitivities'
    options too (with them in the step control, the steps are not the plain solve's), and
    its ``settle``."""
    again = (dict(sensitivity=tuple(d.name for d in directions),
                  sensitivity_error=sensitivity_error) if directions else {})
    if settle:
        again["settle"] = settle
    v, fs, theta = (raw.y[:, i] for i in range(3))
    ft = problem.friction(v, theta) if len(v) else np.empty(0)
    return Solution(problem=problem, algorithm=algorithm, t=raw.t, v=v, fs=fs, ft=ft, theta=theta,
                    event_array=np.asarray(raw.events, dtype=float).reshape(-1, len(EVENT_COLUMNS)),
                    stats=raw.stats, retcode=raw.retcode, message=raw.message,
                    meta=dict(raw.meta), sensitivity=raw.sensitivity,
                    rerun=functools.partial(_save_at, problem, algorithm, **again))


def _save_at(problem: SpringSlider, algorithm: Algorithm, times: np.ndarray,
             sensitivity=None, sensitivity_error: bool = True, settle=None) -> Solution:
    """The solve again, saving at ``times`` (:meth:`Solution.__call__`; a module-level function
    so that a Solution pickles), with the first solve's sensitivities and ``settle``."""
    with warnings.catch_warnings():     # the first solve said it, if its tolerance is loose
        warnings.filterwarnings("ignore", "sensitivity at rtol", UserWarning)
        return solve(problem, algorithm, save_at=times, sensitivity=sensitivity,
                     sensitivity_error=sensitivity_error, settle=settle)


def _progress_bar(problem: SpringSlider, algorithm: Algorithm):
    from tqdm.auto import tqdm

    class _Bar(tqdm):
        def update_to(self, t: float) -> None:
            self.update(min(t, problem.t_end) - self.n)

    return _Bar(total=problem.t_end, unit="s(sim)", desc=f"{algorithm.name} {problem.name}",
                bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} s simulated [{elapsed}<{remaining}]")
