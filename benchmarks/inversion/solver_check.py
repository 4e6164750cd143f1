"""Is the integrator good enough for *this* inversion? Checked on the user's own problem first.

An integrator is chosen on the studies' problems (the work-precision studies' front over the
paper's example, W2 and two external problems, :mod:`benchmarks.devtools.recommendation`) or
named by the user; neither says how it does on
another apparatus. Before an inversion or a sweep, :func:`check_solver` solves the box's four
corners and its centre (in b and log10 Lc) with the integrator and with a tight reference — two
own methods of different families, :data:`REFERENCES`, whose agreement is checked point by
point — and compares what the likelihood reads:

* the limit-cycle metrics, |ΔT − ΔT_ref| / σ_T and |Δμ − Δμ_ref| / σ_μ;
* with curves in the likelihood, the largest change of a whitened curve residual
  (:meth:`benchmarks.inversion.curve_likelihood.CurveLikelihood.residuals`, in units of σ);
* whether the point has a limit cycle at all (a cycle the reference does not have, or misses,
  moves the posterior more than any metric).

Each must be within :data:`FRACTION` (σ/10) wherever the two references agree to a tenth of that;
a point where they do not (near a boundary of stick–slip, or beyond the references' own
accuracy) is not used, and said. A recommended setting (the commands pass their --accuracy as
``level``) must also reach the level it was chosen for: each checked point's ΔT within
``level``, relative, where the references agree in ΔT to a tenth of it; the studies vouch for
it on their problems, this check on the box's. At least one checked point must have a limit cycle (a point
without one in the integrator and in the references checks nothing but that): if none of the
five has, a 3 × 3 grid inside the box is tried, and then the check says that it checked nothing
(``nothing_to_check``: the commands go on with a warning). If the integrator
fails, a tighter setting is tried (``next_setting``: by default rtol and atol ÷ 10, or the ETD
family's steps ÷ 4; the commands tighten a recommended integrator along the work-precision
front, :func:`benchmarks.devtools.recommendation.tighter_on_front`), at most
:data:`TIGHTENINGS` times, and then the check refuses, naming the worst point.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from benchmarks.ensemble import ensemble
from benchmarks.physics.metrics import CYCLES
from integrators import make_algorithm
from integrators.core.registry import RTOL_MIN

__all__ = ["check_solver", "SolverCheck", "REFERENCES", "FRACTION", "TIGHTENINGS", "tighter",
           "WALL_BUDGET", "fastest_on_box", "RACE_REPEATS", "RACE_MARGIN", "recommended_on_box"]

#: the reference pair (integrator, rtol = atol): an exponential Rosenbrock and a Rosenbrock
#: method, tight, in compiled batches
REFERENCES = (("Rodas5P", 1e-9), ("Exprb43", 1e-9))
#: an error is acceptable up to this fraction of its σ
FRACTION = 0.1
#: tighter settings tried before the check refuses
TIGHTENINGS = 3
#: s of wall time per solve of the check unless told: a reference over it vouches for nothing at
#: its point, an integrator over it fails there (a W2 solve takes milliseconds)
WALL_BUDGET = 10.0
#: rounds of :func:`fastest_on_box` (each candidate's time: the least of its rounds)
RACE_REPEATS = 2
#: a rival replaces the recommendation only when faster than it by more than this fraction:
#: near-ties within the timing noise (a few % on a loaded machine) keep the recommendation
RACE_MARGIN = 0.03


@dataclass
class SolverCheck:
    """The outcome: the setting that passed (or the last tried), whether it passed, every
    point's errors in units of σ per setting tried (``points``), the settings tried, a sentence
    (``message``), the wall time and the number of solves."""

    algorithm: object
    passed: bool
    points: pd.DataFrame = field(repr=False)
    tried: list
    message: str
    wall_s: float
    n_solves: int
    #: no checked point had a limit cycle: the integrator is neither vouched for nor refused
    nothing_to_check: bool = False

    def summary(self) -> dict:
        """What ``inversion.json`` records of the check."""
        return {"passed": self.passed, "nothing_to_check": self.nothing_to_check,
                "integrator": self.algorithm.name,
                "options": self.algorithm.options(), "tried": self.tried,
                "message": self.message, "wall_s": self.wall_s, "n_solves": self.n_solves,
                "references": [f"{n} at rtol = atol = {t:g}" for n, t in REFERENCES],
                "fraction_of_sigma": FRACTION, "points": self.points.to_dict(orient="records")}


def tighter(algorithm):
    """The next tighter setting of ``algorithm``: rtol and atol ÷ 10, or the ETD family's
    Δτcnst and Δτmax ÷ 4; None when there is none (rtol at its floor)."""
    if hasattr(algorithm, "rtol"):
        if algorithm.rtol / 10 < RTOL_MIN:
            return None
        return dataclasses.replace(algorithm, rtol=algorithm.rtol / 10, atol=algorithm.atol / 10)
    if hasattr(algorithm, "dtau_cnst"):
        return dataclasses.replace(algorithm, dtau_cnst=algorithm.dtau_cnst / 4,
                                   dtau_max=algorithm.dtau_max / 4)
    return None


def _points(b_range, lc_range, inner: bool = False) -> dict:
    """The box's corners and centre; ``inner``: a 3 × 3 grid inside it, at a quarter, half and
    three quarters of each side (in b and log10 Lc). A side of no width gives each point
    once."""
    (b_lo, b_hi), (lc_lo, lc_hi) = b_range, lc_range
    if inner:
        fb = b_lo + (b_hi - b_lo) * np.array([0.25, 0.5, 0.75])
        fl = 10.0 ** (np.log10(lc_lo) + np.log10(lc_hi / lc_lo) * np.array([0.25, 0.5, 0.75]))
        b, lc = (x.ravel() for x in np.meshgrid(fb, fl, indexing="ij"))
    else:
        b = [b_lo, b_lo, b_hi, b_hi, (b_lo + b_hi) / 2]
        lc = [lc_lo, lc_hi, lc_lo, lc_hi, lc_lo if lc_lo == lc_hi else math.sqrt(lc_lo * lc_hi)]
    kept = list(dict.fromkeys(zip(map(float, b), map(float, lc))))
    return {"b": np.array([p[0] for p in kept]), "lc": np.array([p[1] for p in kept])}


def fastest_on_box(problem, candidates, b_range, lc_range,
                   wall_budget: float | None = WALL_BUDGET, repeats: int = RACE_REPEATS,
                   margin: float = 0.0):
    """``(algorithm, times)``: of ``candidates`` (algorithms), the one whose solves of the
    box's corners, centre and 3 × 3 inner grid (:func:`_points`) take the least wall in all
    (each point's own solve time, on one thread; the least of ``repeats`` rounds, the
    candidates interleaved), among those whose every solve there succeeded; another than the
    first only when it is faster than the first by more than ``margin`` (a fraction of the
    first's time). ``times``: each candidate's label → s (inf where a solve failed). The
    first candidate when every one failed somewhere (the check then judges it)."""
    corners, inner = _points(b_range, lc_range), _points(b_range, lc_range, inner=True)
    points = {k: np.concatenate([corners[k], inner[k]]) for k in corners}
    best = [np.inf] * len(candidates)
    for _ in range(repeats):
        for i, algorithm in enumerate(candidates):
            table = ensemble(problem, algorithm, points, workers=1, progress=False,
                             wall_budget=wall_budget)
            if (table.retcode == "Success").all():
                best[i] = min(best[i], float(table.wall_s.sum()))
    k = int(np.argmin(best)) if np.isfinite(best).any() else 0
    if np.isfinite(best[0]) and best[k] > (1.0 - margin) * best[0]:
        k = 0                                    # not clearly faster: the first stays
    return candidates[k], {_label(a): t for a, t in zip(candidates, best)}


def recommended_on_box(problem, level: float, b_range, lc_range,
                       wall_budget: float | None = WALL_BUDGET, say=None, held=None):
    """``(algorithm, why)``: the recommendation for ``level``
    (:func:`benchmarks.devtools.recommendation.recommended`), or where the front has settings
    within ``level`` at nearly its cost (:func:`~benchmarks.devtools.recommendation.contenders`),
    the fastest of them on this problem's box (:func:`fastest_on_box`; a rival must be
    :data:`RACE_MARGIN` faster than the recommendation): the studies vouch for each one's
    accuracy, the box decides their near-ties. ``held``: the ``repr`` of a setting already in
    use (a store's, to resume): a contender that is it is taken without a race. ``say``: told
    before the race."""
    from benchmarks.devtools.recommendation import contenders, recommended
    algorithm, why = recommended(level)
    rivals = [a for a, _worst, _wall in contenders(level)]
    if len(rivals) < 2:
        return algorithm, why
    kept = [a for a in rivals if repr(a) == held]
    if kept:
        return kept[0], (f"{why}; of the front's near-ties within {level:g}, "
                         f"{_label(kept[0])}: the setting of the stored chunks, kept so that "
                         "the run resumes")
    if say is not None:
        say(f"timing the {len(rivals)} settings of the front within {level:g} on the box")
    fastest, times = fastest_on_box(problem, rivals, b_range, lc_range, wall_budget,
                                    margin=RACE_MARGIN)
    said = ", ".join(f"{k} {t * 1e3:.3g} ms" if np.isfinite(t) else f"{k} failed"
                     for k, t in times.items())
    return fastest, (f"{why}; on this problem's box (corners, centre and a 3 × 3 grid, one "
                     f"thread) took {_label(fastest)}, the fastest of the front's settings "
                     f"within {level:g} (a rival must be {RACE_MARGIN:.0%} faster than the "
                     f"recommendation): {said}")


def _run(problem, algorithm, points, curves: bool, workers, wall_budget) -> pd.DataFrame:
    return ensemble(problem, algorithm, points, curve_dt=5e-5 if curves else None,
                    workers=workers, progress=False, wall_budget=wall_budget)


def _errors(a: pd.DataFrame, b: pd.DataFrame, obs) -> np.ndarray:
    """Per point: the largest error of ``a`` against ``b`` in units of σ (inf where one has a
    cycle and the other not; 0 where neither has)."""
    ca = a.classification.isin(CYCLES).to_numpy()
    cb = b.classification.isin(CYCLES).to_numpy()
    out = np.where(ca == cb, 0.0, np.inf)
    both = ca & cb
    err = np.maximum(np.abs(a.recurrence_s - b.recurrence_s).to_numpy() / obs.sigma_recurrence_s,
                     np.abs(a.friction_drop - b.friction_drop).to_numpy()
                     / obs.sigma_friction_drop)
    like = obs.curve_likelihood
    if like is not None:
        for i in np.flatnonzero(both):
            ra = like.residuals(a.curve_slip.iloc[i], a.curve_friction.iloc[i])
            rb = like.residuals(b.curve_slip.iloc[i], b.curve_friction.iloc[i])
            made = np.isfinite(ra).all() and np.isfinite(rb).all()    # a cycle without its curve
            err[i] = max(err[i], float(np.max(np.abs(ra - rb)))) if made else np.inf
    return np.where(both, err, out)


def check_solver(problem, algorithm, obs, b_range, lc_range, next_setting=None,
                 workers: int | None = None, say=None,
                 wall_budget: float | None = WALL_BUDGET,
                 level: float | None = None) -> SolverCheck:
    """Check ``algorithm`` on ``problem`` for the observations ``obs`` over the box (module
    docstring). ``next_setting(algorithm)``: the next tighter setting to try (default
    :func:`tighter`). ``say``: a callable given a line of text per setting tried.
    ``wall_budget``: s per solve (None: none); a point where a reference failed or ran out of
    it is not used (its references do not agree), one where the integrator did is a failure.
    ``level``: the relative ΔT error the setting was chosen for (the commands' --accuracy);
    each checked point must be within it as well."""
    say = say or (lambda text: None)
    next_setting = next_setting or tighter
    started = time.perf_counter()
    curves = obs.curve_likelihood is not None
    refs = n_solves = None
    unfinished = 0                       # reference solves that failed or ran out of budget
    for inner in (False, True):          # corners and centre; inside the box if none has a cycle
        points = _points(b_range, lc_range, inner)
        refs = [_run(problem, make_algorithm(n, rtol=t, atol=t), points, curves, workers,
                     wall_budget) for n, t in REFERENCES]
        n_solves = (n_solves or 0) + 2 * len(points["b"])
        unfinished += sum(int((r.retcode != "Success").sum()) for r in refs)
        cycles = [r.classification.isin(CYCLES).to_numpy() for r in refs]
        if (cycles[0] & cycles[1]).any():
            break
    else:
        return SolverCheck(algorithm, False, pd.DataFrame(), [],
                           _nothing(n_solves, unfinished, wall_budget),
                           time.perf_counter() - started, n_solves, nothing_to_check=True)
    finished = ((refs[0].retcode == "Success") & (refs[1].retcode == "Success")).to_numpy()
    agree = (_errors(refs[0], refs[1], obs) <= FRACTION / 10) & finished
    rows, tried, current = [], [], algorithm
    base = pd.DataFrame({"b": points["b"], "lc_m": points["lc"],
                         "reference_class": refs[0].classification.to_numpy(),
                         "references_agree": agree})
    compared = agree & cycles[0] & cycles[1]     # a point is checked on its cycle's metrics
    if not compared.any():
        return SolverCheck(algorithm, False, base, [], (
            "the two reference solvers disagree by more than σ/100 wherever they find a limit "
            "cycle: nothing here can vouch for an integrator on this problem (σ too small for "
            "the references, or every such point at a boundary of stick–slip)"),
            time.perf_counter() - started, n_solves)
    for _ in range(TIGHTENINGS + 1):
        label = _label(current)
        tried.append(label)
        say(f"checking {label} against {REFERENCES[0][0]} and {REFERENCES[1][0]} at "
            f"{REFERENCES[0][1]:g} on the box's corners and centre")
        table = _run(problem, current, points, curves, workers, wall_budget)
        n_solves += len(table)
        err, rel, share = _judged(table, refs, obs, agree, level)
        rows.append(base.assign(setting=label, error_in_sigma=err, relative_dT_error=rel,
                                classification=table.classification.to_numpy()))
        if (share <= 1.0).all():
            return SolverCheck(current, True, pd.concat(rows, ignore_index=True), tried,
                               _passed(label, rows, agree, compared, level, tried),
                               time.perf_counter() - started, n_solves)
        nxt = next_setting(current)
        if nxt is None:
            break
        current = nxt
    k = int(np.argmax(share))
    return SolverCheck(current, False, pd.concat(rows, ignore_index=True), tried,
                       f"no setting tried ({', '.join(tried)}) is within {_allowed(level)} of "
                       f"the reference: the last "
                       + _off(rows[-1].iloc[[k]], None if np.isnan(rel[k]) else level) +
                       f" at b = {points['b'][k]:g}, Lc = {points['lc'][k]:g} m (name a more "
                       "accurate --integrator, " + ("" if level is None else
                                                   "ask a looser --accuracy, ")
                       + "or check the σ)",
                       time.perf_counter() - started, n_solves)


def _nothing(n_solves: int, unfinished: int, wall_budget) -> str:
    """Why the check had nothing to check: every reference solve failed (the budget first),
    or no point of the box has a limit cycle."""
    if unfinished == n_solves:
        return (f"every one of the references' {n_solves} solves failed"
                + (f" or ran out of its budget of {wall_budget:g} s" if wall_budget else "")
                + ": nothing to check the integrator on (raise --wall-budget?)")
    return ("no limit cycle at the box's corners, its centre or a 3 × 3 grid inside it, by "
            "either reference: nothing to check the integrator on"
            + (f" ({unfinished} of the references' {n_solves} solves failed or ran out of "
               f"their budget of {wall_budget:g} s per solve: no cycle is read from them)"
               if unfinished and wall_budget is not None else
               f" ({unfinished} of the references' {n_solves} solves failed)"
               if unfinished else ""))


def _passed(label: str, rows: list, agree, compared, level, tried: list) -> str:
    """The sentence of a check passed by ``label``, the last of ``rows``: what was within
    which allowance, at how many points, and what a tightening started from."""
    last, first = rows[-1][agree], rows[0][agree]
    n_level = int(last.relative_dT_error.notna().sum())
    checked = _allowed(level if n_level else None)
    return (f"{label}: every checked point within {checked} of the reference (worst "
            f"{last.error_in_sigma.max():.2g} σ"
            + ("" if level is None else
               f", {last.relative_dT_error.max():.2g} in ΔT at {n_level} of them" if n_level
               else f"; ΔT's level {level:g} not checked: the references agree in ΔT to a "
                    "tenth of it at no point")
            + f"; {int(compared.sum())} points with a cycle where the references agree, of "
            f"{len(agree)})" + ("" if len(tried) == 1 else
                                f"; tightened from {tried[0]}, which " + _off(first, level)))


def _off(rows, level) -> str:
    """How far a setting's checked points were off: its worst in σ (and in ΔT), or that it
    missed a limit cycle the references find (or found one they do not)."""
    worst = rows.error_in_sigma.max()
    if not np.isfinite(worst):
        return "missed a limit cycle the references find, or found one they do not"
    return (f"was {worst:.2g} σ" + ("" if level is None or rows.relative_dT_error.isna().all()
                                    else f" and {rows.relative_dT_error.max():.2g} in ΔT")
            + " off")


def _allowed(level) -> str:
    return (f"σ/{1 / FRACTION:g}" if level is None else
            f"σ/{1 / FRACTION:g} and {level:g} relative in ΔT")


def _judged(table, refs, obs, agree, level) -> tuple:
    """Per point: the error against the first reference in units of σ, the relative ΔT error
    (inf for a cycle one of them misses; NaN without ``level`` and where it is not judged) and
    the larger of each as a share of its allowance (σ/10, ``level``; ≤ 1 passes). A point
    counts only where the references agree (``agree``) and, for the level, where both have a
    cycle whose ΔT they agree on to a tenth of it."""
    err = _errors(table, refs[0], obs)
    share = err / FRACTION
    rel = np.full(len(err), np.nan)
    if level is not None:
        t_ref = refs[0].recurrence_s.to_numpy()
        rel = np.abs(table.recurrence_s.to_numpy() - t_ref) / t_ref
        rel = np.where(np.isinf(err), np.inf, rel)       # a cycle one of them misses
        refs_rel = np.abs(refs[1].recurrence_s.to_numpy() - t_ref) / t_ref
        judged = agree & (np.nan_to_num(refs_rel, nan=np.inf) <= level / 10)
        rel = np.where(judged, rel, np.nan)
        share = np.maximum(share, np.nan_to_num(rel, nan=0.0) / level)
    return err, rel, np.where(agree, share, 0.0)


def _label(algorithm) -> str:
    if hasattr(algorithm, "rtol"):
        atol = getattr(algorithm, "atol", algorithm.rtol)
        return (f"{algorithm.name} at rtol = atol = {algorithm.rtol:g}" if atol == algorithm.rtol
                else f"{algorithm.name} at rtol {algorithm.rtol:g}, atol {atol:g}")
    if hasattr(algorithm, "dtau_cnst"):
        return f"{algorithm.name} at Δτcnst = {algorithm.dtau_cnst:g}"
    return algorithm.name
