"""SUNDIALS CVODE (BDF and Adams) and IDA through scikits-odes, on the shared ODE and DAE forms.

CVODE integrates the ODE form z = (h, u, s) with Newton iteration on the analytic Jacobian; IDA
the DAE form y = (h, u, s, η) with the analytic iteration matrix and consistent (y0, y'0) at
every (re)start. Events: SUNDIALS' own root finding on the four root functions of
:mod:`integrators.core.events`; scikits-odes 3.0.0 wraps neither the root directions nor the root
info, so the functions found and their directions are read off the signs
(:func:`integrators.core.segments.directional_roots` keeps those that count). ``advance(t_out)``
is one ``step(t_out)`` in normal mode, bounded by ``mxstep``. Counters: CVODE's ``get_info()``;
IDA's evaluations counted in the callbacks, its steps as the calls that evaluated the residual
(``mxstep`` = 1), rejected steps unavailable (0).

scikits-odes 3.0.0 passes some values to SUNDIALS as float32 (root values, Jacobian entries,
``tstop``, tolerances): handled as docs/external-adapters.md explains, with its other quirks and
the reasons for the stepping mode.

Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396; Malengier et al. (2018), JOSS 3(22), 165.
"""

from __future__ import annotations

import ctypes
import gc
import importlib.metadata
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scikits.odes import dae, ode
from scikits_odes_sundials import cvode as _cvode_module

from integrators.core.registry import AdaptiveAlgorithm, register
from integrators.core.segments import Advance, directional_roots
from integrators.core.solution import ReturnCode, Stats
from problems.formulations import (dae_differential, dae_initial, dae_jacobian, dae_residual,
                                   form_vector, ode_jacobian, ode_rhs, peak_function)
from problems.loading import ln_load_rate

__all__ = ["OdesCVODEBDF", "OdesCVODEAdams", "OdesIDA"]

_VERSION = importlib.metadata.version("scikits.odes")

# SUNDIALS return flags, identical in CVODE and IDA for these
_SUCCESS, _ROOT, _TOO_MUCH_WORK = 0, 2, -1
# step failures after repeated error-test or corrector-convergence failures: h has collapsed
_UNDERFLOW = {-3, -4}
_TINY = 1e-30           # a float32-representable stand-in for 0 in root values
# steps that do not advance t (the latest time a callback saw): a step-size underflow
_STALLED_STEPS = 1000
# CVODE -8..-11, IDA -8, -9, -12: the right-hand side / residual kept failing; ours fail only on
# non-finite values
_CV_NON_FINITE = {-8, -9, -10, -11}
_IDA_NON_FINITE = {-8, -9, -12}


def _sundials_version() -> str:
    """The SUNDIALS version scikits-odes is linked against, asked of the library itself."""
    try:
        lib = ctypes.CDLL(_cvode_module.__file__)
        buf = ctypes.create_string_buffer(32)
        if lib.SUNDIALSGetVersion(buf, ctypes.c_int(len(buf))) == 0:
            return buf.value.decode()
    except (OSError, AttributeError):
        pass
    return "(version unknown)"


_SUNDIALS_VERSION = _sundials_version()


def _float32_ceil(x: float) -> float:
    """The smallest float32 value >= x: scikits-odes passes ``tstop`` through a float32
    conversion, and a stop time rounded below t_bound would end the segment early."""
    f = np.float32(x)
    if float(f) < x:
        f = np.nextafter(f, np.float32(np.inf))
    return float(f)


def _result_lists(solver) -> list:
    """The private lists in which scikits-odes' CVODE/IDA object accumulates every root (and
    tstop) return since ``init_step``; its ``step`` converts them all to arrays on every call."""
    return [r for r in gc.get_referents(solver._integrator) if type(r) is list]


@dataclass(frozen=True)
class _Odes(AdaptiveAlgorithm):
    """Options of every scikits-odes backend: those of :class:`AdaptiveAlgorithm`."""

    library: ClassVar[str] = "scikits-odes"
    package: ClassVar[str] = "scikits-odes"
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "sundials"
    lmm: ClassVar[str] = "BDF"          # CVODE's linear multistep method

    @classmethod
    def library_version(cls) -> str:
        return f"SUNDIALS {_SUNDIALS_VERSION} via scikits-odes {_VERSION}"

    def make_stepper(self, nd, budget):
        return self._stepper(self, nd, budget)


class _Stepper:
    """The segment protocol over a scikits-odes solver; subclasses make the solver and count."""

    _non_finite: set = set()

    def __init__(self, algorithm: _Odes, nd, budget=None):
        self.algorithm = algorithm
        self.nd = nd
        self.budget = budget         # checked between calls inside one advance
        self.stats = Stats()
        self._solver = None
        self._message = ""
        self._seg_steps = 0          # accepted steps of the current segment
        self._njev = 0
        self._tier = algorithm.rhs
        # the tier's callables, chosen once: compiled, or the same code as plain Python
        pick = (lambda f: f) if self._tier == "numba" else (lambda f: f.py_func)
        self._ode_rhs, self._ode_jac = pick(ode_rhs), pick(ode_jacobian)
        self._dae_res, self._dae_jac = pick(dae_residual), pick(dae_jacobian)
        self._root_lists = []
        self._live = False           # has the current segment's init_step succeeded?

    # --- callbacks shared by both solvers ---------------------------------------------------

    def _set_loading(self, e: float) -> None:
        nd = self.nd
        self._e = e
        self._args = (form_vector(nd, e),)
        # the constants of events.root_functions, hoisted out of the callback; the peak function
        # inline as C h − D η where that is what it is (with mass, no damping), else called
        self._g_const = (math.log(10.0 * nd.e_slow), math.log(nd.e_slow), ln_load_rate(e),
                         nd.c, nd.d, nd.beta)
        plain = not nd.quasi_static and nd.g == 0.0
        self._peak = None if plain else (peak_function if self._tier == "numba"
                                         else peak_function.py_func)

    def _roots_into(self, y, g) -> None:
        """events.root_functions on y[:3], written into g, kept at least _TINY away from 0.

        Why: scikits-odes hands root values to SUNDIALS through a float32 conversion (see the
        module docstring), which flushes |g| < 1.4e−45 to 0; and C h − D η cancels to within a
        few ulp of its terms on the stick-phase slow manifold, so it can be exactly 0.0 at a
        root and again 100 ulp of τ later. SUNDIALS then stops with "Root found at and very
        near t" (CLOSERT, CV_ILL_INPUT). With no zeros every root is a plain sign change (an
        exact 0 counts as positive), which the sign bookkeeping in ``advance`` relies on too.
        """
        l10, l1, le, c, d, beta = self._g_const
        u = y[1]
        g0, g1, g2 = u - l10, u - l1, u - le
        g3 = (c * y[0] - d * (u + beta * y[2]) if self._peak is None
              else self._peak(self._args[0], y))
        g[0] = g0 if abs(g0) >= _TINY else math.copysign(_TINY, g0)
        g[1] = g1 if abs(g1) >= _TINY else math.copysign(_TINY, g1)
        g[2] = g2 if abs(g2) >= _TINY else math.copysign(_TINY, g2)
        g[3] = g3 if abs(g3) >= _TINY else math.copysign(_TINY, g3)

    def _roots(self, z) -> np.ndarray:
        g = np.empty(4)
        self._roots_into(z, g)
        return g

    def _on_error(self, code, module, function, msg) -> None:
        if code != _TOO_MUCH_WORK:       # our per-call step limit, not a problem
            self._message = f"{module.decode()} {function.decode()}: {msg.decode()}"

    # --- the protocol -------------------------------------------------------------------------

    def start(self, tau0, z0, e, t_bound):
        self._close_segment()
        self._set_loading(e)
        self._t, self._z = float(tau0), np.array(z0, dtype=float)
        self._t_seen = self._t               # the latest time a callback was evaluated at
        self._g = self._roots(self._z)
        self._failure = None
        self._message = ""
        try:
            self._init(self._t, self._z, float(t_bound))
            self._live = True
        except Exception as exc:   # scikits-odes raises for what SUNDIALS reports at set-up
            self._failure = f"{type(exc).__name__}: {exc}"

    def advance(self, t_out):
        if self._failure is not None:
            return Advance(self._t, self._z, retcode=ReturnCode.FAILURE, message=self._failure)
        a = self.algorithm
        stalled_since = self.stats.steps + self._seg_steps
        while True:
            if self.stats.steps + self._seg_steps >= a.max_steps:
                return Advance(self._t, self._z, retcode=ReturnCode.MAX_STEPS,
                               message=f"step budget of {a.max_steps} used up at "
                                       f"t = {self._t * self.nd.time_scale:.9g} s")
            seen = self._t_seen
            sol = self._call(t_out)
            flag = int(sol.flag)
            if flag == _TOO_MUCH_WORK:
                if self.budget is not None and self.budget.exceeded():
                    return Advance(self._t, self._z, retcode=ReturnCode.WALL_TIME,
                                   message=f"wall-time budget of {self.budget.wall_s} s used up "
                                           f"at t = {self._t_seen * self.nd.time_scale:.6g} s")
                # the solver's time is not returned here; the callbacks see it. Steps that no
                # longer move it: t + h == t, on which SUNDIALS only warns and goes on
                steps = self.stats.steps + self._seg_steps
                if self._t_seen > seen:
                    stalled_since = steps
                elif steps - stalled_since >= _STALLED_STEPS:
                    return Advance(self._t, self._z, retcode=ReturnCode.STEP_UNDERFLOW,
                                   message=f"step size underflow: {steps - stalled_since} steps "
                                           f"did not advance t = {seen * self.nd.time_scale:.9g} "
                                           "s (t + h == t)")
                continue
            if flag < 0:
                return self._failed(flag, sol)
            t, z = float(sol.values.t), np.array(sol.values.y[:3], dtype=float)
            self._t, self._z = t, z
            if flag != _ROOT:             # t_out reached
                return Advance(t, z)
            for acc in self._root_lists:  # see the module docstring: keeps step() O(1)
                acc.clear()
            # the functions SUNDIALS found: those whose sign differs from the last root (or the
            # start), since between root returns it found no sign change; the direction is
            # the new sign
            g = self._roots(z)
            found = [k for k in range(4) if (g[k] > 0.0) != (self._g[k] > 0.0)]
            signs = [1 if g[k] > 0.0 else -1 for k in found]
            self._g = g
            counted = directional_roots(self.nd, self._e, z, found, signs)
            if counted:
                return Advance(t, z, roots=counted)

    def finish(self):
        self._close_segment()
        self._solver = None

    def _failed(self, flag, sol) -> Advance:
        if flag in _UNDERFLOW:
            code = ReturnCode.STEP_UNDERFLOW
        elif flag in self._non_finite:
            code = ReturnCode.NON_FINITE
        else:
            code = ReturnCode.FAILURE
        message = f"{sol.message} (flag {flag}: {self._message or 'no message'})"
        return Advance(self._t, self._z, retcode=code, message=message)


class _CvodeStepper(_Stepper):
    _non_finite = _CV_NON_FINITE
    _MXSTEP = 500                        # SUNDIALS' default steps per call

    def _rhs(self, t, y, ydot):
        if t > self._t_seen:
            self._t_seen = t
        try:
            self._ode_rhs(*self._args, y, ydot)
        except (OverflowError, ZeroDivisionError, ValueError):   # a plain-Python tier's crash
            return 1
        # a recoverable failure: CVODE retries with a smaller step
        return 0 if math.isfinite(ydot[0] + ydot[1] + ydot[2]) else 1

    def _jac(self, t, y, fy, J):
        self._njev += 1
        try:
            self._ode_jac(*self._args, y, J)
        except (OverflowError, ZeroDivisionError, ValueError):   # a plain-Python tier's crash
            return 1
        return 0

    def _rootfn(self, t, y, g):
        self._roots_into(y, g)
        return 0

    def _init(self, tau0, z0, t_bound):
        a = self.algorithm
        if self._solver is None:
            self._solver = ode("cvode", self._rhs, old_api=False, lmm_type=a.lmm,
                               nonlinsolver="newton", linsolver="dense", jacfn=self._jac,
                               rtol=a.rtol, atol=a.atol,
                               max_steps=int(min(self._MXSTEP, a.max_steps)),
                               err_handler=self._on_error, rootfn=self._rootfn, nr_rootfns=4)
        self._solver.set_options(tstop=_float32_ceil(t_bound))
        self._z0 = z0                    # CVODE's y0 vector wraps this array's memory
        self._solver.init_step(tau0, z0)
        self._njev = 0                   # scikits-odes calls the Jacobian once as a test
        self._root_lists = _result_lists(self._solver)

    def _call(self, t_out):
        sol = self._solver.step(t_out)
        self._seg_steps = self._solver.get_info()["NumSteps"]
        return sol

    def _close_segment(self):
        if self._live:
            info = self._solver.get_info()
            self.stats += Stats(nfev=info["NumRhsEvals"], njev=self._njev,
                                steps=info["NumSteps"], rejected=info["NumErrTestFails"])
        self._seg_steps = self._njev = 0
        self._live = False


class _IdaStepper(_Stepper):
    _non_finite = _IDA_NON_FINITE

    def __init__(self, algorithm, nd, budget=None):
        super().__init__(algorithm, nd, budget)
        self._nres = 0

    def _res(self, t, y, yp, out):
        self._nres += 1
        if t > self._t_seen:
            self._t_seen = t
        try:
            self._dae_res(*self._args, y, yp, out)
        except (OverflowError, ZeroDivisionError, ValueError):   # a plain-Python tier's crash
            return 1
        return 0 if math.isfinite(out[0] + out[1] + out[2] + out[3]) else 1

    def _jac(self, t, y, yp, res, cj, J):
        self._njev += 1
        try:
            self._dae_jac(*self._args, y, cj, J)
        except (OverflowError, ZeroDivisionError, ValueError):   # a plain-Python tier's crash
            return 1
        return 0

    def _rootfn(self, t, y, yp, g):
        self._roots_into(y, g)
        return 0

    def _init(self, tau0, z0, t_bound):
        a = self.algorithm
        if self._solver is None:
            algebraic = [int(i) for i in np.flatnonzero(dae_differential(self.nd) == 0.0)]
            # compute_initcond="yp0" is what hands the id vector to IDA (IDASetId) and runs
            # IDACalcIC(IDA_YA_YDP_INIT); from dae_initial's consistent values it converges at
            # once, so it checks consistency rather than changes anything. max_steps=1: one
            # step per call, which is how _call counts steps
            self._solver = dae("ida", self._res, old_api=False, linsolver="dense",
                               jacfn=self._jac, rtol=a.rtol, atol=a.atol, max_steps=1,
                               algebraic_vars_idx=algebraic, compute_initcond="yp0",
                               err_handler=self._on_error, rootfn=self._rootfn, nr_rootfns=4)
        self._solver.set_options(tstop=_float32_ceil(t_bound))
        self._y0, self._yp0 = dae_initial(self.nd, self._e, z0)   # IDA's vectors wrap these
        sol = self._solver.init_step(tau0, self._y0, self._yp0)
        self._root_lists = _result_lists(self._solver)
        if int(sol.flag) != _SUCCESS:
            raise RuntimeError(f"IDACalcIC failed: {sol.message} ({self._message})")

    def _call(self, t_out):
        before = self._nres
        sol = self._solver.step(t_out)
        flag = int(sol.flag)
        if self._nres > before and (flag >= 0 or flag == _TOO_MUCH_WORK):
            self._seg_steps += 1
        return sol

    def _close_segment(self):
        self.stats += Stats(nfev=self._nres, njev=self._njev, steps=self._seg_steps)
        self._seg_steps = self._njev = self._nres = 0
        self._live = False


@register
@dataclass(frozen=True)
class OdesCVODEBDF(_Odes):
    """SUNDIALS CVODE, variable-order variable-step BDF (orders 1–5), on the ODE form.

    Adaptive. Newton iteration with the dense analytic Jacobian (``ode_jacobian``); SUNDIALS' root
    finding for the events. Needs ``rtol`` and ``atol``. Reference: Hindmarsh et al. (2005),
    ACM TOMS 31, 363–396; Cohen & Hindmarsh (1996), Computers in Physics 10, 138–143.
    """

    name: ClassVar[str] = "odes-CVODE-BDF"
    family: ClassVar[str] = "BDF"
    order: ClassVar[int] = 5
    lmm: ClassVar[str] = "BDF"
    _stepper: ClassVar[type] = _CvodeStepper


@register
@dataclass(frozen=True)
class OdesCVODEAdams(_Odes):
    """SUNDIALS CVODE, variable-order variable-step Adams–Moulton (orders 1–12), on the ODE form.

    Adaptive. Nonlinear solver: Newton iteration with the dense analytic Jacobian, not CVODE's
    fixed-point (functional) iteration, which is meant for non-stiff problems: it converges only
    while h·‖∂f/∂z‖ ≲ 1, and ‖∂f/∂z‖ ≈ D/w ≥ D ≈ 3.6e4 (paper's parameters) through the stick
    phase, so convergence, not accuracy, holds the step to ~1e−5 in τ or less. Measured at
    rtol = atol = 1e−8: W2 slip, first 0.5 s, 2.1 M steps with fixed-point iteration against 12 k
    with Newton; the paper example reached only 0.53 s of 20 s in 150 s. With Newton the
    A-stable low orders (1: backward Euler, 2: trapezoidal) carry the stick phase. Needs ``rtol``
    and ``atol``. Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396.
    """

    name: ClassVar[str] = "odes-CVODE-Adams"
    family: ClassVar[str] = "Adams-Moulton"
    order: ClassVar[int] = 12
    stiff: ClassVar[bool] = False       # Adams–Moulton above order 2 is not A-stable
    lmm: ClassVar[str] = "ADAMS"
    _stepper: ClassVar[type] = _CvodeStepper


@register
@dataclass(frozen=True)
class OdesIDA(_Odes):
    """SUNDIALS IDA, variable-order variable-step BDF (orders 1–5), on the index-1 DAE form.

    Adaptive. y = (h, u, s, η) with u algebraic (``dae_differential`` as the id vector), Newton
    iteration on the analytic iteration matrix ∂F/∂y + cj ∂F/∂y' (``dae_jacobian``), consistent
    initial values from ``dae_initial`` at every restart; root functions on y[:3]. Needs ``rtol``
    and ``atol``. Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396; Brenan, Campbell &
    Petzold (1996), Numerical Solution of Initial-Value Problems in DAEs, SIAM.
    """

    name: ClassVar[str] = "odes-IDA"
    dae: ClassVar[bool] = True
    family: ClassVar[str] = "BDF (DAE)"
    order: ClassVar[int] = 5
    _stepper: ClassVar[type] = _IdaStepper
