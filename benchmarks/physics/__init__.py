"""Reading a run as physics: limit-cycle metrics and the classification of a run
(:mod:`~benchmarks.physics.metrics`), slip-weakening curves
(:mod:`~benchmarks.physics.curves`), figures (:mod:`~benchmarks.physics.plots`), the summary
of one run (:mod:`~benchmarks.physics.summary`). What a laboratory brings is in
:mod:`benchmarks.lab`. Nothing here reads a save grid for a measure."""

from benchmarks._api import lazy_api

__getattr__, __dir__, __all__ = lazy_api(__name__, {
    "metrics": ("summarize", "limit_cycle", "event_metrics", "end_state", "LimitCycle",
                "EndState", "METRICS", "CLASSIFICATIONS"),
    "curves": ("read_curves", "check_curves", "write_curves", "event_curve", "sample_curves",
               "CURVE_COLUMNS"),
    "plots": ("plot_solution", "plot_work_precision", "plot_convergence"),
    "summary": ("simulate_summary",),
})
