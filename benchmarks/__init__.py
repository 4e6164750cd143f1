"""The accuracy-and-cost harness, in rooms by role, each importing only the rooms before it
(``tests/test_layers.py``; stated for import-linter in ``pyproject.toml``):

* :mod:`benchmarks.records` — result files written whole and read back checked, provenance;
* :mod:`benchmarks.physics` — a run read as physics: limit-cycle metrics, slip-weakening
  curves, plots;
* :mod:`benchmarks.devtools` — references, achieved errors, work-precision and convergence
  studies, the recommended integrator;
* :mod:`benchmarks.ensemble` — one problem at many points, as one table;
* :mod:`benchmarks.inversion` — observations, misfits, fits, profiles, posteriors, sweeps;
* :mod:`benchmarks.lab` — what a laboratory brings: a stick–slip recording observed, a
  velocity-step or slide-hold-slide record fitted;
* :mod:`benchmarks.studies` — one module per result in ``results/``;
* :mod:`benchmarks.pipeline` — what ``make reproduce`` runs and may reuse;
* :mod:`benchmarks.cli` — the ``rsfbench`` command line.

The public names of each room are in its ``__all__`` and in ``docs/api.md``.
"""

from integrators.core.cache import drop_stale_caches

drop_stale_caches(("benchmarks",), ("integrators", "problems", "benchmarks"))

__all__ = ["records", "physics", "devtools", "ensemble", "inversion", "lab", "studies",
           "pipeline", "cli"]
