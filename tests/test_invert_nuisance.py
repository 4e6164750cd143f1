"""``rsfbench invert --nuisance``: (b, Lc) with apparatus constants under stated priors, through
the command line; its misuse refused before any work (:mod:`benchmarks.cli.invert_nuisance`)."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from benchmarks.inversion.nuisance import NuisanceFit, proposal_covariance


def _cli(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "benchmarks.cli", "invert", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def test_the_command_fits_and_samples_w2_with_the_stiffness_and_load_speed_free(tmp_path):
    """W2/slip's published means (σ assumed 10 %) with k and vLs known to 3 % and 2 %: the
    means cannot tell the constants from their priors, so the fit keeps them at the priors'
    means and the sampler's spread of each is about its prior's; the chain moves (with the
    uncapped Laplace proposal, log10 Lc's sd of 13 decades in a box of 2, it accepted 1 step
    of 50 and its intervals were a point)."""
    out = _cli("--preset", "W2", "--law", "slip", "--nuisance", "k=3%", "--nuisance",
               "vls=2%", "--nuisance-sampler", "metropolis", "--steps", "400",
               "--no-solver-check", "--out", tmp_path, "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["names"] == ["b", "log10_lc", "stiffness", "vls"] and doc["success"]
    table = pd.read_csv(tmp_path / "nuisance_parameters.csv").set_index("parameter")
    k = table.loc["stiffness"]
    assert k.prior_sd == pytest.approx(0.03 * k.prior_mean)
    assert abs(k.estimate - k.prior_mean) < 0.05 * k.prior_sd
    s = doc["sampler"]
    assert 0.1 < s["acceptance"] < 0.8 and s["steps"] == 400
    assert 0.3 < s["sd"]["stiffness"] / k.prior_sd < 2.0
    lo, hi = s["interval_95"]["log10_lc"]
    assert hi - lo > 0.05
    samples = pd.read_csv(tmp_path / "nuisance_samples.csv")
    assert len(samples) == 400 and (tmp_path / "nuisance.png").stat().st_size > 0
    assert "command" in doc["provenance"] and "integrator_choice" in doc["provenance"]
    # without --integrator: the front's fastest setting with sensitivities within --accuracy
    from benchmarks.cli.args import ACCURACY, sensitive_default
    assert doc["provenance"]["integrator_choice"].startswith(
        sensitive_default(ACCURACY, "--nuisance")[1])


def test_a_named_method_with_sensitivities_is_tightened_to_the_gradients_rtol(tmp_path):
    out = _cli("--preset", "W2", "--law", "slip", "--nuisance", "k=3%", "--integrator",
               "RadauIIA5", "--rtol", "1e-4", "--atol", "1e-4", "--steps", "0", "--no-solver-check",
               "--out", tmp_path, "--json")
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert doc["provenance"]["integrator_choice"].startswith(
        "RadauIIA5 at rtol 1e-06, atol 1e-06, tightened from rtol 0.0001, atol 0.0001")
    # at the top of the document as well, where invert and sweep put it
    assert doc["integrator_choice"] == doc["provenance"]["integrator_choice"]
    assert doc["out"] == str(tmp_path)
    assert doc["names"] == ["b", "log10_lc", "stiffness"] and doc["success"]


@pytest.mark.parametrize("args, match", [
    (["--nuisance", "df=1%"], "inversion can free"),
    (["--nuisance", "k=0"], "σ above 0"),
    (["--nuisance", "k=3%", "--nuisance", "stiffness=1e6"], "named twice"),
    (["--nuisance", "k=3%", "--method", "emcee"], "--method emcee"),
    (["--nuisance", "k=3%", "--integrator", "scipy-RK45"], "name Rodas5P or RadauIIA5"),
    (["--nuisance", "vl=1%"], "has no vl"),       # W2 loads at vls, then vlf
    (["--nuisance-sampler", "nested"], "add --nuisance"),
    (["--nuisance", "k=3%", "--rtol", "1e-7"], "need --integrator"),
    (["--nuisance", "k=3%", "--integrator", "RadauIIA5", "--rtol", "1e-7", "--atol", "1e-7",
      "--accuracy", "1e-5"], "with --integrator it has no effect"),
    (["--accuracy", "1.5"], "below 1"),
])
def test_misuse_is_refused_in_one_line_before_any_work(tmp_path, args, match):
    out = _cli("--preset", "W2", "--law", "slip", *args, "--out", tmp_path / "o", timeout=120)
    assert out.returncode == 2 and match in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_the_proposal_is_shrunk_as_a_whole_to_a_tenth_of_each_span():
    # sd 13 and 0.1, correlation 0.9: shrunk by 2/10/13 as a whole, its shape kept (a cap per
    # parameter turned a thin valley's long axis off the valley)
    cov = np.array([[169.0, 1.17], [1.17, 0.01]])
    fitted = NuisanceFit(("log10_lc", "b"), np.zeros(2), cov, np.sqrt(np.diag(cov)), 0.0, 1,
                         bounds=(np.array([-8.0, 0.0]), np.array([-6.0, 10.0])))
    prop = proposal_covariance(fitted)
    assert np.sqrt(np.diag(prop)) == pytest.approx([0.2, 0.1 * 0.2 / 13])
    assert prop / prop[0, 0] == pytest.approx(cov / cov[0, 0])


def test_the_nested_sampler_weights_its_draws(tmp_path):
    """The default sampler: each draw of (k, vLs) from the priors with (b, log10 Lc) fitted
    for it; weights that sum to 1, an effective size, the intervals within the box."""
    out = _cli("--preset", "W2", "--law", "slip", "--nuisance", "k=3%", "--nuisance", "vls=2%",
               "--steps", "30", "--no-solver-check", "--out", tmp_path, "--json")
    assert out.returncode == 0, out.stderr
    s = json.loads(out.stdout)["sampler"]
    assert s["method"].startswith("nested") and s["draws"] == 30
    assert "few effective samples" in out.stderr          # 30 draws: under 50, said
    assert 1.0 <= s["effective_draws"] <= 30.0
    samples = pd.read_csv(tmp_path / "nuisance_samples.csv")
    assert samples.weight.sum() == pytest.approx(1.0) and (samples.inner_solves > 0).all()
    lo, hi = s["interval_95"]["b"]
    assert samples.b.min() <= lo <= hi <= samples.b.max()


def test_the_weighted_summary_of_draws():
    # 20,000 draws of N(0, 1) weighted by N(1, 1)/N(0, 1) ∝ exp(x − ½): a sample of N(1, 1)
    from benchmarks.inversion.nested_laplace import weighted_summary
    x = np.random.default_rng(3).standard_normal(20_000)
    w = np.exp(x - 0.5)
    s = weighted_summary(pd.DataFrame({"x": x, "weight": w / w.sum()}), ["x"])
    assert s["mean"]["x"] == pytest.approx(1.0, abs=0.05)
    assert s["sd"]["x"] == pytest.approx(1.0, abs=0.05)
    assert s["interval_95"]["x"] == pytest.approx([1 - 1.96, 1 + 1.96], abs=0.1)
    assert 0.25 * 20_000 < s["effective_draws"] < 0.5 * 20_000     # e^{-1} of them in theory


class _LinearMisfit:
    """Residuals linear in (b, log10 Lc, θ1, θ2): r = 100 (b, log10 Lc) + (10 θ1, 0), whose
    posterior is known in closed form."""

    def __init__(self):
        self.failures = {"solves": 0}

    def residuals_and_jacobian(self, values):
        self.failures["solves"] += 1
        u = np.log10(values["lc"])
        r = np.array([100.0 * values["b"] + 10.0 * values["t1"], 100.0 * u])
        jac = np.array([[100.0, 0.0, 10.0, 0.0],
                        [0.0, 100.0 / (values["lc"] * np.log(10.0)), 0.0, 0.0]])
        return r, jac


@pytest.mark.parametrize("b_low", [-1.0, -0.05])
def test_the_nested_sampler_matches_a_posterior_known_in_closed_form(b_low):
    """θ1 ~ N(0, 1) moves the best b to −θ1/10 (sd 0.01 about it): with the box wide (b from
    −1) the data leave θ1 at its prior; with b ≥ −0.05 the box cuts every θ1 above 0.5, and
    θ1's posterior is its prior times Φ((b* + 0.05)/0.01)'s complement, integrated here on a
    grid. The nested draws' weighted mean and sd of θ1 and b agree within their Monte Carlo
    error (1500 draws)."""
    from scipy.stats import norm

    from benchmarks.inversion.nested_laplace import sample_nested, weighted_summary
    names = ("b", "log10_lc", "t1", "t2")
    lo, hi = np.array([b_low, -1.0, -5.0, -5.0]), np.array([1.0, 1.0, 5.0, 5.0])
    fitted = NuisanceFit(names, np.zeros(4), np.eye(4), np.ones(4), 0.0, 1,
                         priors={"t1": (0.0, 1.0), "t2": (0.0, 1.0)}, bounds=(lo, hi))
    table = sample_nested(_LinearMisfit(), fitted, draws=1500, seed=1)
    s = weighted_summary(table, names)
    t = np.linspace(-5, 5, 20001)
    bstar = -t / 10.0
    mass = norm.cdf((hi[0] - bstar) / 0.01) - norm.cdf((lo[0] - bstar) / 0.01)
    p = norm.pdf(t) * mass
    p /= p.sum()
    mean_t = float((t * p).sum())
    sd_t = float(np.sqrt(((t - mean_t) ** 2 * p).sum()))
    mc = sd_t / np.sqrt(s["effective_draws"])
    assert s["mean"]["t1"] == pytest.approx(mean_t, abs=4 * mc)
    assert s["sd"]["t1"] == pytest.approx(sd_t, rel=0.1)
    # b = b* + N(0, 0.01²) cut to the box: its mean follows θ1's
    assert s["mean"]["b"] == pytest.approx(-mean_t / 10.0, abs=4 * mc / 10.0 + 0.002)
    assert s["mean"]["t2"] == pytest.approx(0.0, abs=4 / np.sqrt(s["effective_draws"]))
    if b_low > -1:
        assert mean_t < -0.1 and table.b.min() >= b_low      # the cut moved θ1, no draw out


class _UnresolvedMisfit(_LinearMisfit):
    """r = (100 b, c(θ2) log10 Lc) with c = ½ e^{2 θ2}: where θ2 is low, Lc is unresolved in
    its box of [−1, 1] decades."""

    def residuals_and_jacobian(self, values):
        self.failures["solves"] += 1
        c = 0.5 * np.exp(2.0 * values["t2"])
        u = np.log10(values["lc"])
        return (np.array([100.0 * values["b"], c * u]),
                np.array([[100.0, 0.0, 0.0, 0.0],
                          [0.0, c / (values["lc"] * np.log(10.0)), 0.0, 0.0]]))


def test_the_nested_weights_count_the_box_where_a_parameter_is_unresolved():
    """p(θ2 | data) ∝ N(θ2; 0, 1) ∫ e^{−c² u²/2} du over the box, which is
    N(θ2; 0, 1)·√(2π)(2Φ(c) − 1)/c: finite where c → 0 (its mean −0.34, on a grid here).
    Without the box's mass in the weights, 1/c alone makes it N(−2, 1), and the test fails
    (checked by taking the mass out)."""
    from scipy.stats import norm

    from benchmarks.inversion.nested_laplace import sample_nested, weighted_summary
    names = ("b", "log10_lc", "t1", "t2")
    lo, hi = np.array([-1.0, -1.0, -5.0, -5.0]), np.array([1.0, 1.0, 5.0, 5.0])
    fitted = NuisanceFit(names, np.zeros(4), np.eye(4), np.ones(4), 0.0, 1,
                         priors={"t1": (0.0, 1.0), "t2": (0.0, 1.0)}, bounds=(lo, hi))
    s = weighted_summary(sample_nested(_UnresolvedMisfit(), fitted, draws=1500, seed=2), names)
    t = np.linspace(-5, 5, 20001)
    c = 0.5 * np.exp(2.0 * t)
    p = norm.pdf(t) * (2 * norm.cdf(c) - 1) / c
    p /= p.sum()
    mean_t = float((t * p).sum())
    sd_t = float(np.sqrt(((t - mean_t) ** 2 * p).sum()))
    assert s["mean"]["t2"] == pytest.approx(mean_t, abs=4 * sd_t / np.sqrt(s["effective_draws"]))


def test_the_nested_draws_do_not_depend_on_how_many_threads_fit_them():
    """The draws' fits run side by side; the constants are drawn before and the box draws
    after, in order, so the table is the same on one thread and on three."""
    from benchmarks.inversion.nested_laplace import sample_nested
    names = ("b", "log10_lc", "t1", "t2")
    lo, hi = np.array([-1.0, -1.0, -5.0, -5.0]), np.array([1.0, 1.0, 5.0, 5.0])
    fitted = NuisanceFit(names, np.zeros(4), np.eye(4), np.ones(4), 0.0, 1,
                         priors={"t1": (0.0, 1.0), "t2": (0.0, 1.0)}, bounds=(lo, hi))
    tables = []
    for workers in (1, 3):
        misfit = _UnresolvedMisfit()
        misfit.workers = workers
        tables.append(sample_nested(misfit, fitted, draws=40, seed=5))
        if workers == 1:        # (the fake's own count is not guarded against threads)
            assert misfit.failures["solves"] == tables[-1].inner_solves.sum()
    pd.testing.assert_frame_equal(tables[0], tables[1])


def test_a_misfit_counts_each_threads_solves_apart():
    """A sampler's draws run on threads: each reads its own solves (solves_here), and the
    misfit's total is their sum."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    from benchmarks.inversion.misfit import Misfit, synthetic
    from integrators import Rodas5P
    from problems import window
    problem = window("W2", "slip", t_end=10.0)
    misfit = Misfit(problem, synthetic(3.0446, 0.04522, 0.01, seed=0),
                    Rodas5P(rtol=1e-6, atol=1e-6))

    both = threading.Barrier(2)             # each draw on a thread of its own

    def draw(k):
        both.wait(timeout=60)
        for _ in range(k):
            misfit.residuals_and_jacobian({"b": problem.law.b, "lc": problem.law.lc})
        return misfit.solves_here

    with ThreadPoolExecutor(max_workers=2) as pool:
        here = list(pool.map(draw, [1, 2]))
    assert misfit.solves_here == 0 and misfit.failures["solves"] == sum(here) >= 3


def test_the_gradients_setting_tightens_rtol_and_atol_alike():
    from benchmarks.inversion.misfit import sensitive_setting
    from integrators import RadauIIA5, Rodas5P, Rosenbrock23
    kept = RadauIIA5(rtol=1e-7, atol=1e-8)
    assert sensitive_setting(kept) is kept
    loose = sensitive_setting(Rodas5P(rtol=1e-7, atol=1e-2))
    assert (loose.name, loose.rtol, loose.atol) == ("Rodas5P", 1e-7, 1e-6)
    other = sensitive_setting(Rosenbrock23(rtol=1e-3, atol=1e-3))   # no sensitivities
    assert (other.name, other.rtol, other.atol) == ("Rodas5P", 1e-6, 1e-6)
