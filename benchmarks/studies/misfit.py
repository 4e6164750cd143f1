"""What J2 can see: the misfit of slip-weakening curves on friction against on the spring force.

Eq. 11 compares the *friction* Ft/Fn against slip (:mod:`benchmarks.physics.curves`); earlier
versions of the project compared the spring force Fs/Fn, which during an event is the spring's
unloading line whatever (b, Lc). :func:`j2_information` fits the same synthetic observations —
the curves of ``tests/data/W2_slip_weakening.csv``: W2 under the slip law at its best fit
(b = 0.0094, Lc = 0.3 µm), three events, noise of std 2e−4 — over a grid of (b, Lc) both ways,
so the two J2 maps can be compared: how far J2 rises above the noise variance away from the
truth. The spring-force map is scored against spring-force curves made from the same run the
same way (the observations the project used to make), so each map is its own definition's best
case.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from benchmarks.inversion.objectives import j2_per_event
from benchmarks.physics.curves import (
    event_curve,
    event_window,
    read_curves,
    sample_curves,
)
from benchmarks.physics.metrics import summarize
from benchmarks.records.files import write_output, write_table
from benchmarks.records.report import fmt, markdown_table
from benchmarks.studies.study import Study, markdown_file
from integrators import Rodas5P, solve
from problems import window

__all__ = ["STUDY", "j2_information", "write_j2_information", "CURVES", "NOISE"]

CURVES = Path(__file__).resolve().parents[2] / "tests" / "data" / "W2_slip_weakening.csv"
NOISE = 2e-4                      # the std of the noise in CURVES (tests/test_sweep.py)
B_GRID = (0.0090, 0.0092, 0.0094, 0.0096, 0.0098)
LC_GRID = (0.1e-6, 0.2e-6, 0.3e-6, 0.5e-6, 1e-6)
T_END = 20.0


def spring_curve(sol, index: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """The curve J2 compared first: Fs/Fn against slip over event ``index``."""
    _, slip, fs = event_window(sol, index)
    return slip, fs / sol.problem.normal_force


def j2_information(progress: bool = True) -> pd.DataFrame:
    """J̄2 on the grid (W2, slip law, 20 s, Rodas5P at 1e−8) both ways: the friction curves
    against the observations of :data:`CURVES`, and the spring-force curves against spring-force
    observations made the same way from the same run (what the project compared before)."""
    observed = read_curves(CURVES)
    algorithm = Rodas5P(rtol=1e-8, atol=1e-8)
    truth = solve(window("W2", "slip", t_end=T_END), algorithm, save_every=5e-5)
    observed_spring = sample_curves(truth, 3, 25, NOISE, 1, curve=spring_curve)
    rows = []
    grid = [(b, lc) for b in B_GRID for lc in LC_GRID]
    for b, lc in tqdm(grid, desc="J2", disable=not progress):
        sol = solve(window("W2", "slip", b=b, lc=lc, t_end=T_END), algorithm, save_every=5e-5)
        rows.append({"b": b, "lc_um": lc * 1e6, "retcode": sol.retcode.value,
                     "classification": summarize(sol).classification,
                     "J2_friction": float(np.mean(j2_per_event(*event_curve(sol), observed))),
                     "J2_spring": float(np.mean(j2_per_event(*spring_curve(sol),
                                                             observed_spring)))})
    return pd.DataFrame(rows)


def write_j2_information(table: pd.DataFrame, out: Path) -> str:
    """``j2_information.csv`` and ``.md`` in ``out``; returns the Markdown."""
    out.mkdir(parents=True, exist_ok=True)
    write_table(table, out / "j2_information.csv")
    truth = table[np.isclose(table.b, 0.0094) & np.isclose(table.lc_um, 0.3)].iloc[0]
    lines = []
    for col, what in (("J2_friction", "friction Ft/Fn (Eq. 11, now)"),
                      ("J2_spring", "spring force Fs/Fn (the first channel compared)")):
        grid = table.pivot(index="lc_um", columns="b", values=col) / NOISE ** 2
        grid.index = [f"{x:g}" for x in grid.index]
        grid = grid.map(lambda v: fmt(v, ".3g"))
        lines.append(f"J̄2 over the noise variance σ² = {NOISE ** 2:g}, {what}; rows Lc (µm), "
                     "columns b:\n\n" + markdown_table(grid.reset_index(names="Lc (µm)")))
        away = table[col].drop(truth.name)
        lines.append(f"At the curves' own (b, Lc) {fmt(truth[col] / NOISE ** 2, '.3g')} σ²; "
                     f"elsewhere on the grid {fmt(away.min() / NOISE ** 2, '.3g')}–"
                     f"{fmt(away.max() / NOISE ** 2, '.3g')} σ².\n")
    text = ("Synthetic observations: W2 under the slip law at (b, Lc) = (0.0094, 0.3 µm), three "
            f"events, noise of std {NOISE:g} (`{CURVES.relative_to(CURVES.parents[2])}`); each "
            "grid point simulated 20 s by Rodas5P at 1e−8, its last event compared.\n\n"
            + "\n".join(lines))
    write_output(out / "j2_information.md", text)
    return text


def run(out: Path) -> None:
    print(write_j2_information(j2_information(), out))


STUDY = Study("misfit", "What J2 sees (`j2_information.*`)", 170, run,
              report=markdown_file("j2_information.md"), data=("tests/data/W2_slip_weakening.csv",),
              writes=("j2_information.csv", "j2_information.md"), minutes=1.4)
