"""The paper's exponential time differencing (ETD) integrators: ETD1, ETD2 and the iterated form.

Urata et al. (2017), Appendices 1–2 (slip law Eqs. 33–53, aging law Eqs. 63–69); the iteration
follows Noda & Lapusta (2010). Fixed rule for the step, not error-controlled (Eq. 53):

    Δτ = min(Δτmax, Δτcnst · vmax / v)

with the paper's Δτmax = 0.01, Δτcnst = 1e−5, vmax = 0.05 m/s as defaults. The slip per step is
then at most Δτcnst·vmax/v0 critical distances.

What a user must know (docs/etd.md explains each, with what was measured):

* order reduction: on the stick–slip problem ETD2 converges at first order (η sits on its slow
  manifold and the starred η* lags by one step); ``ETDIterated(n_iterations=2)`` removes the lag;
* an error floor proportional to the slider's mass (w/D), ~3–4·10⁻⁷ in the recurrence interval
  on the paper example: below ~1e−6 ``ETDIterated`` does not improve (``stiff_order = 0``);
* validity — no event is stepped over unseen. Three guards, each for one way a frozen step can
  run over dynamics it does not resolve:

  - the slip a step may take (Eq. 53: Δτcnst·vmax/v0 critical distances) is refused above
    ``SLIP_PER_STEP_MAX`` = 0.5 Lc, ten times the paper's 0.05 Lc (``check_problem``, before
    any work; the work-precision ladder's coarsest setting, 8×, stays accepted). Measured on
    the paper example and W1–W4 under both laws: up to 0.5 Lc the events are the reference's
    (first-order timing drift for ETD1); at 1 Lc ETD2 stops ``Unresolved``; from 2.5 Lc runs
    report Success with events invented (W1: 125 for 7) or none;
  - the load a step may take: Eq. 53 bounds the slip of a step, not the spring's loading while
    the slider sticks (w ≪ E), where only Δτmax bounds the step — a huge Δτmax let one frozen
    step load the spring through a whole nucleation. So each step also changes the spring force
    by at most ``load_max`` (0.1) times A = a·Fn: s·(C/D)·|E − w| ≤ ``load_max`` (C/D = k Lc/A;
    ln w follows the spring force in units of A, so 0.1 is a 10 % change of the slip rate the
    frozen step cannot see). The paper's problems at the paper's settings take at most 0.04 A a
    step, so their steps are unchanged; ``Solution.meta["load_bound_steps"]`` counts the steps
    the bound shortened. With it, any Δτmax (up to 1e6 measured) finds the reference's events;
  - every step checks Eq. 53 at the fastest state it evaluated; a step that exceeds
    ``rule_ratio_max`` (100) stops the run with retcode ``Unresolved`` (a runaway within one
    step: a start out of force balance, strong weakening);
  - the step at steady sliding, at each load-point speed v (where a run starts and sits
    between events; there w = E, so the load bound lapses): it may neither let steady sliding's
    instability grow by more than ``GROWTH_PER_STEP_MAX`` = 0.5 e-folds
    (:func:`problems.stability.growth_rate`), nor slip more than ``RELAX_PER_STEP_MAX`` = 0.5
    times a·Fn/k (the slip over which the spring sheds the direct effect's a·Fn: a step of it
    relaxes η and moves h with the other frozen). ``check_problem`` refuses before any work,
    naming the option and the largest value that passes. The case that needed it: the paper
    example at a = 1e−6 (t_end = 1 s; the reference, scipy Radau and Rodas5P at 1e−10, has one
    event peaking at 0.1623 m/s at 6.12 ms): the first step, of 0.99 e-folds and 3.7 a·Fn/k,
    sent w from E down to 0.36 E (ETD1) or 0.019 E (ETDIterated), the slider stuck, and both
    reported Success with no event (w never rose, so the step-rule check saw nothing; ETD2's
    single correction happened to land above E). On the presets at every accepted setting the
    largest values are 0.074 e-folds (W4/slip, both options 8×) and 0.2 a·Fn/k (the lab's
    velocity step with mass); with only one of the two bounds, the case runs unseen (0.5
    e-folds alone still lets ETD1 and ETDIterated report no event). Past the refusal, ETD1 is
    still far off there (peak 0.050 m/s at the largest accepted Δτcnst, 0.080 at 1e−7: first
    order with a constant ∝ 1/a), ETD2 and ETDIterated within 1.5 %.

  What remains is accuracy, judged against a reference: ETD1 and ETD2 are first order in the
  stick phase, so coarse settings shift event times. Measured on the presets (windows of 3–7
  events, Rodas5P at 1e−9): with either option at the paper's value and the other anywhere it
  is accepted, the first event and every recurrence interval within 0.28 (ETD1), 0.041 (ETD2),
  0.016 (ETDIterated) relative; over whole runs more (ETD1 at Δτcnst = 1e−4: W4/aging's first
  event 0.36 off). Both coarse at once (Δτcnst = 1e−4 and Δτmax = 1e6: stick steps of
  0.5 Lc/w) is worse: ETD2 up to 0.13 on those windows (W3/aging) and 0.29 over a whole W1/aging
  run (its limit cycle's recurrence 16 % long), and on W1/aging one event of seven drifts past
  the window (ETD1 too, and on W1/slip); ETDIterated within 0.041. No step is stepped over
  there either: the events are the reference's, late;
* a tiny Δτcnst (1e−300: steps of 1e−297) is no failure of the scheme but of the budget: the run
  stops at ``max_steps`` with retcode ``MaxSteps`` (at the default 2·10⁸ steps, minutes).

The compiled loop is in :mod:`integrators.own.etd_kernel`; this module holds the options and
drives the loop in chunks.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from integrators.core.cache import announce_compile
from integrators.core.registry import Algorithm, ProblemNotSupported, register
from integrators.core.solution import RawRun, ReturnCode, Stats
from integrators.own import etd_kernel as K
from problems._validate import check_count, check_positive
from problems.formulations import form_vector
from problems.loading import event_thresholds

__all__ = ["ETD1", "ETD2", "ETDIterated"]

_CHUNK_STEPS = 100_000        # steps between returns to Python (progress, budgets)
_EVENT_BUFFER = 4_096
_SAVE_BUFFER_MAX = 65_536
#: the most a step may slip under the rule, in Lc (dtau_cnst · v_max/v0; the paper's 0.05 Lc for
#: v0 = 10 µm/s): module docstring, "validity"
SLIP_PER_STEP_MAX = 0.5
#: the most steady sliding's instability may grow in one step of the rule at a load-point
#: speed, in e-folds (module docstring, "validity")
GROWTH_PER_STEP_MAX = 0.5
#: the most a step of the rule at a load-point speed may slip, in units of a·Fn/k (the slip over
#: which the spring sheds the direct effect's a·Fn: module docstring, "validity")
RELAX_PER_STEP_MAX = 0.5


@dataclass(frozen=True)
class _ETD(Algorithm):
    """Options shared by the ETD family: the step rule of Eq. 53, the check of its validity
    (``rule_ratio_max``: the slip of a step, at the fastest state it evaluated, over what the
    rule allows), the loading bound (``load_max``: the spring force a step may add, in units of
    A = a·Fn; module docstring) and a step budget."""

    dtau_max: float = 0.01
    dtau_cnst: float = 1e-5
    v_max: float = 0.05
    max_steps: int = 200_000_000
    rule_ratio_max: float = 100.0
    load_max: float = 0.1

    family: ClassVar[str] = "exponential time differencing"
    adaptive: ClassVar[bool] = False
    saves_at_times: ClassVar[bool] = False
    library: ClassVar[str] = "rsfbench (numba)"
    package: ClassVar[str] = "own"
    kind: ClassVar[str] = "exponential"
    compiled: ClassVar[bool] = True
    n_iter: ClassVar[int] = 1

    def __post_init__(self) -> None:
        check_positive("dtau_max", self.dtau_max)
        check_positive("dtau_cnst", self.dtau_cnst)
        check_positive("v_max", self.v_max)
        check_count("max_steps", self.max_steps)
        if not check_positive("rule_ratio_max", self.rule_ratio_max) >= 1.0:
            raise ValueError(f"rule_ratio_max must be at least 1 (the rule itself), got "
                             f"{self.rule_ratio_max!r}")
        check_positive("load_max", self.load_max)

    @classmethod
    def library_version(cls) -> str:
        import numba
        return f"numba {numba.__version__}"

    def iterations(self) -> int:
        return self.n_iter

    def check_problem(self, problem) -> None:
        if problem.quasi_static:
            raise ProblemNotSupported(
                f"{self.name} needs a slider with mass: the paper's ETD relaxes the friction η on "
                "the inertial time scale w/D (D = A Lc/(m v0²)), which has no meaning at m = 0 "
                "(the quasi-static limit); use an adaptive method (Rodas5P, CVODE, LSODA)")
        v0 = problem.law.v0
        slip = self.dtau_cnst * self.v_max / v0
        if slip > SLIP_PER_STEP_MAX * (1 + 1e-9):      # the bound itself is allowed
            raise ProblemNotSupported(
                f"dtau_cnst = {self.dtau_cnst!r} lets a step of {problem.name} slip {slip:.3g} Lc "
                f"(dtau_cnst * v_max/v0, v_max = {self.v_max!r} m/s, v0 = {v0!r} m/s); a "
                f"frozen-coefficient step resolves at most {SLIP_PER_STEP_MAX:g} Lc (beyond it "
                f"events are missed or invented): dtau_cnst must be at most "
                f"{SLIP_PER_STEP_MAX * v0 / self.v_max:.3g} here (nondimensional time v0 t/Lc), "
                "or v_max smaller")
        try:
            refusal = _steady_refusal(self, problem)
        except TypeError:                   # a problem that does not hash: no memo
            refusal = self.steady_refusal(problem)
        if refusal:
            raise ProblemNotSupported(refusal)

    def steady_steps(self, problem) -> list[tuple[float, float, float, float]]:
        """One step of the rule at steady sliding at each load-point speed v of ``problem``
        (where a run starts and sits between events; the loading bound does not shorten a step
        there, w = E): rows (v in m/s, the step in units of v0 t/Lc, the e-folds steady
        sliding's fastest mode grows over it (:func:`problems.stability.growth_rate`), its slip
        in units of a·Fn/k)."""
        from problems.stability import growth_rate
        law, hist = problem.law, problem.loading.history
        relax = law.a * problem.normal_force / (problem.stiffness * law.lc)   # a·Fn/k in Lc
        rows = []
        for v in sorted({x for x in (*hist.velocities, hist.overshoot_velocity) if x > 0}):
            dt = min(self.dtau_max, self.dtau_cnst * self.v_max / v)         # Eq. 53, w = v/v0
            rows.append((v, dt, growth_rate(problem, v) * dt * law.lc / law.v0,
                         dt * v / law.v0 / relax))
        return rows

    def steady_refusal(self, problem) -> str:
        """Why a step of the rule at steady sliding (:meth:`steady_steps`) is too long for
        ``problem`` (module docstring, "validity"), naming the option to lower and the largest
        value that works; "" when it is not."""
        law = problem.law
        worst = None
        for v, dt, growth, relax in self.steady_steps(problem):
            for amount, bound, what in (
                    (growth, GROWTH_PER_STEP_MAX, "steady sliding's instability grows by "
                     f"{growth:.3g} e-folds over it (problems.stability.growth_rate)"),
                    (relax, RELAX_PER_STEP_MAX, f"it slips {relax:.3g} times "
                     f"{law.a * problem.normal_force / problem.stiffness:.3g} m (a·Fn/k), the "
                     "slip over which the direct effect relaxes")):
                if not amount > bound * (1 + 1e-9):   # the bound itself is allowed (and NaN)
                    continue
                dt_ok = dt * bound / amount
                name, value, limit = (("dtau_max", self.dtau_max, dt_ok) if dt == self.dtau_max
                                      else ("dtau_cnst", self.dtau_cnst,
                                            dt_ok * v / self.v_max))
                if worst is None or limit / value < worst[0]:
                    worst = (limit / value, name, value, limit, v, dt, what, bound)
        if worst is None:
            return ""
        _, name, value, limit, v, dt, what, bound = worst
        return (f"{name} = {value!r} lets a step of {problem.name} at steady sliding at "
                f"v = {v:.4g} m/s (a load-point speed) last {dt * law.lc / law.v0:.3g} s: {what}; "
                f"a frozen-coefficient step resolves at most {bound:g} (beyond it a step can leap "
                f"over an event and report none): {name} must be at most {_down(limit):.3g} here "
                "(nondimensional time v0 t/Lc), or use an adaptive method (Rodas5P)")

    def run(self, problem, output, budget, progress) -> RawRun:
        nd = problem.nondimensional()
        v0 = problem.law.v0
        w_start, w_end = (v / v0 for v in event_thresholds(problem.loading))
        p = np.concatenate([form_vector(nd, nd.e_slow),
                            [nd.tau_end, w_start, w_end, float(nd.two_speed)], nd.history])
        save_dtau = output.interval(problem.t_end) / nd.time_scale
        o = np.array([self.dtau_max, self.dtau_cnst, self.v_max / v0, self.iterations(), save_dtau,
                      self.rule_ratio_max, self.load_max])
        st = K.initial_loop_state(nd.x0, save_dtau)
        n_save = min(_SAVE_BUFFER_MAX, int(math.ceil(nd.tau_end / save_dtau)) + 2)
        save_buf, ev_buf = np.empty((n_save, 4)), np.empty((_EVENT_BUFFER, K.E_SIZE))
        saved, events = [np.concatenate(([0.0], nd.x0))[None, :]], []
        retcode, message = ReturnCode.SUCCESS, ""
        announce_compile(K.etd_advance, "the ETD kernel")
        while True:
            chunk = int(min(_CHUNK_STEPS, self.max_steps - st[K.S_STEPS]))
            status = K.etd_advance(st, p, o, save_buf, ev_buf, max(chunk, 0))
            saved.append(save_buf[: int(st[K.S_NSAVED])].copy())
            events.append(ev_buf[: int(st[K.S_NEVENTS])].copy())
            st[K.S_NSAVED] = st[K.S_NEVENTS] = 0
            if progress:
                progress(st[K.S_TAU] * nd.time_scale)
            if status == K.DONE:
                break
            if status == K.NONFINITE:
                retcode = ReturnCode.NON_FINITE
                message = (f"a step from t = {st[K.S_TAU] * nd.time_scale:.9g} s produced a "
                           "non-finite value")
                break
            if status == K.STEP_RULE:
                retcode = ReturnCode.UNRESOLVED
                message = (f"the step from t = {st[K.S_TAU] * nd.time_scale:.9g} s slipped "
                           f"{st[K.S_RULE]:.3g} times what its step rule (Eq. 53) allows, at the "
                           "fastest state it evaluated: the scheme runs over dynamics it cannot "
                           "resolve at these settings (it can step over an event); use smaller "
                           "dtau_cnst and dtau_max, or an adaptive method")
                break
            if status == K.STALLED:
                retcode = ReturnCode.STEP_UNDERFLOW
                message = (f"the step from t = {st[K.S_TAU] * nd.time_scale:.9g} s is too short "
                           "to advance t in floating point (a slip rate near overflow)")
                break
            if st[K.S_STEPS] >= self.max_steps:
                retcode, message = ReturnCode.MAX_STEPS, f"step budget of {self.max_steps} used up"
                break
            if budget.exceeded():
                retcode = ReturnCode.WALL_TIME
                message = f"wall-time budget of {budget.wall_s} s used up"
                break
        traj = np.concatenate(saved)
        if traj[-1, 0] < st[K.S_TAU]:
            traj = np.vstack([traj, [st[K.S_TAU], st[K.S_H], st[K.S_ETA], st[K.S_PSI]]])
        steps = int(st[K.S_STEPS])
        stats = Stats(nfev=int(st[K.S_EVALS]), steps=steps, rejected=int(st[K.S_REDONE]))
        return RawRun(t=traj[:, 0] * nd.time_scale,
                      y=np.column_stack(problem.dimensional_state(traj[:, 1], traj[:, 2], traj[:, 3])),
                      events=_events_si(problem, nd, np.concatenate(events)),
                      stats=stats, retcode=retcode, message=message,
                      meta={"step_rule_max": float(st[K.S_RULE_MAX]),
                            "load_bound_steps": int(st[K.S_LOAD_BOUND])})


@functools.lru_cache(maxsize=256)
def _steady_refusal(algorithm: _ETD, problem) -> str:
    # ~0.2 ms of polynomial roots, once per (options, problem): a sweep re-solves the same pair
    return algorithm.steady_refusal(problem)


def _down(x: float) -> float:
    """``x`` rounded down to three significant digits (a limit quoted must pass its check)."""
    unit = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.floor(x / unit) * unit


def _events_si(problem, nd, ev: np.ndarray) -> np.ndarray:
    """Event records of the kernel (nondimensional) in the columns of ``EVENT_COLUMNS``."""
    ts, f0, kl, lc = nd.time_scale, problem.f0, nd.force_h, problem.law.lc
    h0 = nd.x0[0]   # the kernel's slip is load − h; slip since the start is load − (h − h0)
    return np.column_stack([
        ev[:, K.E_TAU_START] * ts, ev[:, K.E_TAU_END] * ts,
        f0 + kl * ev[:, K.E_HMAX], f0 + kl * ev[:, K.E_HMIN],
        problem.law.v0 * ev[:, K.E_WPEAK], ev[:, K.E_TAU_PEAK] * ts,
        lc * (ev[:, K.E_SLIP_START] + h0), lc * (ev[:, K.E_SLIP_END] + h0),
    ])


@register
@dataclass(frozen=True)
class ETD1(_ETD):
    """First-order ETD: one step with coefficients frozen at its start (the starred values,
    Eqs. 33–41). Order 1, fixed step rule (Eq. 53).

    Parameters
    ----------
    dtau_max : float
        Δτmax of the step rule Δτ = min(Δτmax, Δτcnst·vmax/v), in τ = v0 t/Lc (default 0.01).
    dtau_cnst : float
        Δτcnst of the step rule, in τ (default 1e-5).
    v_max : float
        vmax of the step rule (m/s, default 0.05).
    max_steps : int
        The step budget over the whole solve (retcode ``MaxSteps`` when used up).
    rule_ratio_max : float
        A step's slip over what Eq. 53 allows, at the fastest state it evaluated, above which
        the run stops ``Unresolved`` (≥ 1, default 100).
    load_max : float
        The spring force a step may add, in units of A = a·Fn (default 0.1).

    Raises
    ------
    ValueError
        For an option out of range (at construction); :class:`ProblemNotSupported` from
        :func:`~integrators.solve` for a problem without mass, or a step that would slip more
        than 0.5 Lc or be too long at steady sliding.
    """

    name: ClassVar[str] = "ETD1"
    order: ClassVar[int] = 1
    n_iter: ClassVar[int] = 0


@register
@dataclass(frozen=True)
class ETD2(_ETD):
    """The paper's second-order ETD: half a step with the coefficients at the start, half with
    them re-evaluated at the first-order end values (Eqs. 42–52). Order 2 when the fast mode
    is resolved, order 1 on the stiff stick–slip problem (see the module docstring).

    Parameters
    ----------
    dtau_max : float
        Δτmax of the step rule Δτ = min(Δτmax, Δτcnst·vmax/v), in τ = v0 t/Lc (default 0.01).
    dtau_cnst : float
        Δτcnst of the step rule, in τ (default 1e-5).
    v_max : float
        vmax of the step rule (m/s, default 0.05).
    max_steps : int
        The step budget over the whole solve (retcode ``MaxSteps`` when used up).
    rule_ratio_max : float
        A step's slip over what Eq. 53 allows, at the fastest state it evaluated, above which
        the run stops ``Unresolved`` (≥ 1, default 100).
    load_max : float
        The spring force a step may add, in units of A = a·Fn (default 0.1).

    Raises
    ------
    ValueError
        For an option out of range (at construction); :class:`ProblemNotSupported` from
        :func:`~integrators.solve` for a problem without mass, or a step that would slip more
        than 0.5 Lc or be too long at steady sliding.
    """

    name: ClassVar[str] = "ETD2"
    order: ClassVar[int] = 2
    stiff_order: ClassVar[int] = 1
    n_iter: ClassVar[int] = 1


@register
@dataclass(frozen=True)
class ETDIterated(_ETD):
    """Iterated ETD (Noda & Lapusta 2010): the second half-step re-evaluated ``n_iterations``
    times at the newest end-of-step estimate. ``n_iterations`` = 1 is ETD2. Order 2 when the
    fast mode is resolved. On the stiff stick–slip problem ``n_iterations`` >= 2 removes ETD2's
    one-step lag (errors ~70× smaller at the paper's steps, 1 + ``n_iterations`` evaluations
    per step) but meets the frozen-target error floor (module docstring): no asymptotic order
    there, ``stiff_order = 0``.

    Parameters
    ----------
    dtau_max : float
        Δτmax of the step rule Δτ = min(Δτmax, Δτcnst·vmax/v), in τ = v0 t/Lc (default 0.01).
    dtau_cnst : float
        Δτcnst of the step rule, in τ (default 1e-5).
    v_max : float
        vmax of the step rule (m/s, default 0.05).
    max_steps : int
        The step budget over the whole solve (retcode ``MaxSteps`` when used up).
    rule_ratio_max : float
        A step's slip over what Eq. 53 allows, at the fastest state it evaluated, above which
        the run stops ``Unresolved`` (≥ 1, default 100).
    load_max : float
        The spring force a step may add, in units of A = a·Fn (default 0.1).
    n_iterations : int
        How many times the second half-step is re-evaluated (≥ 1; default 2).

    Raises
    ------
    ValueError
        For an option out of range (at construction); :class:`ProblemNotSupported` from
        :func:`~integrators.solve` for a problem without mass, or a step that would slip more
        than 0.5 Lc or be too long at steady sliding.
    """

    n_iterations: int = 2

    name: ClassVar[str] = "ETDIterated"
    order: ClassVar[int] = 2
    stiff_order: ClassVar[int] = 0      # an error floor ∝ mass, not a convergence order

    def __post_init__(self) -> None:
        super().__post_init__()
        check_count("n_iterations", self.n_iterations)

    def iterations(self) -> int:
        return int(self.n_iterations)
