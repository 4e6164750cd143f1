"""The targets for ensembles, measured: every figure reported, met or missed.

* **21 × 21 on W2** (40 s a point, the setting ``rsfbench sweep`` takes for ΔT to 1e−3: the
  recommendation raced against the front's near-ties on the grid's box): the ensemble
  on 1 and 2 numba threads (minimum of ``repeats`` runs after a warm-up, no store), beside the
  same points solved stand-alone, one :func:`integrators.solve` each (Σ of their own wall times).
  Targets: ≤ 0.5 s on 2 cores, 2 threads ≥ 1.8× one, per-point wall on 2 threads within 1.2× of
  the stand-alone solve divided by 2. The same points in a plain loop of the fastest compiled
  peer (the quick study's fastest peer setting reaching the same level: one
  :func:`integrators.solve` per point, ``max_points=2``, one thread, as its users would loop),
  timed in the same run; target: the ensemble at least 2× the loop on the same cores (1 thread
  each), and on 2 threads against the loop too.
* **Accuracy on the grid's own points**, not only on the study's two problems: the recurrence
  interval ΔT of every point against two references (Rodas5P and RadauIIA5 at rtol = atol =
  1e−10, which must agree to 1e−6 on a point for it to count: points whose class or ΔT differ
  between them — long transients, near-chaotic cycles — are left out and counted). Reported for
  the sweep's setting and the peer, and for every own stiff method with a batch kernel at
  :data:`CANDIDATE_TOLS` (2 threads, minimum of ``repeats``): the fastest whose worst ΔT error
  over the points is within 1e−3 is the "fastest own setting" the 0.5 s target is judged on.
* **Stopped on a settled cycle**: the sweep's setting again with ``settle`` =
  :data:`SETTLE` (each point stops at the end of the event where its cycle has settled:
  :func:`integrators.solve`'s ``settle``): its walls, its ΔT errors on the same points and
  whether it equals its stand-alone solves (with the same ``settle``), to the bit.
* **10⁵ points** (W2, 20 s a point, the recommendation for 1e−3) into a Parquet store,
  uninterrupted; then
  the same ensemble in a fresh store, in a subprocess killed (SIGKILL) at ``kills`` random
  moments of the work (after a random number of finished chunks, plus a random part of a
  chunk's time) and restarted each time, then finished: the same table (every column but the wall
  times), each point once. Targets: ≤ 3 min, store ≤ 50 MB.
* **10⁴ points on a local Dask cluster** (a scheduler and 2 one-thread workers on 127.0.0.1,
  started here and stopped after): the table against the local one, and the overhead per point.

``rsfbench study ensemble-scaling`` writes ``ensemble_scaling.json`` and ``.md``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.devtools.recommendation import recommended
from benchmarks.devtools.work_precision import STUDY_CSV, algorithm_at, read_study, recommend
from benchmarks.ensemble import CHUNK_SIZE, ensemble, grid, point_problems, point_rows, read_store
from benchmarks.inversion.published import B_STEP, best_fit
from benchmarks.inversion.solver_check import recommended_on_box
from benchmarks.records.files import atomic_write
from benchmarks.records.provenance import provenance
from benchmarks.records.report import fmt, jsonable, markdown_table
from benchmarks.studies.study import Study, markdown_file
from integrators import REGISTRY, RadauIIA5, Rodas5P, solve
from problems import window

__all__ = ["STUDY", "ensemble_scaling", "same_table", "TARGETS", "fastest_peer"]

TARGETS = {"grid_wall_s": 0.5, "thread_speedup": 1.8, "per_point_ratio": 1.2,
           "big_wall_s": 180.0, "big_store_mb": 50.0, "peer_loop_ratio": 2.0}
#: the ΔT error level of the grid's setting, relative
LEVEL = 1e-3
#: rtol = atol of the own settings tried on the grid's points
CANDIDATE_TOLS = (3e-3, 1e-3, 3e-4, 1e-4)
#: the references' setting, and how closely they must agree on a point's ΔT for it to count
REFERENCE_TOL, REFERENCES_AGREE = 1e-10, 1e-6
#: the settled-cycle stop timed beside the full runs: a tenth of the cycle search's 1e−3
SETTLE = 1e-4


def fastest_peer(level: float, csv=STUDY_CSV):
    """``(algorithm, reason)``: the quick study's fastest setting of a compiled peer (any
    library but the project's, compiled right-hand side) reaching ``level`` on every problem,
    or ``(None, why not)``."""
    path = Path(csv)
    if not path.exists():
        return None, f"no work-precision study at {path}"
    df = read_study(path)
    others = REGISTRY.select(exclude=("own",))
    peers = [n for n in df.integrator.unique() if n in others]
    advice = recommend(df[df.integrator.isin(peers) & (df.rhs_tier == "numba")], [level])
    advice = advice.iloc[0]
    if pd.isna(advice.get("integrator")):
        return None, f"no compiled peer of {path.name} reaches {level:g} on every problem"
    return (algorithm_at(advice.integrator, advice.rhs_tier, float(advice.setting)),
            f"{advice.integrator} at {advice.setting:g} (worst {advice.worst_error:.2g})")


def _time_peer_loop(peer, n, repeats):
    """A plain loop of ``peer`` over the grid's points: min wall over ``repeats`` (s)."""
    base = window("W2", "slip", t_end=40.0)
    points = _grid21(n)
    names, values = tuple(points), np.column_stack(list(points.values()))
    solve(point_problems(base, names, values[:1])[0], peer, max_points=2)    # warm
    walls, failed = [], 0
    for _ in range(repeats):
        start = time.perf_counter()          # the problems' making timed, as the ensemble's
        runs = [solve(problem, peer, max_points=2)
                for problem in point_problems(base, names, values)]
        walls.append(time.perf_counter() - start)
        failed = sum(not r.success for r in runs)
    return min(walls), failed


def _sweep_choice(n: int):
    """``(algorithm, why)``: what ``rsfbench sweep`` takes for the grid without --integrator:
    the recommendation for :data:`LEVEL`, raced against the front's near-ties on the grid's
    box (:func:`benchmarks.inversion.solver_check.recommended_on_box`). The sweep then checks
    it against two references on the box (σ/10 of its observations and the level), which
    may tighten it: not done here, where there are no observations."""
    points = _grid21(n)
    return recommended_on_box(window("W2", "slip", t_end=40.0), LEVEL,
                              (float(points["b"].min()), float(points["b"].max())),
                              (float(points["lc"].min()), float(points["lc"].max())))


def _grid21(n: int):
    b0, lc0 = best_fit("W2", "slip")
    b = np.round(b0 + B_STEP * np.arange(-(n // 2), n - n // 2), 12)
    return grid(b=b, lc=np.geomspace(lc0 / 10, lc0 * 10, n))


def _big_grid(n: int):
    """n points (about √n × √n) over b 0.0084–0.0104 and Lc 0.03–3 µm (log) on W2."""
    nb = max(1, int(round(np.sqrt(n))))
    return grid(b=np.linspace(0.0084, 0.0104, nb), lc=np.geomspace(3e-8, 3e-6, -(-n // nb)))


def same_table(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    """Are two ensemble tables the same, to the bit, in every column but the wall times?"""
    cols = [c for c in a.columns if c != "wall_s"]
    return (list(a.columns) == list(b.columns) and len(a) == len(b)
            and all(a[c].equals(b[c]) for c in cols))


def _walls(algorithm, base, points, repeats, threads=(1, 2), settle=None):
    """``({threads: min wall over repeats}, the last table)`` of the ensemble, after a warm-up."""
    ensemble(base, algorithm, {k: v[:2] for k, v in points.items()}, progress=False)   # warm
    walls = {}
    for workers in threads:
        runs = [ensemble(base, algorithm, points, workers=workers, progress=False,
                         settle=settle) for _ in range(repeats)]
        walls[workers] = min(r.attrs["wall_s"] for r in runs)
    return walls, runs[-1]


def _references(base, points):
    """``(reference table, the points that count, the references' worst disagreement there)``:
    two independent methods at :data:`REFERENCE_TOL`; a point counts where both classify it the
    same, both have a ΔT and they agree on it to :data:`REFERENCES_AGREE`."""
    tol = dict(rtol=REFERENCE_TOL, atol=REFERENCE_TOL)
    a = ensemble(base, Rodas5P(**tol), points, workers=2, progress=False)
    b = ensemble(base, RadauIIA5(**tol), points, workers=2, progress=False)
    gap = ((a.recurrence_s - b.recurrence_s) / a.recurrence_s).abs()
    counts = ((a.classification == b.classification) & a.recurrence_s.notna()
              & (gap <= REFERENCES_AGREE) & (a.retcode == "Success") & (b.retcode == "Success"))
    return a, counts, float(gap[counts].max()) if counts.any() else float("nan")


def grid_errors(table: pd.DataFrame, ref: pd.DataFrame, counts: pd.Series) -> dict:
    """The relative ΔT error of ``table`` against ``ref`` over the points that count: worst (a
    point without a ΔT, or failed, counts as inf), 95th percentile, and the fraction of all
    points classified as the reference does."""
    err = ((table.recurrence_s - ref.recurrence_s) / ref.recurrence_s).abs()
    err = err.where(table.retcode == "Success", np.inf)[counts].fillna(np.inf)
    return {"worst_dt_error": float(err.max()),
            "p95_dt_error": float(err.quantile(0.95, interpolation="higher")),
            "points_compared": int(counts.sum()),
            "same_class": float((table.classification == ref.classification).mean())}


def _settings_on_grid(base, points, ref, counts, repeats):
    """Every own stiff method with a batch kernel at :data:`CANDIDATE_TOLS` on the grid (the
    explicit CashKarp45 crawls through the stiff points): its wall on
    2 threads and its ΔT errors; and the fastest within :data:`LEVEL` (None if none is)."""
    names = [n for n, c in REGISTRY.items()
             if getattr(c, "batch_kernel", None) is not None and c.stiff]
    rows = []
    for name in names:
        for tol in CANDIDATE_TOLS:
            walls, table = _walls(algorithm_at(name, "numba", tol), base, points, repeats, (2,))
            rows.append({"integrator": name, "rtol": tol, "wall_2_threads_s": walls[2],
                         **grid_errors(table, ref, counts)})
    within = [r for r in rows if r["worst_dt_error"] <= LEVEL]
    return rows, (min(within, key=lambda r: r["wall_2_threads_s"]) if within else None)


def _time_grid(algorithm, n, repeats, progress, settings=True):
    """``(summary, (reference table, points that count))`` of the grid (module docstring)."""
    base = window("W2", "slip", t_end=40.0)
    points = _grid21(n)
    walls, table = _walls(algorithm, base, points, repeats)
    names, values = tuple(points), np.column_stack(list(points.values()))
    single = point_rows(point_problems(base, names, values), algorithm, names, values)
    n_points = len(table)
    standalone = float(single.wall_s.sum())
    per_point = walls[2] / n_points
    ref, counts, agree = _references(base, points)
    accuracy = {"references": f"Rodas5P and RadauIIA5 at {REFERENCE_TOL:g}",
                "references_agree": agree, "points_left_out": int((~counts).sum()),
                "recommended": grid_errors(table, ref, counts)}
    extra = {}
    if settings:
        accuracy["settings"], accuracy["fastest_within_level"] = _settings_on_grid(
            base, points, ref, counts, repeats)
        extra["settled"] = _settled(algorithm, base, points, repeats, ref, counts, table)
    return {**extra, "n_points": n_points, "wall_1_thread_s": walls[1],
            "wall_2_threads_s": walls[2], "accuracy": accuracy,
            "thread_speedup": walls[1] / walls[2],
            "sum_batch_solve_s": float(table.wall_s.sum()),
            "sum_standalone_solve_s": standalone,
            "per_point_wall_2_threads_s": per_point,
            "standalone_per_point_per_core_s": standalone / n_points / 2,
            "per_point_ratio": per_point / (standalone / n_points / 2),
            "classes": table.classification.value_counts().to_dict(),
            "same_as_standalone": same_table(table, single)}, (ref, counts)


def _settled(algorithm, base, points, repeats, ref, counts, full) -> dict:
    """The grid with ``settle`` = :data:`SETTLE`: walls on 1 and 2 threads, ΔT errors, how many
    points stopped early and where, the classes it changed against the full runs ``full``, and
    whether it equals its stand-alone solves."""
    walls, table = _walls(algorithm, base, points, repeats, settle=SETTLE)
    names, values = tuple(points), np.column_stack(list(points.values()))
    single = point_rows(point_problems(base, names, values), algorithm, names, values,
                        settle=SETTLE)
    stopped = table.message.str.startswith("settled")
    changed = table.classification != full.classification
    return {"settle": SETTLE, "wall_1_thread_s": walls[1], "wall_2_threads_s": walls[2],
            "accuracy": grid_errors(table, ref, counts), "points_stopped": int(stopped.sum()),
            "sum_batch_solve_s": float(table.wall_s.sum()),
            "classes_changed": [f"{a} -> {b}" for a, b in zip(full.classification[changed],
                                                               table.classification[changed])],
            "same_as_standalone": same_table(table, single)}


_CHILD = """
import sys
from benchmarks.studies.ensemble_scaling import _big_run
_big_run(sys.argv[1], int(sys.argv[2]), progress=False)
"""


def _big_run(store, n, progress=True, workers=2):
    algorithm, _ = recommended(1e-3)
    return ensemble(window("W2", "slip", t_end=20.0), algorithm, _big_grid(n), store=store,
                    workers=workers, progress=progress)


def _time_big(n, kills, seed, progress):
    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory() as tmp:
        whole_dir, killed_dir = Path(tmp) / "whole", Path(tmp) / "killed"
        start = time.perf_counter()
        whole = _big_run(whole_dir, n, progress=progress)
        wall = time.perf_counter() - start
        size = sum(f.stat().st_size for f in whole_dir.iterdir())
        # a kill lands at a random moment of the work: once the store holds a random number of
        # finished chunks (the kills' targets drawn without repeats, so each finds work left),
        # plus a random part of a chunk's time, so that it hits a chunk in flight
        n_chunks = whole.attrs["chunks"]
        targets = np.sort(rng.choice(np.arange(1, n_chunks - 1), size=kills, replace=False))
        per_chunk = wall / n_chunks
        env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
        at_kill, landed = [], []
        for target in targets:
            child = subprocess.Popen([sys.executable, "-c", _CHILD, str(killed_dir), str(n)],
                                     env=env, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
            while child.poll() is None and _chunks_in(killed_dir) < target:
                time.sleep(0.01)
            time.sleep(rng.uniform(0.0, per_chunk))
            landed.append(child.poll() is None)          # still running: the kill hit it
            child.send_signal(signal.SIGKILL)
            child.wait()
            at_kill.append(_chunks_in(killed_dir))
        resumed = _big_run(killed_dir, n, progress=progress)
        stored = read_store(killed_dir)
        names = ["b", "lc"]
        return {"n_points": len(whole), "wall_s": wall, "store_mb": size / 1e6,
                "classes": whole.classification.value_counts().to_dict(),
                "kill_targets_chunks": targets.tolist(), "kills_landed": landed,
                "chunks_done_at_kills": at_kill,
                "chunks": whole.attrs["chunks"],
                "points_resumed_after_kills": resumed.attrs["n_resumed"],
                "same_table_after_kills": same_table(resumed, whole),
                "stored_rows": len(stored),
                "stored_duplicates": int(stored.duplicated(subset=names).sum()),
                "stored_equals_table": same_table(stored, whole)}


def _chunks_in(directory: Path) -> int:
    return len(list(directory.glob("_c*.parquet"))) if directory.exists() else 0


def _time_dask(n, progress):
    from distributed import LocalCluster
    algorithm, _ = recommended(1e-3)
    base, points = window("W2", "slip", t_end=20.0), _big_grid(n)
    local = ensemble(base, algorithm, points, workers=2, progress=progress)
    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", processes=True,
                      dashboard_address=None) as cluster:
        ensemble(base, algorithm, {k: v[:2] for k, v in points.items()}, progress=False,
                 scheduler=cluster.scheduler_address)                       # warm the workers
        on_dask = ensemble(base, algorithm, points, scheduler=cluster.scheduler_address,
                           progress=progress)
    wall = on_dask.attrs["wall_s"]
    return {"n_points": len(on_dask), "wall_local_s": local.attrs["wall_s"], "wall_dask_s": wall,
            "sum_solve_s": float(on_dask.wall_s.sum()),
            "overhead_per_point_s": (2 * wall - float(on_dask.wall_s.sum())) / len(on_dask),
            "chunks": on_dask.attrs["chunks"], "same_as_local": same_table(on_dask, local)}


def ensemble_scaling(out, n: int = 21, big: int = 100_000, kills: int = 3, dask: int = 10_000,
                     repeats: int = 3, seed: int = 0, progress: bool = True,
                     study_csv=STUDY_CSV) -> dict:
    """Measure the three targets (module docstring); write ``out/ensemble_scaling.json``, ``.md``."""
    n_chunks = -(-len(_big_grid(big)["b"]) // CHUNK_SIZE) if big else 0
    if big and not kills <= n_chunks - 2:
        raise ValueError(f"kills = {kills} need at least {kills + 2} chunks of {CHUNK_SIZE} "
                         f"points, and big = {big} makes {n_chunks}: raise big or kill less")
    algorithm, why = _sweep_choice(n)
    grid_summary, (ref, counts) = _time_grid(algorithm, n, repeats, progress)
    summary = {"integrator": algorithm.name, "options": algorithm.options(),
               "integrator_choice": why, "targets": TARGETS,
               "grid": grid_summary}
    peer, peer_why = fastest_peer(LEVEL, study_csv)
    summary["peer"] = {"choice": peer_why}
    if peer is not None:
        wall, failed = _time_peer_loop(peer, n, repeats)
        points = _grid21(n)
        names, values = tuple(points), np.column_stack(list(points.values()))
        table = point_rows(point_problems(window("W2", "slip", t_end=40.0), names, values), peer,
                           names, values)
        summary["peer"].update(name=peer.name, loop_wall_s=wall, failed=failed,
                               accuracy=grid_errors(table, ref, counts),
                               ratio_1_thread=wall / summary["grid"]["wall_1_thread_s"],
                               ratio_2_threads=wall / summary["grid"]["wall_2_threads_s"])
    if big:
        summary["big"] = _time_big(big, kills, seed, progress)
    if dask:
        summary["dask"] = _time_dask(dask, progress)
    summary["provenance"] = provenance()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "ensemble_scaling.json", json.dumps(jsonable(summary), indent=2))
    atomic_write(out / "ensemble_scaling.md", scaling_markdown(summary))
    return summary


def _met(ok: bool) -> str:
    return "met" if ok else "**missed**"


def _grid_rows(g: dict, t: dict) -> list[dict]:
    """The grid's targets: its wall (and the fastest setting within the level), threads."""
    acc = g.get("accuracy", {})
    rec = acc.get("recommended")
    rows = [
        {"target": f"{g['n_points']} points (W2, 40 s each) on 2 cores, the setting "
                   "`rsfbench sweep` takes",
         "goal": f"≤ {t['grid_wall_s']} s", "measured": f"{fmt(g['wall_2_threads_s'])} s"
         + (f" (worst ΔT error {fmt(rec['worst_dt_error'])} on the points)" if rec else ""),
         "": _met(g["wall_2_threads_s"] <= t["grid_wall_s"])},
    ]
    if "settled" in g:
        st = g["settled"]
        rows.append({"target": f"the same, each point stopped on its settled cycle "
                               f"(settle = {st['settle']:g})",
                     "goal": f"≤ {t['grid_wall_s']} s",
                     "measured": f"{fmt(st['wall_2_threads_s'])} s (worst ΔT error "
                                 f"{fmt(st['accuracy']['worst_dt_error'])}; "
                                 f"{st['points_stopped']} points stopped early)",
                     "": _met(st["wall_2_threads_s"] <= t["grid_wall_s"]
                              and st["accuracy"]["worst_dt_error"] <= LEVEL)})
    if "settings" in acc:
        best = acc["fastest_within_level"]
        rows.append({"target": f"the fastest own setting with worst ΔT error ≤ {LEVEL:g} on "
                               "the points, on 2 cores",
                     "goal": f"≤ {t['grid_wall_s']} s",
                     "measured": (f"{fmt(best['wall_2_threads_s'])} s ({best['integrator']} at "
                                  f"{best['rtol']:g}, worst {fmt(best['worst_dt_error'])})"
                                  if best else "none within the level"),
                     "": _met(best is not None and best["wall_2_threads_s"] <= t["grid_wall_s"])})
    return rows + [
        {"target": "2 threads against 1", "goal": f"≥ {t['thread_speedup']}×",
         "measured": f"{fmt(g['thread_speedup'])}× ({fmt(g['wall_1_thread_s'])} s on 1)",
         "": _met(g["thread_speedup"] >= t["thread_speedup"])},
        {"target": "per-point wall (2 threads) / (stand-alone solve / 2)",
         "goal": f"≤ {t['per_point_ratio']}", "measured": fmt(g["per_point_ratio"]),
         "": _met(g["per_point_ratio"] <= t["per_point_ratio"])},
    ]


def _peer_row(peer: dict, t: dict) -> dict:
    goal = t.get("peer_loop_ratio", 2.0)
    return {"target": f"against a plain loop of {peer['choice']} (1 thread)",
            "goal": f"≥ {goal:g}× on 1 thread",
            "measured": f"{fmt(peer['ratio_1_thread'])}× on 1 thread, "
                        f"{fmt(peer['ratio_2_threads'])}× on 2 (loop "
                        f"{fmt(peer['loop_wall_s'])} s, {peer['failed']} failed"
                        + (f"; worst ΔT error {fmt(peer['accuracy']['worst_dt_error'])}"
                           if "accuracy" in peer else "") + ")",
            "": _met(peer["ratio_1_thread"] >= goal)}


def _big_rows(b: dict, t: dict) -> list[dict]:
    """The 10⁵-point run's targets: its wall, its store, and the kills it survived."""
    return [
        {"target": f"{b['n_points']} points (W2, 20 s each) on 2 cores",
         "goal": f"≤ {t['big_wall_s']:g} s", "measured": f"{fmt(b['wall_s'])} s",
         "": _met(b["wall_s"] <= t["big_wall_s"])},
        {"target": "its Parquet store", "goal": f"≤ {t['big_store_mb']:g} MB",
         "measured": f"{fmt(b['store_mb'])} MB", "": _met(b["store_mb"] <= t["big_store_mb"])},
        {"target": f"killed {sum(b['kills_landed'])}× mid-run (SIGKILL) and restarted",
         "goal": "same table, each point once",
         "measured": f"{'same' if b['same_table_after_kills'] else 'DIFFERENT'}; "
                     f"{b['stored_rows']} rows stored, {b['stored_duplicates']} duplicated",
         "": _met(b["same_table_after_kills"] and b["stored_equals_table"]
                  and b["stored_duplicates"] == 0 and all(b["kills_landed"]))},
    ]


def _dask_row(d: dict) -> dict:
    return {"target": f"{d['n_points']} points on a local Dask cluster (2 workers)",
            "goal": "the local table", "measured":
            f"{'same' if d['same_as_local'] else 'DIFFERENT'}; {fmt(d['wall_dask_s'])} s "
            f"(local {fmt(d['wall_local_s'])} s), overhead "
            f"{fmt(1e6 * d['overhead_per_point_s'])} µs/point",
            "": _met(d["same_as_local"])}


def _settings_lines(acc: dict) -> list[str]:
    """The ΔT error of every setting on the grid's points, with how it was measured."""
    rec = acc.get("recommended")
    table = pd.DataFrame([
        {"integrator": r["integrator"], "rtol": f"{r['rtol']:g}",
         "wall, 2 threads (s)": fmt(r["wall_2_threads_s"]),
         "worst ΔT error": fmt(r["worst_dt_error"]), "95th percentile": fmt(r["p95_dt_error"]),
         "same class": f"{r['same_class']:.1%}"} for r in acc["settings"]])
    return ["", f"ΔT error on the grid's points, relative, against {acc['references']} "
            f"(they agree to {fmt(acc['references_agree'])} on the "
            f"{rec['points_compared']} points compared; {acc['points_left_out']} points "
            "are left out, where the references differ in class or have no ΔT: long "
            "transients, near-chaotic cycles). A point compared where a setting has no ΔT "
            "(classified otherwise) or failed counts as an infinite error. \"same class\": "
            "the fraction of all points classified as the reference does.", "",
            markdown_table(table)]


def scaling_markdown(s: dict) -> str:
    g, t = s["grid"], s["targets"]
    acc = g.get("accuracy", {})
    rows = _grid_rows(g, t)
    peer = s.get("peer", {})
    if "loop_wall_s" in peer:
        rows.append(_peer_row(peer, t))
    if "big" in s:
        rows += _big_rows(s["big"], t)
    if "dask" in s:
        rows.append(_dask_row(s["dask"]))
    lines = [f"Integrator: {s['integrator_choice']}. Walls are the minimum of the repeats after "
             "a warm-up (the grid) or one run (10⁵, Dask); \"stand-alone\" is one "
             "`integrators.solve` per point, Σ of their own wall times "
             f"({fmt(g['sum_standalone_solve_s'])} s for the grid; the batch's own per-point "
             f"solves sum to {fmt(g['sum_batch_solve_s'])} s).", "",
             markdown_table(pd.DataFrame(rows))]
    if "settings" in acc:
        lines += _settings_lines(acc)
    if "settled" in g:
        st = g["settled"]
        lines += ["", f"Stopped on a settled cycle (`settle = {st['settle']:g}`: a point stops "
                  "at the end of the event where its last periods' four metrics repeat within "
                  "that tolerance, have changed by less than it since half its time, and by "
                  "at most half of what they changed from a quarter to half of it: "
                  "`integrators.core.cycles.settled`): "
                  f"{st['points_stopped']} of {g['n_points']} points stopped early; 1 thread "
                  f"{fmt(st['wall_1_thread_s'])} s, 2 threads {fmt(st['wall_2_threads_s'])} s; "
                  f"its solves sum to {fmt(st['sum_batch_solve_s'])} s. Worst ΔT error "
                  f"{fmt(st['accuracy']['worst_dt_error'])} (95th percentile "
                  f"{fmt(st['accuracy']['p95_dt_error'])}), same class as the reference "
                  f"{st['accuracy']['same_class']:.1%}; classes changed against the full runs: "
                  f"{', '.join(st['classes_changed']) or 'none'}; the same table as its "
                  f"stand-alone solves with the same `settle`: "
                  f"{'yes' if st['same_as_standalone'] else '**no**'}."]
    if "big" in s:
        b = s["big"]
        lines += ["", f"Each kill came once the store held a random number of finished chunks "
                  f"({', '.join(str(t) for t in b['kill_targets_chunks'])} of {b['chunks']}), "
                  "plus a random part of a chunk's time; finished chunks when it landed: "
                  f"{', '.join(str(c) for c in b['chunks_done_at_kills'])}. The final run "
                  f"resumed {b['points_resumed_after_kills']} points and ran the rest."]
    return "\n".join(lines) + "\n"


def run(out: Path, n: int, big: int, kills: int, dask: int, repeats: int, seed: int) -> None:
    ensemble_scaling(out, n=n, big=big, kills=kills, dask=dask, repeats=repeats, seed=seed,
                     study_csv=out / "wp_quick.csv", progress=False)


STUDY = Study("ensemble-scaling", "Ensembles at kernel speed (`ensemble_scaling.*`)", 140, run,
              report=markdown_file("ensemble_scaling.md"), plan="full", timed=True,
              settings={"n": 21, "big": 100_000, "kills": 3, "dask": 10_000, "repeats": 3,
                        "seed": 0},
              limits={"n": (2, 101), "big": (0, 10_000_000), "kills": (0, 100),
                      "dask": (0, 1_000_000), "repeats": (1, 100), "seed": (0, 2**32 - 1)},
              reads=("wp_quick.csv",), writes=("ensemble_scaling.json", "ensemble_scaling.md"),
              minutes=6)
