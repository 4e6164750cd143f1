"""What ``make reproduce`` runs: every generated file in ``results/``, from scratch."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.cli import simulate_summary
from benchmarks.compare import compare_integrators
from benchmarks.plots import plot_solution
from benchmarks.timing import warm_up
from benchmarks.windows import windows_table, write_windows
from integrators import ETD2, solve
from problems import paper_example, window

__all__ = ["reproduce"]

COMPARE_RTOL = 1e-8          # the side-by-side comparison of every backend (issue 3)
COMPARE_WALL_BUDGET = 60.0   # s per solve: explicit methods crawl through the stick phase


def reproduce(out: Path) -> None:
    """Write the W1–W4 table, the paper example's summary, the integrator table, the
    side-by-side comparison and the figures to ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    print("== integrators ==")
    (out / "integrators.md").write_text(_integrators_markdown())
    print((out / "integrators.md").read_text())
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

    print(f"== every integrator on the paper example, rtol = atol = {COMPARE_RTOL:g} ==")
    table = compare_integrators(paper_example(), COMPARE_RTOL, COMPARE_RTOL,
                                wall_budget=COMPARE_WALL_BUDGET)
    table.to_csv(out / "compare_paper_example.csv", index=False)
    (out / "compare_paper_example.md").write_text(_compare_markdown(table))
    print((out / "compare_paper_example.md").read_text())


def _integrators_markdown() -> str:
    import io
    from contextlib import redirect_stdout

    from benchmarks.cli import main
    buf = io.StringIO()
    with redirect_stdout(buf):
        main(["integrators", "--markdown"])
    return buf.getvalue()


def _compare_markdown(table) -> str:
    from benchmarks.report import markdown_table

    def fmt(x, spec):
        return "" if x is None or x != x else format(x, spec)

    shown = table.assign(
        rtol=[fmt(x, "g") for x in table.rtol],
        wall_s=[fmt(x, ".3g") for x in table.wall_s],
        t_reached_s=[fmt(x, ".4g") for x in table.t_reached_s],
        recurrence_s=[fmt(x, ".8f") for x in table.recurrence_s],
        friction_drop=[fmt(x, ".7f") for x in table.friction_drop],
    )[["integrator", "version", "rtol", "retcode", "t_reached_s", "wall_s", "nfev", "njev",
       "steps", "n_events", "recurrence_s", "friction_drop"]]
    return markdown_table(shown)
