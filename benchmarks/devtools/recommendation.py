"""The integrator a command uses when none is named: a constant in code, not a file read at run
time.

:data:`FRONT` is the quick work-precision study's front (``results/wp_quick.csv``): settings of
one integrator for the whole problem set, each faster than every more accurate one, with its
worst error in the recurrence interval over the study problems. The study writes it
(:func:`benchmarks.devtools.work_precision.write_recommendation`);
``tests/test_recommendation.py`` checks it against the committed study. :func:`recommended`
takes the fastest setting within a level.
"""

from __future__ import annotations

__all__ = ["FRONT", "STUDY", "recommended"]

# --- written by the quick work-precision study (`rsfbench study work-precision`); do not edit ---
STUDY = {"file": 'wp_quick.csv', "commit": '8bdf12b6eb87+dirty',
         "sha256": '2c66ff958aa85f9a826b444cab45cd79cac217e1e34bc87762276d2cc932bd2c'}
#: (worst err_recurrence over the study problems, total wall s, integrator, rhs tier,
#: setting), fastest first
FRONT = (
    (0.010211369512923228, 0.0010774720003610128, 'Rosenbrock23', 'numba', 0.001),
    (0.001184862163067309, 0.001384639000207244, 'Rodas5P', 'numba', 0.001),
    (0.00027323049556251313, 0.001713837999432144, 'Rodas5P', 'numba', 0.0001),
    (0.0001549321791669935, 0.001778313999693637, 'Exprb43', 'numba', 0.001),
    (4.637691856744425e-05, 0.0023532299996986694, 'Rodas5P', 'numba', 1e-05),
    (1.115326473239559e-05, 0.0025240329996449873, 'Exprb43', 'numba', 0.0001),
    (9.306232473322485e-06, 0.002704061000258662, 'Rodas5P', 'numba', 1e-06),
    (6.834545209174347e-07, 0.0032974530004139524, 'Exprb43', 'numba', 1e-05),
    (1.0797415188470654e-07, 0.005437023999547819, 'Exprb43', 'numba', 1e-06),
    (1.2657977737984489e-08, 0.01068235300044762, 'Exprb43', 'numba', 1e-07),
    (2.1010738300307417e-09, 0.01790618299992275, 'Exprb43', 'numba', 1e-08),
    (1.5861502362844947e-09, 0.019268478999947547, 'Rodas5P', 'numba', 1e-10),
    (3.6986606653141927e-10, 0.025372274999881483, 'Exprb43', 'numba', 1e-09),
    (2.7628091922281704e-10, 0.03595546100041247, 'CyRK-Radau', 'numba', 1e-08),
    (1.3386902491137602e-10, 0.044105508000484406, 'Exprb43', 'numba', 1e-10),
    (1.025341927145814e-10, 0.05927374199973201, 'CyRK-Radau', 'numba', 1e-09),
    (6.469281996058299e-11, 2.317756772999928, 'sundials-ARKODE-IMEX', 'numba', 1e-10),
)
# --- end of the written part ---


def recommended(level: float):
    """``(algorithm, reason)``: the fastest setting of :data:`FRONT` whose worst error is within
    ``level``, or ETD2 at the paper's settings when none is."""
    from benchmarks.devtools.work_precision import algorithm_at
    from integrators import ETD2, REGISTRY
    for worst, _wall, name, tier, setting in FRONT:
        if worst <= level and name in REGISTRY:
            return algorithm_at(name, tier, setting), (
                f"the quick work-precision study ({STUDY['file']} at {STUDY['commit']}): "
                f"fastest setting with worst err_recurrence ≤ {level:g} over its problems "
                f"(worst {worst:.2g}): {name} [{tier}] at {setting:g}")
    return ETD2(), (f"the quick work-precision study recommends nothing for err_recurrence ≤ "
                    f"{level:g}: ETD2 at the paper's settings")
