"""Experiment design (benchmarks.lab.design, rsfbench design): the Fisher errors of a planned
velocity step, against the spread of repeated fits to records of the independent model; plans a
laboratory could not run are refused in one line."""

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

from benchmarks.lab.design import Plan, check_plan, compare_plans, fisher_errors, varied

PLAN = dict(velocities=(1e-6, 1e-5), durations=(10.0, 30.0), rate=50.0, noise=6e-4, a=0.006,
            b=0.009, dc=10e-6, k=3e3)
BASE = ["--velocities", "1,10", "--durations", "10,30", "--rate", "50", "--noise", "6e-4",
        "--a", "0.006", "--b", "0.009", "--dc", "10", "--stiffness", "3000"]


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "benchmarks.cli", "design", *map(str, args)],
                          capture_output=True, text=True, timeout=600)


def test_the_fisher_errors_are_the_spread_of_repeated_fits():
    """40 fits to records of the independent model (scipy's Radau, white noise): the Fisher
    se within 25 % of the fits' spread for a, b, ln Dc, ln k′ (0.86–1.04 when this test was
    written; the design study checks 100 fits of three plans), and no bias beyond the spread's
    own uncertainty."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = check_plan(Plan(**PLAN), n=40)
    assert (table.fits == 40).all()
    assert ((table.ratio - 1).abs() <= 0.25).all(), table
    assert (table.bias.abs() < 3 / math.sqrt(40)).all(), table


def test_a_plan_that_does_not_determine_a_parameter_says_so_and_more_data_help():
    """With b = 0 the record carries no trace of Dc: its error is infinite. Ten times the
    sampling rate divides every error by √10 (white noise)."""
    flat = fisher_errors(Plan(**dict(PLAN, b=0.0))).set_index("parameter")
    assert math.isinf(flat.at["dc", "se"]) and math.isfinite(flat.at["a", "se"])
    table = compare_plans({"plan": Plan(**PLAN), "rate": varied(Plan(**PLAN), rate=500.0)})
    assert table.gain.iloc[1] == pytest.approx(math.sqrt(10), rel=0.02)
    assert list(table.best) == [False, True]


@pytest.mark.parametrize("change, match", [
    (dict(durations=(10.0,)), "one duration"), (dict(velocities=(0.0, 1e-5)), "the first > 0"),
    (dict(rate=0.0), r"rate \(Hz\) must be positive"), (dict(dc=-1e-6), r"dc \(m\)"),
    (dict(law="ruina"), "law must be one of"), (dict(detrend="steady"), "detrend must be"),
    (dict(rate=1e6, durations=(1e4, 1e4)), "samples")])
def test_a_plan_no_laboratory_could_run_is_refused(change, match):
    with pytest.raises(ValueError, match=match):
        Plan(**dict(PLAN, **change))


def test_the_command_ranks_the_designs_and_writes_its_files(tmp_path):
    run = _cli(*BASE, "--vary", "rate=500", "--vary", "stiffness=30000", "--json", "--out",
               tmp_path / "d")
    assert run.returncode == 0, run.stderr
    doc = json.loads(run.stdout)
    designs = {d["design"]: d for d in doc["designs"]}
    assert designs["rate=500"]["best"] and not designs["plan"]["best"]
    assert designs["stiffness=30000"]["k_rse"] > designs["plan"]["k_rse"]
    assert "white noise" in doc["provenance"]["assumes"]
    written = sorted(p.name for p in (tmp_path / "d").iterdir() if p.name[0] != ".")
    assert written == ["design.csv", "design_errors.csv", "design_provenance.json"]
    for args, match in ((["--vary", "rate=x"], "numbers in Hz"),
                        (["--vary", "mass=3"], "NAME one of"),
                        (["--target", "c"], "has a, b, dc, k and a_minus_b"),
                        (["--vary", "durations=5"], "one duration")):
        bad = _cli(*BASE, *args)
        assert bad.returncode == 2 and match in bad.stderr and "Traceback" not in bad.stderr
        assert len(bad.stderr.strip().splitlines()) == 1


def test_the_plans_own_history_is_modelled_and_unstable_or_unfit_plans_are_refused():
    """A piece of 0.5 s (25 samples) and a 2 s hold are modelled as planned (their history
    once came from the displacement, which merged the short piece and refused the hold); a
    stiffness near the critical (b − a)/Dc, a piece under 20 samples, a check of fewer than
    10 fits and a non-finite duration are refused in one line."""
    short = Plan(**dict(PLAN, velocities=(1e-6, 1e-5, 1e-6), durations=(10.0, 0.5, 10.0)))
    model = short.model()
    assert model.record.velocities == short.velocities
    np.testing.assert_allclose(model.record.switch_times, (10.0, 10.5))
    hold = Plan(**dict(PLAN, velocities=(1e-6, 0.0, 1e-6), durations=(10.0, 2.0, 10.0)))
    assert np.isfinite(fisher_errors(hold).se).all()
    for change, match in ((dict(k=330.0), "critical stiffness"),
                          (dict(durations=(10.0, 0.3)), "15 samples"),
                          (dict(durations=(10.0, float("nan"))), "durations")):
        with pytest.raises(ValueError, match=match):
            Plan(**dict(PLAN, **change))
    with pytest.raises(ValueError, match="at least 10"):
        check_plan(Plan(**PLAN), n=3)
