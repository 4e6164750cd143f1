"""Probe cases: integrators (see :mod:`benchmarks.probe_families`)."""

from __future__ import annotations

from benchmarks.probe import Case, Observed, Wrong, cli, cli_outcome, one_json  # noqa: F401

__all__ = ["cases"]


def cases() -> list[Case]:
    return []
