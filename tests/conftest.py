"""Shared fixtures: reference solutions are computed once per test session."""

import pytest

import integrators as I
from problems import paper_example


@pytest.fixture(scope="session")
def paper_radau_reference():
    """Paper example (slip law, 20 s) by scipy Radau at rtol = atol = 1e−11, analytic Jacobian.

    The independent reference for the ETD convergence tests (~15 s on the CI machine).
    """
    sol = I.solve(paper_example(), I.ScipyRadau(rtol=1e-11, atol=1e-11))
    assert sol.success, sol.message
    return sol
