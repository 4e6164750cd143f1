"""Coverage of the 95 % regions over 1000 seeded synthetic data sets
(:func:`benchmarks.studies.inversion.calibration_study`)."""

from __future__ import annotations

from pathlib import Path

from benchmarks.studies.inversion import calibration_study
from benchmarks.studies.study import Study

__all__ = ["STUDY"]


def run(out: Path, seeds: int, n: int, sigma: float, check_seeds: int) -> None:
    calibration_study(out, seeds=seeds, n=n, sigma_rel=sigma, check_seeds=check_seeds)
    print((out / "calibration.md").read_text().split("\n## ")[0])


def check(settings: dict) -> None:
    if settings["check_seeds"] > settings["seeds"]:
        raise ValueError(f"study calibration: setting check_seeds = {settings['check_seeds']} "
                         f"is more than seeds = {settings['seeds']}: the checked seeds are "
                         "among the study's")


def report(out: Path) -> str:
    text = (out / "calibration.md").read_text()
    return text.split("\n", 1)[1] + "![coverage](calibration.png)\n"


STUDY = Study("calibration", "Coverage of the 95 % regions (`calibration.*`)", 210, run,
              report=report, settings={"seeds": 1000, "n": 121, "sigma": 0.05, "check_seeds": 2},
              limits={"seeds": (1, 100_000), "n": (5, 1001), "sigma": (1e-6, 0.5),
                      "check_seeds": (0, 100)}, check=check,
              writes=("calibration.csv", "calibration.json", "calibration.md",
                                     "calibration.png"), minutes=2)
