"""The sweep's speed: a 21 × 21 grid on W2, serially and on 2 workers, beside one stand-alone
run of the same integrator (:func:`benchmarks.studies.paper_sweeps.sweep_scaling`)."""

from __future__ import annotations

from pathlib import Path

from benchmarks.studies.paper_sweeps import sweep_scaling
from benchmarks.studies.study import Study, markdown_file

__all__ = ["STUDY"]


def run(out: Path, n: int, t_end: float) -> None:
    sweep_scaling(out, n=n, t_end=t_end)


STUDY = Study("sweep-scaling", "Sweep speed (`sweep_scaling.*`)", 130, run,
              report=markdown_file("sweep_scaling.md"), timed=True,
              settings={"n": 21, "t_end": 40.0}, limits={"n": (2, 101), "t_end": (1.0, 1e4)},
              writes=("sweep_scaling.json", "sweep_scaling.md"), minutes=0.1)
