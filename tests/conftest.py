"""Shared fixtures: reference solutions are computed once per test session; Fortran output is
flushed after each test, while pytest still captures it."""

import ctypes

import numpy as np
import pytest

import integrators as I
from problems import paper_example


@pytest.fixture(scope="session")
def fd_jacobian():
    """Central finite differences of ``f`` at x (steps ε·max(1, |x_j|)): the check of every
    analytic Jacobian."""
    def jacobian(f, x, eps=1e-7):
        jac = np.empty((len(f(x)), len(x)))
        for j in range(len(x)):
            dx = np.zeros(len(x))
            dx[j] = eps * max(1.0, abs(x[j]))
            jac[:, j] = (f(x + dx) - f(x - dx)) / (2 * dx[j])
        return jac
    return jacobian


@pytest.fixture(scope="session")
def paper_radau_reference():
    """Paper example (slip law, 20 s) by scipy Radau at rtol = atol = 1e−11, analytic Jacobian.

    The independent reference for the ETD convergence tests (~15 s on the CI machine).
    """
    sol = I.solve(paper_example(), I.ScipyRadau(rtol=1e-11, atol=1e-11))
    assert sol.success, sol.message
    return sol



def _gfortran_runtimes():
    """Every gfortran runtime loaded in this process: wheels vendor their own copies (assimulo,
    scipy, numpy, scikit-sundae), each with its own unit 6 buffer."""
    with open("/proc/self/maps") as maps:
        paths = {line.split()[-1] for line in maps if "libgfortran" in line}
    return [ctypes.CDLL(p) for p in sorted(paths)]


I.REGISTRY.load_all()                  # the adapters load on first use: load them all now
_GFORTRAN = _gfortran_runtimes()


@pytest.fixture(autouse=True)
def _flush_fortran_output():
    """gfortran buffers its unit 6 (assimulo's Dopri5 prints "THE PROBLEM SEEMS TO BECOME STIFF")
    until the process exits, after pytest's summary; flushing it after each test keeps it in the
    test's captured output."""
    yield
    for runtime in _GFORTRAN:
        runtime._gfortran_flush_i4(None)
