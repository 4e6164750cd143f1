"""The pipeline: the steps that bring ``results/`` up to date and what each may reuse
(:mod:`~benchmarks.pipeline.reproduce`, :mod:`~benchmarks.pipeline.plan`,
:mod:`~benchmarks.pipeline.manifest`), and the README's
generated blocks (:mod:`~benchmarks.pipeline.readme`)."""

from benchmarks._api import lazy_api

__getattr__, __dir__, __all__ = lazy_api(__name__, {
    "plan": ("studies", "study_named"),
    "readme": ("refresh",),
})
