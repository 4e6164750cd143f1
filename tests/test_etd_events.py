"""The paper's ETD family never steps over an event unseen (issue 29).

A ladder of step bounds up to huge values on every preset under both laws: each setting is
refused before any work or finds the reference's events (count in a window ending half-way
between two reference events, event starts within the method's tolerance). The windows, the
tolerances and the comparison are those of the probe family (:mod:`probe.families.etd`);
the reference is Rodas5P at rtol = atol = 1e−9, checked against scipy's Radau at 1e−10 below.
"""

import dataclasses
import math

import numpy as np
import pytest

import integrators as I
import problems as P
from probe.families.etd import (HISTORIES, MISSED_BEFORE, TOLERANCE, WINDOWS,
                                           events_agree, history_problem, reference,
                                           window_problem)
from integrators.own import etd_kernel as K
from integrators.own.etd import SLIP_PER_STEP_MAX

METHODS = [I.ETD1, I.ETD2, I.ETDIterated]
IDS = ["ETD1", "ETD2", "ETDIterated"]


@pytest.mark.slow
def test_the_reference_pair_agrees_on_every_window():
    """Rodas5P at 1e−9 against scipy's Radau at 1e−10: the same events, starts within 1e−7
    (measured ≤ 1.4e−8), far below the smallest tolerance (2e−2) they are used to judge."""
    for name, law in WINDOWS:
        p = window_problem(name, law)
        a = reference(p).events.t_start.to_numpy()
        b = I.solve(p, I.ScipyRadau(rtol=1e-10, atol=1e-10), max_points=2).events.t_start
        assert len(a) == len(b) >= 2, (name, law)
        np.testing.assert_allclose(a, b.to_numpy(), rtol=1e-7, err_msg=f"{name}/{law}")


@pytest.mark.parametrize("make", METHODS, ids=IDS)
def test_a_ladder_of_dtau_max_up_to_1e6_finds_the_reference_events(make):
    """Before the loading bound, a huge dtau_max let a stick step load the spring through a
    whole nucleation: missed events (MISSED_BEFORE below) or Unresolved stops (ETD1 on
    W4/aging, the paper example under the aging law)."""
    for name, law in WINDOWS:
        p = window_problem(name, law)
        for dtau_max in (0.01, 1.0, 1e6):
            sol = I.solve(p, make(dtau_max=dtau_max), max_points=2)
            why = events_agree(sol, reference(p), TOLERANCE[make.name])
            assert not why, f"{make.name} dtau_max={dtau_max} on {name}/{law}: {why}"


@pytest.mark.parametrize("make", METHODS, ids=IDS)
def test_a_ladder_of_dtau_cnst_is_refused_or_finds_the_reference_events(make):
    """Up to 0.5 Lc a step (dtau_cnst = 1e−4 at v0 = 10 µm/s) the events are the reference's;
    above, the run is refused before any work, naming dtau_cnst, its value and the largest that
    works. Without the refusal, 2.5 Lc a step gave W1/slip 125 events for 7 with Success."""
    largest = SLIP_PER_STEP_MAX * P.presets.V0 / 0.05
    assert largest == pytest.approx(1e-4)
    for name, law in WINDOWS:
        p = window_problem(name, law)
        for dtau_cnst in (2e-5, 1e-4, 1.01e-4, 1e-3, 0.1, 1.0):
            alg = make(dtau_cnst=dtau_cnst)
            if dtau_cnst > largest:
                with pytest.raises(I.ProblemNotSupported) as exc:
                    I.solve(p, alg, max_points=2)
                text = str(exc.value)
                assert "\n" not in text and f"dtau_cnst = {dtau_cnst!r}" in text
                assert f"at most {largest:.3g}" in text and "Lc" in text
                continue
            why = events_agree(I.solve(p, alg, max_points=2), reference(p), TOLERANCE[make.name])
            assert not why, f"{make.name} dtau_cnst={dtau_cnst} on {name}/{law}: {why}"


def test_the_loading_bound_finds_the_event_a_huge_stick_step_missed():
    """The defect: the paper example under the aging law (b × 1.1, Lc × 0.3), ETD1 at
    dtau_max = 100. Rodas5P (1e−9) finds three events (0.0064, 3.577, 9.802 s). Without the
    bound (load_max = 1e300) ETD1 reported Success with two (0.0066, 4.471 s): one stick step
    loaded the spring through the nucleation. With it: the reference's three."""
    p = P.paper_example(**MISSED_BEFORE)
    ref = reference(p)
    assert len(ref.events) == 3
    unbounded = I.solve(p, I.ETD1(dtau_max=100.0, load_max=1e300), max_points=2)
    assert unbounded.success and len(unbounded.events) == 2          # the silent miss
    assert events_agree(unbounded, ref, TOLERANCE["ETD1"])
    for make in METHODS:
        sol = I.solve(p, make(dtau_max=100.0), max_points=2)
        assert not events_agree(sol, ref, TOLERANCE[make.name]), make.name
        assert sol.meta["load_bound_steps"] > 0


@pytest.mark.parametrize("make", [I.ETD2, I.ETDIterated], ids=["ETD2", "ETDIterated"])
def test_the_loading_bound_leaves_the_paper_settings_alone(make):
    """At the paper's settings the paper's problems load the spring by at most 0.04 A a step
    (W3/slip: (C/D)·E_fast·Δτmax), below load_max = 0.1 A: not one step is shortened, the runs
    are bit-identical to the unbounded ones."""
    for name in P.PRESET_NAMES:
        for law in ("slip", "aging"):
            p = P.preset(name, law=law, t_end=10.0)
            sol = I.solve(p, make(), max_points=2)
            assert sol.success and sol.meta["load_bound_steps"] == 0, (name, law)
            free = I.solve(p, make(load_max=1e300), max_points=2)
            np.testing.assert_array_equal(sol.events.to_numpy(), free.events.to_numpy())
            for a, b in ((sol.v, free.v), (sol.fs, free.fs), (sol.theta, free.theta)):
                np.testing.assert_array_equal(a, b)


def test_radiation_damping_with_a_huge_dtau_max():
    """W2/aging with the fault's radiation damping (the family study's problem)."""
    p = dataclasses.replace(window_problem("W2", "aging"),
                            radiation_damping=P.presets.fault_radiation_damping())
    ref = reference(p)
    for make in METHODS:
        why = events_agree(I.solve(p, make(dtau_max=1e6), max_points=2), ref,
                           TOLERANCE[make.name])
        assert not why, f"{make.name}: {why}"


def test_the_lab_slider_with_mass_keeps_the_paper_rule():
    """At v0 = 1 µm/s the paper's rule slips 0.5 Lc a step: the largest accepted, not refused
    by rounding (1e−5 · 0.05/1e−6 is 0.5000000000000001 in floating point); a hair more is."""
    p = P.velocity_step_test(mass=1.0)
    I.ETD2().check_problem(p)
    with pytest.raises(I.ProblemNotSupported, match="dtau_cnst = 1.1e-05"):
        I.ETD2(dtau_cnst=1.1e-5).check_problem(p)


def test_the_quasi_static_slider_is_refused_whatever_the_step_bound():
    p = dataclasses.replace(window_problem("W2", "slip"), mass=0.0)
    for make in METHODS:
        with pytest.raises(I.ProblemNotSupported, match="mass"):
            I.solve(p, make(dtau_max=1e6))


def test_a_step_too_short_to_advance_t_stops_the_loop():
    """The kernel's guard: at τ = 1e6 a step of 1e−12 does not change τ in floating point; the
    loop stops (STALLED, retcode StepUnderflow in etd.py) instead of spinning to the budget."""
    p = P.paper_example(t_end=1e6)
    nd = p.nondimensional()
    from problems.formulations import form_vector
    from problems.loading import event_thresholds
    w_start, w_end = (v / p.law.v0 for v in event_thresholds(p.loading))
    q = np.concatenate([form_vector(nd, nd.e_slow),
                        [nd.tau_end, w_start, w_end, float(nd.two_speed)], nd.history])
    o = np.array([1e-12, 1e-5, 0.05 / p.law.v0, 1, 1e9, 100.0, 0.1])
    st = K.initial_loop_state(nd.x0, 1e9)
    st[K.S_TAU] = 1e6
    status = K.etd_advance(st, q, o, np.empty((4, 4)), np.empty((4, K.E_SIZE)), 1000)
    assert status == K.STALLED and st[K.S_STEPS] == 0 and st[K.S_TAU] == 1e6


def test_a_tiny_dtau_cnst_stops_at_its_step_budget():
    sol = I.solve(window_problem("W2", "slip"), I.ETD2(dtau_cnst=1e-300, max_steps=10_000),
                  max_points=2)
    assert sol.retcode is I.ReturnCode.MAX_STEPS and sol.stats.steps == 10_000


@pytest.mark.parametrize("value", [0.0, -0.1, math.nan, math.inf, "0.1"])
def test_load_max_misuse_is_refused(value):
    with pytest.raises(ValueError, match="load_max"):
        I.ETD2(load_max=value)


@pytest.mark.parametrize("history", list(HISTORIES))
def test_load_histories_whose_switches_a_huge_step_would_straddle(history):
    """Steps land on every switch of the loading (a hold, a step up), whatever dtau_max."""
    p = history_problem(history)
    ref = reference(p)
    for make in METHODS:
        sol = I.solve(p, make(dtau_max=1e6), max_points=2)
        why = events_agree(sol, ref, TOLERANCE[make.name])
        assert not why, f"{make.name}: {why}"


def test_a_huge_v_max_is_refused_like_a_huge_dtau_cnst():
    """The slip a step may take is dtau_cnst · v_max/v0: v_max = 5 m/s with the paper's
    dtau_cnst is 5 Lc a step, refused, the message saying both ways out."""
    with pytest.raises(I.ProblemNotSupported, match=r"slip 5 Lc.*or v_max smaller"):
        I.solve(window_problem("W2", "slip"), I.ETD2(v_max=5.0))
