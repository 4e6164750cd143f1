"""numbalsoda's LSODA over an output grid (``numbalsoda-LSODA-grid``): the grid is its dense
output, so its event times converge as the square of the grid spacing to the located ones."""

import pytest

import integrators as I
import problems as P
from integrators import REGISTRY

pytest.importorskip("numbalsoda")
GRID = REGISTRY["numbalsoda-LSODA-grid"]


@pytest.mark.parametrize("bad", [0.5, True, "fine", 2e6])
def test_refuses_a_bad_grid_density(bad):
    with pytest.raises(ValueError, match="points_per_half_period"):
        GRID(rtol=1e-6, atol=1e-6, points_per_half_period=bad)


def test_default_grid_follows_the_tolerance():
    from integrators.external.numbalsoda_grid import default_points
    assert default_points(1e-6) == 8.0
    assert default_points(1e-8) == pytest.approx(80.0)
    assert default_points(1e-2) == 4.0        # the floor


def _first_start(**kw):
    p = P.window("W2", "slip", t_end=0.05)
    sol = I.solve(p, GRID(rtol=1e-10, atol=1e-10, **kw), max_points=2)
    assert sol.success, sol.message
    return sol.events.t_start.iloc[0]


def test_event_times_converge_as_the_square_of_the_grid_spacing():
    # the first event's start located to the last bit by the block adapter at the same
    # tolerance; the grid's linear interpolation misplaces it by x(1 − x)·O(Δt²), x the
    # crossing's (erratic) place in its interval: over a 16× finer grid the error falls by
    # 166–206× for m = 25…100 (measured), 16× if it were first order
    p = P.window("W2", "slip", t_end=0.05)
    ref = I.solve(p, REGISTRY["numbalsoda-LSODA"](rtol=1e-10, atol=1e-10)).events.t_start.iloc[0]
    for m in (25, 50):
        coarse, fine = (abs(_first_start(points_per_half_period=k) - ref) for k in (m, 16 * m))
        assert coarse / fine > 40.0, (m, coarse, fine)


def test_the_step_budget_ends_the_run_with_a_retcode():
    sol = I.solve(P.paper_example(), GRID(rtol=1e-6, atol=1e-6, max_steps=500))
    assert sol.retcode is I.ReturnCode.MAX_STEPS and "step budget of 500" in sol.message
    assert sol.stats.steps >= 500 and sol.stats.nfev > sol.stats.steps
