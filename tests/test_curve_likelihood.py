"""The slip-weakening curves in the likelihood, and the grid posterior refined where its mass is:
the covariance estimate against scikit-learn's, each noise model against its closed form, the
χ² at the truth distributed as it claims, the refined grid against an analytic posterior, and on
W2 the curves narrowing log10 Lc with the truth inside."""

import dataclasses
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from benchmarks.inversion.adaptive import grid_posterior
from benchmarks.inversion.curve_likelihood import CurveLikelihood, ledoit_wolf
from benchmarks.inversion.objectives import j2_per_event
from benchmarks.inversion.observations import Observations


def _curves(n_events=6, n_points=30, noise=0.0, seed=0, shape=None):
    """Events of a smooth weakening curve (μ = 0.6 − 0.04 (1 − exp(−s/Lc'))), each with its own
    offset and white noise, sampled at slips that vary from event to event."""
    rng = np.random.default_rng(seed)
    shape = shape or (lambda s: 0.6 - 0.04 * (1 - np.exp(-s / 2e-5)))
    frames = []
    for i in range(n_events):
        s = np.sort(rng.uniform(0, 3e-4 * (1 + 0.1 * rng.random()), n_points))
        frames.append(pd.DataFrame({"event_id": i, "slip_m": s,
                                    "friction": shape(s) + 0.01 * rng.standard_normal()
                                    + noise * rng.standard_normal(n_points)}))
    return pd.concat(frames, ignore_index=True), shape


def test_ledoit_wolf_is_scikit_learns():
    """Reference: ``sklearn.covariance.ledoit_wolf`` (scikit-learn 1.9.1) on this matrix gave
    shrinkage 0.582967015605632, cov[0, 0] 4.888335458212515, cov[3, 7] −0.674553036930158,
    trace 45.20035242616916 (run once by hand; scikit-learn is not a dependency)."""
    rng = np.random.default_rng(7)
    x = rng.standard_normal((5, 11)) @ rng.standard_normal((11, 11))
    cov, shrinkage = ledoit_wolf(x)
    assert shrinkage == pytest.approx(0.582967015605632, rel=1e-12)
    assert cov[0, 0] == pytest.approx(4.888335458212515, rel=1e-12)
    assert cov[3, 7] == pytest.approx(-0.674553036930158, rel=1e-12)
    assert np.trace(cov) == pytest.approx(45.20035242616916, rel=1e-12)


def test_the_scatter_model_is_its_closed_form_and_blind_to_offsets():
    curves, shape = _curves(noise=2e-3)
    like = CurveLikelihood.from_curves(curves)
    assert like.noise == "scatter" and like.n_events == 6 and like.dof == 11
    s = np.linspace(0, 4e-4, 400)
    m = shape(s)
    # the closed form: contrasts of (mean − model) with the shrunk covariance of the events',
    # each curve read by a Gaussian kernel twice the median spacing of the events' samples wide
    events = [g.sort_values("slip_m") for _, g in curves.groupby("event_id")]
    gaps = [[g.slip_m.to_numpy()[np.clip(np.searchsorted(g.slip_m, x), 1, len(g) - 1)]
             - g.slip_m.to_numpy()[np.clip(np.searchsorted(g.slip_m, x), 1, len(g) - 1) - 1]
             for x in like.slips] for g in events]
    h = 2 * np.median(gaps, axis=0)

    def read(x, y):
        return np.array([np.sum(np.exp(-0.5 * ((x - c) / w) ** 2) * y)
                         / np.sum(np.exp(-0.5 * ((x - c) / w) ** 2)) for c, w in zip(like.slips, h)])

    np.testing.assert_allclose(like.bandwidth, h, rtol=1e-12)
    q = np.linalg.qr(np.column_stack([np.ones(12), np.eye(12)[:, :11]]))[0][:, 1:]
    y = np.array([read(g.slip_m.to_numpy(), g.friction.to_numpy()) for g in events])
    cov = ledoit_wolf(y @ q)[0] * 6 / 5
    d = q.T @ (y.mean(axis=0) - read(s, m))
    assert like.chi2(s, m) == pytest.approx(d @ np.linalg.solve(cov, d), rel=1e-10)
    assert like.chi2(s, m + 0.3) == pytest.approx(like.chi2(s, m), rel=1e-10)   # an offset
    sem = CurveLikelihood.from_curves(curves, reading="sem")
    assert sem.chi2(s, m) == pytest.approx(6 * like.chi2(s, m), rel=1e-10)
    assert like.chi2(s, 0.6 - 0.04 * (1 - np.exp(-s / 6e-5))) > 3 * like.chi2(s, m)


def test_the_kernel_is_no_narrower_than_the_slip_s_filtered_noise():
    """With a chain whose slip column is noisy, the bandwidth is at least that noise's σ after
    the chain's low-pass; the reference is scipy's own Butterworth (4th order, zero phase) on a
    long white draw, independent of the module's filter code."""
    from scipy.signal import butter, sosfiltfilt

    from benchmarks.physics.chain import Chain
    chain = Chain(rate_hz=10_000.0, timing_hz=50.0, start_level=1e-4, end_level=1e-5,
                  force_hz=400.0, acceleration_hz=750.0, slip_hz=750.0,
                  slip_from="slip column", slip_noise=3e-6)
    white = np.random.default_rng(5).standard_normal(1 << 17)
    sd = 3e-6 * sosfiltfilt(butter(4, 750.0, fs=10_000.0, output="sos"), white)[4096:-4096].std()
    curves, _ = _curves(n_events=6, n_points=3000)
    like = CurveLikelihood.from_curves(curves, chain=chain)
    assert like.bandwidth.min() == pytest.approx(sd, rel=0.02)
    plain = CurveLikelihood.from_curves(curves)
    assert (plain.bandwidth < 0.5 * sd).any()          # the spacing alone is finer than that


def test_the_curves_chi2_is_smooth_where_the_slip_has_stopped():
    """Events that end in a pile of samples whose noisy slip (σ 1.2 µm after the chain's
    low-pass, 40 × the pile's own extent) no longer orders them; a model curve of the same kind
    (its own draw) slid along the slip by steps of 0.02 σ: the kernel's χ² moves by small steps,
    where reading the same samples by linear interpolation jumps (the roughness the kernel is
    there to remove)."""
    from benchmarks.inversion.curve_likelihood import kernel_read
    from benchmarks.physics.chain import Chain
    rng = np.random.default_rng(11)
    sigma = 1.2e-6
    chain = Chain(rate_hz=10_000.0, timing_hz=50.0, start_level=1e-4, end_level=1e-5,
                  force_hz=400.0, acceleration_hz=750.0, slip_hz=750.0,
                  slip_from="slip column", slip_noise=3e-6)

    def event(n_slide=60, n_pile=120):
        u = np.concatenate([np.linspace(0, 3e-4, n_slide), 3e-4 + 3e-8 * rng.random(n_pile)])
        mu = np.concatenate([0.6 - 0.04 * np.linspace(0, 1, n_slide) ** 0.5,
                             0.56 + 0.01 * np.linspace(0, 1, n_pile)])
        x = u + sigma * rng.standard_normal(len(u))
        order = np.argsort(x)
        return x[order], mu[order] + 1e-3 * rng.standard_normal(len(u))

    curves = pd.concat([pd.DataFrame({"event_id": i, "slip_m": x, "friction": y})
                        for i, (x, y) in enumerate(event() for _ in range(8))])
    like = CurveLikelihood.from_curves(curves, chain=chain)
    x, y = event(600, 1200)
    shifts = np.arange(200) * 0.02 * sigma
    kernel = np.array([like.chi2(x + d, y) for d in shifts])
    linear = np.array([np.sum((like.whiten @ (like.mean - np.interp(like.slips, x + d, y))) ** 2)
                       for d in shifts])
    assert np.abs(np.diff(kernel)).max() < 0.05 * np.ptp(kernel)
    assert np.abs(np.diff(linear)).max() > 0.2 * np.ptp(linear)
    assert np.isfinite(kernel_read(like.slips, like.bandwidth, x, y)).all()
    # J̄2 (and the sample model, the figures) read the pooled samples as a smoothed curve
    grid, smooth = like.curve(x, y)
    assert len(grid) == 400 and (np.diff(grid) > 0).all() and np.isfinite(smooth).all()
    j2 = np.array([like.j2(x + d, y) for d in shifts])
    assert np.abs(np.diff(j2)).max() < 0.05 * np.ptp(j2)


def test_the_sample_model_is_the_papers_j2_over_sigma_squared():
    """χ² = Σ_i N_i J2(i) / σ² (Eq. 11: J2 is each event's residual variance after its best
    offset), whatever the offsets."""
    curves, shape = _curves(noise=2e-3)
    like = CurveLikelihood.from_curves(curves, "sample", sigma=2e-3)
    s = np.linspace(0, 4e-4, 400)
    m = 0.6 - 0.04 * (1 - np.exp(-s / 3e-5))
    sizes = curves.groupby("event_id", sort=False).size().to_numpy()
    want = np.sum(sizes * j2_per_event(s, m, curves)) / 2e-3 ** 2
    assert like.chi2(s, m) == pytest.approx(want, rel=1e-10)
    assert like.dof == len(curves) - 6
    # the paper's J̄2, as every noise model reports it: objectives.j2_per_event's mean
    for model in (like, CurveLikelihood.from_curves(curves)):
        assert model.j2(s, m) == pytest.approx(np.mean(j2_per_event(s, m, curves)), rel=1e-10)


def test_the_sample_models_chi2_at_the_truth_is_chi2_of_its_dof():
    """Over 400 seeds the χ² of the true curve has the mean and variance of χ²(N − n)."""
    s = np.linspace(0, 4e-4, 400)
    values = []
    for seed in range(400):
        curves, shape = _curves(n_events=4, n_points=10, noise=1e-3, seed=seed)
        values.append(CurveLikelihood.from_curves(curves, "sample", sigma=1e-3)
                      .chi2(s, shape(s)))
    dof = 4 * 10 - 4
    assert abs(np.mean(values) - dof) < 4 * np.sqrt(2 * dof / 400)
    assert np.var(values) == pytest.approx(2 * dof, rel=0.3)


def test_an_empty_model_curve_has_no_chi2_and_no_j2():
    curves, _ = _curves(noise=2e-3)
    for like in (CurveLikelihood.from_curves(curves),
                 CurveLikelihood.from_curves(curves, "sample", sigma=2e-3)):
        assert np.isnan(like.chi2([], [])) and np.isnan(like.j2([], []))
        assert np.isnan(like.residuals([], [])).all()


@pytest.mark.parametrize("curves, kw, match", [
    (_curves(n_events=2)[0], {}, "at least 3 events"),
    (_curves()[0], {"noise": "sample"}, "needs σ per sample"),
    (_curves()[0], {"sigma": 1e-3}, "for curve noise 'sample'"),
    (_curves()[0], {"noise": "white"}, "curve.noise must be one of"),
])
def test_what_a_noise_model_cannot_use_is_refused(curves, kw, match):
    with pytest.raises(ValueError, match=match):
        CurveLikelihood.from_curves(curves, **kw)
    with pytest.raises(ValueError, match=match):          # and so are such observations
        Observations(3.0, 0.1, 0.05, 0.005, curves=curves, curve_noise=kw.get("noise",
                                                                                "scatter"),
                     curve_sigma=kw.get("sigma"))


class _Gauss:
    """A misfit whose posterior on the box is a correlated Gaussian in (b, log10 Lc)."""

    def __init__(self, centre, sd, rho=0.0):
        self.centre, self.sd, self.rho = np.array(centre), np.array(sd), rho
        self.n = 0

    def evaluate(self, b, lc, progress=False):
        x = np.column_stack([np.atleast_1d(b), np.log10(np.atleast_1d(lc))])
        z = (x - self.centre) / self.sd
        J = (z[:, 0] ** 2 - 2 * self.rho * z[:, 0] * z[:, 1] + z[:, 1] ** 2) / (1 - self.rho ** 2)
        self.n += len(x)
        return pd.DataFrame({"misfit": J, "log_likelihood": -0.5 * J})


@pytest.mark.parametrize("sd", [(2e-4, 0.3), (1e-6, 2e-3)])
def test_the_refined_grid_finds_a_gaussian_posterior_of_any_width(sd):
    """A broad posterior (a few first-grid cells) and one some 50× narrower than the first
    grid's spacing (sd 1e-6 in b against 4.8e-5, 2e-3 in log10 Lc against 0.09): the 95 % marginal intervals are the Gaussian's ±1.96 sd within 3 % of their width,
    the mean within 2 % of an sd, the sd within 5 % (measured: 0.963 of it for the narrow one,
    whose tails stay in coarser cells), the refinement settles."""
    m = _Gauss((0.0094, -6.5), sd, rho=0.6)
    post = grid_posterior(m, (0.0086, 0.0102), (1e-8, 1e-5))
    assert post.settled and post.levels >= 1 and post.n_solves == m.n
    for k, (name, c) in enumerate((("b", 0.0094), ("log10_lc", -6.5))):
        lo, hi = post.interval[name]
        z = norm.ppf(0.975) * sd[k]
        assert abs(lo - (c - z)) < 0.03 * 2 * z and abs(hi - (c + z)) < 0.03 * 2 * z
        assert abs(post.mean[name] - c) < 0.02 * sd[k]
        assert post.std[name] == pytest.approx(sd[k], rel=0.05)
    draws = post.sample(20_000, seed=1)
    assert abs(draws.b.mean() - 0.0094) < 0.05 * sd[0]


def test_a_box_without_a_cycle_has_no_grid_posterior():
    class Nothing(_Gauss):
        def evaluate(self, b, lc, progress=False):
            t = super().evaluate(b, lc)
            return t.assign(log_likelihood=-np.inf, misfit=2e6)
    post = grid_posterior(Nothing((0.0094, -6.5), (1e-4, 0.1)), (0.0086, 0.0102), (1e-8, 1e-5))
    assert not np.isfinite(post.best[2]) and post.levels == 0 and not post.settled
    # no numbers it does not have, and nothing to draw from
    assert np.isnan(post.mean["b"]) and np.isnan(post.interval["log10_lc"][0])
    assert np.isnan(post.edge_mass)
    with pytest.raises(ValueError, match="no cell of the grid has a limit cycle"):
        post.sample(10)


def test_curves_that_do_not_scatter_in_shape_are_refused_by_the_scatter_model():
    """Noise-free events differing only by their offsets: no covariance to whiten with."""
    s = np.linspace(0, 3e-4, 30)
    curves = pd.concat([pd.DataFrame({"event_id": i, "slip_m": s,
                                      "friction": 0.6 + 0.01 * i - 0.04 * (1 - np.exp(-s / 2e-5))})
                        for i in range(6)], ignore_index=True)
    with pytest.raises(ValueError, match="do not scatter in shape"):
        CurveLikelihood.from_curves(curves)
    assert CurveLikelihood.from_curves(curves, "sample", sigma=1e-3).n_events == 6


@pytest.mark.slow
def test_on_w2_the_curves_narrow_log10_lc_and_cover_the_truth():
    """W2 (slip law) at its published fit, observed: the means with 1 % noise (seed 1) and ten
    events' curves sampled in time (50 points each, σ = 2e-3): the grid posterior's 95 %
    interval of log10 Lc with the curves (scatter model) is narrower than without them by at
    least a third (measured here: 1.44 → 0.70 decades), both hold the truth."""
    from benchmarks.devtools.recommendation import recommended
    from benchmarks.inversion import Misfit, synthetic
    from benchmarks.physics.curves import sample_curves
    from benchmarks.physics.metrics import summarize
    from integrators import solve
    from problems import window
    p = window("W2", "slip")
    algorithm, _ = recommended(1e-3)
    sol = solve(p, algorithm, save_every=5e-6, max_points=10 ** 8)
    c = summarize(sol)
    box = ((0.0086, 0.0102), (3e-8, 3e-6))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        means = synthetic(c.recurrence_s, c.friction_drop, 0.01, seed=1)
        curves = sample_curves(sol, n_events=10, n_points=50, noise=2e-3, seed=1,
                               spacing="time")
        both = dataclasses.replace(means, curves=curves)
    widths = {}
    for name, obs in (("means", means), ("curves", both)):
        post = grid_posterior(Misfit(p, obs, algorithm), *box)
        lo, hi = post.interval["log10_lc"]
        assert post.settled and lo < np.log10(3e-7) < hi, (name, lo, hi)
        assert post.interval["b"][0] < 0.0094 < post.interval["b"][1]
        widths[name] = hi - lo
    assert widths["curves"] < widths["means"] * 2 / 3, widths
