"""The misfit as a function (issue 17, item 1): the same J1 and J2 as the sweep, defined values
where there is no limit cycle, bad observations refused."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmarks.physics.curves import read_curves
from benchmarks.inversion import NO_CYCLE_RESIDUAL, Misfit
from benchmarks.inversion.observations import Observations, observations
from benchmarks.inversion.sweep import sweep
from integrators import Rodas5P
from problems import preset

CURVES = Path(__file__).parent / "data" / "W2_slip_weakening.csv"


@pytest.fixture(scope="module")
def w2():
    return preset("W2", law="slip", t_end=10.0)


def test_j1_agrees_with_the_sweep(w2, tmp_path):
    b, lc = [0.0084, 0.0092, 0.0094, 0.0100], [5e-8, 3e-7, 2e-6]
    algorithm = Rodas5P(rtol=1e-4, atol=1e-4)
    table = sweep(w2, b, lc, algorithm, observations("W2"), tmp_path, progress=False).table
    m = Misfit(w2, observations("W2"), algorithm)
    got = m.evaluate(table.b.to_numpy(), table.lc_m.to_numpy())
    cycle = table.J1.notna().to_numpy()
    assert cycle.any() and (~cycle).any()                  # both kinds of point are covered
    np.testing.assert_allclose(got.J1[cycle], table.J1[cycle], rtol=1e-12)
    assert (got.J1[~cycle] == 2 * NO_CYCLE_RESIDUAL ** 2).all()
    assert (got.log_likelihood[~cycle] == -np.inf).all()
    np.testing.assert_allclose(got.log_likelihood[cycle], -0.5 * table.J1[cycle], rtol=1e-12)
    np.testing.assert_allclose(got.r_recurrence ** 2 + got.r_drop ** 2, got.J1, rtol=1e-12)


def test_one_point_calls_agree_with_the_batch(w2):
    m = Misfit(w2, observations("W2"), Rodas5P(rtol=1e-4, atol=1e-4))
    row = m.evaluate([0.0094], [3e-7]).iloc[0]
    assert m(0.0094, 3e-7) == row.J1
    assert m.log_likelihood(0.0094, 3e-7) == row.log_likelihood
    assert (m.residuals(0.0094, 3e-7) == [row.r_recurrence, row.r_drop]).all()


def test_velocity_strengthening_has_no_cycle_and_a_defined_misfit(w2):
    """b < a: steady sliding is stable, no stick–slip; never a NaN for an optimizer."""
    m = Misfit(w2, observations("W2"), Rodas5P(rtol=1e-4, atol=1e-4))
    row = m.evaluate([0.006], [3e-7]).iloc[0]
    assert row.classification not in ("stick-slip", "multiple recurrence")
    assert row.J1 == 2 * NO_CYCLE_RESIDUAL ** 2 and row.log_likelihood == -np.inf
    assert np.isfinite([row.r_recurrence, row.r_drop]).all()


def test_j2_agrees_with_the_sweep(tmp_path):
    problem = preset("W2", law="slip", t_end=20.0)
    obs = observations("W2", curves=read_curves(CURVES))
    algorithm = Rodas5P(rtol=1e-8, atol=1e-8)
    table = sweep(problem, [0.0092, 0.0094], [3e-7], algorithm, obs, tmp_path,
                  progress=False).table
    got = Misfit(problem, obs, algorithm).evaluate(table.b.to_numpy(), table.lc_m.to_numpy(),
                                                 j2=True)
    np.testing.assert_allclose(got.J2, table.J2, rtol=1e-12)


@pytest.mark.parametrize("kw, match", [
    (dict(sigma_recurrence_s=0.0), "sigma_recurrence_s"),
    (dict(friction_drop=np.nan), "friction_drop"),
    (dict(curves=pd.DataFrame({"event_id": [], "slip_m": [], "friction": []})), "curves"),
])
def test_bad_observations_are_refused(kw, match):
    base = dict(recurrence_s=3.1, sigma_recurrence_s=0.31, friction_drop=0.046,
                sigma_friction_drop=0.0046)
    with pytest.raises(ValueError, match=match):
        Observations(**{**base, **kw})


def test_misuse_is_refused(w2):
    with pytest.raises(ValueError, match="obs must be Observations"):
        Misfit(w2, {"recurrence_s": 3.1}, Rodas5P(rtol=1e-4, atol=1e-4))
    with pytest.raises(ValueError, match="algorithm must be Algorithm"):
        Misfit(w2, observations("W2"), "Rodas5P")


def _synthetic(problem, algorithm):
    """Noise-free observations of ``problem`` (its own limit cycle), σ = 10 % of each mean."""
    from benchmarks.physics.metrics import summarize
    from integrators import solve
    c = summarize(solve(problem, algorithm, max_points=2))
    assert c.classification == "stick-slip"
    return Observations(c.recurrence_s, 0.1 * c.recurrence_s, c.friction_drop,
                        0.1 * c.friction_drop)


def test_the_fit_recovers_a_known_point_from_noise_free_data():
    """W2 at (0.0094, 0.3 µm): the scan of the box does not contain the truth (its b values are
    0.0086 + k·0.0001875), the least-squares fit reaches it to 1e−3 relative."""
    from benchmarks.inversion.least_squares import fit
    algorithm = Rodas5P(rtol=1e-8, atol=1e-8)
    problem = preset("W2", law="slip", t_end=20.0)
    result = fit(Misfit(problem, _synthetic(problem, algorithm), algorithm),
                 b_range=(0.0086, 0.0101), lc_range=(1e-7, 1e-6))
    assert result.success, result.message
    assert abs(result.b / 0.0094 - 1) < 1e-3 and abs(result.lc / 3e-7 - 1) < 1e-3
    assert result.misfit < 1e-6 and np.isfinite(result.covariance).all()
    assert result.sigma_b > 0 and len(result.starts) == 3


def test_a_box_without_stick_slip_is_a_failed_fit_not_a_guess(w2):
    from benchmarks.inversion.least_squares import fit
    result = fit(Misfit(w2, observations("W2"), Rodas5P(rtol=1e-4, atol=1e-4)),
                 b_range=(0.004, 0.007), lc_range=(1e-7, 1e-6), grid=3)
    assert not result.success and "no point" in result.message and np.isnan(result.b)


def test_a_bad_box_is_refused(w2):
    from benchmarks.inversion.least_squares import fit
    with pytest.raises(ValueError, match="b_range"):
        fit(Misfit(w2, observations("W2"), Rodas5P(rtol=1e-4, atol=1e-4)),
            b_range=(0.01, 0.009))


def _noisy(exact: Observations, seed: int = 0) -> Observations:
    """``exact``'s means with 10 % Gaussian noise (seeded), its σ unchanged."""
    rng = np.random.default_rng(seed)
    return Observations(exact.recurrence_s * (1 + 0.1 * rng.standard_normal()),
                        exact.sigma_recurrence_s,
                        exact.friction_drop * (1 + 0.1 * rng.standard_normal()),
                        exact.sigma_friction_drop)


@pytest.mark.slow                        # 9 s
def test_profile_intervals_contain_the_truth_for_seeded_noisy_data():
    """W2 at (0.0094, 0.3 µm), observations with 10 % Gaussian noise (seed 0): both 95 %
    profile intervals contain the truth. The data leave a long valley in (b, log Lc): the b
    interval spans about 0.001 and Lc is bounded only from above (open at the low end)."""
    from benchmarks.inversion.profile import CHI2_95_1DOF, profile
    algorithm = Rodas5P(rtol=1e-8, atol=1e-8)
    problem = preset("W2", law="slip", t_end=20.0)
    exact = _synthetic(problem, algorithm)
    noisy = _noisy(exact)
    m = Misfit(problem, noisy, algorithm)
    pb = profile(m, "b", np.linspace(0.0086, 0.0102, 17), (1e-8, 1e-5))
    assert pb.low < 0.0094 < pb.high and not (pb.open_low or pb.open_high)
    pl = profile(m, "log10_lc", np.linspace(-8, -5, 13), (0.008, 0.011))
    assert pl.low < np.log10(3e-7) < pl.high
    assert pl.open_low and not pl.open_high          # Lc is not bounded from below
    for p in (pb, pl):
        inside = p.table.misfit - p.table.misfit.min() <= CHI2_95_1DOF
        assert inside.any() and np.isfinite(p.table.misfit[inside]).all()


def test_the_noise_free_profile_is_zero_at_the_truth():
    from benchmarks.inversion.profile import profile
    algorithm = Rodas5P(rtol=1e-8, atol=1e-8)
    problem = preset("W2", law="slip", t_end=20.0)
    m = Misfit(problem, _synthetic(problem, algorithm), algorithm)
    p = profile(m, "b", [0.0093, 0.0094, 0.0095], (1e-7, 1e-6))
    at = p.table.set_index("b").loc[0.0094]      # the table also holds points added between
    assert at.misfit < 1e-8
    assert abs(10 ** at.log10_lc / 3e-7 - 1) < 1e-2


def test_profile_misuse_is_refused(w2):
    from benchmarks.inversion.profile import profile
    m = Misfit(w2, observations("W2"), Rodas5P(rtol=1e-4, atol=1e-4))
    with pytest.raises(ValueError, match="parameter must be"):
        profile(m, "lc", [1, 2], (0.008, 0.01))
    with pytest.raises(ValueError, match="other_range"):
        profile(m, "b", [0.009, 0.01], (1e-6, 1e-7))


@pytest.mark.slow          # ~10 s: make test-slow (make test stays under 8 min)
def test_posterior_credible_intervals_contain_the_truth_for_seeded_noisy_data():
    """W2 at (0.0094, 0.3 µm), 10 % noise (seed 0), started from the least-squares fit: the
    central 95 % of both marginals contains the truth; the chain is reproducible by its seed and
    reports its diagnostics."""
    from benchmarks.inversion.least_squares import fit
    from benchmarks.inversion.posterior import sample
    algorithm = Rodas5P(rtol=1e-6, atol=1e-6)
    problem = preset("W2", law="slip", t_end=20.0)
    exact = _synthetic(problem, Rodas5P(rtol=1e-8, atol=1e-8))
    noisy = _noisy(exact)
    m = Misfit(problem, noisy, algorithm)
    box = dict(b_range=(0.0085, 0.0105), lc_range=(1e-8, 1e-5))
    best = fit(m, **box)
    post = sample(m, start=(best.b, best.lc), walkers=16, steps=400, seed=1, **box)
    s = post.samples
    assert s.b.quantile(0.025) < 0.0094 < s.b.quantile(0.975)
    assert s.log10_lc.quantile(0.025) < np.log10(3e-7) < s.log10_lc.quantile(0.975)
    assert ((s.b > 0.0085) & (s.b < 0.0105)).all() and 0.1 < post.acceptance < 0.9
    assert post.n_solves <= 16 * 400 and post.effective_samples > 0 and "uniform" in post.prior
    again = sample(m, start=(best.b, best.lc), walkers=16, steps=20, seed=1, **box)
    twice = sample(m, start=(best.b, best.lc), walkers=16, steps=20, seed=1, **box)
    pd.testing.assert_frame_equal(again.samples, twice.samples)


def test_posterior_misuse_is_refused(w2):
    from benchmarks.inversion.posterior import sample
    m = Misfit(w2, observations("W2"), Rodas5P(rtol=1e-4, atol=1e-4))
    with pytest.raises(ValueError, match="outside the prior box"):
        sample(m, (0.009, 0.01), (1e-7, 1e-6), start=(0.0094, 3e-8))
    with pytest.raises(ValueError, match="prior box"):
        sample(m, (0.01, 0.009), (1e-7, 1e-6), start=(0.0094, 3e-7))
