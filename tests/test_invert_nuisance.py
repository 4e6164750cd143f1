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


@pytest.mark.parametrize("args, match", [
    (["--nuisance", "df=1%"], "inversion can free"),
    (["--nuisance", "k=0"], "σ above 0"),
    (["--nuisance", "k=3%", "--nuisance", "stiffness=1e6"], "named twice"),
    (["--nuisance", "k=3%", "--method", "emcee"], "--method emcee"),
    (["--nuisance", "k=3%", "--integrator", "Tsit5"], "Rodas5P"),
    (["--nuisance", "vl=1%"], "no parameter 'vl'"),       # W2 loads at vls, then vlf
    (["--nuisance-sampler", "nested"], "add --nuisance"),
])
def test_misuse_is_refused_in_one_line_before_any_work(tmp_path, args, match):
    out = _cli("--preset", "W2", "--law", "slip", *args, "--out", tmp_path / "o", timeout=120)
    assert out.returncode == 2 and match in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_the_proposal_is_capped_to_a_tenth_of_each_span():
    cov = np.array([[169.0, 0.13], [0.13, 0.01]])   # sd 13 and 0.1, correlation 0.1
    fitted = NuisanceFit(("log10_lc", "b"), np.zeros(2), cov, np.sqrt(np.diag(cov)), 0.0, 1,
                         bounds=(np.array([-8.0, 0.0]), np.array([-6.0, 10.0])))
    prop = proposal_covariance(fitted)
    sd = np.sqrt(np.diag(prop))
    assert sd == pytest.approx([0.2, 0.1])          # capped at 2/10; within 10/10 kept
    assert prop[0, 1] / (sd[0] * sd[1]) == pytest.approx(0.1)


def test_the_nested_sampler_weights_its_draws(tmp_path):
    """The default sampler: each draw of (k, vLs) from the priors with (b, log10 Lc) fitted
    for it; weights that sum to 1, an effective size, the intervals within the box."""
    out = _cli("--preset", "W2", "--law", "slip", "--nuisance", "k=3%", "--nuisance", "vls=2%",
               "--steps", "30", "--no-solver-check", "--out", tmp_path, "--json")
    assert out.returncode == 0, out.stderr
    s = json.loads(out.stdout)["sampler"]
    assert s["method"].startswith("nested") and s["draws"] == 30
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
