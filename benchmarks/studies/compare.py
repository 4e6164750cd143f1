"""Every integrator of the registry on the paper example at one tolerance, side by side."""

from __future__ import annotations

from pathlib import Path

from benchmarks.devtools.compare import compare_integrators, compare_markdown
from benchmarks.records.files import write_output, write_table
from benchmarks.studies.study import Study, markdown_file
from problems import paper_example

__all__ = ["STUDY", "COMPARE_RTOL"]

COMPARE_RTOL = 1e-8


def run(out: Path, rtol: float, wall_budget: float) -> None:
    table = compare_integrators(paper_example(), rtol, rtol, wall_budget=wall_budget)
    write_table(table, out / "compare_paper_example.csv")
    write_output(out / "compare_paper_example.md", compare_markdown(table))


STUDY = Study("compare", f"Every integrator on the paper example at rtol = atol = {COMPARE_RTOL:g} "
              "(`compare_paper_example.*`)", 110, run,
              report=markdown_file("compare_paper_example.md"), timed=True,
              settings={"rtol": COMPARE_RTOL, "wall_budget": 60.0},
              limits={"rtol": (1e-14, 0.1), "wall_budget": (0.1, 86_400.0)},
              writes=("compare_paper_example.csv", "compare_paper_example.md"), minutes=3.6)
