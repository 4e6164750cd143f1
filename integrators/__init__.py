"""Integrators: ``solve``, ``Solution``, the registry, the paper's ETD family and the backends."""

from integrators.registry import REGISTRY, Algorithm, algorithm_class, register
from integrators.solution import EVENT_COLUMNS, ReturnCode, Solution, Stats
from integrators.solve import solve
from integrators.etd import ETD1, ETD2, ETDIterated  # noqa: E402  (registers the ETD family)
from integrators.scipy_backend import (ScipyBDF, ScipyDOP853, ScipyLSODA, ScipyRadau,  # noqa: E402
                                      ScipyRK45)

__all__ = ["REGISTRY", "Algorithm", "algorithm_class", "register", "EVENT_COLUMNS", "ReturnCode",
           "Solution", "Stats", "solve", "ETD1", "ETD2", "ETDIterated", "ScipyBDF", "ScipyDOP853",
           "ScipyLSODA", "ScipyRadau", "ScipyRK45"]
