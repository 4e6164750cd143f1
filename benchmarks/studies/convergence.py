"""Observed order of convergence of the fixed-step methods on the paper example."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.devtools.convergence import convergence_study, write_convergence
from benchmarks.studies.study import Study
from problems import paper_example

__all__ = ["STUDY"]


def run(out: Path) -> None:
    problem = paper_example()
    write_convergence(problem, *convergence_study(problem), out)


def report(out: Path) -> str:
    s = json.loads((out / "convergence_paper-example_slip.json").read_text())
    lines = "\n".join(f"* {n}: observed order {o:.2f}; error at the finest step "
                      f"{s['finest_error'][n]:.2g}" for n, o in s["orders"].items())
    return ("Relative error of the recurrence interval against the reference, least-squares "
            "slope over the\nfinest points above the reference's uncertainty:\n\n"
            f"{lines}\n\n![convergence](convergence_paper-example_slip.png)\n")


STUDY = Study("convergence", "Convergence of the fixed-step methods "
              "(`convergence_paper-example_slip.*`)", 60, run, report=report,
              writes=("convergence_paper-example_slip.*",), minutes=0.05)
