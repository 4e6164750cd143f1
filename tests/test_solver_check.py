"""The integrator is checked on the user's own problem before an inversion: a setting too coarse
for the σ is tightened until it is within σ/10 of a tight reference on the box's corners and
centre, or refused; the CLI says what it checked and records it."""

import json
import warnings

import numpy as np
import pytest

from benchmarks.cli.main import main
from benchmarks.inversion import synthetic
from benchmarks.inversion.solver_check import FRACTION, check_solver, fastest_on_box, tighter
from integrators import ETD2, Rosenbrock23
from problems import window

BOX = ((0.0086, 0.0102), (3e-8, 3e-6))


@pytest.fixture(scope="module")
def w2():
    return window("W2", "slip")


@pytest.fixture(scope="module")
def obs():
    # W2's limit cycle at its published fit (ΔT 3.0446 s, Δμ 0.04522: the ensemble of
    # tests/test_ensemble.py) observed with σ = 1 %
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return synthetic(3.0446, 0.04522, 0.01, seed=1)


def test_a_coarse_setting_is_tightened_until_it_is_within_a_tenth_of_sigma(w2, obs):
    """Rosenbrock23 at 1e-3 is 0.8 σ off in ΔT at a corner of W2's box (measured), 1e-4 still
    0.15 σ: the check tightens to 1e-5 and says so."""
    check = check_solver(w2, Rosenbrock23(rtol=1e-3, atol=1e-3), obs, *BOX)
    assert check.passed and check.algorithm.rtol == pytest.approx(1e-5)
    assert len(check.tried) == 3 and "tightened from Rosenbrock23" in check.message
    last = check.points[check.points.setting == check.tried[-1]]
    assert (last.error_in_sigma[last.references_agree] <= FRACTION).all()
    first = check.points[check.points.setting == check.tried[0]]
    assert first.error_in_sigma.max() > 0.5
    assert set(check.points.reference_class) >= {"stick-slip"}
    assert check.summary()["passed"] and len(check.summary()["points"]) == 15


def test_a_recommended_setting_is_checked_on_the_level_it_was_chosen_for(w2):
    """With vague data (σ = 50 %) Rosenbrock23 at 1e-3 is well within σ/10 (it is ~1 % off in
    ΔT at a corner, above); asked for ΔT within 1e-3 as well, the check tightens it until each
    checked point is, and says the level."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vague = synthetic(3.0446, 0.04522, 0.5, seed=1)
    plain = check_solver(w2, Rosenbrock23(rtol=1e-3, atol=1e-3), vague, *BOX)
    assert plain.passed and len(plain.tried) == 1
    check = check_solver(w2, Rosenbrock23(rtol=1e-3, atol=1e-3), vague, *BOX, level=1e-3)
    assert check.passed and check.algorithm.rtol <= 1e-4 and len(check.tried) >= 2
    first = check.points[check.points.setting == check.tried[0]]
    assert first.relative_dT_error[first.references_agree].max() > 1e-3
    last = check.points[check.points.setting == check.tried[-1]]
    assert (last.relative_dT_error[last.references_agree].dropna() <= 1e-3).all()
    assert "0.001 relative in ΔT" in check.message and "tightened from" in check.message


def test_the_race_on_the_box_takes_the_fastest_setting_that_finishes(w2):
    """Rosenbrock23 at 1e-6 takes several times the steps of 1e-3 on every point of the box; a
    setting whose solves run out of their budget there does not win by stopping early."""
    loose, tight = Rosenbrock23(rtol=1e-3, atol=1e-3), Rosenbrock23(rtol=1e-6, atol=1e-6)
    fastest, times = fastest_on_box(w2, [tight, loose], *BOX)
    assert fastest == loose and list(times) == ["Rosenbrock23 at rtol = atol = 1e-06",
                                                "Rosenbrock23 at rtol = atol = 0.001"]
    assert 0 < times["Rosenbrock23 at rtol = atol = 0.001"] < times[
        "Rosenbrock23 at rtol = atol = 1e-06"] < np.inf
    fastest, times = fastest_on_box(w2, [tight, loose], *BOX, wall_budget=1e-6)
    assert fastest == tight and all(t == np.inf for t in times.values())   # all out of budget


def test_a_level_the_references_cannot_vouch_for_is_said_not_checked(w2):
    """At 1e-9 the references (1e-9 themselves) agree in ΔT to a tenth of it nowhere: the
    level is not judged, and the message says so rather than claim it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vague = synthetic(3.0446, 0.04522, 0.5, seed=1)
    check = check_solver(w2, Rosenbrock23(rtol=1e-3, atol=1e-3), vague, *BOX, level=1e-9)
    assert check.passed and "ΔT's level 1e-09 not checked" in check.message
    assert "1e-09 relative in ΔT" not in check.message
    assert check.points.relative_dT_error.isna().all()


def test_the_race_keeps_the_first_within_its_margin_and_a_held_setting(w2):
    from benchmarks.devtools.recommendation import contenders
    from benchmarks.inversion.solver_check import recommended_on_box
    loose, tight = Rosenbrock23(rtol=1e-3, atol=1e-3), Rosenbrock23(rtol=1e-6, atol=1e-6)
    fastest, _ = fastest_on_box(w2, [tight, loose], *BOX, repeats=1, margin=0.99)
    assert fastest == tight                  # not 99 % faster: the first stays
    rivals = [a for a, _w, _t in contenders(1e-3)]
    held, why = recommended_on_box(w2, 1e-3, *BOX, held=repr(rivals[-1]))
    assert held == rivals[-1] and "kept so that the run resumes" in why


def test_a_setting_that_cannot_be_tightened_is_refused_naming_the_worst_point(w2, obs):
    check = check_solver(w2, Rosenbrock23(rtol=1e-3, atol=1e-3), obs, *BOX,
                         next_setting=lambda algorithm: None)
    assert not check.passed
    assert "no setting tried" in check.message and "b = 0.0102" in check.message


def test_a_box_without_a_cycle_checks_nothing_and_says_so(w2, obs):
    """b far below a (0.008): steady sliding everywhere; no point to check a cycle's metrics on,
    so the check says so (the commands warn) rather than pass on points that compare nothing."""
    check = check_solver(w2, Rosenbrock23(rtol=1e-3, atol=1e-3), obs, (0.001, 0.002),
                         (1e-7, 1e-6))
    assert not check.passed and check.nothing_to_check
    assert "nothing to check the integrator on" in check.message
    assert check.n_solves == 2 * (5 + 9)


def test_a_cycle_without_its_curve_is_no_agreement(obs):
    """A missing curve (a second solve that stopped) is an infinite error, not a pass."""
    import dataclasses

    import pandas as pd

    from benchmarks.inversion.solver_check import _errors
    from benchmarks.physics.curves import sample_curves  # noqa: F401 (the format)
    curves = pd.DataFrame({"event_id": np.repeat([1, 2, 3], 20),
                           "slip_m": np.tile(np.linspace(0, 3e-4, 20), 3),
                           "friction": 0.6 + 1e-3 * np.random.default_rng(0).standard_normal(60)})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        o = dataclasses.replace(obs, curves=curves)
    row = dict(classification="stick-slip", recurrence_s=3.0446, friction_drop=0.04522)
    s = np.linspace(0, 3e-4, 50)
    a = pd.DataFrame([{**row, "curve_slip": s, "curve_friction": 0.6 + 0 * s}])
    b = pd.DataFrame([{**row, "curve_slip": np.empty(0), "curve_friction": np.empty(0)}])
    assert _errors(a, a, o)[0] == 0.0 and _errors(a, b, o)[0] == np.inf


def test_a_box_of_no_width_checks_each_point_once():
    from benchmarks.inversion.solver_check import _points
    flat = _points((0.009, 0.0098), (3e-7, 3e-7))
    assert flat["b"] == pytest.approx([0.009, 0.0098, 0.0094]) and (flat["lc"] == 3e-7).all()
    assert len(_points((0.009, 0.0098), (3e-7, 3e-7), inner=True)["b"]) == 3
    assert len(_points(*BOX)["b"]) == 5 and len(_points(*BOX, inner=True)["b"]) == 9


def test_tighter_settings():
    assert tighter(Rosenbrock23(rtol=1e-4, atol=1e-6)).atol == pytest.approx(1e-7)
    assert tighter(Rosenbrock23(rtol=1e-13, atol=1e-13)) is None       # at the floor
    etd = tighter(ETD2())
    assert etd.dtau_cnst == ETD2().dtau_cnst / 4 and etd.dtau_max == ETD2().dtau_max / 4


@pytest.mark.slow
def test_invert_checks_its_integrator_and_records_the_check(tmp_path, capsys):
    code = main(["invert", "--preset", "W2", "--t-end", "20", "--integrator", "Rosenbrock23",
                 "--rtol", "1e-3", "--atol", "1e-3", "--sigma-recurrence", "0.03",
                 "--sigma-drop", "0.0005", "--steps", "0", "--profile-points", "3",
                 "--out", str(tmp_path / "i"), "--json", "--no-progress"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    check = json.loads((tmp_path / "i" / "inversion.json").read_text())["provenance"][
        "solver_check"]
    assert check["passed"] and len(check["tried"]) >= 2
    assert out["options"]["rtol"] < 1e-3 and "tightened" in out["integrator_choice"]
    assert np.isfinite(out["fit"]["misfit"])
