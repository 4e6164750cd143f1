"""Observed orders of convergence (:mod:`benchmarks.devtools.convergence`), two studies:
``convergence``, the fixed-step methods on the paper example's limit cycle, and
``fixed-steps``, the compiled stiff methods with equal steps and the error control off, on the
paper example's stiff stick phase."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.devtools.convergence import (convergence_study, fixed_step_orders,
                                             write_convergence, write_fixed_step_orders)
from benchmarks.studies.study import Study
from problems import paper_example

__all__ = ["STUDIES"]


def run_convergence(out: Path) -> None:
    problem = paper_example()
    write_convergence(problem, *convergence_study(problem), out)


def report_convergence(out: Path) -> str:
    s = json.loads((out / "convergence_paper-example_slip.json").read_text())
    lines = "\n".join(f"* {n}: observed order {o:.2f}; error at the finest step "
                      f"{s['finest_error'][n]:.2g}" for n, o in s["orders"].items())
    return ("Relative error of the recurrence interval against the reference, least-squares "
            "slope over the\nfinest points above the reference's uncertainty:\n\n"
            f"{lines}\n\n![convergence](convergence_paper-example_slip.png)\n")


def run_fixed_steps(out: Path) -> None:
    write_fixed_step_orders(*fixed_step_orders(progress=False), out)


def report_fixed_steps(out: Path) -> str:
    return ("Equal steps with the error control off on the paper example's stick phase, τ ∈ "
            "[5, 9] (stiff:\nhD/w up to 1e7); the error of the state at the end against scipy "
            "Radau at 1e−13:\n\n" + (out / "convergence_fixed_steps.md").read_text()
            + "\n![fixed-step orders](convergence_fixed_steps.png)\n")


STUDIES = (
    Study("convergence", "Convergence of the fixed-step methods "
          "(`convergence_paper-example_slip.*`)", 60, run_convergence,
          report=report_convergence, writes=("convergence_paper-example_slip.*",), minutes=0.05),
    Study("fixed-steps", "Order of the compiled stiff methods (`convergence_fixed_steps.*`)",
          70, run_fixed_steps, report=report_fixed_steps, writes=("convergence_fixed_steps.*",),
          minutes=0.3),
)
