"""Reference solutions: two independent high-accuracy solvers that must agree, cached on disk.

A reference for a problem is computed by the two solvers of :data:`REFERENCE_SOLVERS` (Hairer's
Radau IIA of order 5 and SUNDIALS' CVODE BDF, different methods, libraries and step controls),
each at rtol = atol = 1e−12. Their limit-cycle metrics, compared event by event on the last
complete event and on the start time of that event, must agree to :data:`AGREEMENT_RTOL`
before either is used; otherwise :func:`reference` raises :class:`ReferenceDisagreement` (also
when a solver fails or runs out of its :data:`WALL_BUDGET`; :class:`NoStickSlip` when both find
fewer than two events).
The first solver's run is the reference; the agreement (the largest relative disagreement per
measure) is stored with it and is the floor below which no error in a study means anything.

Cached as JSON under ``$RSFBENCH_CACHE`` (default ``results/cache/references``, not committed),
keyed by a hash of the problem's ``repr`` (a frozen dataclass: every parameter, exactly) and of
the reference settings, so a changed problem or solver never reuses a stale reference.
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.physics.metrics import METRICS, event_metrics, summarize
from benchmarks.records.files import (
    BadResultsFile,
    atomic_write,
    read_json_record,
    remove_stale_temporaries,
)
from integrators import EVENT_COLUMNS, REGISTRY, solve

__all__ = ["Reference", "ReferenceDisagreement", "NoStickSlip", "reference", "no_stick_slip",
           "REFERENCE_SOLVERS",
           "AGREEMENT_RTOL", "GRID_POINTS", "cache_dir", "agreement_table"]

#: candidate pairs of independent reference solvers (name, rtol = atol); the first pair whose
#: backends are installed is used (``make test``/``make reproduce`` install the first)
REFERENCE_SOLVERS = ((("assimulo-Radau5ODE", 1e-12), ("odes-CVODE-BDF", 1e-12)),
                     (("scipy-Radau", 1e-11), ("scipy-BDF", 1e-11)))
#: the two must agree this well on every measure (at 1e-12 they agree to ~1e-9 on the W1–W4
#: limit cycles and the paper example: results/references.csv)
AGREEMENT_RTOL = 1e-7
#: points of the common time grid of the trajectory error
GRID_POINTS = 2001
#: s of wall time per reference solve: the paper's problems take 1–10 s (results/references.csv);
#: one that crawls (a problem without stick–slip can, at 1e-12) fails in minutes, not hours
WALL_BUDGET = 120.0
#: bump when the stored content or the way it is computed changes
_FORMAT = 1


class ReferenceDisagreement(RuntimeError):
    """The two reference solvers do not agree: no reference for this problem."""


class NoStickSlip(ReferenceDisagreement):
    """Both reference solvers agree that the problem has fewer than two events: no recurrence
    interval, friction drop or event to measure an error on."""


class BadReferenceWarning(UserWarning):
    """A cached reference that cannot be trusted; it is recomputed (the message names it)."""


_REQUIRED = ("format", "key", "problem", "events", "grid_t", "grid_mu", "normal_force",
             "event_index", "solvers", "agreement")


@dataclass
class Reference:
    """A reference run of one problem: its events, its spring force on a common grid, which
    event the errors are measured on, and how well the two solvers agreed.

    Parameters
    ----------
    key : str
        The cache key of the problem.
    problem_repr : str
        The problem's ``repr``.
    events : pandas.DataFrame
        The events, columns :data:`~integrators.EVENT_COLUMNS` (SI units).
    grid_t : numpy.ndarray
        Uniform times on [0, t_end] (s).
    grid_mu : numpy.ndarray
        The spring force over the normal force, Fs/Fn, at ``grid_t`` (dimensionless).
    normal_force : float
        Fn (N).
    event_index : int
        The row of ``events`` whose metrics the errors compare.
    solvers : list of dict
        Each reference solver's name, tolerance, wall time (s), evaluations and measures.
    agreement : dict
        The largest relative disagreement of the two solvers, by measure and ``"max"``.
    """

    key: str
    problem_repr: str
    events: pd.DataFrame                 # EVENT_COLUMNS, SI
    grid_t: np.ndarray                   # s, GRID_POINTS uniform points on [0, t_end]
    grid_mu: np.ndarray                  # Fs/Fn on the grid
    normal_force: float
    event_index: int                     # the event whose metrics are compared
    solvers: list[dict] = field(default_factory=list)   # name, tol, wall, nfev, measures
    agreement: dict = field(default_factory=dict)       # largest relative disagreement

    @property
    def metrics(self) -> pd.Series:
        """Per-event metrics (:func:`benchmarks.physics.metrics.event_metrics`) of the compared event."""
        return event_metrics(self.events, self.normal_force).iloc[self.event_index]

    def to_json(self) -> dict:
        return {"format": _FORMAT, "key": self.key, "problem": self.problem_repr,
                "events": self.events.to_dict(orient="list"), "grid_t": self.grid_t.tolist(),
                "grid_mu": self.grid_mu.tolist(), "normal_force": self.normal_force,
                "event_index": self.event_index, "solvers": self.solvers,
                "agreement": self.agreement}

    @classmethod
    def from_json(cls, d: dict) -> "Reference":
        return cls(key=d["key"], problem_repr=d["problem"],
                   events=pd.DataFrame(d["events"], columns=list(EVENT_COLUMNS)),
                   grid_t=np.array(d["grid_t"]), grid_mu=np.array(d["grid_mu"]),
                   normal_force=d["normal_force"], event_index=d["event_index"],
                   solvers=d["solvers"], agreement=d["agreement"])


def cache_dir() -> Path:
    """Where references are cached: ``$RSFBENCH_CACHE``; in a checkout
    ``results/cache/references``; in an installed package ``$XDG_CACHE_HOME/rsfbench/references``
    (``~/.cache`` by default)."""
    env = os.environ.get("RSFBENCH_CACHE")
    if env:
        return Path(env)
    root = Path(__file__).resolve().parents[2]
    if (root / "pyproject.toml").exists():
        return root / "results" / "cache" / "references"
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "rsfbench" / "references"


def _solver_pair():
    for pair in REFERENCE_SOLVERS:
        if all(name in REGISTRY for name, _ in pair):
            return pair
    raise RuntimeError(f"no pair of reference solvers is installed: {REFERENCE_SOLVERS}")


def _key(problem, pair) -> str:
    text = f"{_FORMAT}|{problem!r}|{pair!r}|{AGREEMENT_RTOL}|{GRID_POINTS}"
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def reference(problem, cache: Path | None = None, refresh: bool = False,
              progress: bool = False) -> Reference:
    """The checked reference of ``problem``, from the cache or computed (and cached) now."""
    pair = _solver_pair()
    key = _key(problem, pair)
    path = (cache or cache_dir()) / f"{(problem.name or 'problem').replace('/', '_')}-{key}.json"
    if path.exists() and not refresh:
        cached = _load(path, key, problem)
        if cached is not None:
            return cached
    ref = _compute(problem, pair, key, progress)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path.parent)
    atomic_write(path, json.dumps(ref.to_json()))   # parallel studies never read half a file
    return ref


#: (method, rtol = atol, wall budget in s): the quick compiled run that screens a problem for
#: events before its references are computed (a milliseconds' run on the paper's problems)
SCREEN = ("Rodas5P", 1e-8, 10.0)


def no_stick_slip(problem) -> str:
    """Why ``problem`` has no error to measure — fewer than two events in a quick run of
    :data:`SCREEN` —, or "" (two events or more, or the quick run did not finish: then the
    references decide). Seconds, where the references of such a problem can crawl for
    minutes (a steady slider at 1e-12)."""
    name, tol, budget = SCREEN
    run = solve(problem, REGISTRY[name](rtol=tol, atol=tol), max_points=2, wall_budget=budget)
    if not run.success or len(run.events) >= 2:
        return ""
    n = len(run.events)
    return (f"{problem.name}: no stick–slip events to measure: {n} event{'' if n == 1 else 's'} "
            f"in its {problem.t_end:g} s ({name} at {tol:g}: {summarize(run).reason}); an "
            "error in the recurrence interval needs two: give a problem that sticks and slips, "
            "or a longer t_end")


def _load(path: Path, key: str, problem) -> Reference | None:
    """The cached reference at ``path`` if it is whole and is the one asked for (format, key,
    problem); otherwise None, with a warning naming the file, and it is recomputed."""
    try:
        d = read_json_record(path, _REQUIRED, what="cached reference")
        if (d["format"], d["key"], d["problem"]) != (_FORMAT, key, repr(problem)):
            raise BadResultsFile(f"cached reference {path} is of another problem or format")
        ref = Reference.from_json(d)
        if not (len(ref.grid_t) == len(ref.grid_mu) == GRID_POINTS
                and 0 <= ref.event_index < len(ref.events)
                and np.isfinite(ref.events.to_numpy(dtype=float)).all()):
            raise BadResultsFile(f"cached reference {path} is inconsistent (grid or events)")
        return ref
    except (BadResultsFile, KeyError, TypeError, ValueError) as exc:
        warnings.warn(f"{exc}: recomputing it", BadReferenceWarning, stacklevel=3)
        return None


def _compute(problem, pair, key: str, progress: bool) -> Reference:
    grid = np.linspace(0.0, problem.t_end, GRID_POINTS)
    runs = []
    for name, tol in pair:
        sol = solve(problem, REGISTRY[name](rtol=tol, atol=tol),
                    save_every=problem.t_end / (GRID_POINTS - 1), progress=progress,
                    wall_budget=WALL_BUDGET)
        if not sol.success:
            raise ReferenceDisagreement(f"reference solver {name} failed on {problem.name}: "
                                        f"{sol.retcode.value}: {sol.message}")
        runs.append(sol)
    n = min(len(s.events) for s in runs)
    if n < 2 and len({len(s.events) for s in runs}) == 1:
        raise NoStickSlip(
            f"{problem.name}: no stick–slip events to measure: both reference solvers "
            f"({', '.join(s.algorithm.name for s in runs)}) find {n} event"
            f"{'' if n == 1 else 's'} in its {problem.t_end:g} s (an error in the recurrence "
            "interval needs two); give a problem that sticks and slips, or a longer t_end")
    if n < 2 or len({len(s.events) for s in runs}) != 1:
        raise ReferenceDisagreement(
            f"{problem.name}: reference solvers disagree on the number of events "
            f"({', '.join(f'{s.algorithm.name}: {len(s.events)}' for s in runs)}) or found "
            "fewer than two (no recurrence interval to compare)")
    index = n - 1
    measures = [_measures(s, index) for s in runs]
    agreement = {k: abs(measures[0][k] - measures[1][k]) / abs(measures[1][k]) for k in measures[0]}
    agreement["max"] = max(agreement.values())
    solvers = [{"name": s.algorithm.name, "tol": tol, "wall_s": s.stats.wall_s,
                "nfev": s.stats.nfev, "n_events": len(s.events), **m}
               for s, (_, tol), m in zip(runs, pair, measures)]
    if not agreement["max"] <= AGREEMENT_RTOL:
        raise ReferenceDisagreement(
            f"{problem.name}: reference solvers {pair[0][0]} and {pair[1][0]} disagree by "
            f"{agreement['max']:.3g} (> {AGREEMENT_RTOL:g}) on event {index}: {agreement}")
    first = runs[0]
    return Reference(key=key, problem_repr=repr(problem), events=first.events.copy(),
                     grid_t=grid, grid_mu=np.interp(grid, first.t, first.mu),
                     normal_force=problem.normal_force, event_index=index,
                     solvers=solvers, agreement=agreement)


def _measures(sol, index: int) -> dict:
    """The compared measures of one reference run: the metrics of event ``index`` and its start."""
    m = event_metrics(sol.events, sol.problem.normal_force).iloc[index]
    return {**{k: float(m[k]) for k in METRICS}, "t_start": float(m["t_start"])}


def agreement_table(problems_and_refs) -> pd.DataFrame:
    """One row per (problem, reference solver): its measures, cost and the pair's agreement."""
    rows = []
    for problem, ref in problems_and_refs:
        for s in ref.solvers:
            rows.append({"problem": problem.name, "law": problem.law.name,
                         "event_index": ref.event_index, **s,
                         "max_disagreement": ref.agreement["max"]})
    return pd.DataFrame(rows)
