"""The quick work-precision study: every integrator over a ladder of settings on two problems;
its Pareto summary, and the commands' default integrator written from it."""

from __future__ import annotations

from pathlib import Path

from benchmarks.devtools.work_precision import (
    QUICK,
    study_problems,
    work_precision,
    write_recommendation,
)
from benchmarks.devtools.wp_files import write_work_precision
from benchmarks.records.provenance import checkout
from benchmarks.studies.study import Study

__all__ = ["STUDY"]


def run(out: Path) -> None:
    write_work_precision(work_precision(study_problems("quick"), QUICK), out, "quick")
    root = checkout()
    if root is not None and out.resolve() == (root / "results").resolve():
        # the default integrator, from this run and the committed external study's
        print(f"wrote {write_recommendation(out)}")


def report(out: Path) -> str:
    figures = "\n".join(f"![{p.name}]({p.name})" for p in sorted(out.glob("wp_quick_*.png")))
    return (out / "wp_quick_pareto.md").read_text() + "\n" + figures + "\n"


STUDY = Study("work-precision", "Quick work-precision study (`wp_quick.csv`, `wp_quick_pareto.*`)",
              80, run, report=report, plan="full", timed=True,
              writes=("wp_quick.csv", "wp_quick_pareto.*", "wp_quick_*.png"), minutes=19)
