"""The grid posterior, the coverage study, the solver-effect comparison and one inversion end to
end (issue 17, items 2–4).

The statistics are checked on an analytic forward model: metrics linear in (b, log10 Lc), where
the posterior under a flat prior is Gaussian with known moments and every 95 % region (J1 ≤ 5.99,
the profile intervals, the highest-density region) covers the truth exactly 95 % of the time.
The solver runs are small (a 5 × 5 grid, W4 with 15 s simulated)."""

import json

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from benchmarks.cli.main import main
from benchmarks.inversion import (Misfit, MetricMap, NO_CYCLE_J1, box_grid, metric_map,
                                  synthetic)
from benchmarks.inversion import calibration as C
from benchmarks.inversion import solver_effect as SE
from benchmarks.studies.solver_effect import STUDY as SOLVER_EFFECT
from benchmarks.inversion.observations import Observations
from benchmarks.devtools.work_precision import algorithm_at
from integrators import Rodas5P
from problems import preset

# the analytic model: ΔT = T0 + A·(b − b0)/db + B·(l − l0)/dl, Δμ = M0 + C·(b − b0)/db + D·(l − l0)/dl
B0, L0, DB, DL = 0.0094, np.log10(3e-7), 2e-4, 0.5
T0, M0 = 3.0, 0.045
JAC = np.array([[0.15, 0.06], [0.001, 0.0018]])     # rows: ΔT, Δμ; columns: b/db, l/dl


def linear_map(n=161, half=8.0) -> MetricMap:
    """The analytic model on a grid of ±``half`` scales around the truth (its node)."""
    b = B0 + DB * np.linspace(-half, half, n)
    l = L0 + DL * np.linspace(-half, half, n)
    x, y = np.meshgrid((b - B0) / DB, (l - L0) / DL, indexing="ij")
    return MetricMap(b=b, log10_lc=l, recurrence_s=T0 + JAC[0, 0] * x + JAC[0, 1] * y,
                     friction_drop=M0 + JAC[1, 0] * x + JAC[1, 1] * y,
                     cycle=np.ones(x.shape, bool), classification=np.full(x.shape, "stick-slip"),
                     algorithm="analytic", n_solves=x.size, n_failed=0, nfev=0, wall_s=0.0,
                     run_wall_s=0.0)


def gaussian_moments(obs: Observations):
    """Mean and covariance of (b, log10 Lc) for the linear model under a flat prior."""
    S = np.diag([1 / obs.sigma_recurrence_s, 1 / obs.sigma_friction_drop])
    J = S @ JAC @ np.diag([1 / DB, 1 / DL])
    cov = np.linalg.inv(J.T @ J)
    r = S @ np.array([obs.recurrence_s - T0, obs.friction_drop - M0])
    mean = np.array([B0, L0]) + cov @ J.T @ r
    return mean, cov


# --- the grid posterior ----------------------------------------------------------------------

def test_the_grid_posterior_of_a_linear_model_is_the_gaussian():
    m = linear_map()
    obs = Observations(3.05, 0.15, 0.0445, 0.00225)
    post = m.posterior(obs)
    mean, cov = gaussian_moments(obs)
    sd = np.sqrt(np.diag(cov))
    assert post.ok and post.edge_mass < 1e-4
    for k, name in enumerate(("b", "log10_lc")):
        assert post.mean[name] == pytest.approx(mean[k], abs=0.01 * sd[k])
        assert post.std[name] == pytest.approx(sd[k], rel=0.01)
        lo, hi = post.interval[name]
        assert lo == pytest.approx(mean[k] - norm.ppf(0.975) * sd[k], abs=0.02 * sd[k])
        assert hi == pytest.approx(mean[k] + norm.ppf(0.975) * sd[k], abs=0.02 * sd[k])
    assert post.mass[post.hpd].sum() == pytest.approx(0.95, abs=0.002)
    assert post.mass.sum() == pytest.approx(1.0)


class LinearMisfit:
    """The analytic model as a misfit, for the refined grid to evaluate."""

    def __init__(self, obs: Observations):
        self.obs = obs

    def evaluate(self, b, lc, progress=False):
        from benchmarks.inversion.objectives import scores, total
        x, y = (np.asarray(b) - B0) / DB, (np.log10(lc) - L0) / DL
        t = total(scores(T0 + JAC[0, 0] * x + JAC[0, 1] * y, M0 + JAC[1, 0] * x + JAC[1, 1] * y,
                         np.ones(x.shape, bool), self.obs))
        return pd.DataFrame({"misfit": t.misfit, "log_likelihood": t.log_likelihood})


def test_a_fixed_grid_is_the_refined_grid_with_no_refinement(monkeypatch):
    """One grid posterior: a map's (its nodes) and the refined grid's before any refinement, on
    the same cells, agree number for number (to rounding: the nodes are computed apart)."""
    from benchmarks.inversion import adaptive
    from benchmarks.inversion.grid import cell_box
    monkeypatch.setattr(adaptive, "MAX_LEVELS", 0)
    m = linear_map(41)
    obs = Observations(3.05, 0.15, 0.0445, 0.00225)
    fixed = m.posterior(obs)
    refined = adaptive.grid_posterior(LinearMisfit(obs), *cell_box(m.b, m.log10_lc), n=41)
    assert refined.levels == 0 and refined.shape is None and fixed.shape == (41, 41)
    np.testing.assert_allclose(refined.mass.reshape(41, 41), fixed.mass, rtol=1e-9, atol=1e-15)
    assert (refined.hpd.reshape(41, 41) == fixed.hpd).all()
    for name in ("b", "log10_lc"):
        for got, want in ((refined.mean, fixed.mean), (refined.std, fixed.std)):
            assert got[name] == pytest.approx(want[name], rel=1e-9)
        assert refined.interval[name] == pytest.approx(fixed.interval[name], rel=1e-9)
    assert refined.side_mass == pytest.approx(fixed.side_mass, abs=1e-12)
    assert refined.best == pytest.approx(fixed.best, rel=1e-9)
    assert refined.prior == fixed.prior


def test_nodes_without_a_cycle_carry_no_mass_and_the_no_cycle_j1():
    m = linear_map(41)
    m.cycle[:20] = False
    obs = Observations(3.0, 0.3, 0.045, 0.0045)
    assert (m.j1(obs)[:20] == NO_CYCLE_J1).all()
    post = m.posterior(obs)
    assert post.mass[:20].sum() == 0 and post.ok
    m.cycle[:] = False
    assert not m.posterior(obs).ok


def test_the_grid_profile_is_the_minimum_over_the_other_parameter():
    m = linear_map(41)
    obs = Observations(3.1, 0.3, 0.046, 0.0045)
    x, J = m.profile(obs, "b")
    assert np.array_equal(x, m.b) and np.array_equal(J, m.j1(obs).min(axis=1))
    with pytest.raises(ValueError, match="parameter must be"):
        m.profile(obs, "lc")


def test_box_grid_nodes_are_the_centres_of_cells_tiling_the_box():
    from benchmarks.inversion.grid import cell_box
    b, l = box_grid((0.008, 0.011), (1e-8, 1e-5), 30, 12)
    assert b[0] == pytest.approx(0.008 + 0.0001 / 2) and b[-1] == pytest.approx(0.011 - 0.00005)
    (b_lo, b_hi), (lc_lo, lc_hi) = cell_box(b, l)
    assert (b_lo, b_hi) == pytest.approx((0.008, 0.011))
    assert (lc_lo, lc_hi) == pytest.approx((1e-8, 1e-5))


def test_box_grid_puts_a_point_on_a_node():
    b, l = box_grid((0.008, 0.011), (1e-8, 1e-5), 31, 31, through=(0.0094123, 3.3e-7))
    assert np.isclose(b, 0.0094123, rtol=0, atol=1e-15).any()
    assert np.isclose(l, np.log10(3.3e-7), rtol=0, atol=1e-12).any()
    assert np.allclose(np.diff(b), np.diff(b)[0]) and len(b) == len(l) == 31
    with pytest.raises(ValueError, match="box must have"):
        box_grid((0.01, 0.008), (1e-8, 1e-5))


def test_the_metric_map_agrees_with_the_misfit_node_by_node():
    problem = preset("W4", law="slip", t_end=15.0)
    alg = Rodas5P(rtol=1e-5, atol=1e-5)
    b, l = box_grid((0.0096, 0.0111), (1e-8, 1e-6), 4, 3)
    m = metric_map(problem, alg, b, l)
    obs = Observations(1.2, 0.12, 0.03, 0.003)
    bb, ll = np.meshgrid(b, l, indexing="ij")
    table = Misfit(problem, obs, alg).evaluate(bb.ravel(), 10.0 ** ll.ravel())
    assert np.array_equal(m.j1(obs).ravel(), table.J1.to_numpy())
    assert m.n_solves == 12 and m.wall_s > 0


# --- coverage ----------------------------------------------------------------------------------

def test_binomial_check_tells_95_from_80_percent():
    ok = C.binomial_check(951, 1000)
    assert ok["consistent"] and ok["excludes_80"] and ok["cp_low"] < 0.951 < ok["cp_high"]
    low = C.binomial_check(800, 1000)
    assert not low["consistent"] and not low["excludes_80"]
    few = C.binomial_check(19, 20)              # 20 seeds cannot tell 95 % from 80 %
    assert few["consistent"] and not few["excludes_80"]


def test_synthetic_data_are_seeded_and_scaled():
    a, b = synthetic(3.0, 0.045, 0.05, 7), synthetic(3.0, 0.045, 0.05, 7)
    assert a == b and a.sigma_recurrence_s == pytest.approx(0.15)
    assert synthetic(3.0, 0.045, 0.05, 8) != a
    with pytest.raises(ValueError, match="sigma_rel"):
        synthetic(3.0, 0.045, 0.0, 0)


def test_every_region_covers_95_percent_on_a_linear_model(monkeypatch):
    """Exact coverage is known for the linear Gaussian model: the study must find it."""
    monkeypatch.setattr(C, "metric_map", lambda *a, **k: linear_map(121))
    cal = C.coverage(None, (B0, 10.0 ** L0), Rodas5P(rtol=1e-6, atol=1e-6),
                     (B0 - 8 * DB, B0 + 8 * DB), (10 ** (L0 - 4), 10 ** (L0 + 4)),
                     seeds=600, n_b=121, n_lc=121, check_seeds=0)
    assert set(cal.summary.region) == set(C.REGIONS)
    for row in cal.summary.itertuples():
        assert row.consistent, (row.region, row.coverage)
        assert row.excludes_80
    assert cal.checks.empty


def test_the_coverage_profiles_are_the_maps_profiles(monkeypatch):
    """Each seed's profile flags are the map's profiles read at the truth (an axis mix-up in
    the study would pass the coverage test above: both profiles are χ²₁ there)."""
    m = linear_map(61)
    monkeypatch.setattr(C, "metric_map", lambda *a, **k: m)
    cal = C.coverage(None, (B0, 10.0 ** L0), None, (B0 - 8 * DB, B0 + 8 * DB),
                     (10 ** (L0 - 4), 10 ** (L0 + 4)), seeds=40, n_b=61, n_lc=61,
                     check_seeds=0)
    i, j = 30, 30                                 # the truth is the middle node
    for row in cal.seeds.itertuples():
        obs = Observations(row.obs_recurrence_s, 0.05 * T0, row.obs_friction_drop, 0.05 * M0)
        J_min = m.j1(obs).min()
        assert row.profile_b == (m.profile(obs, "b")[1][i] - J_min <= 3.841458820694124)
        assert row.profile_log10_lc == (m.profile(obs, "log10_lc")[1][j] - J_min
                                        <= 3.841458820694124)
    # the anisotropic model makes the two profiles differ on some seeds
    assert (cal.seeds.profile_b != cal.seeds.profile_log10_lc).any()


def test_coverage_misuse_is_refused_before_any_work(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("ran")
    monkeypatch.setattr(C, "metric_map", boom)
    box = ((0.008, 0.011), (1e-8, 1e-5))
    for kw, match in (({"seeds": 0}, "seeds"), ({"sigma_rel": 1.5}, "sigma_rel")):
        with pytest.raises(ValueError, match=match):
            C.coverage(None, (0.0094, 3e-7), None, *box, **kw)
    with pytest.raises(ValueError, match="outside the box"):
        C.coverage(None, (0.02, 3e-7), None, *box)


# --- the solver's effect -------------------------------------------------------------------------

def _fake_table():
    rows = []
    for data in ("published", "synthetic"):
        for family, setting, ms, same in (("reference", "ref", 9.0, True),
                                          ("floor", "floor", 20.0, True),
                                          ("own", "cheap", 0.5, data == "published"),
                                          ("own", "mid", 1.0, True), ("ETD", "etd", 50.0, True)):
            rows.append({"window": "W2", "law": "slip", "data": data, "family": family,
                         "setting": setting, "wall_per_solve_ms": ms,
                         "posterior_cost_s": 64 * ms, "indistinguishable": same,
                         "resolved": True})
    return pd.DataFrame(rows)


def test_the_recommendation_is_the_cheapest_indistinguishable_setting():
    advice = SE.recommendation(_fake_table()).set_index("data")
    assert advice.loc["published", "setting"] == "cheap"
    assert advice.loc["synthetic", "setting"] == "mid"
    assert advice.loc["all", "setting"] == "mid"           # cheap fails on one data set
    table = _fake_table()
    table.loc[table.family.isin(["own", "ETD"]), "indistinguishable"] = False
    advice = SE.recommendation(table).set_index("data")
    assert pd.isna(advice.loc["all", "setting"])           # the reference is not a candidate
    table = _fake_table()
    table.loc[table.data == "synthetic", "resolved"] = False
    advice = SE.recommendation(table).set_index("data")
    assert pd.isna(advice.loc["synthetic", "setting"]) and not advice.loc["synthetic", "resolved"]
    assert advice.loc["published", "setting"] == "cheap"
    assert pd.isna(advice.loc["all", "setting"]) and not advice.loc["all", "resolved"]


@pytest.mark.needs("numbalsoda", "scikits.odes")
def test_the_candidates_cover_the_own_ladders_etd_and_the_peers():
    from benchmarks.devtools.work_precision import read_study
    from pathlib import Path
    study = Path(__file__).resolve().parents[1] / "results" / "wp_full.csv"
    families = {c.family for c in SE.candidates(read_study(study) if study.exists() else None)}
    assert {"own", "ETD"} <= families
    if study.exists():
        assert {"LSODA", "SUNDIALS"} <= families
    labels = [c.label for c in SE.candidates()]
    assert "Rodas5P 0.001" in labels and any("(paper)" in x for x in labels)


@pytest.mark.parametrize("shift", [0.02, 0.3, 1.5])
def test_compare_measures_a_known_shift_of_a_gaussian_posterior(shift):
    """Two data sets on one linear map give Gaussian posteriors of equal covariance: their
    mean shift is known, and their overlap is 2Φ(−δ/2), δ the Mahalanobis distance."""
    m = linear_map()
    a = Observations(3.0, 0.15, 0.045, 0.00225)
    b = Observations(3.0 + shift * 0.15, 0.15, 0.045, 0.00225)
    (mu_a, cov), (mu_b, _) = gaussian_moments(a), gaussian_moments(b)
    sd = np.sqrt(np.diag(cov))
    c = SE.compare(m.posterior(a), m.posterior(b))
    d = mu_b - mu_a
    assert c["mean_shift_b_sd"] == pytest.approx(d[0] / sd[0], abs=0.01)
    assert c["mean_shift_log10_lc_sd"] == pytest.approx(d[1] / sd[1], abs=0.01)
    delta = np.sqrt(d @ np.linalg.solve(cov, d))
    assert c["overlap"] == pytest.approx(2 * norm.cdf(-delta / 2), abs=0.01)
    expected = (max(abs(d / sd)) <= SE.SHIFT_SD and 2 * norm.cdf(-delta / 2) >= SE.MIN_OVERLAP)
    assert SE.same_inference({**c, "overlap_box": np.nan}) == expected
    assert not SE.same_inference({**c, "overlap_box": 0.5})


def test_compare_without_a_posterior_is_not_the_same_inference():
    m = linear_map(21)
    obs = Observations(3.0, 0.15, 0.045, 0.00225)
    ok = m.posterior(obs)
    m.cycle[:] = False
    c = SE.compare(ok, m.posterior(obs))
    assert c["overlap"] == 0.0 and np.isnan(c["mean_shift_b_sd"])


def test_the_zoom_holds_the_posterior_and_falls_back_to_the_whole_box():
    m = linear_map(41)
    obs = Observations(3.0, 0.15, 0.045, 0.00225)
    (b_lo, b_hi), (lc_lo, lc_hi) = SE._zoom(m, {"published": obs})
    post = m.posterior(obs)
    inside = ((m.b >= b_lo) & (m.b <= b_hi))[:, None] & (
        (m.log10_lc >= np.log10(lc_lo)) & (m.log10_lc <= np.log10(lc_hi)))[None]
    assert post.mass[~inside].sum() < 1e-6 and b_hi - b_lo < m.b[-1] - m.b[0]
    m.cycle[:] = False
    (b_lo, b_hi), _ = SE._zoom(m, {"published": obs})
    assert b_lo < m.b[0] and b_hi > m.b[-1]


@pytest.mark.slow          # 69 s on 2 cores (pytest --durations, 2026-11-26)
def test_the_solver_effect_table_on_w4():
    loose = SE.Candidate("own", "Rosenbrock23 0.01", algorithm_at("Rosenbrock23", "numba",
                                                                        1e-2))
    table = SE.solver_effect([loose], Rodas5P(rtol=1e-8, atol=1e-8),
                             algorithm_at("Exprb43", "numba", 1e-8),
                             windows=("W4",), laws=("slip",), n=6)
    assert list(table.family) == ["reference", "floor", "own"]
    ref, floor, cand = (table.iloc[k] for k in range(3))
    assert ref.overlap == pytest.approx(1.0) and ref.overlap_box == pytest.approx(1.0)
    assert ref.mean_shift_b_sd == 0 and ref.indistinguishable and ref.n_failed == 0
    assert floor.overlap > 0.999 and floor.indistinguishable and bool(ref.resolved)
    assert 0 < cand.overlap <= 1 and np.isfinite(cand.mean_shift_b_sd)
    assert cand.wall_per_solve_ms > 0 and cand.posterior_cost_s > 0
    assert cand.check_grid == "5x5" and 0 <= cand.outside_mass <= 1
    advice = SE.recommendation(table)
    assert advice.resolved.all()


# --- one inversion end to end, and the command line --------------------------------------------

@pytest.mark.slow
def test_an_inversion_writes_its_files(tmp_path):
    from benchmarks.inversion.invert import invert, write_inversion
    from benchmarks.inversion.observations import observations
    misfit = Misfit(preset("W4", law="slip", t_end=15.0), observations("W4"),
                    Rodas5P(rtol=1e-4, atol=1e-4))
    # 120 steps: a chain at least 10 autocorrelation times long after its burn-in, as a sampled
    # posterior must be (12 steps fail that check, measured)
    inv = invert(misfit, (0.0095, 0.0111), (1e-8, 1e-6), walkers=8, steps=120, method="emcee",
                 profile_points=3)
    summary = write_inversion(inv, tmp_path)
    on_disk = json.loads((tmp_path / "inversion.json").read_text())
    assert on_disk["fit"]["b"] == pytest.approx(summary["fit"]["b"])
    assert on_disk["posterior"]["n_solves"] == inv.posterior.n_solves > 0
    assert "uniform in b" in on_disk["posterior"]["prior"]
    for name in ("fit_starts.csv", "profile_b.csv", "profile_log10_lc.csv", "posterior.csv",
                 "corner.png", "profiles.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    samples = pd.read_csv(tmp_path / "posterior.csv")
    assert list(samples.columns) == ["b", "log10_lc"] and len(samples) == 8 * 90


def test_the_default_inversion_is_the_refined_grid_and_writes_its_cells(tmp_path):
    from benchmarks.inversion.invert import invert, write_inversion
    from benchmarks.inversion.observations import observations
    misfit = Misfit(preset("W4", law="slip", t_end=15.0), observations("W4"),
                    Rodas5P(rtol=1e-4, atol=1e-4))
    inv = invert(misfit, (0.0095, 0.0111), (1e-8, 1e-6), profile_points=3, grid=9)
    summary = write_inversion(inv, tmp_path, {"command": "a test"})
    p = summary["posterior"]
    assert p["method"] == "grid" and p["n_solves"] == inv.posterior.n_solves >= 81
    assert p["interval_95"]["b"][0] < p["mean"]["b"] < p["interval_95"]["b"][1]
    cells = pd.read_csv(tmp_path / "posterior_cells.csv")
    assert cells.mass.sum() == pytest.approx(1.0) and len(cells) == p["n_cells"]
    assert len(pd.read_csv(tmp_path / "posterior.csv")) == 4000
    doc = json.loads((tmp_path / "inversion.json").read_text())
    assert doc["provenance"]["command"] == "a test" and doc["method"] == "grid"
    assert "git_commit" in doc["provenance"] and doc["likelihood"]["curves"] is None
    # the fit started from the grid's best cell, and lies inside its own profile intervals
    assert inv.fit.misfit <= inv.posterior.best[2] + 1e-9
    for name, x in (("b", inv.fit.b), ("log10_lc", np.log10(inv.fit.lc))):
        assert inv.profiles[name].low <= x <= inv.profiles[name].high


def test_no_cycle_in_the_box_means_no_posterior_not_a_frozen_chain(tmp_path):
    from benchmarks.inversion.invert import invert, write_inversion
    from benchmarks.inversion.observations import observations
    misfit = Misfit(preset("W4", law="slip", t_end=15.0), observations("W4"),
                    Rodas5P(rtol=1e-4, atol=1e-4))
    inv = invert(misfit, (0.001, 0.002), (1e-8, 1e-6), walkers=8, steps=10, method="emcee",
                 profile_points=3)                    # b < a: velocity strengthening
    assert not inv.fit.success and inv.posterior is None
    assert "no point of the" in inv.no_posterior
    summary = write_inversion(inv, tmp_path)
    assert summary["posterior"] is None and not (tmp_path / "corner.png").exists()


def test_a_bad_chain_is_refused_before_the_fit():
    from benchmarks.inversion.invert import invert
    from benchmarks.inversion.observations import observations
    misfit = Misfit(preset("W4", law="slip", t_end=15.0), observations("W4"),
                    Rodas5P(rtol=1e-4, atol=1e-4))
    with pytest.raises(ValueError, match="walkers must be"):
        invert(misfit, (0.0095, 0.0111), (1e-8, 1e-6), walkers=2, steps=10, method="emcee")


@pytest.mark.parametrize("argv, match", [
    (["invert", "--preset", "W2", "--b-range", "0.01,0.009"], "--b-range"),
    (["invert", "--preset", "W2", "--lc-range", "0,1e-6"], "--lc-range"),
    (["invert", "--preset", "W2", "--walkers", "2"], "--walkers"),
    (["invert", "--preset", "W2", "--steps", "1"], "--steps"),
    (["invert", "--preset", "paper-example"], "--obs-recurrence is required"),
    (["invert", "--preset", "paper-example", "--obs-recurrence", "3", "--obs-drop", "0.04"],
     "--b-range and --lc-range are required"),
    (["study", "calibration", "--set", "sigma=1.5", "--out", "{tmp}"], "sigma = 1.5"),
])
def test_invert_misuse_is_one_line_and_exit_2(argv, match, capsys, tmp_path):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow                      # several seconds: make test-slow
@pytest.mark.needs("emcee", "corner")
def test_invert_json_prints_one_document(capsys, tmp_path):
    code = main(["invert", "--preset", "W4", "--t-end", "15", "--integrator", "Rodas5P",
                 "--rtol", "1e-4", "--atol", "1e-4", "--method", "emcee", "--steps", "6", "--walkers", "8",
                 "--profile-points", "3", "--out", str(tmp_path / "inv"), "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["integrator"] == "Rodas5P" and doc["posterior"]["n_samples"] == 8 * 5
    assert (tmp_path / "inv" / "corner.png").exists()


def test_joint_misfit_agrees_with_the_sweeps_j(tmp_path):
    """J at fixed weights is the sweep's J at its own weights (Eq. 12)."""
    from pathlib import Path
    from benchmarks.physics.curves import read_curves
    from benchmarks.inversion.joint import joint_misfit
    from benchmarks.inversion.observations import observations
    from benchmarks.inversion.sweep import sweep
    curves = Path(__file__).parent / "data" / "W2_slip_weakening.csv"
    problem = preset("W2", law="slip", t_end=20.0)
    obs = observations("W2", curves=read_curves(curves))
    algorithm = Rodas5P(rtol=1e-8, atol=1e-8)
    table = sweep(problem, [0.0092, 0.0094, 0.0096], [3e-7], algorithm, obs, tmp_path,
                  progress=False).table
    a1, a2 = table.attrs["alpha1"], table.attrs["alpha2"]
    got = joint_misfit(Misfit(problem, obs, algorithm), table.b.to_numpy(),
                       table.lc_m.to_numpy(), a1, a2)
    np.testing.assert_allclose(got.J, table.J, rtol=1e-12)
    with pytest.raises(ValueError, match="alpha2 must be"):
        joint_misfit(Misfit(problem, obs, algorithm), [0.0094], [3e-7], a1, 0.0)
    with pytest.raises(ValueError, match="needs observed slip-weakening curves"):
        joint_misfit(Misfit(problem, observations("W2"), algorithm), [0.0094], [3e-7], 1.0, 1.0)


def test_an_inversion_without_any_cycle_exits_1_and_an_unwritable_out_is_refused_first(
        capsys, tmp_path):
    argv = ["invert", "--preset", "W4", "--t-end", "15", "--integrator", "Rodas5P", "--rtol",
            "1e-4", "--atol", "1e-4", "--steps", "0", "--profile-points", "3"]
    assert main(argv + ["--wall-budget", "1e-9", "--out", str(tmp_path / "a"), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["fit"]["success"] is False and doc["posterior"] is None
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(argv + ["--out", str(blocker / "sub")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def _timed_map(n_solves, run_wall_s):
    z = np.zeros((1, 1))
    return MetricMap(b=z[0], log10_lc=z[0], recurrence_s=z, friction_drop=z, cycle=z > 0,
                     classification=z, algorithm="x", n_solves=n_solves, n_failed=0, nfev=0,
                     wall_s=0.0, run_wall_s=run_wall_s)


def test_the_posterior_cost_counts_an_ensembles_fixed_cost_once():
    # 3 s to start an ensemble, 10 ms per solve: 4 solves take 3.04 s, 961 take 12.61 s; a
    # 64,000-solve posterior is 3 + 640 s (64,000 × 12.61 / 961 = 839.8 s counted it 67 times)
    small, big = _timed_map(4, 3.04), _timed_map(961, 12.61)
    assert SE.posterior_cost(small, big) == pytest.approx(643.0)
    assert SE.posterior_cost(small, big, solves=4) == pytest.approx(3.04)
    # noise that makes the big map no slower than the small one costs no solves, not a negative
    assert SE.posterior_cost(small, _timed_map(961, 3.0)) == pytest.approx(3.04)
    with pytest.raises(ValueError, match="more solves"):
        SE.posterior_cost(big, small)


@pytest.mark.parametrize("n", [2, 2.5, True])
def test_solver_effect_refuses_a_grid_too_small_for_the_cost_before_any_work(n, monkeypatch):
    monkeypatch.setattr(SE, "metric_map", lambda *a, **k: pytest.fail("work was done"))
    with pytest.raises(ValueError, match="n must be an integer of at least 3"):
        SE.solver_effect([], Rodas5P(rtol=1e-8, atol=1e-8), Rodas5P(rtol=1e-9, atol=1e-9),
                         windows=("W4",), laws=("slip",), n=n)


def test_solver_effect_takes_an_observations_file(tmp_path):
    """--set observations=FILE: the file's means and σ are the data set "yours" on every window
    and law (its curves left out: the posteriors score J1); a file that cannot be read, or an
    unknown window, is refused by the study's check before any work."""
    from benchmarks.inversion.observations import write_observations
    events = pd.DataFrame({"t_start": [0.0, 3.0, 6.0], "t_end": [0.01, 3.01, 6.01],
                           "recurrence_s": [np.nan, 3.0, 3.1],
                           "friction_drop": [0.045, 0.046, 0.044],
                           "slip_m": [3e-4, 3e-4, 3e-4], "peak_velocity_m_s": [0.05] * 3})
    path = tmp_path / "observations.json"
    write_observations(path, events)
    settings = {**SOLVER_EFFECT.settings, "observations": str(path), "windows": "W1",
                "laws": "slip"}
    SOLVER_EFFECT.checked(settings)
    yours = Observations(3.05, 0.07, 0.045, 0.001, curves=pd.DataFrame(
        {"event_id": [1, 1], "slip_m": [0.0, 1e-4], "friction": [0.6, 0.58]}),
        curve_noise="none")
    data = SE._datasets("W1", "slip", None, None, yours)
    assert set(data) == {"published", "yours"} and data["yours"].curves is None
    assert data["yours"].recurrence_s == 3.05
    with pytest.raises(ValueError, match="setting observations: observations file"):
        SOLVER_EFFECT.checked({**settings, "observations": str(tmp_path / "none.json")})
    with pytest.raises(ValueError, match="setting windows = 'W1,W9'"):
        SOLVER_EFFECT.checked({**settings, "windows": "W1,W9"})


def test_the_solver_effect_command_imports_no_study():
    """``rsfbench solver-effect`` writes a user's files, report and figure with the library
    (:func:`benchmarks.inversion.solver_effect.write_solver_effect`); nothing it imports, at
    module level or inside a function, is a study (``benchmarks.studies.solver_effect`` is the
    run of results/)."""
    from benchmarks.pipeline import manifest as M
    graph = M.import_graph(M.ROOT, ("benchmarks",))
    seen, todo = set(), ["benchmarks.cli.solver_effect"]
    while todo:
        module = todo.pop()
        if module not in seen:
            seen.add(module)
            todo.extend(graph.get(module, ()))
    assert "benchmarks.inversion.solver_effect" in seen
    assert sorted(m for m in seen if m.startswith("benchmarks.studies")) == []


def test_the_settled_coverage_apparatus_is_the_independent_recording_s():
    """The problem file the settled-coverage study inverts with is the apparatus its recordings
    are made of (benchmarks/lab/independent_stick_slip.py), read back as a problem."""
    import tomllib
    from benchmarks.lab import independent_stick_slip as radau
    from benchmarks.studies.settled_coverage import problem_file
    from problems import load_problem
    doc = tomllib.loads(problem_file())
    assert (doc["mass"], doc["stiffness"], doc["normal_force"]) == (radau.M, radau.K, radau.FN)
    assert (doc["law"]["a"], doc["law"]["b"], doc["law"]["lc"]) == (radau.A_LAW, radau.B_LAW,
                                                                    radau.LC)
    assert (doc["loading"]["vls"], doc["loading"]["vlf"]) == (radau.VLS, radau.VLF)


def test_the_settled_coverage_report_counts_against_the_binomial_range():
    """18 of 20 covering is inside Binomial(20, 0.95)'s 95 % range (17–20); 15 is not."""
    from benchmarks.studies.settled_coverage import settled_markdown
    n = 20
    rows = pd.DataFrame({"seed": range(n), "startup": 4, "err_dT": 1e-5, "err_dmu": 2e-3,
                         "err_slip": -1e-4, "sd_rel_dT": 1e-5,
                         "means_covered": [True] * 18 + [False] * 2, "means_s": 60.0,
                         "means_from": "posterior (grid)", "curves_covered": [True] * 15 +
                         [False] * 5, "curves_s": 200.0, "curves_from": "profiles (no)",
                         "effect_exit": 0, "effect_s": 30.0, "effect_answered": True})
    text = settled_markdown(rows, {"duration_s": 60.0, "rate_hz": 1e4, "noise": 0.01})
    means = next(line for line in text.splitlines() if line.startswith("| means"))
    curves = next(line for line in text.splitlines() if line.startswith("| curves"))
    assert "18 / 20" in means and "| yes |" in means and "17–20" in means
    assert "15 / 20" in curves and "**no**" in curves and "| 0 / 20 |" in curves
    assert "within 0.1 % in all three: 0 / 20" in text      # Δμ 0.2 % off in every one
    assert "answered on 20 / 20" in text
    # a curves' inversion stopped at the study's budget: no verdict, so not covered
    stopped = rows.drop(columns=["curves_covered", "curves_from"]).assign(curves_exit=-1)
    text = settled_markdown(stopped, {"duration_s": 60.0, "rate_hz": 1e4, "noise": 0.01})
    curves = next(line for line in text.splitlines() if line.startswith("| curves"))
    assert "0 / 20" in curves and curves.rstrip(" |").endswith("20")
