"""Coverage of the 95 % regions over 1000 seeded synthetic data sets
(:func:`benchmarks.studies.inversion.calibration_study`)."""

from __future__ import annotations

from pathlib import Path

from benchmarks.studies.inversion import calibration_study
from benchmarks.studies.study import Study

__all__ = ["STUDY"]


def run(out: Path) -> None:
    calibration_study(out)
    print((out / "calibration.md").read_text().split("\n## ")[0])


def report(out: Path) -> str:
    text = (out / "calibration.md").read_text()
    return text.split("\n", 1)[1] + "![coverage](calibration.png)\n"


STUDY = Study("calibration", "Coverage of the 95 % regions (`calibration.*`)", 210, run,
              report=report, writes=("calibration.csv", "calibration.json", "calibration.md",
                                     "calibration.png"), minutes=2)
