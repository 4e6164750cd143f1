"""CyRK's C++ solvers from numba (``CyRK-*``): counters, budgets and failures come back the way
every backend reports them; CyRK's own status and message are kept."""

import numpy as np
import pytest

import integrators as I
import problems as P
from integrators import REGISTRY

pytest.importorskip("CyRK")


def test_counters_explicit_and_implicit():
    p = P.window("W2", "slip", t_end=0.05)
    rk = I.solve(p, REGISTRY["CyRK-RK45"](rtol=1e-6, atol=1e-6), max_points=2)
    radau = I.solve(p, REGISTRY["CyRK-Radau"](rtol=1e-6, atol=1e-6), max_points=2)
    assert rk.success and radau.success
    # Dormand–Prince: six new evaluations per attempt (FSAL), so at least six per step
    assert rk.stats.nfev >= 6 * rk.stats.steps and rk.stats.njev == 0
    # Radau: finite-difference Jacobians, counted in the cfunc, three calls each at least
    assert 0 < radau.stats.njev and radau.stats.nfev > 3 * radau.stats.njev


def test_the_step_budget_ends_the_run_with_a_retcode():
    sol = I.solve(P.window("W2", "slip", t_end=0.05),
                  REGISTRY["CyRK-Radau"](rtol=1e-8, atol=1e-8, max_steps=50))
    assert sol.retcode is I.ReturnCode.MAX_STEPS and "step budget of 50" in sol.message
    assert sol.stats.steps == 50


class _FailedCall:
    """What nbsolve2_ivp returns when CyRK gives up at once (status −54: step size error)."""

    status, steps_taken, message, _ptr = -54, 0, "Step size is too small (spacing).", 0
    t = np.array([0.0])

    def __init__(self, z0):
        self.y = np.asarray(z0, float)[:, None]

    def free(self):
        pass


def test_a_cyrk_failure_comes_back_with_its_status_and_message(monkeypatch):
    from integrators.external import cyrk_backend as cb
    solve, call, rhs = cb._library()
    monkeypatch.setattr(cb, "_library", lambda: (lambda f, span, z0, **kw: _FailedCall(z0),
                                                 call, rhs))
    sol = I.solve(P.paper_example(), REGISTRY["CyRK-BDF"](rtol=1e-6, atol=1e-6))
    assert sol.retcode is I.ReturnCode.STEP_UNDERFLOW
    assert "status -54" in sol.message and "spacing" in sol.message
