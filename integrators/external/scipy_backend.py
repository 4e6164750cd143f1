"""scipy's adaptive integrators (``scipy.integrate`` OdeSolver classes) on the shared ODE form.

RK45 (Dormand–Prince 5(4)), DOP853, Radau (implicit Runge–Kutta, order 5), BDF (orders 1–5) and
LSODA (Adams/BDF switching). Implicit methods get the analytic Jacobian. Events are located by
Brent root finding on each method's dense output, as ``solve_ivp`` does for its events
(:mod:`integrators.core.dense_roots`); the step loop is ours so that budgets and restarts are too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import scipy
from scipy import integrate

from integrators.core.dense_roots import DenseStepper
from integrators.core.registry import AdaptiveAlgorithm, register
from integrators.core.segments import Advance
from integrators.core.solution import ReturnCode, Stats
from problems.formulations import OdeForm

__all__ = ["ScipyRK45", "ScipyDOP853", "ScipyRadau", "ScipyBDF", "ScipyLSODA"]


@dataclass(frozen=True)
class _Scipy(AdaptiveAlgorithm):
    """Options of every scipy backend: those of :class:`AdaptiveAlgorithm`."""

    library: ClassVar[str] = "scipy"
    package: ClassVar[str] = "scipy"
    method: ClassVar[type] = None
    uses_jacobian: ClassVar[bool] = False

    @classmethod
    def library_version(cls) -> str:
        return f"scipy {scipy.__version__}"

    def make_stepper(self, nd, budget):
        return _ScipyStepper(self, nd, budget)


class _ScipyStepper(DenseStepper):
    """scipy ``OdeSolver`` under the segment protocol, with the step budget."""

    def __init__(self, algorithm: _Scipy, nd, budget):
        super().__init__(nd, budget)
        self.algorithm = algorithm

    def _new_solver(self, tau0, z0, e, t_bound):
        a = self.algorithm
        form = OdeForm(self.nd, e, a.rhs)
        kw = {"jac": form.jac} if a.uses_jacobian else {}
        return a.method(form.f, tau0, z0, t_bound, rtol=a.rtol, atol=a.atol, **kw)

    def _count(self, solver):
        return Stats(nfev=int(solver.nfev),
                     njev=int(getattr(solver, "njev", 0) or 0))     # LSODA's is a numpy int32

    def advance(self, t_out):
        if self.steps >= self.algorithm.max_steps:
            return Advance(self._cursor, self._z_cursor, retcode=ReturnCode.MAX_STEPS,
                           message=f"step budget of {self.algorithm.max_steps} used up")
        return super().advance(t_out)


@register
@dataclass(frozen=True)
class ScipyRK45(_Scipy):
    """Explicit Runge–Kutta 5(4), Dormand–Prince, adaptive. Order 5."""
    name: ClassVar[str] = "scipy-RK45"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge-Kutta"
    order: ClassVar[int] = 5
    stiff: ClassVar[bool] = False
    method: ClassVar[type] = integrate.RK45


@register
@dataclass(frozen=True)
class ScipyDOP853(_Scipy):
    """Explicit Runge–Kutta 8(5,3), Dormand–Prince, adaptive. Order 8."""
    name: ClassVar[str] = "scipy-DOP853"
    kind: ClassVar[str] = "explicit"
    family: ClassVar[str] = "explicit Runge-Kutta"
    order: ClassVar[int] = 8
    stiff: ClassVar[bool] = False
    method: ClassVar[type] = integrate.DOP853


@register
@dataclass(frozen=True)
class ScipyRadau(_Scipy):
    """Implicit Runge–Kutta Radau IIA, 3 stages, adaptive, analytic Jacobian. Order 5."""
    name: ClassVar[str] = "scipy-Radau"
    kind: ClassVar[str] = "implicit"
    family: ClassVar[str] = "implicit Runge-Kutta"
    order: ClassVar[int] = 5
    method: ClassVar[type] = integrate.Radau
    uses_jacobian: ClassVar[bool] = True


@register
@dataclass(frozen=True)
class ScipyBDF(_Scipy):
    """Variable-order BDF (NDF), orders 1–5, adaptive, analytic Jacobian."""
    name: ClassVar[str] = "scipy-BDF"
    kind: ClassVar[str] = "multistep"
    family: ClassVar[str] = "BDF"
    order: ClassVar[int] = 5
    method: ClassVar[type] = integrate.BDF
    uses_jacobian: ClassVar[bool] = True


@register
@dataclass(frozen=True)
class ScipyLSODA(_Scipy):
    """ODEPACK LSODA: Adams/BDF switching on stiffness, adaptive, analytic Jacobian."""
    name: ClassVar[str] = "scipy-LSODA"
    kind: ClassVar[str] = "multistep"
    code: ClassVar[str] = "lsoda"
    family: ClassVar[str] = "Adams/BDF (LSODA)"
    order: ClassVar[int] = 12
    method: ClassVar[type] = integrate.LSODA
    uses_jacobian: ClassVar[bool] = True
