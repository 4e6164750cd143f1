"""The one search for the ends of a profile interval (:mod:`benchmarks.inversion.profile_ends`),
used by the stick–slip profiles and the laboratory ones, on profiles known in closed form."""

import numpy as np
import pytest

from benchmarks.inversion.objectives import CHI2_95_1DOF
from benchmarks.inversion.profile_ends import ends, level_crossing, next_point

Z95 = float(np.sqrt(CHI2_95_1DOF))


def walk_out(f, x0, limits, budget=200, **kw):
    """Both ends searched from ``x0`` one point at a time, as the laboratory profile does."""
    d = {x0: f(x0)}
    for side, limit in ((-1, limits[0]), (1, limits[1])):
        for _ in range(budget):
            x = np.array(sorted(d))
            step = next_point(x, [d[v] for v in x], CHI2_95_1DOF, side, limit, **kw)
            if step is None:
                break
            assert step.origin in d and d[step.origin] <= CHI2_95_1DOF   # from inside
            d[step.x] = f(step.x)
    x = np.array(sorted(d))
    return x, np.array([d[v] for v in x])


def test_a_quadratic_profile_is_walked_out_and_its_ends_are_exact_in_the_root():
    """Δ = ((x − 1)/0.1)² from a first step 100× too short: the steps double, the bracket is
    halved until its far end rises less than twice the level, and the root's interpolation is
    exact for a quadratic: 1 ± 1.96 × 0.1 to rounding."""
    x, d = walk_out(lambda u: ((u - 1.0) / 0.1) ** 2, 1.0, (-5.0, 5.0), walk=(1.0, 1e-3),
                    overshoot=2.0)
    low, high, open_low, open_high, resolved = ends(x, d, CHI2_95_1DOF, (-5.0, 5.0), root=True)
    assert (low, high) == pytest.approx((1 - 0.1 * Z95, 1 + 0.1 * Z95), rel=1e-12)
    assert not (open_low or open_high) and resolved
    assert len(x) < 40 and d.max() <= 2 * CHI2_95_1DOF * 4    # doubling: no long crawl


def test_a_flat_side_is_open_at_its_limit_and_an_unknown_rise_where_it_begins():
    """Flat below: the walk reaches the limit, the end is the limit, open; above, the model
    fails (NaN) past 1.05: the end is the last point before, open (no rise is known past it)."""
    def f(u):
        return np.nan if u > 1.05 else max(u - 1.0, 0.0) * 10.0
    x, d = walk_out(f, 1.0, (-2.0, 5.0), walk=(1.0, 0.02), overshoot=2.0)
    low, high, open_low, open_high, _ = ends(x, d, CHI2_95_1DOF, (-2.0, 5.0), root=True)
    assert x[0] == -2.0 and low == -2.0 and open_low
    assert open_high and high == x[np.flatnonzero(np.isnan(d))[0] - 1] and high <= 1.05


def test_a_crossing_at_its_limit_is_the_limits():
    x, d = np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 5.0])
    assert ends(x, d, CHI2_95_1DOF, (0.0, 2.0), bound_tol=0.3)[1] == 2.0
    assert ends(x, d, CHI2_95_1DOF, (0.0, 2.0), bound_tol=0.3)[3]
    assert ends(x, d, CHI2_95_1DOF, (0.0, 2.0))[1] == pytest.approx(
        level_crossing(1.0, 1.0, 2.0, 5.0, CHI2_95_1DOF))


def test_a_grid_is_bisected_until_each_crossing_cell_is_a_quarter_of_the_interval():
    """The stick–slip way: points on a grid that reaches the limits (no walk), crossing cells
    halved to 1/4 of the interval; a point without a cycle (inf) is beyond any level."""
    def f(u):
        return np.inf if u > 1.3 else ((u - 1.0) / 0.1) ** 2
    grid = np.linspace(0.0, 2.0, 5)
    d = {v: f(v) for v in grid}
    for _ in range(50):
        x = np.array(sorted(d))
        new = [s.x for side, lim in ((-1, x[0]), (1, x[-1]))
               if (s := next_point(x, [d[v] for v in x], CHI2_95_1DOF, side, lim, cells=4))]
        if not new:
            break
        d.update({v: f(v) for v in new})
    x = np.array(sorted(d))
    low, high, open_low, open_high, resolved = ends(x, [d[v] for v in x], CHI2_95_1DOF,
                                                    (0.0, 2.0), cells=4)
    assert resolved and not (open_low or open_high)
    for got, want in ((low, 1 - 0.1 * Z95), (high, 1 + 0.1 * Z95)):
        assert abs(got - want) < 0.02 * 2 * 0.1 * Z95


def test_an_unresolved_interval_is_the_points_about_it_and_no_point_inside_is_nan():
    x, d = np.array([0.0, 1.0, 2.0]), np.array([50.0, 0.0, 50.0])
    assert ends(x, d, CHI2_95_1DOF, (0.0, 2.0), cells=4) == (0.0, 2.0, False, False, False)
    low, high, *flags = ends(x, np.full(3, np.inf), np.nan, (0.0, 2.0))
    assert np.isnan(low) and np.isnan(high) and flags == [True, True, False]


def test_a_profile_without_an_interval_says_so_rather_than_print_nan():
    """A box where no point has a limit cycle: the interval is [nan, nan]; the warning says
    there is none (a hostile probe read 'narrower than 4 cells … [nan, nan]')."""
    import numpy as np

    from benchmarks.inversion.profile import _warnings
    x = np.linspace(0.0, 1.0, 5)
    none = _warnings("b", x, np.full(5, 1e6), [], (np.nan, np.nan, False), 3)
    assert none == ["the profile of b has no interval: none of its points is within the 95 % "
                    "level (no point of it has a limit cycle, or none fits)"]
    narrow = _warnings("b", x, np.full(5, 1e6), [], (0.2, 0.3, False), 3)
    assert "not resolved" in narrow[0] and "[0.2, 0.3]" in narrow[0]
