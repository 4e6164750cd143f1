"""What every solve returns: trajectory, events, counters and a return code."""

from __future__ import annotations

import dataclasses
import enum
import functools
import numbers
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import numpy as np

from problems._validate import check_count, check_positive

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["ReturnCode", "Stats", "Solution", "EVENT_COLUMNS", "TRAJECTORY_UNITS", "Output",
           "RawRun", "DEFAULT_POINTS", "SAVE_LIMIT", "RunNotRepeated", "REPEAT_FACTOR",
           "REPEAT_CAP", "Sensitivity"]

#: points saved over a run when neither ``save_every`` nor ``max_points`` is given
DEFAULT_POINTS = 20_000
#: the most points ``save_every`` may save unless ``max_points`` allows more (~0.5 GB of arrays)
SAVE_LIMIT = 10_000_000

#: columns of :attr:`Solution.events`, one row per completed event, SI units.
#: ``slip_*`` is the slip since the start of the run; ``fs_max_before`` is the largest spring
#: force since the previous event ended, ``fs_min`` the smallest during the event.
EVENT_COLUMNS = ("t_start", "t_end", "fs_max_before", "fs_min", "v_peak", "t_peak",
                 "slip_start", "slip_end")


#: a repeated run (``sol(t)``) is the same run when each event agrees with the run's within
#: min(REPEAT_FACTOR · max(rtol, atol), REPEAT_CAP) relative (:meth:`Solution.repeats`)
REPEAT_FACTOR = 100.0
REPEAT_CAP = 0.1


class RunNotRepeated(ValueError):
    """``sol(t)`` asked a solve to repeat itself saving at other times, and the repeat is not
    the same run within its accuracy (:meth:`Solution.repeats` says what disagreed)."""


#: the columns of :meth:`Solution.to_dataframe` and their units (θ's is the law's:
#: ``problem.law.theta_unit``)
TRAJECTORY_UNITS = {"t": "s", "v": "m/s", "fs": "N", "ft": "N", "mu": "1", "theta": None}


class ReturnCode(enum.Enum):
    """Outcome of a solve. ``SUCCESS``: no failure; the run reached ``t_end``, or stopped on
    its settled cycle where it was asked to (``solve(..., settle=)``: ``Solution.settled_s``).
    The others stopped it."""

    SUCCESS = "Success"
    MAX_STEPS = "MaxSteps"            # the step budget ran out
    WALL_TIME = "WallTime"            # the wall-time budget ran out
    NON_FINITE = "NonFinite"          # a step produced NaN or inf
    STEP_UNDERFLOW = "StepUnderflow"  # the step size fell below what the library allows
    UNRESOLVED = "Unresolved"         # a fixed-step rule left its own validity (ETD: Eq. 53)
    FAILURE = "Failure"               # any other library failure (its message is kept)

    @property
    def success(self) -> bool:
        return self is ReturnCode.SUCCESS


@dataclass(frozen=True)
class Stats:
    """Cost counters, summed over restarts. ``nfev`` counts right-hand-side evaluations (for ETD:
    evaluations of the frozen coefficients, which cost the same as one right-hand side).

    A value: ``a + b`` sums every counter (a run's are its segments' summed), and
    ``dataclasses.replace`` sets one.

    Parameters
    ----------
    nfev : int
        Right-hand-side evaluations.
    njev : int
        Jacobian evaluations.
    steps : int
        Accepted steps.
    rejected : int
        Rejected steps (for ETD: steps redone).
    wall_s : float
        Wall time of the run (s).
    """

    nfev: int = 0
    njev: int = 0
    steps: int = 0
    rejected: int = 0
    wall_s: float = 0.0

    def __add__(self, other: Stats) -> Stats:
        if not isinstance(other, Stats):
            return NotImplemented
        return Stats(self.nfev + other.nfev, self.njev + other.njev, self.steps + other.steps,
                     self.rejected + other.rejected, self.wall_s + other.wall_s)

    def as_dict(self) -> dict:
        return {"nfev": self.nfev, "njev": self.njev, "steps": self.steps,
                "rejected": self.rejected, "wall_s": self.wall_s}


@dataclass(frozen=True)
class Output:
    """What to save of the trajectory: every ``save_every`` seconds, or else ``max_points`` in all
    (default :data:`DEFAULT_POINTS`), or exactly at the times ``save_at`` (s; increasing, within
    the run: a record's sample times). With ``save_every``, ``max_points`` caps the number of
    saved points (default :data:`SAVE_LIMIT`), so a typo cannot fill the memory.

    Events are always recorded exactly, whatever the decimation.

    Parameters
    ----------
    save_every : float, optional
        The save interval (s, positive).
    max_points : int, optional
        The saved points in all, or with ``save_every`` their cap (≥ 2).
    save_at : numpy.ndarray, optional
        The save times (s), increasing, within the run.

    Raises
    ------
    ValueError
        From :meth:`interval` and :meth:`times`, which check the options before any work: an
        interval that is not positive, fewer than 2 points, more than ``max_points``.
    """

    save_every: float | None = None
    max_points: int | None = None
    save_at: np.ndarray | None = None

    def interval(self, t_end: float) -> float:
        """The save interval in seconds (validates the options: call it before any work)."""
        if self.save_at is not None:
            raise ValueError("save_at saves at given times, not at an interval")
        if self.save_every is None:
            n = check_count("max_points", DEFAULT_POINTS if self.max_points is None
                            else self.max_points, minimum=2)
            return t_end / (n - 1)
        dt = check_positive("save_every", self.save_every)
        limit = check_count("max_points", SAVE_LIMIT if self.max_points is None
                            else self.max_points, minimum=2)
        if t_end / dt + 1 > limit:
            raise ValueError(f"save_every = {dt:g} s would save {t_end / dt + 1:.3g} points over "
                             f"t_end = {t_end:g} s, more than max_points = {limit}: save less "
                             "often, or raise max_points")
        return dt

    def times(self, t_end: float) -> np.ndarray:
        """The save times in seconds (validates the options: call it before any work). Computed
        once per ``t_end`` (an Output serves one solve: the array is handed out again)."""
        memo = self.__dict__.get("_times")
        if memo is not None and memo[0] == t_end:
            return memo[1]
        grid = self._times(t_end)
        self.__dict__["_times"] = (t_end, grid)     # a frozen dataclass: its memo goes round
        return grid

    def _times(self, t_end: float) -> np.ndarray:
        if self.save_at is None:
            dt = self.interval(t_end)
            n = int(np.floor(t_end / dt * (1.0 + 1e-12))) + 1
            grid = np.arange(n) * dt
            grid = grid[grid <= t_end]
            if grid[-1] < t_end * (1.0 - 1e-12):
                grid = np.append(grid, t_end)
            grid[-1] = t_end
            return grid
        if self.save_every is not None or self.max_points is not None:
            raise ValueError("save_at names the save times itself: give it without save_every "
                             "and max_points")
        try:
            times = np.asarray(self.save_at, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"save_at must be an array of times in s, got "
                             f"{type(self.save_at).__name__}") from None
        if times.ndim != 1 or not len(times):
            raise ValueError(f"save_at must be a non-empty 1-D array of times in s, got shape "
                             f"{times.shape}")
        if not np.isfinite(times).all():
            raise ValueError(f"save_at[{int(np.argmax(~np.isfinite(times)))}] is not finite")
        if (np.diff(times) <= 0).any():
            i = int(np.argmax(np.diff(times) <= 0)) + 1
            raise ValueError(f"save_at must increase: save_at[{i}] = {times[i]:.9g} s follows "
                             f"{times[i - 1]:.9g} s")
        if times[0] < 0 or times[-1] > t_end:
            bad = times[0] if times[0] < 0 else times[-1]
            raise ValueError(f"save_at holds t = {bad:.9g} s, outside the run (0 to t_end = "
                             f"{t_end:g} s)")
        return times.copy() if times is self.save_at else times


@dataclass
class Sensitivity:
    """Forward sensitivities of a solve (``solve(..., sensitivity=("b", "lc"))``): the
    derivatives of what it saved and of its events table with respect to each parameter of
    ``names``, in SI units per unit of the parameter (per m for lc, per N/m for stiffness).

    Parameters
    ----------
    names : tuple of str
        The parameters (:data:`problems.directions.SENSITIVE`).
    y : numpy.ndarray
        (len(t), 3, len(names)): ∂(v, fs, theta)/∂θ at the saved times, each at its fixed t.
    events : numpy.ndarray
        (events, len(EVENT_COLUMNS), len(names)): ∂(each column of the events table)/∂θ.
    message : str
        Why they are NaN from some point on (after an arrest), else empty. A failed run's
        appended stop point has NaN rows too. A repeat of the solve at other times
        (``sol(t)``, :meth:`Solution.resolved`) carries them at its times.
    """

    names: tuple
    y: np.ndarray
    events: np.ndarray
    message: str = ""

    def event_frame(self, name: str) -> pd.DataFrame:
        """∂(events table)/∂``name`` (its alias too): one row per event, the columns of
        :data:`EVENT_COLUMNS`."""
        import pandas as pd
        from problems.directions import ALIASES
        name = ALIASES.get(name, name)
        if name not in self.names:
            raise ValueError(f"no sensitivity to {name!r}; this solve has {self.names}")
        return pd.DataFrame(self.events[:, :, self.names.index(name)],
                            columns=list(EVENT_COLUMNS))


@dataclass
class RawRun:
    """What a backend hands back to :func:`integrators.core.solve`: SI arrays, counters, outcome."""

    t: np.ndarray
    y: np.ndarray              # shape (len(t), 3): columns v (m/s), Fs (N), θ
    events: np.ndarray         # shape (n, len(EVENT_COLUMNS))
    stats: Stats
    retcode: ReturnCode
    message: str = ""
    meta: dict = field(default_factory=dict)   # a method's own diagnostics (Solution.meta)
    sensitivity: "Sensitivity | None" = None   # forward sensitivities, when asked for


@dataclass
class Solution:
    """The result of :func:`integrators.core.solve`.

    Trajectory arrays are 1-D over saved times ``t`` (s): slip rate ``v`` (m/s), spring force
    ``fs`` (N), friction ``ft`` (N) and state ``theta`` (newtons for the slip law, seconds for
    the aging law). ``sol(t)`` is the run at other times (a DataFrame, from the method's
    dense output); ``to_dataframe()`` and ``plot()`` export and draw the saved trajectory.
    ``events`` is a DataFrame with :data:`EVENT_COLUMNS`, built when first read from
    ``event_array`` (the same table as a float array, one column per name: what a loop over
    many solves should read). ``meta`` holds a method's own diagnostics (the ETD family:
    ``step_rule_max``, the largest slip of a step over what its step rule allows).

    Parameters
    ----------
    problem : SpringSlider
        The problem solved.
    algorithm : Algorithm
        The method and its options.
    t : numpy.ndarray
        The saved times (s).
    v, fs, ft, theta : numpy.ndarray
        Slip rate (m/s), spring force (N), friction (N) and state (the law's unit) at ``t``.
    event_array : numpy.ndarray
        The events, one row each, one column per name of :data:`EVENT_COLUMNS` (SI units).
    stats : Stats
        The run's cost counters.
    retcode : ReturnCode
        The outcome.
    message : str
        What happened, in words (empty on success).
    meta : dict
        The method's own diagnostics.
    sensitivity : Sensitivity, optional
        Forward sensitivities, when the solve was asked for them.
    rerun : callable, optional
        Repeats the solve saving at given times (s); set by :func:`~integrators.solve`.
    """

    problem: object
    algorithm: object
    t: np.ndarray
    v: np.ndarray
    fs: np.ndarray
    ft: np.ndarray
    theta: np.ndarray
    event_array: np.ndarray
    stats: Stats
    retcode: ReturnCode
    message: str = ""
    meta: dict = field(default_factory=dict)
    #: the forward sensitivities, when the solve was asked for them (:class:`Sensitivity`)
    sensitivity: Sensitivity | None = None
    #: repeats this solve saving at given times (``rerun(times) -> Solution``): set by
    #: :func:`integrators.core.solve.solve`; None in a Solution built otherwise, which
    #: ``sol(t)`` then refuses
    rerun: Callable[[np.ndarray], Solution] | None = field(default=None, repr=False,
                                                            compare=False)

    @property
    def success(self) -> bool:
        return self.retcode.success

    @functools.cached_property
    def events(self) -> pd.DataFrame:
        """The events table, one row per completed event, columns :data:`EVENT_COLUMNS` (SI)."""
        import pandas as pd
        return pd.DataFrame(self.event_array, columns=list(EVENT_COLUMNS))

    @property
    def t_reached(self) -> float:
        return float(self.t[-1]) if len(self.t) else 0.0

    @property
    def reached_end(self) -> bool:
        """Did the run reach ``problem.t_end``? Only then may its events be read as physics
        (a failure or an exhausted budget stops it earlier: see ``retcode``); a run that
        stopped on its settled cycle did not (False), and says where (:attr:`settled_s`)."""
        return self.success and self.t_reached >= self.problem.t_end * (1.0 - 1e-9)

    @property
    def settled_s(self) -> float | None:
        """Where a run asked to stop on its settled cycle (``solve(..., settle=)``) stopped
        (s); None for one that ran to its end or failed. Its save points after the stop are
        not in it; the stop is, when save points were asked for after it."""
        return self.meta.get("settled_s") if self.success else None

    @property
    def mu(self) -> np.ndarray:
        """Friction coefficient shown in plots, μ = Fs/Fn."""
        return self.fs / self.problem.normal_force

    def __call__(self, t) -> pd.DataFrame:
        """The run at the times ``t``, from the method's own dense output: the solve is repeated
        with ``save_at=t`` and the values are its interpolant's at exactly t. Costs one solve:
        ask for all the times at once.

        The own methods take the same steps whatever they save; a library may not (SUNDIALS
        steps to each output time, and root brackets move with them), so the repeat is
        accepted when it is the same run within its accuracy (:meth:`repeats`).

        Parameters
        ----------
        t : float or array_like
            A time or an increasing array of times (s) within the run.

        Returns
        -------
        pandas.DataFrame
            As :meth:`to_dataframe` has it, one row per time.

        Raises
        ------
        ValueError
            For a method that saves at its own step ends (the ETD family: no dense output), a
            run that failed, a ``t`` that is not times, or one after where a settled run
            stopped.
        RunNotRepeated
            (a ``ValueError``) When the repeat is not the same run, saying which event and
            column disagreed.
        """
        try:
            times = np.atleast_1d(np.asarray(t, dtype=float))
        except (TypeError, ValueError):
            raise ValueError(f"sol(t): t must be a time or an array of times in s, got "
                             f"{t!r}") from None
        return self._at(times).to_dataframe()

    def _at(self, times: np.ndarray) -> Solution:
        """This run with its trajectory at ``times`` (:meth:`__call__`): events, counters and
        retcode are this run's."""
        if not self.algorithm.saves_at_times:
            raise ValueError(f"sol(t) needs a method with dense output; {self.algorithm.name} "
                             "saves at its own step ends (its solve's save_every sets them)")
        if not self.success:
            raise ValueError(f"sol(t) needs a successful run; this one ended {self.retcode.value}"
                             f" at t = {self.t_reached:.6g} s ({self.message})")
        if self.rerun is None:
            raise ValueError("sol(t) needs a Solution made by integrators.solve (this one was "
                             "built otherwise: it cannot repeat its run)")
        if (self.settled_s is not None and times.size and np.isfinite(times).all()
                and times.max() > self.settled_s):
            raise ValueError(f"sol(t): the run stopped on its settled cycle at t = "
                             f"{self.settled_s:.6g} s; t = {times.max():.6g} s is after it")
        again = self.rerun(times)
        why = self.repeats(again)
        if why:
            raise RunNotRepeated(f"sol(t): {self.algorithm.name} did not repeat its run when "
                                 f"saving at other times: {why}; read the saved trajectory "
                                 "(sol.t), or solve at a tighter rtol")
        return dataclasses.replace(self, t=again.t, v=again.v, fs=again.fs, ft=again.ft,
                                   theta=again.theta, meta=dict(self.meta),
                                   sensitivity=again.sensitivity)

    def resolved(self, per_event: int = 200) -> Solution:
        """This run at its saved times and ``per_event`` more across each completed event
        (:meth:`__call__`: the method's dense output), so that a figure draws a 10 ms event as
        a curve and not as the few saved points it spans.

        Parameters
        ----------
        per_event : int
            The times added across each event.

        Returns
        -------
        Solution
            The denser run; or this one as it is, for a run without events, by a method
            without dense output, or whose repeat is not the same run (:meth:`repeats`).

        Raises
        ------
        ValueError
            For a ``per_event`` that is not an integer ≥ 1.

        Warns
        -----
        RuntimeWarning
            When the repeat is not the same run, saying why.
        """
        per_event = check_count("per_event", per_event)
        ev = self.event_array
        if not len(ev) or not self.success or not self.algorithm.saves_at_times:
            return self
        fine = np.concatenate([np.linspace(a, b, per_event) for a, b in ev[:, :2]])
        times = np.union1d(self.t, fine)
        try:
            return self._at(times[(times >= 0.0) & (times <= self.problem.t_end)])
        except RunNotRepeated as exc:
            warnings.warn(f"the events are drawn from the saved points only, not resolved: "
                          f"{exc}", RuntimeWarning, stacklevel=2)
            return self

    def repeats(self, again: Solution) -> str:
        """Is ``again`` (this solve repeated, saving at other times) the same run?

        The same run: it succeeded, has as many events, and each event's
        times, peak slip rate, least spring force and slips agree with this run's within
        min(:data:`REPEAT_FACTOR` · max(rtol, atol), :data:`REPEAT_CAP`) relative (1e-9 for
        a method without tolerances). Two runs at one tolerance each lie within their error
        of the truth: the contract (tests/test_contract.py) accepts event starts 500·rtol
        from a reference; measured between repeats on W2 (10 s), at most 58·rtol
        (sundials-CVODE-BDF at 1e-3, the peak slip rate; 21·rtol at 1e-6; odes-CVODE-BDF
        15·rtol at 1e-9), scipy's Radau and LSODA within 2e-11, rounding in their root
        brackets. Every column is compared: the extremes of the spring force are read at
        roots, segment ends and step ends, never at save points (integrators/core/events.py),
        so a denser save grid cannot move them.

        Parameters
        ----------
        again : Solution
            This solve repeated, saving at other times.

        Returns
        -------
        str
            ``""`` if it is the same run, else what disagreed.
        """
        if not again.success:
            return (f"the repeat ended {again.retcode.value} at t = {again.t_reached:.6g} s "
                    f"({again.message})")
        mine, theirs = self.event_array, again.event_array
        if len(mine) != len(theirs):
            return f"{len(theirs)} events against the run's {len(mine)}"
        tols = [getattr(self.algorithm, k, None) for k in ("rtol", "atol")]
        tols = [float(x) for x in tols if isinstance(x, numbers.Real) and x > 0]
        tol = min(REPEAT_FACTOR * max(tols), REPEAT_CAP) if tols else 1e-9
        compared = list(range(len(EVENT_COLUMNS)))
        a, b = mine[:, compared], theirs[:, compared]
        with np.errstate(invalid="ignore"):
            off = np.abs(b - a) / np.maximum(np.maximum(np.abs(a), np.abs(b)),
                                             np.finfo(float).tiny)
        off[(a == b) | (np.isnan(a) & np.isnan(b))] = 0.0
        off[np.isnan(off)] = np.inf                  # a value against a NaN: not the same
        if not len(a) or not (off > tol).any():
            return ""
        i, j = np.unravel_index(int(np.argmax(off)), off.shape)
        return (f"event {i + 1} of {len(a)}: {EVENT_COLUMNS[compared[j]]} {b[i, j]:.9g} against "
                f"{a[i, j]:.9g} ({off[i, j]:.2g} relative, more than {tol:.2g})")

    def to_dataframe(self) -> pd.DataFrame:
        """The trajectory as a DataFrame: t (s), v (m/s), fs (N), ft (N), mu (Fs/Fn) and theta
        (N for the slip law, s for the aging law); ``attrs`` hold the units, the integrator,
        the problem and the retcode (Parquet keeps them; CSV does not)."""
        import pandas as pd
        df = pd.DataFrame({"t": self.t, "v": self.v, "fs": self.fs, "ft": self.ft,
                           "mu": self.mu, "theta": self.theta})
        df.attrs.update(units=dict(TRAJECTORY_UNITS, theta=self.problem.law.theta_unit),
                        integrator=self.algorithm.name, problem=self.problem.name or "",
                        retcode=self.retcode.value, message=self.message)
        return df

    def plot(self, path=None, resolve_events: bool = True):
        """A figure of the run: the slip rate (log) and μ against time, events marked.

        Parameters
        ----------
        path : str or os.PathLike, optional
            A file to write the figure to (.png, .pdf, .svg), or an open binary file.
        resolve_events : bool
            Draw each event from the dense output (:meth:`resolved`).

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ValueError
            For a ``path`` that is not a figure's file name, first, in one line.
        """
        from integrators.core.plotting import check_figure_path, plot_run
        check_figure_path(path)
        return plot_run(self.resolved() if resolve_events else self, path)

    def __repr__(self) -> str:
        return (f"Solution({type(self.algorithm).__name__} on {self.problem.name or 'problem'}: "
                f"{self.retcode.value}, t={self.t_reached:.6g} s, {len(self.event_array)} events, "
                f"{self.stats.steps} steps, {self.stats.nfev} rhs, {self.stats.wall_s:.3g} s)")
