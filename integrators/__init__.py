"""Integrators: ``solve``, ``Solution``, the registry, the paper's ETD family and the backends."""

from integrators.registry import REGISTRY, Algorithm, algorithm_class, make_algorithm, register
from integrators.solution import EVENT_COLUMNS, ReturnCode, Solution, Stats
from integrators.solve import solve
from integrators.etd import ETD1, ETD2, ETDIterated  # noqa: E402  (registers the ETD family)
from integrators.cash_karp import CashKarp45  # noqa: E402  (Press et al.'s adaptive RK, numba)
from integrators.exp_rosenbrock import Exprb32, Exprb43  # noqa: E402  (exponential Rosenbrock, numba)
from integrators.rosenbrock import Rodas5P, Rosenbrock23  # noqa: E402  (Rosenbrock, numba)
from integrators.scipy_backend import (ScipyBDF, ScipyDOP853, ScipyLSODA, ScipyRadau,  # noqa: E402
                                      ScipyRK45)

#: optional backends: each registers its integrators when its library imports; otherwise the
#: reason is kept here (tests report it as a skip; `make test` installs them all).
OPTIONAL_BACKENDS = ("integrators.scikits_odes_backend", "integrators.assimulo_backend",
                     "integrators.sksundae_backend", "integrators.numbalsoda_backend")
UNAVAILABLE: dict[str, str] = {}


def _load_optional() -> None:
    import importlib
    for module in OPTIONAL_BACKENDS:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            UNAVAILABLE[module] = f"{type(exc).__name__}: {exc}"


_load_optional()

__all__ = ["REGISTRY", "Algorithm", "algorithm_class", "make_algorithm", "register", "EVENT_COLUMNS", "ReturnCode",
           "Solution", "Stats", "UNAVAILABLE", "solve", "ETD1", "ETD2", "ETDIterated", "CashKarp45", "Exprb32", "Exprb43", "Rosenbrock23", "Rodas5P",
           "ScipyBDF", "ScipyDOP853", "ScipyLSODA", "ScipyRadau", "ScipyRK45"]
