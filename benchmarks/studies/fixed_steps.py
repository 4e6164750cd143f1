"""Fixed-step order of the compiled stiff methods: equal steps, error control off, on the
paper example's stiff stick phase."""

from __future__ import annotations

from pathlib import Path

from benchmarks.devtools.convergence import fixed_step_orders, write_fixed_step_orders
from benchmarks.studies.study import Study

__all__ = ["STUDY"]


def run(out: Path) -> None:
    write_fixed_step_orders(*fixed_step_orders(progress=False), out)


def report(out: Path) -> str:
    return ("Equal steps with the error control off on the paper example's stick phase, τ ∈ "
            "[5, 9] (stiff:\nhD/w up to 1e7); the error of the state at the end against scipy "
            "Radau at 1e−13:\n\n" + (out / "convergence_fixed_steps.md").read_text()
            + "\n![fixed-step orders](convergence_fixed_steps.png)\n")


STUDY = Study("fixed-steps", "Order of the compiled stiff methods (`convergence_fixed_steps.*`)",
              70, run, report=report, writes=("convergence_fixed_steps.*",), minutes=0.3)
