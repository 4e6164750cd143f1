"""Observed order of convergence from a ladder of step sizes."""

from __future__ import annotations

import numpy as np

__all__ = ["observed_order"]


def observed_order(steps, errors) -> float:
    """Least-squares slope of log(error) against log(step)."""
    steps, errors = np.asarray(steps, float), np.asarray(errors, float)
    if len(steps) < 2 or np.any(errors <= 0) or np.any(steps <= 0):
        raise ValueError(f"need >= 2 positive steps and errors, got {steps!r}, {errors!r}")
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])
