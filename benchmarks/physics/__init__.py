"""Reading a run as physics: limit-cycle metrics and the classification of a run
(:mod:`~benchmarks.physics.metrics`), what a laboratory user measures on a velocity step or a
slide-hold-slide test (:mod:`~benchmarks.physics.lab`), slip-weakening curves
(:mod:`~benchmarks.physics.curves`), figures (:mod:`~benchmarks.physics.plots`), the summary
of one run (:mod:`~benchmarks.physics.summary`), and a laboratory recording: read and checked
(:mod:`~benchmarks.physics.recording`), measured (:mod:`~benchmarks.physics.record_analysis`),
or made by the forward model (:mod:`~benchmarks.physics.model_recording`); a laboratory
velocity-step record read for a fit (:mod:`~benchmarks.physics.lab_record`), its history found
(:mod:`~benchmarks.physics.lab_history`),
and the fit's forward model (:mod:`~benchmarks.physics.lab_model`, with two state variables
:mod:`~benchmarks.physics.lab_two_state`). Nothing here reads a save grid for a measure."""

from benchmarks._api import lazy_api

__getattr__, __dir__, __all__ = lazy_api(__name__, {
    "metrics": ("summarize", "limit_cycle", "event_metrics", "end_state", "LimitCycle",
                "EndState", "METRICS", "CLASSIFICATIONS"),
    "lab": ("step_response", "healing", "healing_rate", "step_reference", "UnsettledWarning",
            "PeakNotReached"),
    "curves": ("read_curves", "check_curves", "write_curves", "event_curve", "sample_curves",
               "CURVE_COLUMNS"),
    "plots": ("plot_solution", "plot_work_precision", "plot_convergence"),
    "summary": ("simulate_summary",),
    "recording": ("read_recording", "recording_from", "Recording", "CHANNELS", "UNITS"),
    "record_analysis": ("analyse", "Analysis"),
    "model_recording": ("synthetic_recording",),
    "lab_record": ("read_lab_record", "lab_record_from", "LabRecord"),
    "lab_model": ("LabModel",),
    "lab_two_state": ("two_state_friction",),
})
