"""The probe's case families added after its first catalogue (:mod:`probe.cases`),
one module by area: each module's ``cases()`` returns its :class:`~probe.harness.Case` list."""

from __future__ import annotations

from probe.families import (
    classification,
    etd,
    histories,
    integrators,
    inversion,
    lab,
    observe,
    problem_files,
    review,
    store,
    units,
)

__all__ = ["cases"]

_MODULES = (problem_files, lab, units, classification, integrators, etd, histories, store,
            inversion, review, observe)


def cases() -> list:
    """Every case of every family, in a fixed order."""
    return [case for module in _MODULES for case in module.cases()]
