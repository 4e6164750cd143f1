"""The integrator a command uses when none is named: a constant in code, not a file read at run
time.

:data:`FRONT` is the front of the work-precision studies over the paper's example, W2 and the
two external problems (``results/wp_quick.csv`` and ``results/wp_external.csv``:
:func:`benchmarks.devtools.work_precision.advice_study`): settings of one integrator for the
whole problem set, each faster than every more accurate one, with its worst error in the
recurrence interval over all four problems. The studies write it
(:func:`benchmarks.devtools.work_precision.write_recommendation`);
``tests/test_recommendation.py`` checks it against the committed studies. :func:`recommended`
takes the fastest setting within a level, and :func:`tighter_on_front` the next setting
:data:`TIGHTER` times as accurate when a check on the user's own problem asks for more.
"""

from __future__ import annotations

import warnings

from benchmarks.devtools.work_precision import algorithm_at
from integrators import ETD2, REGISTRY

__all__ = ["FRONT", "STUDY", "recommended", "tighter_on_front", "TIGHTER", "contenders",
           "CONTENDERS_SPAN"]

#: a tighter setting on the front is at least this many times as accurate: about what rtol ÷ 10
#: gives a method of order p = 3 to 5 (10^(p/(p+1)) = 5.6 to 6.8)
TIGHTER = 5.0

#: settings within a level whose total wall in the studies is within this factor of the
#: fastest's are raced on the user's own box (:func:`contenders`): the studies' order of
#: near-ties (Rodas5P at 1e-4 and RadauIIA5 at 1e-3 are 10 % apart) need not be a problem's
CONTENDERS_SPAN = 1.25

# --- written by the work-precision studies (`study work-precision`, `external`); do not edit ---
STUDY = {"files": ('wp_quick.csv', 'wp_external.csv'),
         "commits": ('2f5dc43a4efe', 'f7fb128af3b2'),
         "sha256": ('173c27b0b1a9d54b39aa8e9ac58cfbf71ddcf96b6dcef330dab4756daeb33b0d',
                    'cc3257f2fb9e0c663c01e9cedbd172812c87daf69656a364bb39c85259e957c7'),
         "problems": 4}
#: (worst err_recurrence over the studies' problems, total wall s, integrator, rhs
#: tier, setting), fastest first
FRONT = (
    (0.011198825790385303, 0.0010619390068313805, 'Rosenbrock23', 'numba', 0.001),
    (0.0027650939520882, 0.0015844839945202693, 'Rosenbrock23', 'numba', 0.0001),
    (0.0015063812002567875, 0.0016283629993267823, 'Rodas5P', 'numba', 0.001),
    (0.001286825710707439, 0.0018362499813520117, 'Exprb43', 'numba', 0.001),
    (0.00027323049556251313, 0.0019862959961756133, 'Rodas5P', 'numba', 0.0001),
    (0.0002142234658407011, 0.0021352589938032907, 'RadauIIA5', 'numba', 0.001),
    (1.6715139223642846e-05, 0.0023214760058181128, 'RadauIIA5', 'numba', 0.0001),
    (1.3035948330728903e-06, 0.0032367330022680108, 'RadauIIA5', 'numba', 1e-05),
    (8.976686451622734e-08, 0.0052028959908057, 'RadauIIA5', 'numba', 1e-06),
    (4.982416158514556e-09, 0.00850225400972704, 'RadauIIA5', 'numba', 1e-07),
    (7.050229986264348e-10, 0.01443000100152858, 'RadauIIA5', 'numba', 1e-08),
    (6.168342236865305e-10, 0.02373604100648663, 'RadauIIA5', 'numba', 1e-09),
    (6.111881066733134e-10, 0.04130131399506354, 'RadauIIA5', 'numba', 1e-10),
    (5.036177584387575e-10, 0.06488140299916267, 'Exprb43', 'numba', 1e-10),
)
# --- end of the written part ---


def recommended(level: float, sensitive: bool = False):
    """``(algorithm, reason)``: the fastest setting of :data:`FRONT` whose worst error is within
    ``level``; when none is, the front's most accurate setting with a warning that the level
    is beyond what the studies vouch for (ETD2 at the paper's settings only if no setting of
    the front is installed).

    Parameters
    ----------
    level : float
        The worst relative error in the recurrence interval to meet (dimensionless).
    sensitive : bool
        Only settings whose method has forward sensitivities, at an rtol gradients can use
        (:data:`problems.directions.SENSITIVITY_RTOL`).

    Returns
    -------
    algorithm : Algorithm
        The method at its setting.
    reason : str
        Why, naming the study it was read from.
    """
    from problems.directions import SENSITIVITY_RTOL
    rows = [r for r in FRONT if r[2] in REGISTRY and not (sensitive and not (
        getattr(REGISTRY[r[2]], "sensitive", False) and r[4] <= SENSITIVITY_RTOL))]
    kind = (f" with forward sensitivities at rtol ≤ {SENSITIVITY_RTOL:g}" if sensitive
            else "")
    for worst, _wall, name, tier, setting in rows:
        if worst <= level:
            return algorithm_at(name, tier, setting), (
                f"the work-precision studies ({_studies()}): fastest setting{kind} with worst "
                f"err_recurrence ≤ {level:g} over their {STUDY['problems']} problems "
                f"(worst {worst:.2g}): {name} [{tier}] at {setting:g}")
    if rows:
        worst, _wall, name, tier, setting = min(rows, key=lambda row: row[0])
        why = (f"the work-precision studies ({_studies()}) recommend nothing{kind} for "
               f"err_recurrence ≤ {level:g}, beyond what they vouch for: their most accurate "
               f"setting{kind}, {name} [{tier}] at {setting:g} (worst {worst:.2g} over their "
               f"{STUDY['problems']} problems)")
        warnings.warn(why, stacklevel=2)
        return algorithm_at(name, tier, setting), why
    return ETD2(), (f"the work-precision studies ({_studies()}) recommend nothing{kind} for "
                    f"err_recurrence ≤ {level:g}: ETD2 at the paper's settings")


def _studies() -> str:
    """The studies :data:`FRONT` was written from, each with its commit."""
    return ", ".join(f"{f} at {c}" for f, c in zip(STUDY["files"], STUDY["commits"]))


def contenders(level: float) -> list:
    """The settings of :data:`FRONT` within ``level`` (worst error over the studies' problems)
    whose wall in the studies is within :data:`CONTENDERS_SPAN` of the fastest of them,
    fastest first, as ``(algorithm, worst, wall_s)``; empty when none is within ``level``."""
    rows = [r for r in FRONT if r[0] <= level and r[2] in REGISTRY]
    return [(algorithm_at(name, tier, setting), worst, wall)
            for worst, wall, name, tier, setting in rows
            if wall <= CONTENDERS_SPAN * rows[0][1]]


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
