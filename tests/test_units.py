"""Unit plausibility of every dimensional input (issue 29): a value implausible in its unit warns
once, naming the parameter, the value and the unit; an impossible one is refused; no real
apparatus warns."""

import dataclasses
import json
import math
import warnings

import pytest

import problems as P
from benchmarks.inversion.observations import Observations, observations
from problems._validate import (PLAUSIBLE, UnitWarning, check_possible, implausible_message,
                                units_checked_already)


def _unit_warnings(make):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        make()
    return [str(w.message) for w in seen if issubclass(w.category, UnitWarning)]


# --- the examples ---------------------------------------------------------------------

def test_a_normal_force_in_mpa_warns_naming_value_and_unit():
    seen = _unit_warnings(lambda: dataclasses.replace(P.window("W2"), normal_force=5.0))
    assert len(seen) == 1
    assert seen[0].startswith("normal_force = 5 N is implausibly small")
    assert "newtons (N), not MPa" in seen[0]


def test_a_load_speed_in_um_per_s_warns():
    seen = _unit_warnings(lambda: P.ConstantLoading(10.0))
    assert len(seen) == 1 and seen[0].startswith("vl = 10 m/s is implausibly large")


def test_a_friction_drop_in_percent_warns_and_ten_is_refused():
    seen = _unit_warnings(lambda: Observations(3.1, 0.31, 8.4, 0.84))
    assert len(seen) == 1 and "friction_drop = 8.4" in seen[0] and "percentage" in seen[0]
    with pytest.raises(ValueError, match="friction_drop = 10 is impossible"):
        Observations(3.1, 0.31, 10.0, 1.0)


@pytest.mark.parametrize("mu0", [1e300, 60.0, 10.0])
def test_an_impossible_mu0_is_refused(mu0):
    with pytest.raises(ValueError, match=r"mu0 = .* is impossible"):
        dataclasses.replace(P.window("W2"), mu0=mu0)


def test_a_negative_mu0_is_refused_and_zero_warns():
    with pytest.raises(ValueError, match="mu0 must be non-negative"):
        dataclasses.replace(P.window("W2"), mu0=-0.1)
    assert _unit_warnings(lambda: dataclasses.replace(P.window("W2"), mu0=0.0))


@pytest.mark.parametrize("field", ["a", "b"])
def test_a_or_b_of_one_or_more_is_refused(field):
    with pytest.raises(ValueError, match=f"{field} = 1.5 is impossible"):
        P.SlipLaw(**{**dict(a=0.008, b=0.0092, lc=5e-7), field: 1.5})


# --- every range, at its edges ------------------------------------------------------------------

@pytest.mark.parametrize("key", sorted(PLAUSIBLE))
def test_every_range_is_half_open_and_names_its_unit(key):
    p = PLAUSIBLE[key]
    assert implausible_message(key, p.low) is None
    assert implausible_message(key, p.high * (1 - 1e-9)) is None
    small, large = implausible_message(key, p.low * (1 - 1e-9)), implausible_message(key, p.high)
    assert small.startswith(f"{key} = ") and "implausibly small" in small
    assert large.startswith(f"{key} = ") and "implausibly large" in large
    assert p.unit in small and p.unit in large
    assert (implausible_message(key, 0.0) is None) == p.zero_ok


@pytest.mark.parametrize("key", [k for k, p in PLAUSIBLE.items() if math.isfinite(p.impossible)])
def test_the_impossible_is_refused_even_where_warnings_are_off(key):
    p = PLAUSIBLE[key]
    with units_checked_already(), pytest.raises(ValueError, match=f"{key} = .* is impossible"):
        check_possible(key, p.impossible)
    assert check_possible(key, p.low) == p.low


# --- no real apparatus warns --------------------------------------------------------------------

def test_the_presets_the_laboratory_apparatus_and_the_example_file_never_warn():
    from probe.cases import APPARATUS
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        for law in ("slip", "aging", "nagata"):
            for name in P.PRESET_NAMES:
                if not (name == "paper-example" and law == "nagata"):
                    P.preset(name, law=law)
            P.velocity_step_test(law)
            P.slide_hold_slide_test(law)
        for w in P.WINDOWS:
            observations(w)
        P.load_problem(APPARATUS)


# --- warned once --------------------------------------------------------------------------------

def test_a_variant_warns_for_what_it_changes_only():
    base = _unit_warnings(lambda: dataclasses.replace(P.window("W2"), normal_force=5.0))
    assert len(base) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = dataclasses.replace(P.window("W2"), normal_force=5.0)
    assert _unit_warnings(lambda: P.variant(p, t_end=2.0)) == []
    seen = _unit_warnings(lambda: P.variant(p, stiffness=10.0))
    assert len(seen) == 1 and seen[0].startswith("stiffness = 10 N/m")


def test_a_loading_warns_once_however_it_is_read():
    """The loading's .history and the balanced start are built from values the loading judged:
    they do not warn again (a speed in µm/s was warned three times)."""
    seen = _unit_warnings(lambda: dataclasses.replace(
        P.window("W2"), loading=P.TwoSpeedLoading(vls=75.0, vlf=2e-3, df=0.04)).initial_state)
    assert len(seen) == 1 and seen[0].startswith("vls = 75 m/s")


def test_the_command_line_shows_a_warning_as_one_line(capsys):
    from benchmarks.cli.main import main
    status = main(["simulate", "--preset", "W2", "--lc", "0.3", "--t-end", "0.05",
                   "--wall-budget", "5", "--integrator", "Rodas5P", "--rtol", "1e-6",
                   "--atol", "1e-6", "--json"])
    captured = capsys.readouterr()
    assert status in (0, 1)
    json.loads(captured.out)
    lines = [x for x in captured.err.splitlines() if "warning" in x.lower()]
    assert len(lines) == 1 and lines[0].startswith("rsfbench: warning: lc = 0.3 m is implausibly")


def test_a_sweep_warns_once_not_once_a_point(tmp_path):
    from benchmarks.inversion.sweep import sweep
    from integrators import ETD2

    def run():
        problem = dataclasses.replace(P.window("W2", t_end=0.05), normal_force=5.0)
        sweep(problem, [0.0093, 0.0094], [0.3], ETD2(), Observations(3.1, 0.31, 8.4, 0.84),
              tmp_path / "s", workers=1, progress=False)
    seen = _unit_warnings(run)
    assert sorted(m.split(" = ")[0] for m in seen) == ["friction_drop", "lc", "normal_force"]


# --- the derived checks -------------------------------------------------------------------------

def _start(law, **kw):
    p = P.window("W2", law, t_end=1.0)
    ini = p.initial_state
    return lambda: dataclasses.replace(p, initial=P.InitialState(
        **{**dict(v=ini.v, theta=ini.theta, fs=ini.fs), **kw}))


@pytest.mark.parametrize("law, change, warned", [
    ("aging", dict(theta=1e-12), True),         # steady at 0.3 km/s: θ in ms? µs?
    ("aging", dict(theta=1e5), False),          # a day's hold
    ("slip", dict(theta=-1e6), True),           # steady far beyond any slip rate
    ("slip", dict(fs=0.6), True),               # a friction coefficient typed for a force
    ("slip", dict(fs=6e7), True),               # 60 Fn
    ("slip", dict(fs=0.0), False),              # an unloaded spring
    ("slip", dict(v=100.0), True),              # µm/s typed for m/s
])
def test_an_explicit_initial_state_is_judged_in_its_units(law, change, warned):
    assert bool(_unit_warnings(_start(law, **change))) == warned


def test_a_sigma_in_another_unit_than_its_mean_warns_once():
    seen = _unit_warnings(lambda: Observations(3.1, 0.31, 0.046, 0.46))
    assert len(seen) == 1 and seen[0].startswith("sigma_friction_drop = 0.46 is 10 ×")
    seen = _unit_warnings(lambda: Observations(3.1, 0.31, 0.046, 1e-7))
    assert len(seen) == 1 and "implausibly small" in seen[0]


def test_observations_refuse_a_non_string_preset_and_a_string_mean():
    with pytest.raises(ValueError, match="preset_name"):
        observations(3)
    with pytest.raises(ValueError, match="obs_recurrence must be a real number"):
        observations("", obs_recurrence="3", obs_drop=0.04)


def test_docs_units_md_lists_every_range_as_the_code_has_it():
    from pathlib import Path
    text = (Path(__file__).parents[1] / "docs" / "units.md").read_text()
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 5 and cells[0] and cells[1][:1].isdigit():
            rows[cells[0].split(" ")[0]] = cells[1:]
    assert set(rows) == set(PLAUSIBLE)
    for key, (low, high, unit, refused) in rows.items():
        p = PLAUSIBLE[key]
        assert (float(low), float(high), unit) == (p.low, p.high, p.unit), key
        assert (float(refused) if refused else math.inf) == p.impossible, key
