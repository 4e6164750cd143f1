"""The registry as a table: every integrator, its family, orders and library version."""

from __future__ import annotations

from pathlib import Path

from benchmarks.physics.summary import integrators_markdown
from benchmarks.records.files import write_output
from benchmarks.studies.study import Study, markdown_file

__all__ = ["STUDY"]


def run(out: Path) -> None:
    write_output(out / "integrators.md", integrators_markdown())


STUDY = Study("integrators", "The registry (`integrators.md`)", 10, run,
              report=markdown_file("integrators.md"), writes=("integrators.md",), minutes=0.05)
