"""Shared fixtures: reference solutions are computed once per test session; Fortran output is
flushed after each test, while pytest still captures it.

Optional libraries (the peers, pyarrow and Dask, emcee and corner): a test that needs one says so
with ``@pytest.mark.needs("module", ...)`` and is skipped where it is missing (``pip install .``
without extras); ``make test`` passes ``--require-all``, which first checks that every optional
library imports and stops the run, naming the missing ones, if one does not."""

import contextlib
import ctypes
import importlib.util

import numpy as np
import pytest

import integrators as I
from problems import paper_example


@pytest.fixture(scope="session")
def fd_jacobian():
    """Central finite differences of ``f`` at x (steps ε·max(1, |x_j|)): the check of every
    analytic Jacobian."""
    def jacobian(f, x, eps=1e-7):
        jac = np.empty((len(f(x)), len(x)))
        for j in range(len(x)):
            dx = np.zeros(len(x))
            dx[j] = eps * max(1.0, abs(x[j]))
            jac[:, j] = (f(x + dx) - f(x - dx)) / (2 * dx[j])
        return jac
    return jacobian


@pytest.fixture(scope="session")
def paper_radau_reference():
    """Paper example (slip law, 20 s) by scipy Radau at rtol = atol = 1e−11, analytic Jacobian.

    The independent reference for the ETD convergence tests (~15 s on the CI machine).
    """
    sol = I.solve(paper_example(), I.ScipyRadau(rtol=1e-11, atol=1e-11))
    assert sol.success, sol.message
    return sol



def _gfortran_runtimes():
    """Every gfortran runtime loaded in this process: wheels vendor their own copies (assimulo,
    scipy, numpy, scikit-sundae), each with its own unit 6 buffer."""
    with open("/proc/self/maps") as maps:
        paths = {line.split()[-1] for line in maps if "libgfortran" in line}
    return [ctypes.CDLL(p) for p in sorted(paths)]


#: the optional modules ``--require-all`` checks (besides every adapter of the registry)
OPTIONAL = ("pyarrow", "dask", "distributed", "emcee", "corner", "pytest_benchmark", "sphinx",
            "myst_parser", "furo")


def pytest_addoption(parser):
    parser.addoption("--require-all", action="store_true",
                     help="every optional library must import: stop before any test, naming "
                          "the missing ones (make test), instead of skipping the tests that "
                          "need them")


def pytest_configure(config):
    config.addinivalue_line("markers", "needs(*modules): the optional modules a test needs; "
                                       "skipped where one is missing")
    if config.getoption("--require-all"):
        missing = [m for m in OPTIONAL if not _imports(m)]
        missing += [f"{module} ({why})" for module, why in sorted(I.UNAVAILABLE.items())]
        if missing:
            pytest.exit(f"--require-all: missing {', '.join(missing)}; `make setup` installs "
                        f"every extra", returncode=3)


def _imports(module: str) -> bool:
    """Does ``module`` import (not only exist: a broken install counts as missing here)?"""
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True


def _absent(exc: ModuleNotFoundError, config) -> bool:
    """Is ``exc`` an optional library that is not installed at all, outside --require-all?"""
    top = (exc.name or "").split(".")[0]
    return (top in OPTIONAL_ALL and not config.getoption("--require-all")
            and _missing(top))


def _missing(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is None
    except ModuleNotFoundError:          # a dotted name whose parent is not installed
        return True


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item):
    """A test marked ``needs`` is skipped where a module it names is missing; a fixture that
    reaches a missing optional library skips its test, naming it."""
    for mark in item.iter_markers("needs"):
        missing = [m for m in mark.args if _missing(m)]
        if missing:
            pytest.skip(f"needs {', '.join(missing)}, not installed (pip install '.[all]')")
    with _skipped_if_absent(item):
        return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    """A test that reaches an optional library that is not installed is skipped, naming it
    (never under --require-all, where every one is installed)."""
    with _skipped_if_absent(item):
        return (yield)


@contextlib.contextmanager
def _skipped_if_absent(item):
    try:
        yield
    except ModuleNotFoundError as exc:
        if _absent(exc, item.config):
            pytest.skip(f"needs {exc.name}, not installed: {exc}")
        raise


#: every optional top-level module: those above and the peers' libraries
OPTIONAL_ALL = {*OPTIONAL, "scikits", "assimulo", "sksundae", "numbalsoda", "CyRK"}

I.REGISTRY.load_all()                  # the adapters load on first use: load them all now
_GFORTRAN = _gfortran_runtimes()


@pytest.fixture(autouse=True)
def _flush_fortran_output():
    """gfortran buffers its unit 6 (assimulo's Dopri5 prints "THE PROBLEM SEEMS TO BECOME STIFF")
    until the process exits, after pytest's summary; flushing it after each test keeps it in the
    test's captured output."""
    yield
    for runtime in _GFORTRAN:
        runtime._gfortran_flush_i4(None)
