"""Integrators: ``solve``, ``Solution``, the registry, the paper's ETD family and the backends."""

from integrators.registry import REGISTRY, Algorithm, algorithm_class, register
from integrators.solution import EVENT_COLUMNS, ReturnCode, Solution, Stats
from integrators.solve import solve
from integrators.etd import ETD1, ETD2, ETDIterated  # noqa: E402  (registers the ETD family)

__all__ = ["REGISTRY", "Algorithm", "algorithm_class", "register", "EVENT_COLUMNS", "ReturnCode",
           "Solution", "Stats", "solve", "ETD1", "ETD2", "ETDIterated"]
