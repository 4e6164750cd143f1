"""The points of an ensemble: one base problem, and columns of values of its scalar fields.

A point is the base problem with some fields replaced (:func:`problems.variant`: the law's a, b,
lc, v0, the problem's mass, stiffness, normal_force, mu0, t_end, the loading's speeds, the start
rule). :func:`grid` makes the columns of an outer product; :func:`check_points` checks them, and
every point's problem, before any work.
"""

from __future__ import annotations

import numpy as np

from problems import SpringSlider, growth_rate, growth_rates, variant, variant_fields
from problems._validate import (
    PLAUSIBLE,
    check_count,
    units_checked_already,
    warn_implausible,
)

__all__ = ["grid", "check_points", "point_problems", "MAX_POINTS"]

#: the most points an ensemble runs unless ``max_points`` allows more: a typo in a grid step
#: must not start 10⁹ solves
MAX_POINTS = 1_000_000


def grid(**axes) -> dict[str, np.ndarray]:
    """The columns of the outer product of ``axes`` (name → values), the first axis outermost:
    ``grid(b=[0.009, 0.01], lc=[1e-7, 1e-6])`` has b = (0.009, 0.009, 0.01, 0.01) and
    lc = (1e-7, 1e-6, 1e-7, 1e-6).

    Parameters
    ----------
    **axes : array_like
        Each axis's values by field name, in the field's SI unit.

    Returns
    -------
    dict of str to numpy.ndarray
        One column per axis, of the product's length.

    Raises
    ------
    ValueError
        Without an axis, or for an axis that is not a list of finite numbers.
    """
    if not axes:
        raise ValueError("grid needs at least one axis, e.g. grid(b=[...], lc=[...])")
    values = [_column(name, x) for name, x in axes.items()]
    mesh = np.meshgrid(*values, indexing="ij")
    return {name: m.ravel() for name, m in zip(axes, mesh)}


def _column(name: str, values) -> np.ndarray:
    try:
        x = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"the values of {name!r} must be numbers, got {values!r}") from None
    x = np.atleast_1d(x)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"the values of {name!r} must be a non-empty 1-D sequence, got shape "
                         f"{x.shape}")
    if not np.isfinite(x).all():
        raise ValueError(f"the values of {name!r} must be finite, got "
                         f"{x[~np.isfinite(x)][:3].tolist()}")
    return x


def check_points(problem: SpringSlider, params, max_points: int = MAX_POINTS):
    """``(names, values)``: the parameter names and an (n, k) array of their values, one row a
    point, or ValueError naming the bad parameter: a SpringSlider, fields its variants can
    change, columns of finite numbers of one length, at most ``max_points`` points. An axis
    outside the plausible range for its units warns once (not once a point).

    Parameters
    ----------
    problem : SpringSlider
        The base problem.
    params : mapping of str to array_like
        The values of each varied field (SI units), one per point.
    max_points : int
        The most points accepted.

    Returns
    -------
    names : tuple of str
        The parameter names.
    values : numpy.ndarray
        The points, shape (n, len(names)).

    Raises
    ------
    ValueError
        Naming the bad parameter.
    """
    if not isinstance(problem, SpringSlider):
        raise ValueError(f"problem must be a SpringSlider, got {type(problem).__name__}")
    if not hasattr(params, "items") or not params:
        raise ValueError(f"params must be a non-empty mapping of field name to values, e.g. "
                         f"{{'b': [...], 'lc': [...]}}, got {params!r}")
    known = variant_fields(problem)
    names = list(params)
    for name in names:
        if name not in known:
            raise ValueError(f"{name!r} is not a field a variant of this problem can change; "
                             f"the fields are {', '.join(known)}")
    columns = [_column(name, params[name]) for name in names]
    n = {c.size for c in columns}
    if len(n) != 1:
        raise ValueError("the parameter columns differ in length: "
                         + ", ".join(f"{k} has {c.size}" for k, c in zip(names, columns)))
    limit = check_count("max_points", max_points)
    if columns[0].size > limit:
        raise ValueError(f"the ensemble has {columns[0].size} points, more than max_points = "
                         f"{limit}: raise it if you mean it")
    for name, c in zip(names, columns):
        for value in ({c.min(), c.max()} if name in PLAUSIBLE else ()):
            warn_implausible(name, value, stacklevel=3)
    return tuple(names), np.column_stack(columns)


def point_problems(problem: SpringSlider, names, values, first: int = 0) -> list[SpringSlider]:
    """The problem of each row of ``values`` (its index offset by ``first`` in a message), or
    ValueError naming the point and its bad value.

    Parameters
    ----------
    problem : SpringSlider
        The base problem.
    names : sequence of str
        The varied fields.
    values : numpy.ndarray
        The points, one row each (SI units).
    first : int
        The index of the first row in the ensemble, for messages.

    Returns
    -------
    list of SpringSlider

    Raises
    ------
    ValueError
        Naming the point, its values and why the problem refuses them.
    """
    out = []
    with units_checked_already():            # check_points warned once per axis
        for i, row in enumerate(values):
            changes = dict(zip(names, (float(v) for v in row)))
            try:
                point = variant(problem, **changes)
                point.nondimensional()       # what a solve needs first (Ψ of θ, say)
                out.append(point)
            except ValueError as exc:
                raise ValueError(f"point {first + i} ({_at(changes)}): {exc}") from None
        try:
            growth_rates(out)                # kept on each point, all in one call
        except ValueError:                   # which point: one by one
            for i, (point, row) in enumerate(zip(out, values)):
                try:
                    growth_rate(point)
                except ValueError as exc:
                    at = _at(dict(zip(names, (float(v) for v in row))))
                    raise ValueError(f"point {first + i} ({at}): {exc}") from None
            raise
    return out


def _at(changes: dict) -> str:
    return ", ".join(f"{k} = {v:g}" for k, v in changes.items())
