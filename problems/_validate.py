"""Checks shared by the problem dataclasses: a bad parameter fails at construction, by name."""

from __future__ import annotations

import math


def check_finite(name: str, value) -> float:
    """Return ``value`` as a float, or raise ``ValueError`` naming it if it is not a finite number."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
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
