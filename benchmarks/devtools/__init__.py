"""The DevTools layer, as DiffEqDevTools is to DifferentialEquations.jl: references from two
independent solvers that agree (:mod:`~benchmarks.devtools.reference`), achieved errors on the
measured quantities (:mod:`~benchmarks.devtools.errors`), work-precision studies and the
recommendation they give (:mod:`~benchmarks.devtools.work_precision`,
:mod:`~benchmarks.devtools.recommendation`), convergence orders
(:mod:`~benchmarks.devtools.convergence`), every integrator side by side
(:mod:`~benchmarks.devtools.compare`) and timing after warm-up
(:mod:`~benchmarks.devtools.timing`)."""

from benchmarks._api import lazy_api

__getattr__, __dir__, __all__ = lazy_api(__name__, {
    "reference": ("Reference", "ReferenceDisagreement"),
    "errors": ("ERROR_COLUMNS",),
    "work_precision": ("study_problems", "recommend", "pareto_front",
                       "read_study", "QUICK", "FULL"),
    "recommendation": ("recommended",),
    "wp_files": ("write_work_precision",),
    "convergence": ("convergence_study", "observed_order"),
    "compare": ("compare_integrators",),
    "timing": ("warm_up",),
})
