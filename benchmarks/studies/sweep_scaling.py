"""The sweep's speed: a 21 × 21 grid on W2, serially and on 2 workers, beside one stand-alone
run of the same integrator (:func:`benchmarks.studies.paper_sweeps.sweep_scaling`)."""

from __future__ import annotations

from pathlib import Path

from benchmarks.studies.paper_sweeps import sweep_scaling
from benchmarks.studies.study import Study, markdown_file

__all__ = ["STUDY"]


def run(out: Path) -> None:
    sweep_scaling(out, study_csv=out / "wp_quick.csv")


STUDY = Study("sweep-scaling", "Sweep speed (`sweep_scaling.*`)", 130, run,
              report=markdown_file("sweep_scaling.md"), timed=True, reads=("wp_quick.csv",),
              writes=("sweep_scaling.json", "sweep_scaling.md"), minutes=0.1)
