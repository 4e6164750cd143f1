"""Cross-solver agreement on the limit cycle: every stiff backend at tight tolerance against
recorded references, and ETD2 at the paper's step settings.

References: the last complete event of each run (the cycle has converged by then, SPEC §4),
computed with scipy Radau and scipy BDF at rtol = atol = 1e−11 (analytic Jacobian, events by
Brent root finding on the dense output), which agree with each other to 3e−9 relative:

    paper example (slip law, constant vL, 20 s):  ΔT = 2.6712562364 s (BDF 2.6712562289),
                                                  Δμ = 0.03891370834 (BDF 0.03891370824)
    W2, slip law, two-speed loading (20 s):       ΔT = 3.0440933348 s (BDF 3.0440933215),
                                                  Δμ = 0.04521408348 (BDF 0.04521408332)

Reproduce with ``rsfbench simulate --preset W2 --t-end 20 --integrator scipy-Radau --rtol 1e-11
--atol 1e-11 --json`` (``last_event``).
"""

import pytest

import integrators as I
import problems as P
from benchmarks.physics.metrics import event_metrics
from integrators import REGISTRY

REFERENCES = {
    "paper-example": (2.6712562364, 0.03891370834),
    "W2": (3.0440933348, 0.04521408348),
}
STIFF_ADAPTIVE = sorted(n for n, c in REGISTRY.items() if c.adaptive and c.stiff)
#: runs moved to make test-slow (pytest --durations on 2 cores) to keep make test under 8 min
SLOW = {("scipy-Radau", "W2"): "5 s", ("scipy-Radau", "paper-example"): "4 s"}
#: not run: assimulo-LSODAR at 1e-10 on the paper example took 637 s (over 10 min of a 60-min
#: CI for one case); its agreement at 1e-10 is checked on W2 here, and the work-precision
#: study (results/wp_quick.csv) measures its error on the paper example at every tolerance
SKIPPED = {("assimulo-LSODAR", "paper-example")}


def _cases():
    for name in STIFF_ADAPTIVE:
        for preset in sorted(REFERENCES):
            if (name, preset) in SKIPPED:
                continue
            marks = [pytest.mark.slow] if (name, preset) in SLOW else []
            yield pytest.param(name, preset, marks=marks, id=f"{name}-{preset}")


def _last(problem, algorithm):
    sol = I.solve(problem, algorithm, max_points=100)
    assert sol.success, f"{algorithm.name}: {sol.retcode.value} {sol.message}"
    m = event_metrics(sol.events, problem.normal_force).iloc[-1]
    return m.recurrence_s, m.friction_drop


@pytest.mark.parametrize("name, preset", list(_cases()))
def test_stiff_backends_agree_at_tight_tolerance(name, preset):
    p = P.preset(preset, "slip", t_end=20.0)
    recurrence, drop = _last(p, REGISTRY[name](rtol=1e-10, atol=1e-10))
    ref_recurrence, ref_drop = REFERENCES[preset]
    assert recurrence == pytest.approx(ref_recurrence, rel=1e-5)
    assert drop == pytest.approx(ref_drop, rel=1e-5)


@pytest.mark.parametrize("preset", sorted(REFERENCES))
def test_etd2_at_the_paper_settings_agrees_to_1e3(preset):
    p = P.preset(preset, "slip", t_end=20.0)
    recurrence, drop = _last(p, I.ETD2())
    ref_recurrence, ref_drop = REFERENCES[preset]
    assert recurrence == pytest.approx(ref_recurrence, rel=1e-3)
    assert drop == pytest.approx(ref_drop, rel=1e-3)
    # and it is not better than that by accident: its error is the scheme's, ~1e−4
    assert abs(recurrence / ref_recurrence - 1) > 1e-5
