"""Assimulo's solvers (``assimulo-testing``) on the shared ODE form, and IDA on the DAE form.

CVode (SUNDIALS BDF, analytic Jacobian), IDA (DAE form, analytic iteration matrix), Radau5ODE,
LSODAR, RodasODE and Dopri5. Events use assimulo's own state-event machinery (``state_events``
returns the four root functions of :mod:`integrators.core.events`, the solver calls
``handle_event``); LSODAR's root info has no direction, so its directions come from
:func:`integrators.core.segments.directional_roots`.

``simulate`` is assimulo's only entry point that runs its event handling, and each call
re-initialises the solver; so each loading segment is ONE ``simulate(t_bound)`` run as a
coroutine in a helper thread (``report_continuously``), answering the driver's output times from
the solver's dense output after every step; the threads take turns. Counters are
``get_statistics()`` summed over segments; ``max_steps`` and the wall budget are checked after
every step. Why so, and the library's quirks (its SUNDIALS 2.7.0, output that cannot be turned
off, LSODAR stuck in Adams after a restart at u' = 0): docs/external-adapters.md.
"""

from __future__ import annotations

import importlib.metadata
import queue
import re
import threading
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from assimulo import solvers as _solvers
from assimulo.exception import TerminateSimulation
from assimulo.problem import Explicit_Problem, Implicit_Problem
from assimulo.solvers.sundials import get_sundials_version

from integrators.core.events import RootFunctions
from integrators.core.registry import AdaptiveAlgorithm, register
from integrators.core.segments import Advance, directional_roots
from integrators.core.solution import ReturnCode, Stats
from problems.formulations import DaeForm, OdeForm, dae_differential, dae_initial

__all__ = ["AssimuloCVode", "AssimuloIDA", "AssimuloRadau5ODE", "AssimuloLSODAR",
           "AssimuloRodasODE", "AssimuloDopri5"]

_VERSION = importlib.metadata.version("assimulo-testing")
_STOP = None            # the request that ends a segment
_QUIET = 50
#: an exact zero of a root function is handed over as this (counted positive): at steady
#: sliding u − ln E is 0.0 to the bit, and LSODAR stops on a root at its initial point ("too
#: near to the initial point", flag −3), SUNDIALS on a root "at and very near" t
_TINY = 1e-300


def _nonzero(g: np.ndarray) -> np.ndarray:
    g[g == 0.0] = _TINY
    return g


@dataclass(frozen=True)
class _Assimulo(AdaptiveAlgorithm):
    """Options of every assimulo backend: those of :class:`AdaptiveAlgorithm`."""

    library: ClassVar[str] = "assimulo"
    package: ClassVar[str] = "assimulo"
    solver: ClassVar[str] = ""                 # class name in assimulo.solvers
    uses_jacobian: ClassVar[bool] = True
    root_directions: ClassVar[bool] = True     # does the event info carry the direction?

    @classmethod
    def library_version(cls) -> str:
        return f"assimulo {_VERSION}"

    def make_stepper(self, nd, budget):
        return _AssimuloStepper(self, nd, budget)

    def make_solver(self, nd, e, tau0, z0, link, steps_left: int):
        """The assimulo solver of one segment, its problem calling back into ``link``."""
        if self.dae:
            y0, yp0 = dae_initial(nd, e, np.asarray(z0, float))
            prob = _DaeProblem(DaeForm(nd, e, self.rhs), nd, e, link, y0, yp0, tau0)
        else:
            prob = _OdeProblem(OdeForm(nd, e, self.rhs), nd, e, link, z0, tau0)
        sim = getattr(_solvers, self.solver)(prob)
        sim.verbosity = _QUIET
        sim.display_progress = False
        sim.store_event_points = False
        sim.report_continuously = True
        sim.rtol = self.rtol
        sim.atol = self.atol
        # the budget is our count of accepted steps (``after_step``); the library's own limit
        # counts attempted steps per call and is only a backstop against endless rejections
        sim.maxsteps = int(min(10 * steps_left + 1000, 2**31 - 1))
        if self.uses_jacobian:
            sim.usejac = True
        if self.dae:
            sim.algvar = dae_differential(nd)
        return sim


class _Callbacks:
    """The problem's side of the segment protocol: assimulo calls these, ``link`` answers."""

    def step_events(self, solver):
        return self.link.after_step(solver)

    def handle_event(self, solver, event_info):
        self.link.on_event(solver, event_info)


class _OdeProblem(_Callbacks, Explicit_Problem):
    """z' = f(z) with the four root functions; results are not stored (see the module doc)."""

    def __init__(self, form, nd, e, link, z0, tau0):
        super().__init__(y0=np.array(z0, float), t0=float(tau0))
        self.form, self.nd, self.e, self.link = form, nd, e, link
        self.roots = RootFunctions(nd, e)

    def rhs(self, t, y, sw=None):
        return self.form.f(t, y)

    def jac(self, t, y, sw=None):
        return self.form.jac(t, y)

    def state_events(self, t, y, sw=None):
        return _nonzero(self.roots(y))

    def handle_result(self, solver, t, y):
        pass


class _DaeProblem(_Callbacks, Implicit_Problem):
    """F(y, y') = 0 of the DAE form, y = (h, u, s, η); the root functions read (h, u, s)."""

    def __init__(self, form, nd, e, link, y0, yp0, tau0):
        super().__init__(y0=y0, yd0=yp0, t0=float(tau0))
        self.form, self.nd, self.e, self.link = form, nd, e, link
        self.roots = RootFunctions(nd, e)

    def res(self, t, y, yd, sw=None):
        out = np.empty(4)
        self.form.residual(t, y, yd, out)
        return out

    def jac(self, c, t, y, yd, sw=None):
        out = np.empty((4, 4))
        self.form.jacobian(t, y, c, out)
        return out

    def state_events(self, t, y, yd, sw=None):
        return _nonzero(self.roots(y[:3]))

    def handle_result(self, solver, t, y, yd):
        pass


class _AssimuloStepper:
    """The segment protocol over one ``simulate`` per segment, run in a helper thread.

    Main thread: ``start``/``advance``/``finish`` post requests (a ``t_out`` or ``_STOP``) and
    wait for the reply. Helper thread: ``simulate`` and the problem's callbacks
    (``after_step``, ``on_event``), which answer requests and block for the next one.
    """

    def __init__(self, algorithm: _Assimulo, nd, budget=None):
        self.algorithm, self.nd, self.budget = algorithm, nd, budget
        self.stats = Stats()           # the finished simulations' counters
        self.steps = 0                 # accepted steps over the whole solve (the budget)
        self._thread = None

    # --- main thread ---------------------------------------------------------------------
    def start(self, tau0, z0, e, t_bound):
        self.finish()
        self._e, self._t_bound = e, t_bound
        self._end = Advance(tau0, np.array(z0, float))
        self._sim = self.algorithm.make_solver(self.nd, e, tau0, z0, self,
                                               self.algorithm.max_steps - self.steps)
        self._requests, self._replies = queue.SimpleQueue(), queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"{self.algorithm.name} segment")
        self._thread.start()

    def advance(self, t_out):
        self._requests.put(float(t_out))
        while True:
            try:
                return self._replies.get(timeout=1.0)
            except queue.Empty:
                if not self._thread.is_alive():
                    return Advance(self._end.tau, self._end.z, retcode=ReturnCode.FAILURE,
                                   message="assimulo helper thread ended without an answer")

    def finish(self):
        if self._thread is not None:
            self._requests.put(_STOP)
            self._thread.join()
            self._thread = None
            self._sim = None

    # --- helper thread -------------------------------------------------------------------
    def _reply(self, adv: Advance) -> None:
        """Answer the pending request, then wait for the next one (``self._t_out``)."""
        self._end = adv
        self._replies.put(adv)
        self._t_out = self._requests.get()

    def _serve(self, sim, t, z) -> bool:
        """Answer every pending ``t_out`` ≤ t from the last step's dense output; True = stop."""
        tiny = 1e-12 * max(1.0, abs(t))
        while self._t_out is not _STOP and self._t_out <= t + tiny:
            t_out = self._t_out
            z_out = z if t_out >= t - tiny else np.array(sim.interpolate(t_out)[:3])
            self._reply(Advance(t_out, z_out))
        return self._t_out is _STOP

    def after_step(self, sim) -> bool:
        """``step_events``: called after every accepted step; True stops the solver."""
        self.steps += 1
        z = np.array(sim.y[:3])
        if self._serve(sim, sim.t, z):
            return True
        if self.steps >= self.algorithm.max_steps:
            code = ReturnCode.MAX_STEPS
            message = f"step budget of {self.algorithm.max_steps} used up"
        elif self.budget is not None and self.budget.exceeded():
            # checked here too: a solver creeping with tiny steps may never reach the next t_out
            ts = self.nd.time_scale
            code, message = ReturnCode.WALL_TIME, (
                f"wall-time budget of {self.budget.wall_s} s used up at t = {sim.t * ts:.6g} s "
                f"of {self.nd.tau_end * ts:g} s")
        else:
            return False
        while self._t_out is not _STOP:
            self._reply(Advance(sim.t, z, retcode=code, message=message))
        return True

    def on_event(self, sim, event_info) -> None:
        """``handle_event``: a located root (or the stop that ``after_step`` asked for)."""
        if self._t_out is _STOP:
            raise TerminateSimulation
        info = list(event_info[0])
        found = [k for k, v in enumerate(info) if v != 0]
        if not found:
            return
        z = np.array(sim.y[:3])
        signs = [int(np.sign(info[k])) for k in found] if self.algorithm.root_directions else None
        counted = directional_roots(self.nd, self._e, z, found, signs)
        if counted:
            self._reply(Advance(sim.t, z, roots=counted))
            if self._serve(sim, sim.t, z):
                raise TerminateSimulation
        # assimulo now re-initialises the solver at the root and continues

    def _run(self):
        sim = self._sim
        self._t_out = self._requests.get()
        if self._t_out is _STOP:
            return
        try:
            sim.simulate(self._t_bound)
        except Exception as exc:       # a library failure: a result, not a crash
            if self._t_out is not _STOP:
                self._reply(_failure(exc, sim))
        finally:
            self._count(sim)
        while self._t_out is not _STOP:   # ended without a stop request: answer from the end
            t, z = self._end.tau, self._end.z
            if self._end.retcode is ReturnCode.SUCCESS and self._t_out > t + 1e-12 * max(1, t):
                self._reply(Advance(t, z, retcode=ReturnCode.FAILURE,
                                    message=f"simulate ended at tau = {t:.9g} before "
                                            f"tau = {self._t_out:.9g}"))
            else:
                self._reply(self._end)

    def _count(self, sim):
        st = sim.get_statistics()
        self.stats += Stats(nfev=int(st["nfcns"] + st["nfcnjacs"]), njev=int(st["njacs"]),
                            steps=int(st["nsteps"]),
                            rejected=int(st["nerrfails"] + st["nnfails"]))


#: library failure codes → return codes (CVODE/IDA flags, RADAU5/DOPRI5/RODAS IDID, LSODAR ISTATE)
_CODES = {"CVodeError": {-1: ReturnCode.MAX_STEPS, -3: ReturnCode.STEP_UNDERFLOW},
          "IDAError": {-1: ReturnCode.MAX_STEPS, -3: ReturnCode.STEP_UNDERFLOW},
          "Radau5Error": {-2: ReturnCode.MAX_STEPS, -3: ReturnCode.STEP_UNDERFLOW},
          "Dopri5": {-2: ReturnCode.MAX_STEPS, -3: ReturnCode.STEP_UNDERFLOW},
          "Rodas": {-2: ReturnCode.MAX_STEPS, -3: ReturnCode.STEP_UNDERFLOW},
          "LSODAR": {-1: ReturnCode.MAX_STEPS, -4: ReturnCode.STEP_UNDERFLOW}}


def _failure(exc: Exception, sim) -> Advance:
    """An Advance carrying a library failure, with its message and the right return code."""
    message = f"{type(exc).__name__}: {str(exc).strip(chr(39))}"
    value = getattr(exc, "value", None)
    table = _CODES.get(type(exc).__name__, {})
    if value is None:       # DOPRI5, RODAS and LSODAR raise "<solver> failed with flag <n>"
        m = re.match(r"(\w+) failed with flag (-?\d+)", str(exc))
        if m:
            table, value = _CODES.get(m.group(1), {}), int(m.group(2))
    code = table.get(value, ReturnCode.FAILURE)
    err_msg = str(getattr(exc, "err_msg", None) or "")    # RADAU5's C port: its own codes
    if err_msg:
        code = (ReturnCode.MAX_STEPS if "number of steps" in err_msg else
                ReturnCode.STEP_UNDERFLOW if "too small with h" in err_msg else ReturnCode.FAILURE)
    z = np.array(sim.y[:3], float)
    if not np.all(np.isfinite(z)):
        code = ReturnCode.NON_FINITE
    return Advance(float(sim.t), z, retcode=code, message=message)


class _Sundials(_Assimulo):
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "sundials"

    @classmethod
    def library_version(cls) -> str:
        v = ".".join(str(i) for i in get_sundials_version())
        return f"SUNDIALS {v} via assimulo {_VERSION}"


@register
@dataclass(frozen=True)
class AssimuloCVode(_Sundials):
    """SUNDIALS CVODE (BDF) through assimulo.

    Variable order 1–5, adaptive; Newton iteration with the analytic Jacobian of the ODE form.
    Hindmarsh et al. (2005), ACM TOMS 31, 363–396."""
    name: ClassVar[str] = "assimulo-CVode"
    family: ClassVar[str] = "BDF"
    order: ClassVar[int] = 5
    solver: ClassVar[str] = "CVode"

    def make_solver(self, nd, e, tau0, z0, link, steps_left):
        sim = super().make_solver(nd, e, tau0, z0, link, steps_left)
        sim.discr, sim.iter, sim.linear_solver = "BDF", "Newton", "DENSE"
        return sim


@register
@dataclass(frozen=True)
class AssimuloIDA(_Sundials):
    """SUNDIALS IDA (BDF for DAEs) through assimulo, on the DAE form.

    Variable order 1–5, adaptive; the index-1 DAE y = (h, u, s, η) with u = ln w algebraic
    (``algvar``), analytic iteration matrix (problems/formulations.py, SPEC §1).
    Hindmarsh et al. (2005), ACM TOMS 31, 363–396."""
    name: ClassVar[str] = "assimulo-IDA"
    family: ClassVar[str] = "BDF (DAE)"
    order: ClassVar[int] = 5
    solver: ClassVar[str] = "IDA"
    dae: ClassVar[bool] = True


@register
@dataclass(frozen=True)
class AssimuloRadau5ODE(_Assimulo):
    """RADAU5 (implicit Runge–Kutta Radau IIA, 3 stages) through assimulo.

    Order 5, adaptive; analytic Jacobian. Hairer & Wanner (1996), Solving ODEs II, Sect. IV.8."""
    name: ClassVar[str] = "assimulo-Radau5ODE"
    kind: ClassVar[str] = "implicit"
    family: ClassVar[str] = "implicit Runge-Kutta"
    order: ClassVar[int] = 5
    solver: ClassVar[str] = "Radau5ODE"


@register
@dataclass(frozen=True)
class AssimuloLSODAR(_Assimulo):
    """ODEPACK LSODAR (Adams/BDF switching, with root finding) through assimulo.

    Adams orders 1–12, BDF orders 1–5, adaptive; analytic Jacobian. Its root info has no
    direction (see the module doc). Hindmarsh (1983), ODEPACK; Petzold (1983), SIAM J. Sci.
    Stat. Comput. 4, 136–148."""
    name: ClassVar[str] = "assimulo-LSODAR"
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "lsoda"
    family: ClassVar[str] = "Adams/BDF (LSODA)"
    order: ClassVar[int] = 12
    solver: ClassVar[str] = "LSODAR"
    root_directions: ClassVar[bool] = False


@register
@dataclass(frozen=True)
class AssimuloRodasODE(_Assimulo):
    """RODAS (Rosenbrock 4(3)) through assimulo.

    Order 4, adaptive; analytic Jacobian. Hairer & Wanner (1996), Solving ODEs II, Sect. IV.7."""
    name: ClassVar[str] = "assimulo-RodasODE"
    kind: ClassVar[str] = "rosenbrock"
    family: ClassVar[str] = "Rosenbrock"
    order: ClassVar[int] = 4
    solver: ClassVar[str] = "RodasODE"


@register
@dataclass(frozen=True)
class AssimuloDopri5(_Assimulo):
    """DOPRI5 (explicit Runge–Kutta 5(4), Dormand–Prince) through assimulo.

    Order 5, adaptive; not for stiff problems: between events its steps are held at the
    stability limit (~w/D). Hairer, Nørsett & Wanner (1993), Solving ODEs I, Sect. II.5."""
    name: ClassVar[str] = "assimulo-Dopri5"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge-Kutta"
    order: ClassVar[int] = 5
    solver: ClassVar[str] = "Dopri5"
    stiff: ClassVar[bool] = False
    uses_jacobian: ClassVar[bool] = False
