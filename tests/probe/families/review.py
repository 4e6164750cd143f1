"""Probe cases: what a second, hostile reading of the hardened commands found (a store in use, a
step too small to move v off vL, a negligible damping or mass in the peak search, a curve grid
coarser than an event, a crawling setting under a budget, one warning a value and a piece)."""

from __future__ import annotations

import json
import time

from filelock import FileLock

from probe.harness import Case, Observed, Wrong, cli, cli_outcome

__all__ = ["cases"]


def _lab_peak(*flags) -> float:
    run = cli("lab", "step", "--json", *flags)
    if run.status != 0:
        raise Wrong(f"exit status {run.status}: {run.err.strip()[-300:]}")
    return json.loads(run.out)["steps_response"][0]["mu_extreme"]


def _same_peak_as_without(*flags):
    def run(tmp):
        plain, other = _lab_peak(), _lab_peak(*flags)
        if abs(other - plain) > 1e-6:
            raise Wrong(f"peak {other!r} with {' '.join(flags)}, {plain!r} without")
        return Observed("ok", f"peak {other:.9g}")
    return run


def _runs(*args, expect_status=0):
    def run(tmp):
        got = cli(*args)
        if got.status != expect_status:
            raise Wrong(f"exit status {got.status}, expected {expect_status}: "
                        f"{got.err.strip()[-300:]}")
        return cli_outcome(got, "--json" in args)
    return run


def _store_in_use(tmp):
    chunks = tmp / "s" / "chunks"
    chunks.mkdir(parents=True)
    with FileLock(chunks / ".lock", timeout=0):             # another run holds it
        run = cli("sweep", "--preset", "W2", "--b", "0.0093:0.0094:0.0001", "--lc", "3e-7:4e-7:2",
                  "--t-end", "5", "--integrator", "Rodas5P", "--rtol", "1e-6", "--atol", "1e-6",
                  "--workers", "1", "--no-progress", "--no-plot", "--out", str(tmp / "s"))
    if run.status != 1 or "in use" not in run.err:
        raise Wrong(f"exit status {run.status}: {run.err.strip()[-300:]}")
    return cli_outcome(run)


def _warnings(*args, count: int):
    def run(tmp):
        got = cli(*args)
        lines = [x for x in got.err.splitlines() if "warning:" in x]
        if len(lines) != count:
            raise Wrong(f"{len(lines)} warning lines, expected {count}: {lines}")
        return Observed("warned", lines[0])
    return run


def _crawl_under_budget(tmp):
    from integrators import ETD2, solve
    from problems import preset
    solve(preset("W2", law="slip", t_end=0.05), ETD2(), max_points=2)    # compiled first
    start = time.perf_counter()
    sol = solve(preset("W2", law="slip"), ETD2(dtau_cnst=1e-300), wall_budget=1.0)
    took = time.perf_counter() - start
    if sol.retcode.value != "WallTime":
        raise Wrong(f"retcode {sol.retcode.value}")
    if took > 1.0 + 0.1 + 2.0:      # the budget, the warm-up's tenth, the checks' granularity
        raise Wrong(f"a 1 s budget took {took:.2f} s")
    return Observed("retcode", f"WallTime after {took:.2f} s")


def _history_file(tmp):
    f = tmp / "steps.toml"
    f.write_text("mass = 0.0\nstiffness = 1e7\nnormal_force = 1e4\nt_end = 30.0\n"
                 "[law]\nname = \"aging\"\na = 0.005\nb = 0.01\nlc = 1e-5\nv0 = 1e-6\n"
                 "[loading]\nvelocities = [1e-6, 1e-5, 1e-6]\nswitch_times = [10.0, 20.0]\n")
    return f


def _unsettled_once(tmp):
    # three pieces, none settled (the start is a healed fault): three warnings, not four
    return _warnings("lab", "step", "--problem", str(_history_file(tmp)), "--no-progress",
                     count=3)(tmp)


def _coarse_curves(tmp):
    return _runs("slip-weakening", "--preset", "W2", "--integrator", "Rodas5P", "--rtol", "1e-6",
                 "--atol", "1e-6", "--curve-dt", "1e-2", "--out", str(tmp / "c.csv"),
                 expect_status=2)(tmp)


def cases() -> list[Case]:
    return [
        Case("store", "a store in use by another run: exit 1, one line", _store_in_use,
             "retcode", timeout=120),
        Case("lab", "lab step: a step of 1e-10 relative (v stays at vL)",
             _runs("lab", "step", "--v2", "1.0000000001e-6", "--no-progress"), "ok"),
        Case("lab", "lab shs: a hold of 1e-12 s",
             _runs("lab", "shs", "--holds", "1e-12", "--json"), "ok"),
        Case("lab", "lab step: a negligible damping finds the undamped peak",
             _same_peak_as_without("--radiation-damping", "1e-9"), "ok"),
        Case("lab", "lab step: a 1e-30 kg slider finds the quasi-static peak",
             _same_peak_as_without("--mass", "1e-30"), "ok"),
        Case("lab", "lab step: each unsettled piece warned once", _unsettled_once, "warned"),
        Case("units", "lab shs --v 20: one warning for one value",
             _warnings("lab", "shs", "--v", "20", "--holds", "1", "--no-progress", count=1),
             "warned"),
        Case("cli-input", "slip-weakening: a --curve-dt coarser than an event", _coarse_curves,
             "refused", names="--curve-dt"),
        Case("budgets", "a crawling ETD2 (dtau_cnst = 1e-300) under a 1 s budget",
             _crawl_under_budget, "retcode", timeout=60),
    ]
