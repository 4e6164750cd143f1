"""A work-precision study's files: every point as CSV, the Pareto summary and the one setting
for the whole problem set as CSV and Markdown, and a figure per problem."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd

from benchmarks.devtools.work_precision import best_at_levels, recommend
from benchmarks.physics.plots import plot_work_precision
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import fmt, markdown_table

__all__ = ["ERROR_LEVELS", "write_work_precision", "pareto_markdown"]

#: the error levels of the Pareto summary and the recommendation
ERROR_LEVELS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)


def write_work_precision(df: pd.DataFrame, out: Path, name: str,
                         error: str = "err_recurrence") -> dict[str, Path]:
    """Write a study: ``wp_<name>.csv`` (every point), ``wp_<name>_pareto.csv/.md`` (the fastest
    integrator per problem and error level, and the one setting to use across all problems) and
    one ``wp_<name>_<problem>.png`` per problem. Returns the paths.

    Parameters
    ----------
    df : pandas.DataFrame
        The study, one row per (problem, integrator, tier, setting).
    out : pathlib.Path
        The directory written into (made if missing).
    name : str
        The study's name, in every file name.
    error : str
        The error column compared (:data:`ERROR_COLUMNS`).

    Returns
    -------
    dict of str to pathlib.Path
        Each file written, by kind (``csv``, ``pareto_csv``, ``pareto_md``,
        ``png_<problem>``).
    """
    out.mkdir(parents=True, exist_ok=True)
    paths = {"csv": out / f"wp_{name}.csv"}
    write_table(df, paths["csv"])
    pareto = best_at_levels(df, ERROR_LEVELS, error)
    advice = recommend(df, ERROR_LEVELS, error)
    paths["pareto_csv"] = out / f"wp_{name}_pareto.csv"
    write_table(pareto, paths["pareto_csv"])
    paths["pareto_md"] = out / f"wp_{name}_pareto.md"
    write_output(paths["pareto_md"], pareto_markdown(pareto, advice, error))
    for problem, g in df.groupby("problem", sort=False):
        key = f"png_{problem}"
        paths[key] = out / f"wp_{name}_{re.sub(r'[^A-Za-z0-9._-]+', '_', problem)}.png"
        plot_work_precision(g, paths[key], error=error,
                            title=f"work-precision: {problem} ({error}; study '{name}')")
    return paths


def _text(df: pd.DataFrame, column: str, missing: str = "") -> pd.Series:
    """A text column for a table, ``missing`` where absent or NaN."""
    if column not in df:
        return pd.Series([missing] * len(df), index=df.index)
    return df[column].astype(object).where(df[column].notna(), missing)


def _num(df: pd.DataFrame, column: str, spec: str = ".3g") -> pd.Series:
    """A number column for a table, formatted, empty where absent or NaN."""
    if column not in df:
        return pd.Series([""] * len(df), index=df.index)
    return df[column].map(lambda x: fmt(x, spec))


def pareto_markdown(pareto: pd.DataFrame, advice: pd.DataFrame, error: str) -> str:
    """The Pareto summary and the recommendation as Markdown."""
    lines = [f"Error measure: `{error}` (relative, against the checked reference). A setting "
             "counts for a level when it and every tighter setting of the same method reach "
             "it (error is not monotone in the tolerance; a lucky loose setting is not "
             "recommended).\n",
             "### One setting for every problem of the study (what an inversion needs)\n",
             "The (integrator, setting) whose worst error over the study problems is within the "
             "level, at the least total wall time.\n"]
    shown = pd.DataFrame({
        "error level": advice.level.map(lambda x: f"{x:g}"),
        "use": _text(advice, "integrator", "(none reached it)"),
        "rhs": _text(advice, "rhs_tier"),
        "setting": _num(advice, "setting"),
        "worst error": _num(advice, "worst_error"),
        "total wall (s)": _num(advice, "total_wall_s"),
        "next best": _text(advice, "next_integrator"),
        "its wall (s)": _num(advice, "next_total_wall_s"),
    })
    lines.append(markdown_table(shown))
    lines.append("\n### Fastest per problem and error level\n")
    per = pd.DataFrame({
        "problem": pareto.problem, "error level": pareto.level.map(lambda x: f"{x:g}"),
        "fastest": _text(pareto, "fastest", "(none)"),
        "rhs": _text(pareto, "fastest_tier"),
        "setting": _num(pareto, "fastest_setting"),
        "wall (s)": _num(pareto, "fastest_wall_s"),
        "runner-up": _text(pareto, "runner_up") + _text(pareto, "runner_up_tier").map(
            lambda t: f" [{t}]" if t else ""),
        "× slower": _num(pareto, "runner_up_ratio", ".2f"),
    })
    lines.append(markdown_table(per))
    return "\n".join(lines)
