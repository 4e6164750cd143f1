"""Every library of the design is installed and integrates y' = −y (CI proves the install).

`make test` installs them all and passes --require-all, so nothing here is skipped in CI; after
`pip install .` without an extra, its tests are skipped.
"""

import math

import numpy as np
import pytest

EXPECTED = math.exp(-1.0)


@pytest.mark.needs("scikits.odes")
def test_scikits_odes_cvode_and_ida():
    from scikits.odes import dae, ode

    def rhs(t, y, ydot):
        ydot[0] = -y[0]

    sol = ode("cvode", rhs, old_api=False, rtol=1e-10, atol=1e-12).solve([0.0, 1.0], [1.0])
    assert sol.values.y[-1, 0] == pytest.approx(EXPECTED, rel=1e-8)

    def res(t, y, yd, r):       # y' + y = 0 as a residual
        r[0] = yd[0] + y[0]

    sol = dae("ida", res, old_api=False, rtol=1e-10, atol=1e-12).solve([0.0, 1.0], [1.0], [-1.0])
    assert sol.values.y[-1, 0] == pytest.approx(EXPECTED, rel=1e-7)


@pytest.mark.needs("assimulo")
def test_assimulo_cvode():
    from assimulo.problem import Explicit_Problem
    from assimulo.solvers import CVode

    sim = CVode(Explicit_Problem(lambda t, y: -y, y0=np.array([1.0])))
    sim.verbosity, sim.rtol, sim.atol = 50, 1e-10, 1e-12
    t, y = sim.simulate(1.0)
    assert y[-1][0] == pytest.approx(EXPECTED, rel=1e-8)


@pytest.mark.needs("sksundae")
def test_scikit_sundae_cvode():
    from sksundae.cvode import CVODE

    def rhs(t, y, yp):
        yp[0] = -y[0]

    sol = CVODE(rhs, rtol=1e-10, atol=1e-12).solve(np.array([0.0, 1.0]), np.array([1.0]))
    assert sol.y[-1, 0] == pytest.approx(EXPECTED, rel=1e-8)


@pytest.mark.needs("numbalsoda")
def test_numbalsoda_lsoda():
    from numba import cfunc
    from numbalsoda import lsoda, lsoda_sig

    @cfunc(lsoda_sig)
    def rhs(t, u, du, p):
        du[0] = -u[0]

    usol, ok = lsoda(rhs.address, np.array([1.0]), np.array([0.0, 1.0]), rtol=1e-10, atol=1e-12)
    assert ok and usol[-1, 0] == pytest.approx(EXPECTED, rel=1e-8)
