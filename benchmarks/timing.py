"""Timing helpers: compiled methods are warmed up before any clock is read."""

from __future__ import annotations

import dataclasses

from integrators import solve

__all__ = ["warm_up"]


def warm_up(problem, algorithm, fraction: float = 1e-3) -> None:
    """Run ``algorithm`` on a short piece of ``problem`` so that numba has compiled it."""
    solve(dataclasses.replace(problem, t_end=problem.t_end * fraction), algorithm, max_points=2)
