"""The paper's example (Appendix 1.4) with ETD2 at the paper's settings: its limit cycle, and
figures of it and of W2."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.devtools.timing import warm_up
from benchmarks.physics.plots import plot_solution
from benchmarks.physics.summary import simulate_summary
from benchmarks.records.files import write_output
from benchmarks.studies.study import Study
from integrators import ETD2, solve
from problems import paper_example, window

__all__ = ["STUDY"]


def run(out: Path) -> None:
    algorithm, problem = ETD2(), paper_example()
    warm_up(problem, algorithm)
    sol = solve(problem, algorithm, max_points=200_000)
    summary = simulate_summary(sol)
    write_output(out / "paper_example.json", json.dumps(summary, indent=2) + "\n")
    plot_solution(sol, out / "paper_example.png")
    plot_solution(solve(window("W2"), algorithm, max_points=200_000), out / "W2_slip.png")
    print(json.dumps(summary["limit_cycle"], indent=2))


def report(out: Path) -> str:
    cycle = json.loads((out / "paper_example.json").read_text())["limit_cycle"]
    rows = "\n".join(f"| {k} | {v:.6g} |" for k, v in cycle.items()
                     if isinstance(v, (int, float)) and not isinstance(v, bool))
    return (f"ETD2 at the paper's settings; the limit cycle:\n\n| measure | value |\n|---|---|\n"
            f"{rows}\n\n![paper example](paper_example.png)\n")


STUDY = Study("paper-example", "The paper's example, Appendix 1.4 (`paper_example.*`)", 30, run,
              report=report, writes=("paper_example.json", "paper_example.png", "W2_slip.png"),
              minutes=0.05)
