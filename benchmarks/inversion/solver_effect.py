"""Does the choice of solver change what a data set infers? Every candidate setting inverts the
same data (J1: the means and their σ), and is compared with the inversion by a tight
``reference`` setting:

* the posterior on the **zoom** (:mod:`benchmarks.inversion.grid`): a coarse reference map of
  the box finds where any data set's posterior lives (nodes within 1e−6 of the maximum density),
  and a fine ``n`` × ``n`` grid over that zoom (padded by one coarse node) carries every
  setting's posterior. Compared: the shift of the posterior mean of b and of log10 Lc in units
  of the reference posterior's standard deviation; the overlap of the two posteriors,
  Σ min(p, q) (1 − the total variation distance); the Jaccard index of their 95 % HPD sets;
* the posterior on the **whole box**, on a ``check_n`` × ``check_n`` grid for every setting: a
  setting whose posterior has mass where the reference's has none (a spurious cycle matching the
  data elsewhere) would look the same on the zoom; its whole-box overlap, and its mass outside
  the zoom, show it;
* the best fit: :func:`benchmarks.inversion.least_squares.fit` started from each setting's best
  node, its shift from the reference's best fit in the same units (``fit_ok``: the fit
  converged).

**Precise data.** When the zoom's grid does not resolve the reference's posterior — fewer than
:data:`MIN_NODES_PER_SD` nodes per standard deviation, or an sd off the Gauss–Newton one of the
reference's least-squares fit by more than a factor 2 (a ridge across which the nodes are too
far apart: with σ(ΔT)/ΔT = 5e−4 on W2 the old zoom held the posterior on one node, 0.01 nodes
per sd, and with 1e−5 its sd was 0 and the shifts a division by zero) — and that fit's
Gauss–Newton frame lies inside the box, every setting's posterior is compared on the nodes of
that frame instead (:func:`benchmarks.inversion.zoom.frame_map`: ``n`` × ``n`` nodes over
± :data:`FRAME_HALF` sd of the fit's covariance, the same nodes for every setting), its moments
read in (b, log10 Lc) (``zoom_kind`` says which grid). A shift is never divided by a zero sd:
it is NaN then, and the setting is not indistinguishable.

A setting's inversion is **indistinguishable** from the reference's when both posterior-mean
shifts are within :data:`SHIFT_SD` = 0.1 standard deviations and both overlaps (zoom and whole
box) are at least :data:`MIN_OVERLAP` = 0.95: a tenth of the posterior's own width, far below
what a user would read as a different answer. The comparison is **resolved** when the floor (a
second tight setting of another method) is indistinguishable by that rule; an unresolved data
set gets no recommendation. The grid's resolution is reported as nodes per reference standard
deviation. The best-fit shift is reported beside the rule, not in it: where the misfit has a
flat valley (Lc bounded only on one side) the best fit wanders along the valley with any
perturbation while the posterior does not move.

The reference and the floor run without a wall budget (a node that timed out would be read as
without a cycle, and the reference would depend on the machine's load); the candidates run with
``wall_budget`` per solve, and ``n_failed`` counts their nodes whose solve failed (they count as
without a cycle, as :class:`~benchmarks.inversion.Misfit` defines).

Cost: the mean wall time of one forward solve (the solves' own time over the fine grid, with as
many solves at once as there are workers), and the cost of a 64,000-solve posterior on this
machine, all workers and the harness included (:func:`posterior_cost`): what one ensemble costs
whatever its size (its workers' start, compiling that no cache keeps: numbalsoda's driver is
``@njit`` without a cache), measured as a 2 × 2 map's wall time, plus 64,000 × the fine map's
extra time per extra node. Each setting first solves a 2 × 2 map in this process, untimed, so
that its compilation (and the numba cache its worker processes load) is not in either: a cold
cache once put 16 s of compiling into W1/slip's first Rosenbrock23 and Exprb32 maps, and
64,000 × the map's time per node (the rule then) made that 20× their cost.

:func:`write_solver_effect` runs the comparison with the project's candidates, reference and
floor and writes its files, report and figure: for the study over the windows and laws
(:mod:`benchmarks.studies.solver_effect`) and, for a problem of one's own, for ``rsfbench
solver-effect``.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.devtools.work_precision import algorithm_at, read_study, recommend
from benchmarks.inversion.adaptive import GridPosterior
from benchmarks.inversion.grid import MetricMap, box_grid, metric_map
from benchmarks.inversion.least_squares import fit
from benchmarks.inversion.misfit import Misfit, synthetic
from benchmarks.inversion.observations import Observations, observations
from benchmarks.inversion.zoom import SD_FACTOR, Frame, frame_map, frame_moments, frame_of
from benchmarks.records.files import write_figure, write_output, write_table
from benchmarks.records.report import fmt, markdown_table
from integrators import REGISTRY, Algorithm, Exprb43, Rodas5P
from problems import preset

__all__ = ["solver_effect", "candidates", "Candidate", "recommendation", "compare",
           "same_inference", "posterior_cost", "SHIFT_SD", "MIN_OVERLAP", "POSTERIOR_SOLVES",
           "QUICK_LADDERS", "QUICK_N", "write_solver_effect", "MIN_NODES_PER_SD", "FRAME_HALF"]

#: the largest shift of a posterior mean, in reference standard deviations, called no change
SHIFT_SD = 0.1
#: the smallest overlap Σ min(p, q) of two posteriors called the same
MIN_OVERLAP = 0.95
#: the forward solves a posterior costs (the size of the inversion study's posterior target)
POSTERIOR_SOLVES = 64_000
#: a node is in a posterior's zoom when its density is within this factor of the maximum
ZOOM_DENSITY = 1e-6
#: a reference posterior with fewer nodes than this per sd (in b or log10 Lc) is not resolved
#: by the zoom's grid: it is compared on the frame of the reference's fit instead
MIN_NODES_PER_SD = 2.0
#: the frame's grid spans ± this many Gauss–Newton sd (15 nodes: 0.53 sd apart; the mass of a
#: Gaussian beyond ± 4 sd in either parameter is 1.3e−4)
FRAME_HALF = 4.0


@dataclass(frozen=True)
class Candidate:
    """A setting to compare: its family (``own``, ``ETD``, ``LSODA``, ``SUNDIALS``,
    ``reference``, ``floor``), a label, and the algorithm."""

    family: str
    label: str
    algorithm: Algorithm


def candidates(study: pd.DataFrame | None = None, own_ladders=None, etd_factors=(4, 1),
               peer_levels=(1e-2, 1e-3, 1e-4)) -> list[Candidate]:
    """The settings compared: the own methods over ``own_ladders`` ({method: tolerances}), ETD2
    at the paper's Δτ rule scaled by ``etd_factors`` (1: the paper's), and from the
    work-precision ``study`` the fastest LSODA and the fastest SUNDIALS setting whose worst
    recurrence error is within each of ``peer_levels`` (:func:`benchmarks.devtools.work_precision.
    recommend` within each family)."""
    own_ladders = own_ladders or {"Rodas5P": (1e-3, 1e-4, 1e-5, 1e-6, 1e-7),
                                  "Rosenbrock23": (1e-3, 1e-4, 1e-5, 1e-6),
                                  "Exprb43": (1e-3, 1e-4, 1e-5),
                                  "Exprb32": (1e-3, 1e-4, 1e-5)}
    out = [Candidate("own", f"{m} {tol:g}", algorithm_at(m, "numba", tol))
           for m, tols in own_ladders.items() for tol in tols]
    paper = REGISTRY["ETD2"]().dtau_cnst
    out += [Candidate("ETD", f"ETD2 Δτcnst {paper * f:g}" + (" (paper)" if f == 1 else ""),
                      algorithm_at("ETD2", "numba", paper * f)) for f in etd_factors]
    if study is not None:
        families = {"LSODA": study.integrator.str.contains("LSODA"),
                    "SUNDIALS": study.integrator.str.contains("CVODE|CVode|IDA|ARKODE")}
        for family, rows in families.items():
            advice = recommend(study[rows], peer_levels).dropna(subset=["integrator"])
            for a in advice.drop_duplicates(["integrator", "rhs_tier", "setting"]).itertuples():
                out.append(Candidate(family, f"{a.integrator} [{a.rhs_tier}] {a.setting:g}",
                                     algorithm_at(a.integrator, a.rhs_tier, float(a.setting))))
    return out


#: the candidates of the quick mode: the own methods' front settings and the paper's ETD2
QUICK_LADDERS = {"Rodas5P": (1e-3, 1e-4, 1e-5), "Exprb43": (1e-3, 1e-4),
                 "Rosenbrock23": (1e-3, 1e-4)}
#: nodes per parameter of the quick mode's grids
QUICK_N = 15


def _datasets(name: str, law: str, reference_map: MetricMap, truth,
              yours: Observations | None = None,
              published: bool = True) -> dict[str, Observations]:
    """The published means, for W2/slip one synthetic set at ``truth`` (seed 0, σ 5 %), and
    ``yours`` when given (its curves left out: J1 is what the posteriors here score); for a
    problem of one's own (``published`` False), ``yours`` alone."""
    if not published:
        return {"yours": dataclasses.replace(yours, curves=None)}
    data = {"published": observations(name)}
    if yours is not None:
        data["yours"] = dataclasses.replace(yours, curves=None)
    if (name, law) == ("W2", "slip"):
        i = int(np.argmin(np.abs(reference_map.b - truth[0])))
        j = int(np.argmin(np.abs(reference_map.log10_lc - np.log10(truth[1]))))
        if reference_map.cycle[i, j]:
            data["synthetic"] = synthetic(float(reference_map.recurrence_s[i, j]),
                                          float(reference_map.friction_drop[i, j]), 0.05, 0)
    return data


def _zoom(coarse: MetricMap, data: dict) -> tuple[tuple, tuple]:
    """The box of the coarse nodes where any data set's density is within ZOOM_DENSITY of its
    maximum, padded by one node and clipped to the grid (the whole grid when no node has a
    cycle)."""
    keep = np.zeros(coarse.cycle.shape, bool)
    if coarse.cycle.any():
        for obs in data.values():
            J = coarse.j1(obs)
            keep |= coarse.cycle & (J - J[coarse.cycle].min() <= -2 * np.log(ZOOM_DENSITY))
    else:
        keep[:] = True
    ii, jj = np.nonzero(keep)
    nb, nl = len(coarse.b) - 1, len(coarse.log10_lc) - 1
    i0, i1 = max(ii.min() - 1, 0), min(ii.max() + 1, nb)
    j0, j1 = max(jj.min() - 1, 0), min(jj.max() + 1, nl)
    hb = (coarse.b[1] - coarse.b[0]) / 2
    hl = (coarse.log10_lc[1] - coarse.log10_lc[0]) / 2
    return ((coarse.b[i0] - hb, coarse.b[i1] + hb),
            (10.0 ** (coarse.log10_lc[j0] - hl), 10.0 ** (coarse.log10_lc[j1] + hl)))


def compare(ref: GridPosterior, post: GridPosterior, frame=None) -> dict:
    """The comparison of a setting's grid posterior ``post`` with the reference's ``ref`` on the
    same grid: mean shifts in reference standard deviations, overlap Σ min(p, q), Jaccard index
    of the 95 % HPD sets (NaN where either posterior is not ``ok``, and a shift NaN where the
    reference's sd is 0: a posterior on one node, which the grid does not resolve). ``frame``:
    the grid is a frame's (:func:`benchmarks.inversion.zoom.frame_map`), its moments read back
    in (b, log10 Lc)."""
    if not (ref.ok and post.ok):
        return {"mean_shift_b_sd": np.nan, "mean_shift_log10_lc_sd": np.nan,
                "overlap": 0.0 if ref.ok else np.nan, "hpd_jaccard": np.nan}
    (rm, rs), (pm, _) = _moments(ref, frame), _moments(post, frame)
    union = (post.hpd | ref.hpd).sum()
    return {"mean_shift_b_sd": _in_sd(pm["b"] - rm["b"], rs["b"]),
            "mean_shift_log10_lc_sd": _in_sd(pm["log10_lc"] - rm["log10_lc"], rs["log10_lc"]),
            "overlap": float(np.minimum(post.mass, ref.mass).sum()),
            "hpd_jaccard": float((post.hpd & ref.hpd).sum() / union)}


def _moments(post: GridPosterior, frame=None) -> tuple[dict, dict]:
    """The mean and sd of b and log10 Lc of a grid posterior (of a frame's grid: read back)."""
    return (post.mean, post.std) if frame is None else frame_moments(post, frame)


def _in_sd(shift: float, sd: float) -> float:
    """``shift`` in units of ``sd``; NaN for a zero or undefined sd (no division by it)."""
    return float(shift / sd) if np.isfinite(sd) and sd > 0 else float("nan")


def posterior_cost(small: MetricMap, big: MetricMap, solves: int = POSTERIOR_SOLVES) -> float:
    """s for ``solves`` solves in one ensemble, from two maps of one setting: the small map's
    wall time (what an ensemble costs whatever its size, with its few solves) plus the big
    map's extra wall time per extra solve for the rest."""
    if big.n_solves <= small.n_solves:
        raise ValueError(f"the big map must have more solves than the small one, got "
                         f"{big.n_solves} and {small.n_solves}")
    per = max(big.run_wall_s - small.run_wall_s, 0.0) / (big.n_solves - small.n_solves)
    return small.run_wall_s + (solves - small.n_solves) * per


def same_inference(c: dict) -> bool:
    """The rule of the module docstring on :func:`compare`'s values (``overlap_box``: the
    whole-box overlap, NaN when the reference has no posterior on the whole-box grid)."""
    box = c.get("overlap_box", np.nan)
    return bool(abs(c["mean_shift_b_sd"]) <= SHIFT_SD
                and abs(c["mean_shift_log10_lc_sd"]) <= SHIFT_SD
                and c["overlap"] >= MIN_OVERLAP and (np.isnan(box) or box >= MIN_OVERLAP))


def _best_fit(problem, obs, algorithm, m: MetricMap, box, workers, wall_budget, frame=None):
    """(b, log10 Lc, converged, the fit) of the least-squares fit started at the map's best node
    (a frame's map: that node read back in (b, log10 Lc))."""
    if not m.cycle.any():
        return np.nan, np.nan, False, None
    J = m.j1(obs)
    i, j = np.unravel_index(np.argmin(J), J.shape)
    x = (m.b[i], m.log10_lc[j]) if frame is None else frame.to_x([m.b[i], m.log10_lc[j]])[0]
    res = fit(Misfit(problem, obs, algorithm, wall_budget=wall_budget, workers=workers), *box,
              start=(x[0], 10.0 ** x[1]))
    return res.b, np.log10(res.lc), bool(res.success), res


def _framed(everyone, maps, obs, where, n, workers, wall_budget, say):
    """The reference's least-squares fit on ``obs`` and, when the zoom's grid does not resolve
    the reference's posterior (fewer than :data:`MIN_NODES_PER_SD` nodes per sd, or an sd off
    the Gauss–Newton one by more than :data:`~benchmarks.inversion.zoom.SD_FACTOR`) while the
    fit's Gauss–Newton frame (± :data:`FRAME_HALF` σ) lies inside the box: that frame and every
    setting's map on it (:func:`benchmarks.inversion.zoom.frame_map`); else no frame."""
    problem, box, _, grid = where
    reference = everyone[0]
    m = maps[reference.label]
    ref_fit = _best_fit(problem, obs, reference.algorithm, m, box, workers, None)
    frame = None if ref_fit[3] is None else frame_of(ref_fit[3])
    if frame is None:
        return ref_fit, None, maps
    frame = Frame(frame.centre, frame.scale, FRAME_HALF)
    post = m.posterior(obs)
    per = [post.std[k] / (g[1] - g[0]) for k, g in zip(("b", "log10_lc"), grid)]
    ratio = [post.std["b"] / ref_fit[3].sigma_b,
             post.std["log10_lc"] / ref_fit[3].sigma_log10_lc]
    resolved = post.ok and min(per) >= MIN_NODES_PER_SD and all(
        1 / SD_FACTOR <= r <= SD_FACTOR for r in ratio)
    narrow = (2 * frame.extent() < np.diff(
        [box[0], np.log10(box[1])], axis=1)[:, 0]).all()
    if resolved or not narrow:
        return ref_fit, None, maps
    framed = {}
    for c in everyone:
        say(f"{problem.name or 'problem'}: {c.label} on the frame of the reference's fit")
        budget = None if c.family in ("reference", "floor") else wall_budget
        framed[c.label] = frame_map(problem, c.algorithm, frame, *box, n, wall_budget=budget,
                                    workers=workers)
    return ref_fit, frame, framed


def solver_effect(settings: list[Candidate], reference: Algorithm, floor: Algorithm,
                  windows=("W1", "W2", "W3", "W4"), laws=("slip", "aging"), n: int = 31,
                  check_n: int | None = None, workers: int | None = None,
                  wall_budget: float | None = 5.0, progress=None,
                  yours: Observations | None = None, own=None) -> pd.DataFrame:
    """One row per (window, law, data set, setting) with the comparison of the module
    docstring; ``floor``: a second tight setting of another method, compared like the others.
    ``yours``: a data set of one's own (an observations file of ``rsfbench observe`` read),
    inverted on every window and law beside the others as the data set ``yours``.
    ``check_n``: nodes per parameter of the whole-box grid (default n // 2). ``wall_budget``:
    s per solve of a candidate (a solve over it is a failed node). ``progress``: a callable
    given a line of text per map, or None. ``own`` = (label, problem, (b_range, lc_range)): a
    problem of one's own with its prior box, inverted (``yours`` alone) beside the windows."""
    say = progress or (lambda text: None)
    if isinstance(n, bool) or not isinstance(n, int) or n < 3:
        # the posterior's cost compares the fine map with a 2 × 2 one: it must have more nodes
        raise ValueError(f"n must be an integer of at least 3, got {n!r}")
    check_n = check_n or max(n // 2, 5)
    everyone = [Candidate("reference", f"{reference.name} {_tol(reference)}", reference),
                Candidate("floor", f"{floor.name} {_tol(floor)}", floor), *settings]
    rows, warmed = [], set()
    for name, law, problem, box, (b0, lc0), published in _cases(windows, laws, yours, own):
        coarse = metric_map(problem, reference, *box_grid(*box, n, n, through=(b0, lc0)),
                            workers=workers)
        data = _datasets(name, law, coarse, (b0, lc0), yours, published)
        zoom = _zoom(coarse, data)
        grid, check = box_grid(*zoom, n, n), box_grid(*box, check_n, check_n)
        inside = ((check[0] >= zoom[0][0]) & (check[0] <= zoom[0][1]))[:, None] & (
            (check[1] >= np.log10(zoom[1][0])) & (check[1] <= np.log10(zoom[1][1])))[None]
        maps, checks, smalls = {}, {}, {}
        for c in everyone:
            say(f"{name}/{law}: {c.label}")
            budget = None if c.family in ("reference", "floor") else wall_budget
            if c.label not in warmed:         # compile out of the timed map (docstring)
                metric_map(problem, c.algorithm, *box_grid(*box, 2, 2), wall_budget=budget,
                           workers=1)
                warmed.add(c.label)
            smalls[c.label] = metric_map(problem, c.algorithm, *box_grid(*zoom, 2, 2),
                                         wall_budget=budget, workers=workers)
            maps[c.label] = metric_map(problem, c.algorithm, *grid, wall_budget=budget,
                                       workers=workers)
            checks[c.label] = metric_map(problem, c.algorithm, *check, wall_budget=budget,
                                         workers=workers)
        say(f"{name}/{law}: best fits")
        tail = {"zoom_b": f"{zoom[0][0]:.5f}:{zoom[0][1]:.5f}",
                "zoom_lc_um": f"{zoom[1][0] * 1e6:.3g}..{zoom[1][1] * 1e6:.3g}",
                "grid": f"{n}x{n}", "check_grid": f"{check_n}x{check_n}"}
        for key, obs in data.items():
            rows += _dataset_rows(everyone, (maps, checks, smalls), obs,
                                  (problem, box, inside, grid), n, workers, wall_budget,
                                  ({"window": name, "law": law, "data": key}, tail), say)
    table = pd.DataFrame(rows)
    if len(table):                       # the floor's verdict applies to its whole data set
        table["resolved"] = table.groupby(["window", "law", "data"], sort=False)[
            "resolved"].transform(lambda r: bool(r.dropna().all()) if r.notna().any() else False)
    return table


def _cases(windows, laws, yours, own) -> list:
    """``(name, law, problem, box, centre, published)`` of each window and law on the paper
    sweep's box, and of ``own`` (a problem of one's own with its box)."""
    from benchmarks.inversion.published import GRID, T_END, best_fit, grid_around
    cases = []
    for law in laws:
        for name in windows:
            b0, lc0 = best_fit(name, law)
            b_axis, lc_axis = grid_around(b0, lc0, **GRID[law])
            cases.append((name, law, preset(name, law=law, t_end=T_END[name]),
                          ((b_axis.min(), b_axis.max()), (lc_axis.min(), lc_axis.max())),
                          (b0, lc0), True))
    if own is not None:
        if yours is None:
            raise ValueError("a problem of one's own needs its observations (yours)")
        label, problem, box = own
        cases.append((label, problem.law.name, problem, box,
                      (float(np.mean(box[0])), float(np.sqrt(box[1][0] * box[1][1]))), False))
    return cases


def _dataset_rows(everyone, maps, obs, where, n, workers, wall_budget, labels, say):
    """The rows of one data set (:func:`_rows`), on the zoom's maps, or on the frame of the
    reference's fit when the zoom does not resolve its posterior (:func:`_framed`)."""
    problem, box, inside, grid = where
    maps, checks, smalls = maps
    ref_fit, frame, compared = _framed(everyone, maps, obs, where, n, workers, wall_budget, say)
    head, tail = labels
    tail = {**tail, "zoom_kind": "nodes of the zoom"}
    if frame is not None:
        check = (checks[everyone[0].label].b, checks[everyone[0].label].log10_lc)
        zc = frame.to_z(np.stack(np.meshgrid(*check, indexing="ij"), -1).reshape(-1, 2))
        inside = (np.abs(zc) <= frame.half).all(axis=1).reshape(len(check[0]), len(check[1]))
        z = compared[everyone[0].label].b
        grid = (z, z)
        ext = frame.extent()
        tail = {**tail, "zoom_kind": f"frame of the reference's fit (± {frame.half:g} sd)",
                "zoom_b": f"{frame.centre[0] - ext[0]:.7f}:{frame.centre[0] + ext[0]:.7f}",
                "zoom_lc_um": f"{10 ** (frame.centre[1] - ext[1]) * 1e6:.4g}.."
                              f"{10 ** (frame.centre[1] + ext[1]) * 1e6:.4g}"}
    return _rows(everyone, (compared, checks, smalls, maps), obs,
                 (problem, box, inside, grid, frame, ref_fit), workers, wall_budget,
                 (head, tail))


def _rows(everyone, maps, obs, where, workers, wall_budget, labels) -> list[dict]:
    """A row per setting of ``everyone`` (the reference first, then the floor) on the data
    ``obs``: its comparison with the reference's inversion on the compared maps, the whole
    box's, the small maps of the cost and the zoom's (``maps``); ``where``: the problem, its
    box, the whole-box nodes inside the compared grid, that grid's axes, its frame (or None)
    and the reference's fit; ``labels``: the columns before and after."""
    maps, checks, smalls, costs = maps
    problem, box, inside, grid, frame, ref_fit = where
    head, tail = labels
    reference = everyone[0]
    ref, ref_box = maps[reference.label].posterior(obs), checks[reference.label].posterior(obs)
    ref_sd = _moments(ref, frame)[1]
    floor_same, rows = None, []
    for c in everyone:
        m = maps[c.label]
        post, post_box = m.posterior(obs), checks[c.label].posterior(obs)
        budget = None if c.family in ("reference", "floor") else wall_budget
        fb, fl, fit_ok, _ = (ref_fit if c.family == "reference" else
                             _best_fit(problem, obs, c.algorithm, m, box, workers, budget, frame))
        cmp = compare(ref, post, frame)
        cmp["overlap_box"] = (float(np.minimum(post_box.mass, ref_box.mass).sum())
                              if ref_box.ok else np.nan)
        row = {**head, "family": c.family, "setting": c.label, "integrator": c.algorithm.name,
               "posterior_ok": post.ok, **cmp,
               "outside_mass": (float(post_box.mass[~inside].sum()) if post_box.ok
                                else np.nan)}
        mean, sd = _moments(post, frame)
        for p, f, rf in (("b", fb, ref_fit[0]), ("log10_lc", fl, ref_fit[1])):
            row[f"mean_{p}"], row[f"std_{p}"], row[f"fit_{p}"] = mean[p], sd[p], f
            row[f"fit_shift_{p}_sd"] = _in_sd(f - rf, ref_sd[p]) if ref.ok else np.nan
        row["fit_ok"] = fit_ok
        row["n_cycle_nodes"] = int(m.cycle.sum())
        row["n_failed"] = m.n_failed + checks[c.label].n_failed
        cost = costs[c.label]            # the zoom's map, the same nodes for every data set
        row["wall_per_solve_ms"] = 1e3 * cost.wall_s / cost.n_solves
        row["posterior_cost_s"] = posterior_cost(smalls[c.label], cost)
        row["nfev_per_solve"] = cost.nfev / cost.n_solves
        row["indistinguishable"] = bool(post.ok and ref.ok and same_inference(cmp))
        if c.family == "floor":
            floor_same = row["indistinguishable"]
        row["resolved"] = floor_same
        # nodes per sd along the grid's axes (a frame's: its z)
        row["ref_nodes_per_sd_b"] = ref.std["b"] / (grid[0][1] - grid[0][0])
        row["ref_nodes_per_sd_log10_lc"] = ref.std["log10_lc"] / (grid[1][1] - grid[1][0])
        rows.append({**row, **tail})
    return rows


def _tol(algorithm: Algorithm) -> str:
    rtol = getattr(algorithm, "rtol", None)
    return f"{rtol:g}" if rtol is not None else ""


def recommendation(table: pd.DataFrame) -> pd.DataFrame:
    """Per window/law/data set and over all: the cheapest setting (by wall time per solve)
    whose inversion is indistinguishable from the reference's (the reference and the floor
    themselves are not candidates), with its cost per posterior; none for a data set whose
    comparison is not resolved (``resolved`` False: the floor itself differs)."""
    cands = table[~table.family.isin(["reference", "floor"])]
    rows = []
    for key, group in cands.groupby(["window", "law", "data"], sort=False):
        resolved = bool(group.resolved.all()) if "resolved" in group else True
        ok = group[group.indistinguishable].sort_values("wall_per_solve_ms")
        rows.append({"window": key[0], "law": key[1], "data": key[2],
                     **(_pick(ok.iloc[0]) if len(ok) and resolved else _none()),
                     "resolved": resolved})
    if "resolved" in cands:
        cands = cands.assign(indistinguishable=cands.indistinguishable & cands.resolved)
    every = cands.groupby("setting").agg(all_ok=("indistinguishable", "all"),
                                         wall_per_solve_ms=("wall_per_solve_ms", "mean"),
                                         posterior_cost_s=("posterior_cost_s", "mean"),
                                         family=("family", "first"))
    ok = every[every.all_ok].sort_values("wall_per_solve_ms")
    overall = ({"setting": ok.index[0], "family": ok.iloc[0].family,
                "wall_per_solve_ms": ok.iloc[0].wall_per_solve_ms,
                "posterior_cost_s": ok.iloc[0].posterior_cost_s} if len(ok) else _none())
    rows.append({"window": "all", "law": "all", "data": "all", **overall,
                 "resolved": bool(all(r["resolved"] for r in rows))})
    return pd.DataFrame(rows)


def _pick(row) -> dict:
    return {"setting": row.setting, "family": row.family,
            "wall_per_solve_ms": row.wall_per_solve_ms, "posterior_cost_s": row.posterior_cost_s}


def _none() -> dict:
    return {"setting": None, "family": None, "wall_per_solve_ms": np.nan,
            "posterior_cost_s": np.nan}


def write_solver_effect(out, n: int = 31, windows=("W1", "W2", "W3", "W4"),
                        laws=("slip", "aging"), study_csv=None,
                        progress: bool = False, yours: Observations | None = None,
                        own=None, quick: bool = False, command: str | None = None
                        ) -> pd.DataFrame:
    """The solver-effect table (:func:`solver_effect`) with the candidates of the full work-precision study ``study_csv`` (default
    ``out/wp_full.csv``; ``quick``: :data:`QUICK_LADDERS` and the paper's ETD2 only), the
    reference Rodas5P and the floor Exprb43 at rtol = atol = 1e−9; write
    ``out/solver_effect.*`` (the table, the recommendation, the report ``solver_effect.md`` and
    its figure). ``own``: a problem of one's own (:func:`solver_effect`); ``command``: the
    command line the report names (default: the study of ``make reproduce-full``)."""
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
                  f"{ref.mean_b:.7g} ± {ref.std_b:.2g}, log10 Lc = {ref.mean_log10_lc:.5g} ± "
                  f"{ref.std_log10_lc:.2g} ({ref.ref_nodes_per_sd_b:.1f} and "
                  f"{ref.ref_nodes_per_sd_log10_lc:.1f} nodes per sd); compared on the "
                  f"{ref.zoom_kind}: b {ref.zoom_b}, Lc "
                  f"{ref.zoom_lc_um} µm; the reference's failed solves: {ref.n_failed}; "
                  f"resolved: {'yes' if ref.resolved else '**no**'}.\n\n",
                  markdown_table(t)]
    parts.append(f"\nCommand: `{command}`.\n" if command else
                 "\nCommand: `rsfbench study solver-effect` (a study of "
                 "`make reproduce-full`).\n")
    return "".join(parts)


def _plot_solver_effect(table, path: Path, min_overlap: float) -> None:
    from matplotlib.figure import Figure        # deferred: rsfbench starts without matplotlib
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
