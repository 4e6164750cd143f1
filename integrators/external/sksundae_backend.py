"""SUNDIALS CVODE (BDF) and IDA through scikit-sundae, on the shared ODE and DAE forms.

CVODE integrates the ODE form z = (h, u, s) with Newton iteration on the analytic Jacobian; IDA
the index-1 DAE form y = (h, u, s, η) with the analytic iteration matrix and consistent
(y0, y'0) at every (re)start. Events: SUNDIALS' own root finding on the four root functions of
:mod:`integrators.core.events`, their counting directions given to ``*SetRootDirection``, the
signs read from its root info. Stepping: one-step mode with ``tstop`` at the segment's end; a
step past ``t_out`` is drained of its roots, then ``t_out`` is SUNDIALS' own interpolant.
Counters: ``nfev`` and ``njev`` from its results; ``steps`` counts the one-step calls that
evaluated f; rejected steps unavailable (0). Why the stepping is done this way, and the two
details around exact zeros and the roots log: docs/external-adapters.md.

Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396; Gardner et al. (2022), ACM TOMS,
doi:10.1145/3539801; scikit-sundae, https://github.com/NatLabRockies/scikit-sundae.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import sksundae

from integrators.core.events import DIRECTIONS
from integrators.core.registry import AdaptiveAlgorithm, register
from integrators.core.segments import Advance, directional_roots
from integrators.core.solution import ReturnCode, Stats
from problems.formulations import (dae_differential, dae_initial, dae_jacobian, dae_residual,
                                   form_vector, ode_jacobian, ode_rhs, peak_function)
from problems.loading import ln_load_rate

__all__ = ["SundaeCVODE", "SundaeIDA"]

# SUNDIALS return flags, the same in CVODE and IDA for these
_SUCCESS, _TSTOP, _ROOT, _WARNING = 0, 1, 2, 99
_TOO_MUCH_WORK = -1
# failures after repeated error-test or corrector-convergence failures: h has collapsed
_UNDERFLOW = {-3, -4}
# a crash of a plain-Python callback (python tier); SUNDIALS then retries with a smaller step
_PY_MATH_ERRORS = (OverflowError, ZeroDivisionError, ValueError)
_TINY = 1e-300
#: one-step calls between two checks of the wall budget inside one advance
_BUDGET_EVERY = 100
#: consecutive internal steps that do not advance t before the run stops (step underflow)
_STALLED_STEPS = 10


@dataclass(frozen=True)
class _Sundae(AdaptiveAlgorithm):
    """Options of every scikit-sundae backend: those of :class:`AdaptiveAlgorithm`."""

    library: ClassVar[str] = "scikit-sundae"
    package: ClassVar[str] = "scikit-sundae"
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "sundials"

    @classmethod
    def library_version(cls) -> str:
        return f"SUNDIALS {sksundae.SUNDIALS_VERSION} via scikit-sundae {sksundae.__version__}"

    def make_stepper(self, nd, budget):
        return self._stepper(self, nd, budget)


class _OneStepper:
    """The segment protocol over a scikit-sundae solver in one-step mode (see the module
    docstring); subclasses build the solver and its callbacks."""

    def __init__(self, algorithm: _Sundae, nd, budget=None):
        self.algorithm = algorithm
        self.nd = nd
        self.budget = budget       # checked inside advance: one advance can be many steps
        self.steps = 0                 # accepted steps over the whole solve
        self._solver = None
        self._base = Stats()           # the finished segments' nfev, njev
        self._nfev = self._njev = 0    # the current segment's
        self._tier = algorithm.rhs

    @property
    def stats(self) -> Stats:
        """The counters so far, summed over restarts."""
        return self._base + Stats(nfev=self._nfev, njev=self._njev, steps=self.steps)

    # --- callbacks ------------------------------------------------------------------------------

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
        """events.root_functions on y[:3], written into g (same expressions), an exact zero
        counted as positive.

        Why: C h − D η cancels to a few ulps of C h (~1e−11), so near a flat maximum of w it
        can be exactly 0.0 at two times 1e−12 apart; SUNDIALS then stops with "Root found at
        and very near t" (flag −22). No function is ever exactly zero this way.
        """
        l10, l1, le, c, d, beta = self._g_const
        u = y[1]
        g[0] = u - l10
        g[1] = u - l1
        g[2] = u - le
        g[3] = (c * y[0] - d * (u + beta * y[2]) if self._peak is None
                else self._peak(self._args[0], y))
        for k in range(4):
            if g[k] == 0.0:
                g[k] = _TINY

    def _with_directions(self, fn):
        """The events callback with the attributes scikit-sundae reads."""
        fn.direction = list(DIRECTIONS)
        fn.terminal = [True] * len(DIRECTIONS)   # step() stops at every root anyway
        return fn

    # --- the protocol ---------------------------------------------------------------------------

    def start(self, tau0, z0, e, t_bound):
        self._close_segment()
        self._set_loading(e)
        self._t_bound = float(t_bound)
        self._t, self._z = float(tau0), np.array(z0, dtype=float)
        self._tn, self._zn, self._h = self._t, self._z, 0.0    # end of the last internal step
        self._queue = deque()          # roots inside the last step, not yet reported
        self._nfev = self._njev = 0
        self._failure = None
        self._stalled = 0
        try:
            if self._solver is None:
                self._solver = self._make_solver()
            self._init(self._t, self._z)
        except Exception as exc:   # scikit-sundae raises for what SUNDIALS reports at set-up
            self._failure = f"{type(exc).__name__}: {exc}"

    def advance(self, t_out):
        if self._failure is not None:
            return Advance(self._t, self._z, retcode=ReturnCode.FAILURE, message=self._failure)
        try:
            return self._advance(float(t_out))
        except Exception as exc:   # a callback raised, or SUNDIALS refused an input
            return Advance(self._t, self._z, retcode=ReturnCode.FAILURE,
                           message=f"{type(exc).__name__}: {exc}")

    def finish(self):
        self._close_segment()
        self._solver = None

    # --- internals ------------------------------------------------------------------------------

    def _roundoff(self) -> float:
        # above SUNDIALS' own 100·uround·(|tn| + |h|), below which it treats times as equal
        return 1e3 * np.finfo(float).eps * (abs(self._tn) + abs(self._h))

    def _advance(self, t_out: float) -> Advance:
        a = self.algorithm
        calls = 0
        while True:
            calls += 1
            if calls % _BUDGET_EVERY == 0 and self.budget is not None and self.budget.exceeded():
                return Advance(self._t, self._z, retcode=ReturnCode.WALL_TIME,
                               message=f"wall-time budget of {self.budget.wall_s} s used up at "
                                       f"t = {self._t * self.nd.time_scale:.6g} s")
            if self._queue:
                t, z, roots = self._queue[0]
                if t <= t_out + self._roundoff():
                    self._queue.popleft()
                    self._t, self._z = t, z
                    return Advance(t, z, roots=roots)
                return self._interpolate(t_out)
            if self._tn >= t_out:
                return self._interpolate(t_out)
            if self.steps >= a.max_steps:
                return Advance(self._t, self._z, retcode=ReturnCode.MAX_STEPS,
                               message=f"step budget of {a.max_steps} used up at "
                                       f"tau = {self._t:.9g}")
            failed = self._one_step()
            if failed is not None:
                return failed

    def _call(self, t, method, tstop=None):
        """One scikit-sundae ``step``; keeps the counters current."""
        # scikit-sundae logs every root on the events function and turns the whole log into
        # arrays at every call: emptied here, so a call costs the same in the 1000th cycle
        for log in ("_i", "_t", "_y", "_yp"):
            getattr(self._eventsfn, log, []).clear()
        res = self._solver.step(t, method=method, tstop=tstop)
        self._nfev, self._njev = int(res.nfev), int(res.njev)
        return res

    def _one_step(self) -> Advance | None:
        """Take one internal step, then collect every root inside it; None on success."""
        tn_old = self._tn
        while True:
            before = self._nfev
            res = self._call(self._t_bound, "onestep", tstop=self._t_bound)
            flag = int(res.status)
            if flag < 0:
                return self._failed(flag, res)
            if self._nfev > before:            # a new internal step (only the first call)
                self.steps += 1
            t, z = float(res.t), np.array(res.y[:3], dtype=float)
            if flag == _ROOT:
                signs = [int(x) for x in np.asarray(res.i_events)[-1]]
                found = [k for k, sgn in enumerate(signs) if sgn != 0]
                roots = directional_roots(self.nd, self._e, z, found,
                                          [signs[k] for k in found])
                if roots:
                    self._queue.append((t, z, roots))
                continue                           # drain: more roots in this step?
            if flag not in (_SUCCESS, _TSTOP, _WARNING):
                return Advance(t, z, retcode=ReturnCode.FAILURE,
                               message=f"unexpected SUNDIALS flag {flag}: {res.message}")
            if not np.all(np.isfinite(z)):
                return Advance(t, z, retcode=ReturnCode.NON_FINITE,
                               message=f"non-finite state at tau = {t:.9g}")
            if t > tn_old:
                self._h = t - tn_old
                self._stalled = 0
            elif self._nfev > before:
                # a step that evaluated f but did not move: t + h == t at this τ; SUNDIALS goes
                # on taking such steps (it only warns), so stop after a few
                self._stalled += 1
                if self._stalled >= _STALLED_STEPS:
                    return Advance(t, z, retcode=ReturnCode.STEP_UNDERFLOW,
                                   message=f"step size underflow: {_STALLED_STEPS} steps did not "
                                           f"advance t = {t * self.nd.time_scale:.9g} s "
                                           "(t + h == t)")
            self._tn, self._zn = t, z
            return None

    def _interpolate(self, t_out: float) -> Advance:
        """The state at t_out ≤ tn from SUNDIALS' interpolant, then back to 'tn returned'."""
        if self._tn - t_out <= self._roundoff():
            self._t, self._z = self._tn, self._zn
            return Advance(self._tn, self._zn)
        res = self._call(t_out, "normal")
        flag = int(res.status)
        if flag < 0:
            return self._failed(flag, res)
        t, z = float(res.t), np.array(res.y[:3], dtype=float)
        # SUNDIALS' last returned time is t_out now: one one-step call returns tn again (no
        # step, no root: the interval tn..tn is empty), so that the next call searches forward
        before, tn = self._nfev, self._tn
        res = self._call(self._t_bound, "onestep", tstop=self._t_bound)
        if int(res.status) < 0:
            return self._failed(int(res.status), res)
        if self._nfev != before or float(res.t) != tn or int(res.status) == _ROOT:
            return Advance(t, z, retcode=ReturnCode.FAILURE,
                           message=f"SUNDIALS did not return to tn = {tn:.17g} after "
                                   f"interpolating at {t_out:.17g} (flag {res.status}, "
                                   f"t = {float(res.t):.17g})")
        self._t, self._z = t, z
        return Advance(t, z)

    def _failed(self, flag: int, res) -> Advance:
        if flag in _UNDERFLOW:
            code = ReturnCode.STEP_UNDERFLOW
        elif flag == _TOO_MUCH_WORK:
            code = ReturnCode.MAX_STEPS
        else:
            code = ReturnCode.FAILURE
        t = float(res.t) if res.t is not None else self._t
        message = f"{self._name} flag {flag} at tau = {t:.9g}: {res.message}"
        return Advance(self._t, self._z, retcode=code, message=message)

    def _close_segment(self):
        if self._solver is not None:
            self._base += Stats(nfev=self._nfev, njev=self._njev)
        self._nfev = self._njev = 0


class _CvodeStepper(_OneStepper):
    _name = "CVODE"

    def _make_solver(self):
        numba = self._tier == "numba"
        f, jac = (ode_rhs, ode_jacobian) if numba else (ode_rhs.py_func, ode_jacobian.py_func)

        def rhsfn(t, y, yp):
            try:
                f(*self._args, y, yp)
            except _PY_MATH_ERRORS:
                yp[:] = np.nan

        def jacfn(t, y, yp, jj):
            try:
                jac(*self._args, y, jj)
            except _PY_MATH_ERRORS:
                jj[:, :] = np.nan

        def eventsfn(t, y, g):
            self._roots_into(y, g)

        self._eventsfn = self._with_directions(eventsfn)
        a = self.algorithm
        return sksundae.cvode.CVODE(rhsfn, method="BDF", rtol=a.rtol, atol=a.atol,
                                    linsolver="dense", jacfn=jacfn, eventsfn=self._eventsfn,
                                    num_events=len(DIRECTIONS))

    def _init(self, tau0, z0):
        self._solver.init_step(tau0, z0)


class _IdaStepper(_OneStepper):
    _name = "IDA"

    def _make_solver(self):
        numba = self._tier == "numba"
        res, jac = (dae_residual, dae_jacobian) if numba else (dae_residual.py_func,
                                                               dae_jacobian.py_func)

        def resfn(t, y, yp, out):
            try:
                res(*self._args, y, yp, out)
            except _PY_MATH_ERRORS:
                out[:] = np.nan

        def jacfn(t, y, yp, rr, cj, jj):
            try:
                jac(*self._args, y, cj, jj)
            except _PY_MATH_ERRORS:
                jj[:, :] = np.nan

        def eventsfn(t, y, yp, g):
            self._roots_into(y, g)

        self._eventsfn = self._with_directions(eventsfn)
        a = self.algorithm
        algebraic = [int(i) for i in np.flatnonzero(dae_differential(self.nd) == 0.0)]
        return sksundae.ida.IDA(resfn, rtol=a.rtol, atol=a.atol, linsolver="dense",
                                algebraic_idx=algebraic, jacfn=jacfn, eventsfn=self._eventsfn,
                                num_events=len(DIRECTIONS))

    def _init(self, tau0, z0):
        y0, yp0 = dae_initial(self.nd, self._e, z0)
        self._solver.init_step(tau0, y0, yp0)


@register
@dataclass(frozen=True)
class SundaeCVODE(_Sundae):
    """SUNDIALS CVODE, variable-order variable-step BDF (orders 1–5), on the ODE form.

    Adaptive. Newton iteration with the dense analytic Jacobian (``ode_jacobian``); SUNDIALS' root
    finding with root directions for the events; scikit-sundae's one-step interface. Needs
    ``rtol`` and ``atol``. Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396.
    """

    name: ClassVar[str] = "sundae-CVODE"
    family: ClassVar[str] = "BDF"
    order: ClassVar[int] = 5
    _stepper: ClassVar[type] = _CvodeStepper


@register
@dataclass(frozen=True)
class SundaeIDA(_Sundae):
    """SUNDIALS IDA, variable-order variable-step BDF (orders 1–5), on the index-1 DAE form.

    Adaptive. y = (h, u, s, η) with u algebraic (``dae_differential``), Newton iteration on the
    analytic iteration matrix ∂F/∂y + cj ∂F/∂y' (``dae_jacobian``), consistent initial values
    from ``dae_initial`` at every restart; root functions on y[:3] with their directions. Needs
    ``rtol`` and ``atol``. Reference: Hindmarsh et al. (2005), ACM TOMS 31, 363–396; Brenan,
    Campbell & Petzold (1996), Numerical Solution of Initial-Value Problems in DAEs, SIAM.
    """

    name: ClassVar[str] = "sundae-IDA"
    dae: ClassVar[bool] = True
    family: ClassVar[str] = "BDF (DAE)"
    order: ClassVar[int] = 5
    _stepper: ClassVar[type] = _IdaStepper
