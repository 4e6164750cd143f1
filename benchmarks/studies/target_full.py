"""The 2× target on every study problem: the full work-precision study of the stiff
adaptive integrators of the three sides (own, LSODA, SUNDIALS), 10 s per run."""

from __future__ import annotations

from pathlib import Path

from benchmarks.studies.study import Study
from benchmarks.studies.target import full_target, target_markdown

__all__ = ["STUDY"]


def run(out: Path) -> None:
    print(target_markdown(full_target(out)))


def report(out: Path) -> str:
    return ("On every study problem (`target_full.*`, from `wp_full.csv`: the stiff adaptive "
            "integrators of\nthe three sides on the full ladder, 10 s per run):\n\n"
            + (out / "target_full.md").read_text())


STUDY = Study("target-full", "The 2× target on every study problem", 100, run, report=report,
              plan="full", timed=True,
              writes=("target_full.csv", "target_full.md", "wp_full.csv", "wp_full_*.png",
                      "wp_full_pareto.*"), minutes=26)
