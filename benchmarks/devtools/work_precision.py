"""Work-precision study: every integrator of the registry over a ladder of precision settings.

The analogue of DiffEqDevTools' ``WorkPrecisionSet``. For each study problem the reference comes
from :func:`benchmarks.devtools.reference.reference` (two solvers that agree); then each integrator runs
at each setting of its ladder — rtol = atol for adaptive methods, Δτcnst for ETD (with Δτmax
scaled by the same factor: in the stick phase Δτmax is the binding limit) — once per right-hand-
side tier it offers. A point records the achieved errors (:mod:`benchmarks.devtools.errors`), the wall
time of runs that record events only (after a gridded run that warms up and gives the trajectory
error; the minimum over ``repeats`` runs when a run is shorter than ``repeat_below`` seconds, a
single timing otherwise), the counters and the retcode.

A point that fails or runs out of its wall budget is a row with that retcode and NaN errors.
Only for explicit methods does a budget stop end the ladder (the tighter settings are rows with
retcode ``Skipped``): on this stiff problem their cost is set by stability and does not fall as
the tolerance tightens. Implicit methods run every rung: a numerical failure at a loose setting
(CVODE's error-test failures at 1e−5) or a slow loose run (Radau's Newton failures at 1e−3) says
nothing about the tighter ones.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from benchmarks.devtools.errors import ERROR_COLUMNS, errors
from benchmarks.devtools.reference import reference
from benchmarks.records.files import read_table
from benchmarks.records.provenance import provenance
from integrators import REGISTRY, solve
from integrators.core.registry import ProblemNotSupported
from problems import paper_example, window

__all__ = ["Ladder", "FULL", "QUICK", "study_problems", "settings", "measure", "work_precision",
           "WP_COLUMNS", "SKIPPED", "REFUSED", "reliable_error", "best_at_levels", "recommend",
           "fastest_within",
           "algorithm_at", "read_study", "STUDY_CSV", "pareto_front",
           "front_source", "write_recommendation", "advice_study", "ADVICE_FILES"]

SKIPPED = "Skipped"
#: the retcode of a method that cannot integrate a problem at all (the paper's ETD without mass)
REFUSED = "Refused"
#: the columns every work-precision CSV has (then the errors, then provenance)
WP_COLUMNS = ("problem", "law", "integrator", "rhs_tier", "setting_name", "setting", "options",
              "retcode", "message", "t_reached_s", "wall_s", "timings", "nfev", "njev", "steps",
              "rejected", "n_events") + ERROR_COLUMNS + ("reference_agreement", "library",
                                                         "library_version")
_BUDGET_STOPS = ("WallTime", "MaxSteps")


@dataclass(frozen=True)
class Ladder:
    """The precision settings of a study and how long a point may take."""

    tolerances: tuple[float, ...]        # rtol = atol of adaptive methods, loosest first
    etd_factors: tuple[float, ...]       # factors on the paper's Δτcnst = 1e−5, Δτmax = 0.01
    wall_budget: float                   # s per solve
    repeats: int = 3
    repeat_below: float = 1.0            # s: runs shorter than this are timed ``repeats`` times


FULL = Ladder(tolerances=tuple(10.0 ** -k for k in range(3, 12)),
              etd_factors=(8, 4, 2, 1, 0.5, 0.25, 0.125, 1 / 16, 1 / 32, 1 / 64),
              wall_budget=120.0)
QUICK = Ladder(tolerances=tuple(10.0 ** -k for k in range(3, 11)),
               etd_factors=(4, 2, 1, 0.5, 0.25, 0.125, 1 / 16),
               wall_budget=10.0)


def study_problems(which: str = "full"):
    """``full``: the paper example and W1–W4 under both laws (the full study set);
    ``quick``: the paper example and W2 under the aging law.

    Parameters
    ----------
    which : str
        ``"full"`` or ``"quick"``.

    Returns
    -------
    list of SpringSlider

    Raises
    ------
    ValueError
        For any other ``which``.
    """
    if which == "quick":
        return [paper_example(), window("W2", "aging")]
    if which == "full":
        return [paper_example()] + [window(w, law) for law in ("slip", "aging")
                                    for w in ("W1", "W2", "W3", "W4")]
    raise ValueError(f"study must be 'quick' or 'full', got {which!r}")


def settings(cls, ladder: Ladder, tier: str):
    """``(setting_name, setting, algorithm)`` for each rung of ``cls``'s ladder, loosest first."""
    if cls.adaptive:
        return [("rtol=atol", tol, cls(rtol=tol, atol=tol, rhs=tier)) for tol in ladder.tolerances]
    defaults = cls()
    return [("dtau_cnst", defaults.dtau_cnst * f,
             cls(dtau_cnst=defaults.dtau_cnst * f, dtau_max=defaults.dtau_max * f))
            for f in ladder.etd_factors]


def tiers_of(cls, tiers) -> list[str]:
    """The right-hand-side tiers ``cls`` offers among ``tiers`` (fixed-step ETD: numba)."""
    offered = cls.rhs_tiers if cls.adaptive else ("numba",)
    return [t for t in tiers if t in offered]


def measure(problem, algorithm, ref, ladder: Ladder, error_of=errors,
            gridded_timing: bool = False) -> dict:
    """One point. First a run that saves μ on the reference's grid: it warms numba up and gives
    the trajectory error. Then the timed runs, which record events only (``max_points=2``, what
    an inversion uses): the minimum over ``repeats`` for runs under ``repeat_below`` s, one run
    otherwise. The headline errors and the counters are those of the timed run.

    Why not time the gridded run: a method that returns to Python at every output time (the
    segment backends do) would pay ~2000 round trips that ETD, saving inside its kernel, does
    not, and a method that lands its steps on output times would take extra steps.

    ``gridded_timing``: time the gridded run instead, for problems whose user needs the
    trajectory (a laboratory test fitted sample by sample); ``error_of(solution, ref)`` gives
    the errors (default :func:`benchmarks.devtools.errors.errors`). A method that cannot integrate the
    problem at all (``check_problem``) is a row with retcode ``Refused`` and its reason."""
    try:
        algorithm.check_problem(problem)
    except ProblemNotSupported as exc:
        return {"retcode": REFUSED, "message": str(exc), **dict.fromkeys(ERROR_COLUMNS, math.nan)}
    save = problem.t_end / (len(ref.grid_t) - 1)
    grid = solve(problem, algorithm, wall_budget=ladder.wall_budget, save_every=save)
    sol, timings = grid, [grid.stats.wall_s]
    if grid.success and gridded_timing:
        while min(timings) < ladder.repeat_below and len(timings) < ladder.repeats:
            again = solve(problem, algorithm, wall_budget=ladder.wall_budget, save_every=save)
            if not again.success:               # a repeat that fails (its budget): that row
                sol, grid = again, again
                break
            timings.append(again.stats.wall_s)
    elif grid.success:
        sol = solve(problem, algorithm, wall_budget=ladder.wall_budget, max_points=2)
        timings = [sol.stats.wall_s]
        while sol.success and min(timings) < ladder.repeat_below and len(timings) < ladder.repeats:
            timings.append(solve(problem, algorithm, wall_budget=ladder.wall_budget,
                                 max_points=2).stats.wall_s)
    s = sol.stats
    return {"retcode": sol.retcode.value, "message": sol.message, "t_reached_s": sol.t_reached,
            "wall_s": min(timings), "timings": len(timings), "nfev": s.nfev, "njev": s.njev,
            "steps": s.steps, "rejected": s.rejected, "n_events": len(sol.events),
            **error_of(sol, ref), "err_trajectory": error_of(grid, ref)["err_trajectory"]}


def work_precision(problems, ladder: Ladder = QUICK, names=None, tiers=("numba", "python"),
                   progress: bool = True, reference_of=reference, error_of=errors,
                   gridded_timing: bool = False) -> pd.DataFrame:
    """Run the study; one row per (problem, integrator, tier, setting), columns WP_COLUMNS.
    ``reference_of(problem)``, ``error_of`` and ``gridded_timing``: the references, errors and
    timing of another kind of problem (:mod:`benchmarks.studies.family`)."""
    names = sorted(REGISTRY, key=str.lower) if names is None else list(names)
    jobs = [(p, n, t) for p in problems for n in names for t in tiers_of(REGISTRY[n], tiers)]
    total = sum(len(settings(REGISTRY[n], ladder, t)) for _, n, t in jobs)
    meta = provenance()
    rows = []
    with tqdm(total=total, desc="work-precision", unit="run", disable=not progress) as bar:
        refs = {}
        for problem, name, tier in jobs:
            if problem not in refs:
                bar.set_postfix_str(f"reference {problem.name}")
                refs[problem] = reference_of(problem)
            ref, cls = refs[problem], REGISTRY[name]
            stopped = None
            for setting_name, setting, algorithm in settings(cls, ladder, tier):
                bar.set_postfix_str(f"{problem.name} {name} [{tier}] {setting:.3g}")
                if stopped is None:
                    point = measure(problem, algorithm, ref, ladder, error_of, gridded_timing)
                    if point["retcode"] in _BUDGET_STOPS and not cls.stiff:
                        stopped = setting
                else:
                    point = {"retcode": SKIPPED, "message": f"not run: this explicit method "
                             f"ran out of budget at the looser setting {stopped:g}",
                             **dict.fromkeys(ERROR_COLUMNS, math.nan)}
                rows.append({"problem": problem.name, "law": problem.law.name,
                             "integrator": name, "rhs_tier": tier,
                             "setting_name": setting_name, "setting": setting,
                             "options": json.dumps(algorithm.options()), **point,
                             "reference_agreement": ref.agreement["max"],
                             "library": cls.library, "library_version": cls.library_version(),
                             **meta})
                bar.update()
    df = pd.DataFrame(rows)
    first = [c for c in WP_COLUMNS if c in df.columns]
    return df[first + [c for c in df.columns if c not in first]]


def reliable_error(df: pd.DataFrame, error: str = "err_recurrence") -> pd.Series:
    """The error a user can count on when choosing a setting: the largest ``error`` at that
    setting and at every tighter one of the same (problem, integrator, tier). Error is not
    monotone in the tolerance; this keeps a lucky cancellation at a loose setting from being
    recommended. Settings that were not run (budget) do not count."""
    key = ["problem", "integrator", "rhs_tier"]
    flat = df.reset_index(drop=True)                     # positions: any index will do
    ordered = flat.sort_values(key + ["setting"])        # tightest first within each group
    env = ordered.groupby(key, sort=False)[error].transform(lambda x: x.cummax())
    return pd.Series(env.sort_index().to_numpy(), index=df.index, name=error)


def best_at_levels(df: pd.DataFrame, levels, error: str = "err_recurrence") -> pd.DataFrame:
    """Pareto summary per problem: for each error level, the fastest (integrator, tier) with a
    setting that reaches it reliably (:func:`reliable_error`), its setting and time, and the
    runner-up with its time ratio."""
    df = df.assign(**{error: reliable_error(df, error)})
    ok = df[(df.retcode == "Success") & np.isfinite(df[error])]
    rows = []
    for problem, g in ok.groupby("problem", sort=False):
        for level in levels:
            hit = g[g[error] <= level].sort_values("wall_s")
            best = hit.drop_duplicates(["integrator", "rhs_tier"])
            row = {"problem": problem, "error": error, "level": level}
            for rank, label in enumerate(("fastest", "runner_up")):
                if rank < len(best):
                    b = best.iloc[rank]
                    row.update({label: b.integrator, f"{label}_tier": b.rhs_tier,
                                f"{label}_setting": b.setting, f"{label}_wall_s": b.wall_s})
            if len(best) > 1:
                row["runner_up_ratio"] = best.iloc[1].wall_s / best.iloc[0].wall_s
            rows.append(row)
    return pd.DataFrame(rows)


def recommend(df: pd.DataFrame, levels, error: str = "err_recurrence") -> pd.DataFrame:
    """One setting for the whole problem set, as an inversion over (b, Lc) needs: for each error
    level, the (integrator, tier, setting) whose worst error over the study problems is within
    the level at the least total wall time. Only rows that succeeded on every problem count, and
    a setting counts for a level only if it reaches it reliably (:func:`reliable_error`).

    Parameters
    ----------
    df : pandas.DataFrame
        A work-precision study (:func:`read_study`).
    levels : sequence of float
        The error levels (relative, dimensionless).
    error : str
        The error column compared (:data:`ERROR_COLUMNS`).

    Returns
    -------
    pandas.DataFrame
        One row per level: integrator, rhs_tier, setting, worst_error, total_wall_s (s) and
        the next-fastest other integrator; only ``level`` where no setting reaches it.
    """
    n_problems = df.problem.nunique()
    df = df.assign(**{error: reliable_error(df, error)})
    keys = ["integrator", "rhs_tier", "setting"]
    ok = df[df.retcode == "Success"]
    agg = ok.groupby(keys).agg(worst_error=(error, "max"), total_wall_s=("wall_s", "sum"),
                               n=("problem", "nunique")).reset_index()
    agg = agg[(agg.n == n_problems) & np.isfinite(agg.worst_error)]
    rows = []
    for level in levels:
        hit = agg[agg.worst_error <= level].sort_values("total_wall_s")
        if not len(hit):
            rows.append({"level": level})
            continue
        best = hit.iloc[0]
        others = hit[hit.integrator != best.integrator]
        rows.append({"level": level, "integrator": best.integrator, "rhs_tier": best.rhs_tier,
                     "setting": best.setting, "worst_error": best.worst_error,
                     "total_wall_s": best.total_wall_s,
                     "next_integrator": others.iloc[0].integrator if len(others) else None,
                     "next_total_wall_s": others.iloc[0].total_wall_s if len(others) else math.nan})
    return pd.DataFrame(rows)


def fastest_within(df: pd.DataFrame, limits: dict) -> pd.DataFrame:
    """The settings (integrator, tier, setting) that succeeded on every problem of the study
    with each error of ``limits`` (a column such as ``err_recurrence`` → the largest relative
    error allowed) reliably within its limit on every problem, fastest first (total wall time
    over the problems): the choice for an inversion whose σ sets the limits."""
    n_problems = df.problem.nunique()
    keys = ["integrator", "rhs_tier", "setting"]
    ok = df[df.retcode == "Success"].assign(
        **{c: reliable_error(df, c)[df.retcode == "Success"] for c in limits})
    agg = ok.groupby(keys).agg(total_wall_s=("wall_s", "sum"), n=("problem", "nunique"),
                               **{f"worst_{c}": (c, "max") for c in limits}).reset_index()
    agg = agg[agg.n == n_problems]
    for c, level in limits.items():
        agg = agg[np.isfinite(agg[f"worst_{c}"]) & (agg[f"worst_{c}"] <= level)]
    return agg.drop(columns="n").sort_values("total_wall_s").reset_index(drop=True)


#: the committed quick study
STUDY_CSV = Path(__file__).resolve().parents[2] / "results" / "wp_quick.csv"
#: the studies the front of :mod:`benchmarks.devtools.recommendation` is written from, in
#: ``results/``: the quick study's problems (the paper's example, W2) and the external ones
#: (Im et al.'s slider, NIED's apparatus: ``rsfbench study external``), so that the advice
#: holds on problems nobody here chose too
ADVICE_FILES = ("wp_quick.csv", "wp_external.csv")


def advice_study(out=STUDY_CSV.parent) -> pd.DataFrame:
    """The studies of :data:`ADVICE_FILES` in ``out`` as one table: a setting counts on the
    front only where it ran on all of their problems (:func:`pareto_front`). Each file must be
    there (:class:`benchmarks.records.files.BadResultsFile` otherwise), and no problem in two."""
    out = Path(out)
    tables = [read_study(out / name) for name in ADVICE_FILES]
    names = [set(t.problem) for t in tables]
    if set.intersection(*names):
        raise ValueError(f"{', '.join(ADVICE_FILES)} share the problems "
                         f"{sorted(set.intersection(*names))}: their walls would count twice")
    return pd.concat(tables, ignore_index=True)


def algorithm_at(integrator: str, rhs_tier: str, setting: float):
    """The algorithm a study row describes: rtol = atol = ``setting``, or for ETD Δτcnst =
    ``setting`` with Δτmax scaled by the same factor (as :func:`settings` builds them)."""
    cls = REGISTRY[integrator]
    if cls.adaptive:
        return cls(rtol=setting, atol=setting, rhs=rhs_tier)
    d = cls()
    return cls(dtau_cnst=setting, dtau_max=d.dtau_max * setting / d.dtau_cnst)


def read_study(path) -> pd.DataFrame:
    """A work-precision study written by :func:`benchmarks.devtools.wp_files.write_work_precision`, its
    columns checked (:class:`benchmarks.records.files.BadResultsFile` otherwise).

    Parameters
    ----------
    path : str or pathlib.Path
        The study's CSV file.

    Returns
    -------
    pandas.DataFrame

    Raises
    ------
    BadResultsFile
        For a missing or unreadable file, or one without the study's columns.
    """
    return read_table(path, WP_COLUMNS, what="work-precision study",
                      hint="`rsfbench work-precision` writes one")


def pareto_front(df: pd.DataFrame, error: str = "err_recurrence") -> pd.DataFrame:
    """The study's front for one setting over the whole problem set: the (integrator, tier,
    setting) rows of :func:`recommend`'s table (succeeded on every problem, reliable worst
    error) that no faster row beats in worst error, fastest first. The fastest front row within
    a level is :func:`recommend`'s choice for that level.

    Parameters
    ----------
    df : pandas.DataFrame
        A work-precision study (:func:`read_study`).
    error : str
        The error column compared (:data:`ERROR_COLUMNS`).

    Returns
    -------
    pandas.DataFrame
        Columns worst_error, total_wall_s (s), integrator, rhs_tier, setting.
    """
    n_problems = df.problem.nunique()
    df = df.assign(**{error: reliable_error(df, error)})
    keys = ["integrator", "rhs_tier", "setting"]
    agg = df[df.retcode == "Success"].groupby(keys).agg(
        worst_error=(error, "max"), total_wall_s=("wall_s", "sum"),
        n=("problem", "nunique")).reset_index()
    agg = agg[(agg.n == n_problems) & np.isfinite(agg.worst_error)]
    agg = agg.sort_values(["total_wall_s", "worst_error"], kind="stable")
    front = agg[agg.worst_error < agg.worst_error.cummin().shift(fill_value=math.inf)]
    return front[["worst_error", "total_wall_s", *keys]].reset_index(drop=True)


RECOMMENDATION_MODULE = Path(__file__).resolve().parent / "recommendation.py"
_BEGIN, _END = "# --- written by the work-precision studies", "# --- end of the written part"


def front_source(out=STUDY_CSV.parent) -> str:
    """The written part of :mod:`benchmarks.devtools.recommendation` for the studies in
    ``out`` (:func:`advice_study`): their front as Python literals and their provenance (files,
    commits, SHA-256)."""
    out = Path(out)
    files = ADVICE_FILES
    front = pareto_front(advice_study(out))
    commits = [str(read_study(out / f)["git_commit"].iloc[0]) for f in files]
    digests = [hashlib.sha256((out / f).read_bytes()).hexdigest() for f in files]
    lines = [f"{_BEGIN} (`study work-precision`, `external`); do not edit ---",
             f"STUDY = {{\"files\": {tuple(files)!r},",
             f"         \"commits\": {tuple(commits)!r},",
             "         \"sha256\": (" + ",\n                    ".join(map(repr, digests))
             + ("," if len(digests) == 1 else "") + "),",
             f"         \"problems\": {advice_study(out).problem.nunique()}}}",
             "#: (worst err_recurrence over the studies' problems, total wall s, integrator, rhs",
             "#: tier, setting), fastest first",
             "FRONT = ("]
    lines += [f"    ({r.worst_error!r}, {r.total_wall_s!r}, {r.integrator!r}, {r.rhs_tier!r}, "
              f"{r.setting!r})," for r in front.itertuples()]
    lines += [")", _END + " ---"]
    return "\n".join(lines) + "\n"


def write_recommendation(out, module: Path = RECOMMENDATION_MODULE) -> Path:
    """Rewrite the written part of ``module`` from the studies in the directory ``out`` (the
    rest is kept)."""
    text = module.read_text(encoding="utf-8")
    begin, end = text.index(_BEGIN), text.index(_END)
    end = text.index("\n", end) + 1
    new = text[:begin] + front_source(out) + text[end:]
    if new != text:                  # an unchanged file keeps its time (make's caches go by it)
        module.write_text(new, encoding="utf-8")
    return module
