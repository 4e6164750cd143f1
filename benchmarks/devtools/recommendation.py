"""The integrator a command uses when none is named: a constant in code, not a file read at run
time.

:data:`FRONT` is the quick work-precision study's front (``results/wp_quick.csv``): settings of
one integrator for the whole problem set, each faster than every more accurate one, with its
worst error in the recurrence interval over the study problems. The study writes it
(:func:`benchmarks.devtools.work_precision.write_recommendation`);
``tests/test_recommendation.py`` checks it against the committed study. :func:`recommended`
takes the fastest setting within a level, and :func:`tighter_on_front` the next setting
:data:`TIGHTER` times as accurate when a check on the user's own problem asks for more.
"""

from __future__ import annotations

from benchmarks.devtools.work_precision import algorithm_at
from integrators import ETD2, REGISTRY

__all__ = ["FRONT", "STUDY", "recommended", "tighter_on_front", "TIGHTER"]

#: a tighter setting on the front is at least this many times as accurate: about what rtol ÷ 10
#: gives a method of order p = 3 to 5 (10^(p/(p+1)) = 5.6 to 6.8)
TIGHTER = 5.0

# --- written by the quick work-precision study (`rsfbench study work-precision`); do not edit ---
STUDY = {"file": 'wp_quick.csv', "commit": '2f5dc43a4efe',
         "sha256": '173c27b0b1a9d54b39aa8e9ac58cfbf71ddcf96b6dcef330dab4756daeb33b0d'}
#: (worst err_recurrence over the study problems, total wall s, integrator, rhs tier,
#: setting), fastest first
FRONT = (
    (0.011198825790385303, 0.0006235470063984394, 'Rosenbrock23', 'numba', 0.001),
    (0.001184862163067309, 0.0009543699998175725, 'Rodas5P', 'numba', 0.001),
    (0.0001549321791669935, 0.00114884898357559, 'Exprb43', 'numba', 0.001),
    (0.00013117153669851782, 0.0013071949942968786, 'RadauIIA5', 'numba', 0.001),
    (1.6715139223642846e-05, 0.0014503870042972267, 'RadauIIA5', 'numba', 0.0001),
    (1.115326473239559e-05, 0.001823803992010653, 'Exprb43', 'numba', 0.0001),
    (1.3035948330728903e-06, 0.002053064003121108, 'RadauIIA5', 'numba', 1e-05),
    (6.834545209174347e-07, 0.0028103510121582076, 'Exprb43', 'numba', 1e-05),
    (8.976686451622734e-08, 0.003351865991135128, 'RadauIIA5', 'numba', 1e-06),
    (4.982416158514556e-09, 0.005529116009711288, 'RadauIIA5', 'numba', 1e-07),
    (1.776657760788129e-10, 0.009387714002514258, 'RadauIIA5', 'numba', 1e-08),
    (1.0422915420953134e-10, 0.015798513006302528, 'RadauIIA5', 'numba', 1e-09),
    (1.025341927145814e-10, 0.05794437900476623, 'CyRK-Radau', 'numba', 1e-09),
    (6.469281996058299e-11, 1.5866062660061289, 'sundials-ARKODE-IMEX', 'numba', 1e-10),
)
# --- end of the written part ---


def recommended(level: float):
    """``(algorithm, reason)``: the fastest setting of :data:`FRONT` whose worst error is within
    ``level``, or ETD2 at the paper's settings when none is.

    Parameters
    ----------
    level : float
        The worst relative error in the recurrence interval to meet (dimensionless).

    Returns
    -------
    algorithm : Algorithm
        The method at its setting.
    reason : str
        Why, naming the study it was read from.
    """
    for worst, _wall, name, tier, setting in FRONT:
        if worst <= level and name in REGISTRY:
            return algorithm_at(name, tier, setting), (
                f"the quick work-precision study ({STUDY['file']} at {STUDY['commit']}): "
                f"fastest setting with worst err_recurrence ≤ {level:g} over its problems "
                f"(worst {worst:.2g}): {name} [{tier}] at {setting:g}")
    return ETD2(), (f"the quick work-precision study recommends nothing for err_recurrence ≤ "
                    f"{level:g}: ETD2 at the paper's settings")


def tighter_on_front(algorithm):
    """The fastest setting of :data:`FRONT` at least :data:`TIGHTER` times as accurate (its
    worst error) as ``algorithm``'s own place on it, which may be another method: the front's
    way of tightening, as rtol ÷ 10 is one method's. None when ``algorithm`` is not on the front or
    nothing on it is that accurate."""
    setting = getattr(algorithm, "rtol", getattr(algorithm, "dtau_cnst", None))
    rhs = getattr(algorithm, "rhs", None)
    here = [worst for worst, _wall, name, tier, value in FRONT
            if name == algorithm.name and value == setting and (rhs is None or tier == rhs)]
    if not here:
        return None
    for worst, _wall, name, tier, value in FRONT:
        if worst <= here[0] / TIGHTER and name in REGISTRY:
            return algorithm_at(name, tier, value)
    return None
