"""What ``make reproduce`` runs: every generated file in ``results/``, from scratch."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.cli import simulate_summary
from benchmarks.plots import plot_solution
from benchmarks.timing import warm_up
from benchmarks.windows import windows_table, write_windows
from integrators import ETD2, solve
from problems import paper_example, window

__all__ = ["reproduce"]


def reproduce(out: Path) -> None:
    """Write the W1–W4 table, the paper example's summary and the figures to ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    print("== W1–W4 limit cycles (ETD2, both laws) ==")
    table = windows_table()
    write_windows(table, out)
    print((out / "windows.md").read_text())

    print("== paper example (Appendix 1.4) ==")
    problem, algorithm = paper_example(), ETD2()
    warm_up(problem, algorithm)
    sol = solve(problem, algorithm, max_points=200_000)
    summary = simulate_summary(sol)
    (out / "paper_example.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary["limit_cycle"], indent=2))
    plot_solution(sol, out / "paper_example.png")
    w2 = solve(window("W2"), algorithm, max_points=200_000)
    plot_solution(w2, out / "W2_slip.png")
    print(f"figures: {out / 'paper_example.png'}, {out / 'W2_slip.png'}")
