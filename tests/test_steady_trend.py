"""The trend read where the slider is steady (benchmarks/lab/steady_trend.py, ``--detrend
steady``): each piece's slope from its steady part only, recovered on records of the
independent model (scipy's Radau) with a different trend in each piece; a fit that holds it
recovers (a, b, Dc) inside its intervals; a piece whose evolution does not end keeps the slope
before it, and says so."""

import numpy as np
import pytest

from benchmarks.lab.fit import fit_lab
from benchmarks.lab.independent_model import synthetic_record
from benchmarks.lab.model import LabModel
from benchmarks.lab.steady_trend import steady_trend, travel_columns
from benchmarks.lab.step_data import lab_record_from

COLUMNS = ["time=time_s", "load_point=load_point_um:um", "friction=friction"]
#: three steps (up ×10, down ×10, up ×3), 10⁴ samples over 150 s; Dc = 10 µm is 1 s at 10 µm/s
T = np.linspace(0.0, 150.0, 10_000)
VELOCITIES, SWITCHES = (1e-6, 1e-5, 1e-6, 3e-6), (20.0, 50.0, 100.0)
TRUTH = dict(a=0.006, b=0.009, dc=10e-6, k=3e3)
#: a trend per piece, per metre of load-point travel (5e-5 per µm is 50): a different one in
#: each piece, as a gouge that compacts at a rate of its own would give
SLOPES = (50.0, -30.0, 80.0, 20.0)


def _record(t=T, slopes=SLOPES, seed=0, noise=6e-4):
    df = synthetic_record(t, VELOCITIES, SWITCHES, **TRUTH, noise=noise, seed=seed)
    df["friction"] += travel_columns(t, VELOCITIES, SWITCHES) @ np.asarray(slopes)
    return lab_record_from(df, COLUMNS)


@pytest.mark.parametrize("seed", [0, 1])
def test_each_piece_slope_is_read_from_its_steady_part(seed):
    rec = _record(seed=seed)
    trend = steady_trend(rec.t, rec.mu, rec.velocities, rec.switch_times)
    assert not any(trend.fitted) and not trend.notes
    for slope, se, truth in zip(trend.slopes, trend.se, SLOPES):
        assert 0 < se and abs(slope - truth) <= 3 * se
    # the steady part starts after the evolution: the transient decays over a few Dc
    # (Dc/v = 1 s in piece 1, 10 s in piece 2, 3.3 s in piece 3)
    for start, switch, dc_time in zip(trend.steady_from[1:], SWITCHES, (1.0, 10.0, 3.3)):
        assert start >= switch + 2 * dc_time


@pytest.mark.parametrize("seed", [0, 1])
def test_a_fit_that_holds_the_steady_trend_recovers_the_law(seed):
    fit = fit_lab(LabModel(_record(seed=seed), "aging", detrend="steady"))
    assert fit.success and not fit.at_bound
    for name, tol in (("a", 0.05), ("b", 0.05), ("dc", 0.1)):
        low, high = fit.interval(name)
        assert low <= TRUTH[name] <= high and fit.values[name] == pytest.approx(TRUTH[name],
                                                                               rel=tol)
    # the held slopes are reported with their errors, and they widen the intervals
    assert {"trend_0", "trend_1", "trend_2", "trend_3"} <= set(fit.linear)
    assert all(fit.linear_se[f"trend_{i}"] > 0 for i in range(4))


def test_a_piece_whose_evolution_does_not_end_fits_its_own_slope():
    """The record ends 2 s (2 Dc) after the up-step, still 0.009 above its new steady state
    and falling almost straight: a slope read off its last second (about −900 per m against the
    truth's −30) would be held with an error of 13 and put the intervals of a, b and Dc 60–86 %
    off, outside them (before the fit settled the steady parts). The fit with a slope per
    piece says that the evolution has not ended, and the piece's slope is fitted with the
    rest: the truth inside the intervals."""
    t = np.linspace(0.0, 22.0, 4_000)
    df = synthetic_record(t, VELOCITIES[:2], SWITCHES[:1], **TRUTH, noise=6e-4, seed=0)
    df["friction"] += travel_columns(t, VELOCITIES[:2], SWITCHES[:1]) @ np.asarray(SLOPES[:2])
    fit = fit_lab(LabModel(lab_record_from(df, COLUMNS), "aging", detrend="steady"))
    trend = fit.model.steady
    assert trend.fitted[1] and np.isnan(trend.slopes[1])
    assert "trend_1" in fit.model.linear_names
    assert any("or not within the record" in n for n in fit.notes)
    for name in ("a", "b", "dc"):
        low, high = fit.interval(name)
        assert low <= TRUTH[name] <= high


def test_a_record_that_opens_inside_a_transient_is_said_whatever_the_trend():
    """The same record cut 0.5 s after its 10 → 1 µm/s step (Dc/v = 10 s), so that the first
    half of its first piece is the step's evolution: the note says so with every trend (the
    model starts at steady state; its quadratic term was 5.1 se when written, the note's
    threshold 4); the record from its start, a straight first piece, has none (0.67 se). A
    transient short against the first piece is not seen: cut 0.5 s after the 1 → 10 µm/s
    step (Dc/v = 1 s of a 30 s piece) the term is 1.3 se."""
    from benchmarks.lab.steady_trend import OPENS_IN_TRANSIENT, opens_in_transient
    rec = _record(seed=2)
    assert not opens_in_transient(rec.t, rec.mu, rec.velocities, rec.switch_times)
    cut = T >= SWITCHES[1] + 0.5
    df = synthetic_record(T, VELOCITIES, SWITCHES, **TRUTH, noise=6e-4, seed=2)[cut].copy()
    df["time_s"] -= df["time_s"].iloc[0]
    opened = lab_record_from(df, COLUMNS)
    assert opens_in_transient(opened.t, opened.mu, opened.velocities, opened.switch_times)
    for detrend in ("piece", "none", "steady"):
        with pytest.warns(Warning):
            fit = fit_lab(LabModel(opened, "aging", detrend=detrend))
        assert OPENS_IN_TRANSIENT in fit.notes, (detrend, fit.notes)
