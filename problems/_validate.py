"""Checks shared by the problem and algorithm dataclasses: a bad parameter fails at construction,
by name, before any work.

A number must be a real number of a numeric type: a string such as ``"0.01"``, a bool, None or an
array is refused here rather than failing mid-solve. A value that is valid but implausible in the
unit the parameter is documented in (an Lc typed in µm where metres are expected) is accepted
with a :class:`UnitWarning` that names the value and the unit.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import numbers
import warnings

import numpy as np

__all__ = ["check_finite", "check_positive", "check_non_negative", "check_count", "UnitWarning",
           "warn_implausible", "units_checked_already", "PLAUSIBLE"]

_UNITS_CHECKED = contextvars.ContextVar("rsfbench_units_checked", default=False)


class UnitWarning(UserWarning):
    """A parameter outside the range its documented unit makes plausible (probably a unit slip)."""


def _real(name: str, value) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number, got {value!r} "
                         f"({type(value).__name__})")
    return float(value)


def check_finite(name: str, value) -> float:
    """Return ``value`` as a float, or raise ``ValueError`` naming it if it is not a finite real
    number of a numeric type."""
    x = _real(name, value)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x


def check_positive(name: str, value) -> float:
    """Finite and > 0."""
    x = check_finite(name, value)
    if x <= 0:
        raise ValueError(f"{name} must be positive, got {value!r}")
    return x


def check_non_negative(name: str, value) -> float:
    """Finite and >= 0."""
    x = check_finite(name, value)
    if x < 0:
        raise ValueError(f"{name} must be non-negative, got {value!r}")
    return x


def check_count(name: str, value, minimum: int = 1) -> int:
    """An integer (an int, or a float with an integer value) ≥ ``minimum``."""
    x = check_finite(name, value)
    if x != int(x) or x < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(x)


#: (low, high, unit, hint): outside [low, high] a value is implausible in its unit. The ranges
#: are wide (laboratory and natural faults); they catch a unit slip (µm for m, mm/s for m/s,
#: percent for a fraction), not an unusual experiment.
PLAUSIBLE = {
    "lc": (1e-10, 1e-2, "m", "Lc is in metres: 0.3 µm is 3e-07"),
    "a": (1e-5, 0.2, "", "a is a fraction (0.008), not a percentage"),
    "b": (1e-5, 0.2, "", "b is a fraction (0.0092), not a percentage"),
    "v0": (1e-12, 1.0, "m/s", "v0 is in m/s: 10 µm/s is 1e-05"),
    "vl": (1e-12, 1.0, "m/s", "loading velocities are in m/s: 0.1 mm/s is 1e-04"),
    "vls": (1e-12, 1.0, "m/s", "loading velocities are in m/s: 0.1 mm/s is 1e-04"),
    "vlf": (1e-12, 1.0, "m/s", "loading velocities are in m/s: 0.1 mm/s is 1e-04"),
}


@contextlib.contextmanager
def units_checked_already():
    """No :class:`UnitWarning` inside: the caller has warned once already (a sweep builds
    thousands of problems from one axis). A context variable, not a warnings filter: filters
    are global, and a sweep's worker threads would save and restore each other's."""
    token = _UNITS_CHECKED.set(True)
    try:
        yield
    finally:
        _UNITS_CHECKED.reset(token)


def warn_implausible(name: str, value: float, stacklevel: int = 3) -> None:
    """Warn (:class:`UnitWarning`) if ``value`` of parameter ``name`` is outside
    :data:`PLAUSIBLE`; zero (b = 0, an allowed limit) is never implausible."""
    low, high, unit, hint = PLAUSIBLE[name]
    if value != 0 and not _UNITS_CHECKED.get() and not low <= abs(value) <= high:
        where = f"{low:g}–{high:g} {unit}".rstrip()
        warnings.warn(f"{name} = {value:g} {unit} is outside the plausible range {where}: "
                      f"{hint}".replace("  ", " "), UnitWarning, stacklevel=stacklevel)
