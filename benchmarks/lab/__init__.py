"""The laboratory: what a user brings from their apparatus, and everything done with it.

A stick–slip recording: read and checked (:mod:`~benchmarks.lab.channels`), its events and the
fault's friction measured (:mod:`~benchmarks.lab.events`), turned into the observations of an
inversion (:mod:`~benchmarks.lab.observe_recording`) with its figure
(:mod:`~benchmarks.lab.figures`), its start-up and outliers found
(:mod:`~benchmarks.lab.settled`), or made by the forward model to be read back
(:mod:`~benchmarks.lab.synthetic`). An event catalogue read into the same observations
(:mod:`~benchmarks.lab.catalogue`), and the apparatus constants it does not state estimated
from it (:mod:`~benchmarks.lab.catalogue_constants`).

A velocity-step or slide-hold-slide test: what it measures on a run
(:mod:`~benchmarks.lab.measures`); a record read for a fit (:mod:`~benchmarks.lab.step_data`)
and its load-point history (:mod:`~benchmarks.lab.history`); the fit's forward model with one
state (:mod:`~benchmarks.lab.model`) or two (:mod:`~benchmarks.lab.two_state`), and an
independent one to check it against (:mod:`~benchmarks.lab.independent_model`); the
least-squares fit (:mod:`~benchmarks.lab.fit`), its profile intervals
(:mod:`~benchmarks.lab.profile_intervals`), posterior sample (:mod:`~benchmarks.lab.sampling`)
and checks (:mod:`~benchmarks.lab.checks`).

The room sits between :mod:`benchmarks.inversion` (which keeps the inversion of (b, Lc)) and
the studies; nothing below it imports it."""

from benchmarks._api import lazy_api

__getattr__, __dir__, __all__ = lazy_api(__name__, {
    "channels": ("read_recording", "recording_from", "Recording", "CHANNELS", "UNITS"),
    "events": ("analyse", "Analysis"),
    "observe_recording": ("observe",),
    "settled": ("judge", "Settling"),
    "catalogue": ("read_catalogue", "observe_catalogue"),
    "catalogue_constants": ("estimate_constants", "CatalogueConstants"),
    "synthetic": ("synthetic_recording",),
    "measures": ("step_response", "healing", "healing_rate", "step_reference",
                 "UnsettledWarning", "PeakNotReached"),
    "step_data": ("read_lab_record", "lab_record_from", "LabRecord"),
    "model": ("LabModel",),
    "two_state": ("two_state_friction",),
    "independent_model": ("reference_friction", "synthetic_record"),
    "fit": ("fit_lab", "LabFit"),
    "profile_intervals": ("profile_lab", "LabProfile"),
    "sampling": ("sample_lab", "LabPosterior"),
    "checks": ("check_lab_solver", "inertia_check"),
})
