"""The studies: one module per result in ``results/``, each built on the library rooms and run
by the pipeline (:mod:`benchmarks.pipeline.reproduce`). No library module imports a study."""
