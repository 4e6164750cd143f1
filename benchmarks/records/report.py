"""Small writers for the generated reports (Markdown tables without extra dependencies)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["markdown_table", "jsonable", "fmt", "literal"]


def markdown_table(df: pd.DataFrame, floatfmt: str | None = None) -> str:
    """A GitHub-flavoured Markdown table of ``df`` (values as ``str``; floats with ``floatfmt``
    if given, NaN as a gap).

    Parameters
    ----------
    df : pandas.DataFrame
        The table.
    floatfmt : str, optional
        A format spec for floats (``".3g"``).

    Returns
    -------
    str
    """
    def cell(v):
        if floatfmt is not None and isinstance(v, (float, np.floating)):
            return fmt(float(v), floatfmt)
        return str(v)
    cols = [str(c) for c in df.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def jsonable(x):
    """``x`` with numpy scalars as Python numbers and NaN/inf as None (valid JSON).

    Parameters
    ----------
    x : object
        A value, or dicts, lists and tuples of them.

    Returns
    -------
    object
        The same structure, JSON-ready.
    """
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, list):
        return [jsonable(v) for v in x]
    return x


def literal(text: str) -> str:
    """``text`` (a file's or a problem's name) as matplotlib draws it literally: a pair of
    ``$`` in it would otherwise be read as mathematics (and a stray one fail the figure)."""
    return str(text).replace("$", r"\$")


def fmt(x, spec: str = ".3g") -> str:
    """``format(x, spec)``, or an empty string for None/NaN (tables show a gap, not "nan").

    Parameters
    ----------
    x : float or None
        The value.
    spec : str
        The format spec.

    Returns
    -------
    str
    """
    if x is None or (isinstance(x, float) and x != x):
        return ""
    return format(x, spec)
