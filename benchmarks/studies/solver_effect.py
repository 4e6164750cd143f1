"""Does the choice of solver change what is inferred?

For each window and law, the data are the published means with σ = 10 % of each (assumed, as in
:mod:`benchmarks.studies.paper_sweeps`), and for W2/slip also one synthetic set (ΔT and Δμ of the
reference at the published fit, plus noise of σ = 5 %, seed 0). The prior is uniform in
(b, log10 Lc) on the paper sweep's box around the published fit. With the setting
``observations`` (``rsfbench study solver-effect --set observations=FILE``: an observations file
of ``rsfbench observe``) one's own data are the data set ``yours`` beside them, on each window
and law of the settings ``windows`` and ``laws`` (W2 and slip alone: ``--set windows=W2 --set
laws=slip``) — the question for a recording of an apparatus that is one of the windows. For an
apparatus of one's own, ``rsfbench solver-effect --problem FILE --observations FILE`` inverts
``yours`` on that problem alone (``own``); its quick mode compares only the own methods' front
settings and the paper's ETD2 (:data:`~benchmarks.inversion.solver_effect.QUICK_LADDERS`) on
:data:`~benchmarks.inversion.solver_effect.QUICK_N`-node grids.
Every candidate setting inverts the same data and is compared with the inversion by a tight
reference setting, by the rule of :mod:`benchmarks.inversion.solver_effect` (the computation:
the maps, the comparison, the cost, the recommendation); this module writes the files, the
report and the figure.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.inversion.observations import Observations
from benchmarks.inversion.solver_effect import (
    MIN_OVERLAP,
    QUICK_LADDERS,
    SHIFT_SD,
    candidates,
    recommendation,
    solver_effect,
)
from benchmarks.records.files import write_figure, write_output, write_table
from benchmarks.records.report import fmt, markdown_table
from benchmarks.studies.study import Study

__all__ = ["STUDY", "solver_effect_study"]


def solver_effect_study(out, n: int = 31, windows=("W1", "W2", "W3", "W4"),
                        laws=("slip", "aging"), study_csv=None,
                        progress: bool = False, yours: Observations | None = None,
                        own=None, quick: bool = False, command: str | None = None
                        ) -> pd.DataFrame:
    """The solver-effect table (:func:`benchmarks.inversion.solver_effect.solver_effect`) with
    the candidates of the full work-precision study ``study_csv`` (default
    ``out/wp_full.csv``; ``quick``: :data:`QUICK_LADDERS` and the paper's ETD2 only), the
    reference Rodas5P and the floor Exprb43 at rtol = atol = 1e−9; write
    ``out/solver_effect.*``. ``own``: a problem of one's own (:func:`solver_effect`)."""
    from benchmarks.devtools.work_precision import read_study
    from integrators import Exprb43, Rodas5P
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)          # before the work, not after it
    study_csv = Path(study_csv) if study_csv else out / "wp_full.csv"
    study = read_study(study_csv) if study_csv.exists() and not quick else None
    started = time.perf_counter()
    say = (lambda text: print(f"  [{time.perf_counter() - started:6.0f} s] {text}", flush=True)
           ) if progress else None
    chosen = candidates(None, QUICK_LADDERS, etd_factors=(1,)) if quick else candidates(study)
    table = solver_effect(chosen, Rodas5P(rtol=1e-9, atol=1e-9),
                          Exprb43(rtol=1e-9, atol=1e-9), windows=windows, laws=laws, n=n,
                          progress=say, yours=yours, own=own)
    wall = time.perf_counter() - started
    write_table(table, out / "solver_effect.csv")
    advice = recommendation(table)
    write_table(advice, out / "solver_effect_recommendation.csv")
    write_output(out / "solver_effect.md", _solver_effect_markdown(
        table, advice, study_csv.name if study is not None else None, wall, SHIFT_SD,
        MIN_OVERLAP, own, quick, command))
    _plot_solver_effect(table, out / "solver_effect.png", MIN_OVERLAP)
    return table


def _solver_effect_markdown(table, advice, study_name, wall, shift_sd, min_overlap,
                            own=None, quick=False, command=None) -> str:
    a = advice.assign(**{
        "ms per solve": [fmt(x, ".3g") for x in advice.wall_per_solve_ms],
        "s per 64,000-solve posterior": [fmt(x, ".3g") for x in advice.posterior_cost_s],
        "resolved": ["yes" if r else "**no** (the floor differs)" for r in advice.resolved]}
    ).drop(columns=["wall_per_solve_ms", "posterior_cost_s"]).fillna("none")
    parts = [
        "# The solver's effect on the inferred (b, Lc)\n\n"
        + ("Each setting inverts the same data (W1–W4, both laws: the published means with "
           "σ = 10 % of each, assumed; W2/slip also one synthetic set, the reference's ΔT and "
           "Δμ at the published fit plus 5 % noise, seed 0) under a uniform prior in "
           "(b, log10 Lc) on the paper sweep's box. " if own is None else
           f"Each setting inverts your observations (their means and σ) on {own[0]} under a "
           f"uniform prior in (b, log10 Lc) on b ∈ [{own[2][0][0]:g}, {own[2][0][1]:g}], "
           f"Lc ∈ [{own[2][1][0]:g}, {own[2][1][1]:g}] m. ")
        + "Posteriors on one grid per problem "
        f"({table.grid.iloc[0]} over the zoom where the reference's posterior lives, and "
        f"{table.check_grid.iloc[0]} over the whole box), compared with the reference Rodas5P "
        "at rtol = atol = 1e−9; the floor is Exprb43 at 1e−9. "
        f"**Indistinguishable**: both posterior means within {shift_sd:g} reference sd and "
        f"overlap Σ min(p, q) ≥ {min_overlap:g} on the zoom and on the whole box; a data set "
        "is **resolved** when the floor is indistinguishable by that rule (no recommendation "
        "otherwise). "
        + ("Candidates (quick): the own methods' front settings and ETD2 at the paper's Δτ "
           "rule" if quick else
           "Candidates: the own methods over their tolerance ladders, ETD2 at the paper's Δτ "
           "rule and 4× coarser, and "
           + (f"from {study_name} the fastest LSODA and SUNDIALS settings reaching worst ΔT "
              "errors of 1e−2, 1e−3 and 1e−4" if study_name else
              "(no full work-precision study: no LSODA or SUNDIALS settings)")) +
        f". Wall time of the study: {wall / 60:.0f} min.\n\n"
        "## The cheapest indistinguishable setting\n\n", markdown_table(a),
        "\nms per solve: the solves' own wall time, two at a time on 2 cores; s per posterior: "
        "a 2 × 2 map's wall time (an ensemble's fixed cost) + 64,000 × the fine map's extra "
        "time per extra node (harness included).\n"]
    for (w, law, data), g in table.groupby(["window", "law", "data"], sort=False):
        t = pd.DataFrame({
            "setting": g.setting, "ms/solve": [fmt(x, ".3g") for x in g.wall_per_solve_ms],
            "mean shift b (sd)": [fmt(x, "+.2g") for x in g.mean_shift_b_sd],
            "mean shift log10 Lc (sd)": [fmt(x, "+.2g") for x in g.mean_shift_log10_lc_sd],
            "fit shift b (sd)": [fmt(x, "+.2g") for x in g.fit_shift_b_sd],
            "fit shift log10 Lc (sd)": [fmt(x, "+.2g") for x in g.fit_shift_log10_lc_sd],
            "overlap": [fmt(x, ".3f") for x in g.overlap],
            "overlap (box)": [fmt(x, ".3f") for x in g.overlap_box],
            "mass outside zoom": [fmt(x, ".2g") for x in g.outside_mass],
            "HPD Jaccard": [fmt(x, ".2f") for x in g.hpd_jaccard],
            "fit converged": ["yes" if x else "no" for x in g.fit_ok],
            "failed nodes": g.n_failed, "cycle nodes": g.n_cycle_nodes,
            "same inference": ["yes" if x else "**no**" for x in g.indistinguishable]})
        ref = g.iloc[0]
        parts += [f"\n## {w}/{law}, {data} data\n\nReference posterior: b = "
                  f"{ref.mean_b:.5f} ± {ref.std_b:.2g}, log10 Lc = {ref.mean_log10_lc:.3f} ± "
                  f"{ref.std_log10_lc:.2g} ({ref.ref_nodes_per_sd_b:.1f} and "
                  f"{ref.ref_nodes_per_sd_log10_lc:.1f} nodes per sd); zoom b {ref.zoom_b}, Lc "
                  f"{ref.zoom_lc_um} µm; the reference's failed solves: {ref.n_failed}; "
                  f"resolved: {'yes' if ref.resolved else '**no**'}.\n\n",
                  markdown_table(t)]
    parts.append(f"\nCommand: `{command}`.\n" if command else
                 "\nCommand: `rsfbench study solver-effect` (a study of "
                 "`make reproduce-full`).\n")
    return "".join(parts)


def _plot_solver_effect(table, path: Path, min_overlap: float) -> None:
    from matplotlib.figure import Figure
    groups = list(table.groupby(["window", "law", "data"], sort=False))
    cols = 3
    rows = -(-len(groups) // cols)
    fig = Figure(figsize=(4 * cols, 3.2 * rows))
    axes = fig.subplots(rows, cols, squeeze=False, sharey=True)
    families = ["own", "ETD", "LSODA", "SUNDIALS", "floor"]
    for ax, ((w, law, data), g) in zip(axes.flat, groups):
        for k, fam in enumerate(families):
            s = g[g.family == fam]
            if s.empty:
                continue
            worst = np.fmin(s.overlap.to_numpy(), s.overlap_box.fillna(1.0).to_numpy())
            y = np.clip(1.0 - worst, 1e-6, 1.0)
            ok = s.indistinguishable.to_numpy()
            ax.scatter(s.wall_per_solve_ms[ok], y[ok], color=f"C{k}", s=18, label=fam)
            ax.scatter(s.wall_per_solve_ms[~ok], y[~ok], facecolors="none",
                       edgecolors=f"C{k}", s=18)
        ax.axhline(1 - min_overlap, color="k", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{w}/{law} ({data})", fontsize=9)
        ax.set_xlabel("ms per forward solve")
    for ax in axes[:, 0]:
        ax.set_ylabel("1 − overlap with the reference\n(the worse of zoom and box)")
    for ax in axes.flat[len(groups):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    fig.suptitle("The solver's effect on the posterior: filled = same inference (dashed: the "
                 "overlap threshold; hollow: a mean shifted or the overlap too small)",
                 fontsize=9)
    fig.tight_layout()
    write_figure(fig, path, dpi=100)


def run(out: Path, n: int, windows: str, laws: str, observations: str) -> None:
    from benchmarks.inversion.observations import read_observations
    yours = read_observations(observations, curve_noise="none") if observations else None
    solver_effect_study(out, n=n, windows=_words(windows), laws=_words(laws), yours=yours,
                        study_csv=out / "wp_full.csv", progress=True)
    print((out / "solver_effect.md").read_text().split("\n## ")[1])


def report(out: Path) -> str:
    section = (out / "solver_effect.md").read_text().split("\n## ")[1].split("\n", 1)[1]
    return (f"{section}\nEvery window and law: `solver_effect.md`.\n\n"
            "![solver effect](solver_effect.png)\n")


def _words(text: str) -> tuple[str, ...]:
    return tuple(w.strip() for w in text.split(",") if w.strip())


def check(settings: dict) -> None:
    """Refuse an unknown window or law, and an observations file that cannot be read, before
    any work."""
    from benchmarks.inversion.observations import read_observations
    from problems import WINDOWS
    for key, known in (("windows", WINDOWS), ("laws", ("slip", "aging"))):
        words = _words(settings[key])
        bad = [w for w in words if w not in known]
        if bad or not words:
            raise ValueError(f"study solver-effect: setting {key} = {settings[key]!r}: expected "
                             f"some of {', '.join(known)}, joined by commas")
    if settings["observations"]:
        try:
            read_observations(settings["observations"], curve_noise="none")
        except ValueError as exc:
            raise ValueError(f"study solver-effect: setting observations: {exc}") from None


STUDY = Study("solver-effect", "The solver's effect on the inferred (b, Lc) (`solver_effect.*`)",
              220, run, report=report, plan="full", timed=True, reads=("wp_full.csv",),
              settings={"n": 31, "windows": "W1,W2,W3,W4", "laws": "slip,aging",
                        "observations": ""}, limits={"n": (5, 301)}, check=check,
              writes=("solver_effect.csv", "solver_effect.md", "solver_effect.png",
                      "solver_effect_recommendation.csv"), minutes=101)
