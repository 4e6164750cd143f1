"""SUNDIALS called from compiled code (``sundials-*``): counters from SUNDIALS' getters, exact
step budgets, failures with SUNDIALS' flag name and message."""

import pytest

import integrators as I
import problems as P
from integrators import REGISTRY

pytestmark = pytest.mark.skipif("integrators.external.sundials_c" in I.UNAVAILABLE,
                                reason="the system SUNDIALS 6 is not installed")
W2_SHORT = dict(t_end=0.05)


@pytest.mark.parametrize("name", ["sundials-CVODE-BDF", "sundials-IDA", "sundials-ARKODE-IMEX",
                                  "sundials-ARKODE-ERK"])
def test_the_step_budget_is_exact(name):
    sol = I.solve(P.window("W2", "slip", **W2_SHORT), REGISTRY[name](rtol=1e-8, atol=1e-8,
                                                                     max_steps=123))
    assert sol.retcode is I.ReturnCode.MAX_STEPS and sol.stats.steps == 123


def test_counters_of_the_implicit_and_the_explicit_arkode_methods():
    p = P.window("W2", "slip", **W2_SHORT)
    imex = I.solve(p, REGISTRY["sundials-ARKODE-IMEX"](rtol=1e-6, atol=1e-6), max_points=2)
    erk = I.solve(p, REGISTRY["sundials-ARKODE-ERK"](rtol=1e-6, atol=1e-6), max_points=2)
    assert imex.success and erk.success
    # ARK4(3)6L: six stages, each implicit one with Newton iterations; nfev sums ARKStep's
    # explicit and implicit evaluations (ARKStepGetNumRhsEvals gives both)
    assert imex.stats.nfev > 6 * imex.stats.steps and imex.stats.njev > 0
    # ERKStep's default order-4 pair: at least four new evaluations per attempt, no Jacobian
    assert erk.stats.nfev >= 4 * erk.stats.steps and erk.stats.njev == 0


def test_a_sundials_failure_comes_back_with_its_flag_name_and_message():
    # ARKODE's IMEX pair at 1e−4 on W2: Newton fails to converge repeatedly in the third event
    # (t ≈ 1.9 s, h ≈ 1e−5 τ; measured): a retcode, never a truncated "success"
    sol = I.solve(P.preset("W2", "slip", t_end=20.0),
                  REGISTRY["sundials-ARKODE-IMEX"](rtol=1e-4, atol=1e-4), max_points=2)
    assert sol.retcode is I.ReturnCode.STEP_UNDERFLOW
    assert "ARK_CONV_FAILURE (flag -4)" in sol.message and "converge" in sol.message
    assert sol.t_reached < 10.0
