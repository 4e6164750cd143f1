"""The Rodas5P kernel's twin in C (benchmarks/devtools/c_twin.py, benchmarks/native/rodas5p.c):
built with gcc -O3 -ffp-contract=off, it takes the numba kernel's steps, rejections and roots and
ends in its state, so the two times per attempt compare the same work."""

import numpy as np
import pytest

import integrators as I
import problems as P
from benchmarks.devtools import c_twin
from problems.formulations import to_ode_state

pytestmark = pytest.mark.skipif(c_twin.compiler() is None, reason="needs gcc")


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    return c_twin.build(tmp_path_factory.mktemp("twin"))


@pytest.mark.parametrize("tol", [1e-4, 1e-8])
def test_the_twin_takes_the_kernels_steps_to_the_bit(twin, tmp_path, tol):
    problem = P.paper_example()
    sol = I.solve(problem, I.Rodas5P(rtol=tol, atol=tol), max_points=2)
    got = c_twin.run_twin(twin, c_twin.write_input(tmp_path / "in.txt", problem, tol), 1)
    s = sol.stats
    assert (got["steps"], got["rejected"], got["nfev"], got["njev"]) == \
        (s.steps, s.rejected, s.nfev, s.njev)
    assert got["roots"] == list(sol.meta["roots"].values()) and got["events"] == len(sol.events)
    # the end state in the ODE form, through the solve's SI output and back (which rounds)
    nd = problem.nondimensional()
    law = problem.law
    x = ((sol.fs[-1] - problem.f0) / (problem.stiffness * law.lc),
         (sol.ft[-1] - problem.f0) / (law.a * problem.normal_force),
         law.psi(sol.theta[-1], problem.normal_force))
    np.testing.assert_allclose(got["z_end"], to_ode_state(nd.law_code, nd.beta, np.array(x)),
                               rtol=1e-12, atol=1e-12)
    assert got["us_per_attempt"] > 0


def test_the_twin_refuses_what_it_does_not_port(tmp_path):
    with pytest.raises(ValueError, match="slip law with mass"):
        c_twin.write_input(tmp_path / "in.txt", P.paper_example("aging"), 1e-6)
