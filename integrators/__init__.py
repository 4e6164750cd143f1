"""Integrators: ``solve``, ``Solution``, the registry, and three rooms of methods.

* :mod:`integrators.core`: ``solve``, ``Solution``, the registry and base classes, the events,
  and the segment driver the adapters share;
* :mod:`integrators.own`: the project's compiled methods (the paper's ETD family; CashKarp45,
  Rosenbrock23, Rodas5P, RadauIIA5, Exprb32, Exprb43 on one compiled engine);
* :mod:`integrators.external`: adapters to scipy, numbalsoda, scikits-odes, assimulo and
  scikit-SUNDAE, declared by name here and imported on first use (``import integrators`` imports
  none of those libraries; a name whose library fails to import is left out of the registry, the
  reason in :data:`UNAVAILABLE`).
"""

from integrators.core.cache import drop_stale_caches

# before any kernel loads its cache (integrators/core/cache.py says why)
drop_stale_caches(("integrators", "problems"), ("integrators", "problems"))

from integrators.core.registry import (REGISTRY, UNAVAILABLE, Algorithm, ProblemNotSupported,
                                       algorithm_class, make_algorithm, register)
from integrators.core.solution import EVENT_COLUMNS, Output, ReturnCode, Solution, Stats
from integrators.core.solve import Budget, solve
from integrators.own.etd import ETD1, ETD2, ETDIterated
from integrators.own.cash_karp import CashKarp45
from integrators.own.exprb32 import Exprb32
from integrators.own.exprb43 import Exprb43
from integrators.own.radau5 import RadauIIA5
from integrators.own.rodas5p import Rodas5P
from integrators.own.rosenbrock23 import Rosenbrock23

#: the adapters to external libraries: module → the names it registers (a test checks the lists)
EXTERNAL = {
    "integrators.external.scipy_backend": ("scipy-RK45", "scipy-DOP853", "scipy-Radau",
                                           "scipy-BDF", "scipy-LSODA"),
    "integrators.external.numbalsoda_backend": ("numbalsoda-LSODA",),
    "integrators.external.numbalsoda_grid": ("numbalsoda-LSODA-grid",),
    "integrators.external.scikits_odes_backend": ("odes-CVODE-BDF", "odes-CVODE-Adams",
                                                  "odes-IDA"),
    "integrators.external.assimulo_backend": ("assimulo-CVode", "assimulo-IDA",
                                              "assimulo-Radau5ODE", "assimulo-LSODAR",
                                              "assimulo-RodasODE", "assimulo-Dopri5"),
    "integrators.external.sksundae_backend": ("sundae-CVODE", "sundae-IDA"),
    "integrators.external.sundials_c": ("sundials-CVODE-BDF", "sundials-CVODE-Adams",
                                        "sundials-IDA", "sundials-ARKODE-IMEX",
                                        "sundials-ARKODE-ERK"),
    "integrators.external.cyrk_backend": ("CyRK-RK45", "CyRK-DOP853", "CyRK-Tsit5", "CyRK-BDF",
                                          "CyRK-Radau", "CyRK-LSODA"),
}
#: how to install what an adapter needs (the extras of pyproject.toml)
INSTALL = {
    "integrators.external.scipy_backend": "pip install scipy",
    "integrators.external.numbalsoda_backend": "pip install 'rsfbench[numbalsoda]' (builds from "
                                              "source: needs gfortran and cmake)",
    "integrators.external.numbalsoda_grid": "pip install 'rsfbench[numbalsoda]' (builds from "
                                            "source: needs gfortran and cmake)",
    "integrators.external.scikits_odes_backend": "pip install 'rsfbench[sundials]' (builds "
                                                 "against SUNDIALS 6: apt-get install "
                                                 "libsundials-dev pkg-config)",
    "integrators.external.assimulo_backend": "pip install 'rsfbench[assimulo]'",
    "integrators.external.sksundae_backend": "pip install 'rsfbench[sundials]'",
    "integrators.external.sundials_c": "the system's SUNDIALS 6 library (apt-get install "
                                       "libsundials-dev)",
    "integrators.external.cyrk_backend": "pip install 'rsfbench[cyrk]'",
}
for _module, _names in EXTERNAL.items():
    REGISTRY.declare(_module, _names, INSTALL[_module])

#: classes of the adapters reachable as attributes (``integrators.ScipyRadau``), imported on use
_CLASSES = {"ScipyRK45": "scipy-RK45", "ScipyDOP853": "scipy-DOP853", "ScipyRadau": "scipy-Radau",
            "ScipyBDF": "scipy-BDF", "ScipyLSODA": "scipy-LSODA"}


def __getattr__(name: str):
    if name in _CLASSES:
        return REGISTRY[_CLASSES[name]]
    raise AttributeError(f"module 'integrators' has no attribute {name!r}")


__all__ = ["REGISTRY", "UNAVAILABLE", "EXTERNAL", "INSTALL", "Algorithm", "ProblemNotSupported",
           "algorithm_class", "make_algorithm",
           "register", "EVENT_COLUMNS", "Output", "ReturnCode", "Solution", "Stats", "Budget",
           "solve", "ETD1", "ETD2", "ETDIterated", "CashKarp45", "Exprb32", "Exprb43",
           "Rosenbrock23", "Rodas5P", "RadauIIA5", *_CLASSES]
