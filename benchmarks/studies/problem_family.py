"""The problem family against published numbers: Marone's velocity step and slide-hold-slide
(:func:`benchmarks.studies.family.write_lab_checks`)."""

from __future__ import annotations

from pathlib import Path

from benchmarks.studies.family import write_lab_checks
from benchmarks.studies.study import Study

__all__ = ["STUDY"]


def run(out: Path) -> None:
    checks = write_lab_checks(out)
    print(checks["marone"].to_string(index=False))


def report(out: Path) -> str:
    return ((out / "problem_family.md").read_text().split("\n", 2)[2]
            + "![healing](problem_family_healing.png)\n")


STUDY = Study("problem-family", "The problem family: Marone's numbers, laboratory tests "
              "(`problem_family.*`)", 230, run, report=report,
              writes=("problem_family.md", "problem_family_healing.csv",
                      "problem_family_healing.png"), minutes=0.1)
