"""The own compiled engine against its speed targets, with numbalsoda's LSODA as the yardstick.

For each own adaptive method and tolerance (rtol = atol = 1e−2 … 1e−10) on the paper example and
W2/aging (40 s, two-speed loading): the relative error of the recurrence interval ΔT against the
cached two-solver reference (:mod:`benchmarks.devtools.reference`), the counters, and the wall time
(``Solution.stats.wall_s``: the solve without building the ``Solution``), the minimum over
``repeats`` runs after a warm-up, ``max_points=2``. A setting is *reliable* at a level when its
error and the error of every tighter tolerance of the same method are at most that level (a
lucky cancellation at a loose tolerance does not count). The yardstick, timed in the same run:
numbalsoda's ``lsoda`` called once over a 20,001-point grid at rtol = atol = 1e−6 with a numba
``cfunc`` right-hand side, as its users call it: no events, no restarts (so W2's two-speed
loading is not followed: it measures the machine, not an answer).

The Python side of a solve (the whole call less its compiled calls, ``Solution.meta
["kernel_s"]``), and Rodas5P's kernel against its twin in C
(:mod:`benchmarks.devtools.c_twin`: the same arithmetic, steps and events), interleaved in one
run, µs per step attempt.

Start-up, in fresh processes: ``import integrators``, the first solve after it (Rodas5P on the
paper example) and ``rsfbench simulate --preset paper-example --json``, with the numba cache
warm (the minimum of 3) and, for the first two, cold (a copy of the sources with no cache: every
kernel that solve needs is compiled).

``rsfbench study engine-speed`` writes ``engine_speed.csv`` (every setting),
``engine_speed_c_twin.csv`` and ``engine_speed.md`` (the targets, met or missed, and the
start-up times).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from numba import carray, cfunc

from benchmarks.devtools.errors import errors
from benchmarks.devtools.reference import reference
from benchmarks.records.files import atomic_write
from benchmarks.studies.study import Study, markdown_file
from integrators import REGISTRY, solve
from problems import paper_example, window
from problems.formulations import N_Q, form_vector, ode_rhs, to_ode_state

__all__ = ["STUDY", "engine_speed", "targets", "startup", "engine_speed_markdown", "write_engine_speed",
           "METHODS", "TOLERANCES", "python_side", "python_side_fresh", "c_twin_comparison"]

METHODS = ("Rosenbrock23", "Rodas5P", "RadauIIA5", "Exprb32", "Exprb43")
TOLERANCES = tuple(10.0 ** -k for k in range(2, 11))
#: the engine's speed targets: (problem, reliable ΔT error, wall time in ms)
TARGETS = (("paper-example", 1e-3, 0.3), ("paper-example", 1e-7, 1.0), ("W2/aging", 1e-3, 1.0))
#: the cost of a Rodas5P step attempt on the paper example, µs, events included
ATTEMPT_TARGET_US = 0.4


def _problems():
    return {"paper-example": paper_example(), "W2/aging": window("W2", "aging")}


def _lsoda_wall(problem, repeats: int) -> float:
    """numbalsoda's ``lsoda`` once over 20,001 points at 1e−6, slow loading throughout (s)."""
    from numbalsoda import lsoda, lsoda_sig

    @cfunc(lsoda_sig)
    def rhs(t, u, du, data):
        ode_rhs(carray(data, (N_Q,)), carray(u, (3,)), carray(du, (3,)))

    nd = problem.nondimensional()
    data = form_vector(nd, nd.e_slow)
    z0, grid = to_ode_state(nd.law_code, nd.beta, nd.x0), np.linspace(0.0, nd.tau_end, 20_001)
    walls = []
    for _ in range(repeats + 1):
        start = time.perf_counter()
        _, ok = lsoda(rhs.address, z0, grid, data=data, rtol=1e-6, atol=1e-6)
        walls.append(time.perf_counter() - start)
        if not ok:
            raise RuntimeError(f"numbalsoda's lsoda failed on {problem.name}")
    return min(walls[1:])


def _min_wall(problem, algorithm, repeats: int, **kw):
    solve(problem, algorithm, **kw)                       # compiled, cache loaded
    runs = [solve(problem, algorithm, **kw) for _ in range(repeats)]
    return min(s.stats.wall_s for s in runs), runs[-1]


def engine_speed(repeats: int = 5, progress: bool = False) -> tuple[pd.DataFrame, dict]:
    """Every setting (a row each) and the yardstick's walls per problem (s)."""
    rows, lsoda = [], {}
    for pname, problem in _problems().items():
        ref = reference(problem, progress=progress)
        lsoda[pname] = _lsoda_wall(problem, repeats)
        for name in METHODS:
            for tol in TOLERANCES:
                wall, sol = _min_wall(problem, REGISTRY[name](rtol=tol, atol=tol), repeats,
                                      max_points=2)
                err = errors(sol, ref)["err_recurrence"] if sol.reached_end else math.nan
                s = sol.stats
                rows.append(dict(problem=pname, method=name, tol=tol, err_dT=err,
                                 steps=s.steps, rejected=s.rejected, nfev=s.nfev, njev=s.njev,
                                 wall_ms=wall * 1e3,
                                 us_per_attempt=wall * 1e6 / max(1, s.steps + s.rejected),
                                 ratio_to_lsoda=wall / lsoda[pname]))
    table = pd.DataFrame(rows)
    # reliable at a level: this tolerance's error and every tighter one's are below it
    table["err_reliable"] = (table.sort_values("tol").groupby(["problem", "method"])["err_dT"]
                             .cummax().reindex(table.index))
    return table, lsoda


def targets(table: pd.DataFrame, lsoda: dict) -> pd.DataFrame:
    """The speed targets: the fastest reliable own setting per (problem, level), met or not."""
    out = []
    for pname, level, target_ms in TARGETS:
        ok = table[(table.problem == pname) & (table.err_reliable <= level)]
        best = ok.loc[ok.wall_ms.idxmin()] if len(ok) else None
        out.append(dict(
            target=f"{pname}, reliable ΔT error ≤ {level:g}", target_ms=target_ms,
            fastest=(f"{best.method} {best.tol:.0e}" if best is not None else "none"),
            wall_ms=best.wall_ms if best is not None else math.nan,
            err_dT=best.err_dT if best is not None else math.nan,
            lsoda_ms=lsoda[pname] * 1e3,
            ratio_to_lsoda=best.ratio_to_lsoda if best is not None else math.nan,
            attempts=int(best.steps + best.rejected) if best is not None else 0,
            us_per_attempt=best.us_per_attempt if best is not None else math.nan,
            met=bool(best is not None and best.wall_ms <= target_ms)))
    rodas = table[(table.problem == "paper-example") & (table.method == "Rodas5P")]
    out.append(dict(target="Rodas5P µs per step attempt, paper example (median over tolerances)",
                    target_ms=ATTEMPT_TARGET_US, fastest="Rodas5P",
                    wall_ms=float(np.median(rodas.us_per_attempt)), err_dT=math.nan,
                    lsoda_ms=lsoda["paper-example"] * 1e3, ratio_to_lsoda=math.nan,
                    attempts=0, us_per_attempt=math.nan,
                    met=bool(np.median(rodas.us_per_attempt) <= ATTEMPT_TARGET_US)))
    return pd.DataFrame(out)


#: the Python side of a solve (the whole call less its compiled calls), paper example, µs
PYTHON_SIDE_TARGET_US = 50.0


def python_side(repeats: int = 200, method: str = "Rodas5P", tol: float = 1e-3) -> dict:
    """The Python side of ``solve`` on the paper example (``max_points=2``): the wall time of
    the whole call less ``Solution.meta["kernel_s"]``, µs, minimum and median over ``repeats``
    warm calls, with the kernel's own time beside it."""
    problem, algorithm = paper_example(), REGISTRY[method](rtol=tol, atol=tol)
    solve(problem, algorithm, max_points=2)
    whole, kernel = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        sol = solve(problem, algorithm, max_points=2)
        whole.append(time.perf_counter() - start)
        kernel.append(sol.meta["kernel_s"])
    side = (np.array(whole) - np.array(kernel)) * 1e6
    return {"method": f"{method} {tol:.0e}", "min_us": float(side.min()),
            "median_us": float(np.median(side)), "kernel_us": float(np.min(kernel) * 1e6),
            "whole_us": float(np.min(whole) * 1e6)}


def python_side_fresh(repeats: int = 200) -> dict:
    """:func:`python_side` in a fresh process: measured after the study's other parts, in
    their process, the minimum varied from 40 to 62 µs between runs (why was not pinned
    down), against 40 µs every time in a process of its own."""
    root = Path(__file__).resolve().parents[2]
    code = ("import json; from benchmarks.studies.engine_speed import python_side; "
            f"print(json.dumps(python_side({int(repeats)})))")
    out = subprocess.run([sys.executable, "-c", code], cwd=root, check=True, text=True,
                         capture_output=True, env={**os.environ, "PYTHONPATH": str(root)})
    return json.loads(out.stdout.strip().splitlines()[-1])


#: the tolerances and goal of the comparison with the C twin: the kernel's µs per attempt
#: within TWIN_FACTOR × the twin's at each
TWIN_TOLERANCES, TWIN_FACTOR = (1e-3, 1e-5, 1e-7, 1e-9), 1.15


def c_twin_comparison(rounds: int = 8, solves: int = 10) -> pd.DataFrame | None:
    """Rodas5P's kernel against its C twin (:mod:`benchmarks.devtools.c_twin`) on the paper
    example, interleaved by tolerance and round: µs per step attempt, the kernel's from
    ``Solution.meta["kernel_s"]`` (the minimum over ``solves`` solves), the twin's (the minimum
    over as many runs), each the minimum over ``rounds``; the ratio and whether the two took
    the same steps. None without gcc."""
    from benchmarks.devtools import c_twin
    if c_twin.compiler() is None:
        return None
    problem = paper_example()
    kernel = {tol: math.inf for tol in TWIN_TOLERANCES}
    twin = dict(kernel)
    same = {}
    with tempfile.TemporaryDirectory() as tmp:
        binary = c_twin.build(tmp)
        inputs = {tol: c_twin.write_input(Path(tmp) / f"in_{tol:g}.txt", problem, tol)
                  for tol in TWIN_TOLERANCES}
        for _ in range(rounds):
            for tol in TWIN_TOLERANCES:
                algorithm = REGISTRY["Rodas5P"](rtol=tol, atol=tol)
                for _ in range(solves):
                    sol = solve(problem, algorithm, max_points=2)
                    attempts = sol.stats.steps + sol.stats.rejected
                    kernel[tol] = min(kernel[tol], sol.meta["kernel_s"] * 1e6 / attempts)
                got = c_twin.run_twin(binary, inputs[tol], solves)
                twin[tol] = min(twin[tol], got["us_per_attempt"])
                same[tol] = (got["steps"], got["rejected"], got["roots"]) == (
                    sol.stats.steps, sol.stats.rejected, list(sol.meta["roots"].values()))
    return pd.DataFrame([dict(tol=tol, kernel_us=kernel[tol], twin_us=twin[tol],
                              ratio=kernel[tol] / twin[tol], same_steps=same[tol])
                         for tol in TWIN_TOLERANCES])


_STARTUP = ("import time; t0 = time.perf_counter(); import integrators as I, problems as P; "
            "t1 = time.perf_counter(); I.solve(P.paper_example(), I.Rodas5P(rtol=1e-4, atol=1e-4)); "
            "print(t1 - t0, time.perf_counter() - t1)")


def startup(warm_repeats: int = 3) -> dict:
    """Seconds: import, first solve (warm and cold) and the simulate command (warm)."""
    root = Path(__file__).resolve().parents[2]          # the checkout

    def once(cwd, env_path):
        env = {**__import__("os").environ, "PYTHONPATH": str(env_path)}
        out = subprocess.run([sys.executable, "-c", _STARTUP], cwd=cwd, env=env, check=True,
                             capture_output=True, text=True).stdout.split()
        return float(out[0]), float(out[1])

    once(root, root)                                          # the cache filled
    warm = [once(root, root) for _ in range(warm_repeats)]
    with tempfile.TemporaryDirectory() as tmp:
        for package in ("integrators", "problems", "benchmarks"):
            shutil.copytree(root / package, Path(tmp) / package,
                            ignore=shutil.ignore_patterns("__pycache__"))
        cold = once(tmp, tmp)
    simulate = []
    for _ in range(warm_repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "benchmarks.cli", "simulate", "--preset",
                        "paper-example", "--json"], cwd=root, check=True, capture_output=True)
        simulate.append(time.perf_counter() - start)
    return {"import_warm": min(w[0] for w in warm), "first_solve_warm": min(w[1] for w in warm),
            "import_cold": cold[0], "first_solve_cold": cold[1], "simulate_warm": min(simulate)}


def _times(ratio: float) -> str:
    """A miss ratio in two digits, or in as many as it takes not to read 1 (1.0025: "1.003")."""
    text = f"{ratio:.2g}"
    return text if float(text) > 1.0 or ratio <= 1.0 else f"{ratio:.4f}".rstrip("0")


def _verdict(goals: pd.DataFrame) -> str:
    """The targets in sentences read from the table: how many are met, and by how much each
    missed one misses (for a wall-time target, what the setting's steps cost)."""
    words = [f"{int(goals.met.sum())} of the {len(goals)} speed targets are met."]
    for r in goals[~goals.met].itertuples():
        if r.fastest == "none":
            words.append(f"{r.target}: no own setting reaches it.")
        elif r.attempts:
            words.append(f"{r.target}: missed by {_times(r.wall_ms / r.target_ms)}×; {r.fastest} "
                         f"takes {r.attempts:,} step attempts at {r.us_per_attempt:.2g} µs each.")
        else:
            words.append(f"{r.target}: missed by {_times(r.wall_ms / r.target_ms)}×.")
    return " ".join(words)


def engine_speed_markdown(goals: pd.DataFrame, t: dict, repeats: int,
                          side: dict | None = None, twin: pd.DataFrame | None = None) -> str:
    """``engine_speed.md``: the targets table and the start-up times."""
    lines = ["# The own compiled engine against its speed targets",
             "",
             f"`rsfbench study engine-speed` (min of {repeats} after a warm-up, "
             "`max_points=2`, wall time of the solve without building the Solution; "
             "numbalsoda's lsoda called once over a 20,001-point grid at 1e−6, no events, "
             "timed in the same run). The last row's times are µs per step attempt.",
             "",
             "| target | goal (ms) | fastest reliable own setting | wall (ms) | ΔT error | "
             "lsoda (ms) | ratio to lsoda | met |",
             "|---|---|---|---|---|---|---|---|"]
    for r in goals.itertuples():
        lines.append(f"| {r.target} | {r.target_ms:g} | {r.fastest} | {r.wall_ms:.3g} | "
                     f"{r.err_dT:.2g} | {r.lsoda_ms:.3g} | {r.ratio_to_lsoda:.2g} | "
                     f"{'yes' if r.met else 'no'} |")
    lines += ["", _verdict(goals), ""]
    if side is not None:
        met = "met" if side["median_us"] <= PYTHON_SIDE_TARGET_US else "missed"
        lines += [f"The Python side of a solve ({side['method']} on the paper example, "
                  "`max_points=2`: the whole call less the compiled calls, 200 warm calls in a "
                  "process of its own): "
                  f"minimum {side['min_us']:.0f} µs, median {side['median_us']:.0f} µs, "
                  f"against a goal of {PYTHON_SIDE_TARGET_US:.0f} µs: {met}; the kernel "
                  f"{side['kernel_us']:.0f} µs, the whole call {side['whole_us']:.0f} µs "
                  "(minima).", ""]
    if twin is not None:
        met = "met" if (twin.ratio <= TWIN_FACTOR).all() else "missed"
        lines += ["Rodas5P's kernel against its C twin (`benchmarks/native/rodas5p.c`, gcc "
                  "-O3 -ffp-contract=off: the same arithmetic, steps and events) on the paper "
                  "example, µs per step attempt, interleaved, the minimum of 8 rounds of 10 "
                  f"solves each; goal: within {TWIN_FACTOR:g}× at every tolerance ({met}):", "",
                  "| rtol = atol | kernel (µs) | C twin (µs) | kernel / C | same steps |",
                  "|---|---|---|---|---|"]
        lines += [f"| {r.tol:g} | {r.kernel_us:.3f} | {r.twin_us:.3f} | {r.ratio:.2f} | "
                  f"{'yes' if r.same_steps else 'no'} |" for r in twin.itertuples()]
        lines += [""]
    elif side is not None:
        lines += ["No C compiler (gcc): the kernel's C twin was not run.", ""]
    lines += ["Start-up in a fresh process (`import integrators`; then the first solve, Rodas5P "
              "on the paper example; the simulate command as a whole), warm numba cache (min of 3) "
              "and cold (no cache: the kernels that solve needs are compiled):",
              "",
              "| | warm (s) | goal (s) | cold (s) |",
              "|---|---|---|---|",
              f"| `import integrators` | {t['import_warm']:.2f} | 1 | {t['import_cold']:.2f} |",
              f"| first solve after it | {t['first_solve_warm']:.2f} | 0.5 | "
              f"{t['first_solve_cold']:.1f} |",
              f"| `rsfbench simulate --preset paper-example --json` | {t['simulate_warm']:.2f} | 2 "
              "| – |"]
    return "\n".join(lines) + "\n"


def write_engine_speed(out: Path | None, repeats: int = 5) -> tuple[pd.DataFrame, str]:
    """Measure; write ``engine_speed.csv`` and ``engine_speed.md`` in ``out`` (if given).
    Returns the targets table and the Markdown."""
    table, lsoda = engine_speed(repeats)
    goals = targets(table, lsoda)
    twin = c_twin_comparison()
    text = engine_speed_markdown(goals, startup(), repeats, python_side_fresh(), twin)
    if out is not None:
        atomic_write(out / "engine_speed.csv", table.to_csv(index=False))
        if twin is not None:
            atomic_write(out / "engine_speed_c_twin.csv", twin.to_csv(index=False))
        atomic_write(out / "engine_speed.md", text)
    return goals, text


def run(out: Path, repeats: int) -> None:
    print(write_engine_speed(out, repeats)[1])


STUDY = Study("engine-speed", "The own compiled engine against its speed targets "
              "(`engine_speed.*`)", 180, run, report=markdown_file("engine_speed.md"),
              timed=True, modules=("benchmarks.cli",), settings={"repeats": 5},
              limits={"repeats": (1, 100)},   # it times the CLI's start-up
              writes=("engine_speed.csv", "engine_speed.md", "engine_speed_c_twin.csv"),
              minutes=1.0)
