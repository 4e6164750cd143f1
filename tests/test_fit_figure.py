"""fit.png of ``rsfbench invert``: the model at the least-squares fit drawn over the observed
events and curves. The figure's lines are checked against an independent evaluation of the same
point (``Misfit.evaluate``), the file against its size, and the command end to end."""

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from benchmarks.cli.main import main
from benchmarks.inversion import Misfit
from benchmarks.inversion.fit_figure import (MODEL_GID, fit_figure, model_at, observed_events,
                                             plot_fit)
from benchmarks.inversion.invert import Inversion, inversion_files, write_inversion
from benchmarks.inversion.least_squares import FitResult
from benchmarks.inversion.observations import Observations, observations, write_observations
from benchmarks.physics.curves import sample_curves
from benchmarks.physics.metrics import event_metrics
from integrators import Rodas5P, solve
from problems import preset, variant

#: W4 (slip law) over 15 s: ~35 events of ΔT ≈ 0.43 s, a few ms per solve
ALGORITHM = Rodas5P(rtol=1e-4, atol=1e-4)
B, LC = 0.0103, 1e-7


def _problem():
    return preset("W4", law="slip", t_end=15.0)


def _inversion(obs) -> Inversion:
    """An Inversion whose fit is (B, LC): the figure reads only the misfit and the fit."""
    fit = FitResult(B, LC, 0.5, np.eye(2), 1e-4, 0.1, 1, pd.DataFrame())
    return Inversion(Misfit(_problem(), obs, ALGORITHM), (0.0095, 0.0111), (1e-8, 1e-6), fit,
                     {}, None, {})


@pytest.fixture(scope="module")
def recorded():
    """The events and curves of a run at a nearby point (b 1 % higher), with noise: a
    per-event table (its last 12 events, ΔT and Δμ with 0.5 % noise) and 5 events' curves."""
    sol = solve(variant(_problem(), b=1.01 * B, lc=LC), ALGORITHM, save_every=2e-5)
    rng = np.random.default_rng(3)
    events = event_metrics(sol.events, sol.problem.normal_force).iloc[-12:].reset_index(drop=True)
    for name in ("recurrence_s", "friction_drop"):
        events[name] *= 1 + 5e-3 * rng.standard_normal(len(events))
    curves = sample_curves(sol, n_events=5, n_points=40, noise=1e-3, seed=3, spacing="time")
    return events, curves


def _model_lines(ax):
    return [line for line in ax.get_lines() if line.get_gid() == MODEL_GID]


def test_typed_in_means_show_the_band_and_the_model_s_values():
    obs = observations("W4")                      # the published means, σ assumed
    inv = _inversion(obs)
    fig = fit_figure(inv)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    # the same point evaluated by the misfit, not by the figure's own solve
    row = inv.misfit.evaluate([B], [LC]).iloc[0]
    for ax, name in zip(fig.axes, ("recurrence_s", "friction_drop")):
        (line,) = _model_lines(ax)
        assert line.get_ydata()[0] == pytest.approx(row[name], rel=1e-12)
        assert "typed-in means" in ax.get_xlabel()
        assert not [ln for ln in ax.get_lines() if ln.get_marker() == "o"]   # no event points
        (band,) = ax.patches
        lo, hi = band.get_y(), band.get_y() + band.get_height()
        mean, sigma = (obs.recurrence_s, obs.sigma_recurrence_s) if name == "recurrence_s" \
            else (obs.friction_drop, obs.sigma_friction_drop)
        assert (lo, hi) == pytest.approx((mean - sigma, mean + sigma), rel=1e-12)


def test_events_and_curves_are_drawn_with_the_model_over_them(recorded):
    events, curves = recorded
    obs = Observations(float(events.recurrence_s.mean()), float(events.recurrence_s.std()),
                       float(events.friction_drop.mean()), float(events.friction_drop.std()),
                       curves=curves)
    inv = _inversion(obs)
    model = model_at(inv.misfit, B, LC)
    fig = fit_figure(inv, events, model)
    assert len(fig.axes) == 3
    points = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() == "o"]
    np.testing.assert_array_equal(points[0].get_xdata(), events.t_start)
    np.testing.assert_array_equal(points[0].get_ydata(), events.recurrence_s)
    row = inv.misfit.evaluate([B], [LC]).iloc[0]
    assert _model_lines(fig.axes[1])[0].get_ydata()[0] == pytest.approx(row.friction_drop,
                                                                          rel=1e-12)
    # the model's curve is the misfit's (the one its curves' χ² reads), in µm
    (curve,) = _model_lines(fig.axes[2])
    np.testing.assert_allclose(curve.get_xdata(), np.asarray(row.curve_slip) * 1e6, rtol=1e-12)
    observed = [ln for ln in fig.axes[2].get_lines() if ln.get_color() == "0.55"]
    assert len(observed) == 5
    # each observed event shifted by its best offset: its mean residual against the drawn
    # model curve is the same for every event (it is zero after the shift, up to the common
    # level that both share)
    left = [np.mean(np.interp(ln.get_xdata(), curve.get_xdata(), curve.get_ydata())
                    - ln.get_ydata()) for ln in observed]
    assert np.ptp(left) < 1e-12 and abs(left[0]) < 1e-12
    assert f"χ² = {obs.curve_likelihood.chi2(row.curve_slip, row.curve_friction):.4g}" in \
        fig.axes[2].get_title()


def test_events_left_out_of_the_means_are_drawn_apart(recorded):
    """observe's start-up (``kept`` False) is shown, hollow, beside the events of the means."""
    events, _ = recorded
    events = events.assign(kept=np.arange(len(events)) >= 2)      # the first two: a start-up
    obs = Observations(float(events.recurrence_s.mean()), float(events.recurrence_s.std()),
                       float(events.friction_drop.mean()), float(events.friction_drop.std()))
    fig = fit_figure(_inversion(obs), events, model_at(_inversion(obs).misfit, B, LC))
    used, left = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() == "o"]
    np.testing.assert_array_equal(used.get_xdata(), events.t_start[2:])
    np.testing.assert_array_equal(left.get_xdata(), events.t_start[:2])
    assert left.get_markerfacecolor() == "none" and "left out" in left.get_label()


def test_plot_fit_writes_a_png_of_the_figure_s_size(tmp_path):
    inv = _inversion(observations("W4"))
    drawn = plot_fit(inv, tmp_path / "fit.png")
    data = (tmp_path / "fit.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert (width, height) == (round(2 * 4.6 * 110), round(4.2 * 110))   # 2 panels at 110 dpi
    assert drawn["retcode"] == "Success" and drawn["recurrence_s"] > 0
    assert "chi2_curves" not in drawn                         # no curves in the likelihood


def test_observed_events_reads_the_per_event_table(recorded, tmp_path):
    events, curves = recorded
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_observations(tmp_path / "o.json", events, curves)
    back = observed_events(tmp_path / "o.json")
    np.testing.assert_allclose(back.recurrence_s, events.recurrence_s, rtol=1e-12)
    (tmp_path / "none.json").write_text(json.dumps({"events": {}}))
    assert observed_events(tmp_path / "none.json") is None
    (tmp_path / "bad.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="bad.json"):
        observed_events(tmp_path / "bad.json")


def test_fit_png_is_one_of_the_inversion_s_files(tmp_path):
    assert tmp_path / "fit.png" in inversion_files(tmp_path)
    # a user's fit.png there is refused before anything is written
    (tmp_path / "fit.png").write_bytes(b"mine")
    with pytest.raises(Exception, match="fit.png"):
        write_inversion(_inversion(observations("W4")), tmp_path)
    assert (tmp_path / "fit.png").read_bytes() == b"mine"
    assert not (tmp_path / "inversion.json").exists()


@pytest.mark.slow                      # ~30 s: the inversion's ~1,000 solves, with curves
def test_invert_draws_the_fit_over_an_observations_file(recorded, tmp_path, capsys):
    events, curves = recorded
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_observations(tmp_path / "observations.json", events, curves)
    out = tmp_path / "inv"
    code = main(["invert", "--preset", "W4", "--t-end", "15", "--integrator", "Rodas5P",
                 "--rtol", "1e-4", "--atol", "1e-4", "--steps", "0", "--profile-points", "3",
                 "--b-range", "0.0095,0.0111", "--lc-range", "1e-8,1e-6",
                 "--observations", str(tmp_path / "observations.json"), "--out", str(out),
                 "--no-solver-check", "--workers", "1",
                 "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["files"]["fit_plot"] == str(out / "fit.png") and (out / "fit.png").exists()
    model = doc["fit"]["model"]
    again = model_at(Misfit(_problem(), Observations(1, 0.1, 0.05, 0.005), ALGORITHM),
                     doc["fit"]["b"], doc["fit"]["lc_m"])
    assert model["recurrence_s"] == pytest.approx(again.recurrence_s, rel=1e-12)
    assert model["chi2_curves"] >= 0
