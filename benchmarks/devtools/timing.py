"""Timing helpers: compiled methods are warmed up before any clock is read."""

from __future__ import annotations

from integrators.core.solve import compile_ahead

__all__ = ["warm_up"]

#: run ``algorithm`` on a short piece of ``problem`` so that numba has compiled it
warm_up = compile_ahead
