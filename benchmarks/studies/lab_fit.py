"""Fitting (a, b, Dc) to velocity steps: recovery, coverage under real noise, cost, and five
real records against an independent fit (``lab_fit.*``).

* **Synthetic records** made by an independent model (:mod:`benchmarks.lab.independent_model`:
  scipy's Radau on the published equations): 10⁴ samples over 150 s, the load point stepping
  1 → 10 → 1 → 3 µm/s at 20, 50 and 100 s, aging law a = 0.006, b = 0.009, Dc = 10 µm,
  k′ = 0.003 per µm; white noise of 0.1 % of μ (σ = 6e-4) on μ and 0.05 µm on the
  displacement, and a drift of 5e-5 per µm of load-point travel. For ``seeds`` seeds: the fit
  (a, b, Dc, k′, a level and the trend at its default, held where the slider is steady) and
  its errors against the truth. Targets:
  a, b within 2 %, Dc within 5 %.
* **Coverage under real noise** (:data:`NOISE_KINDS`): the same records with white noise, AR(1)
  noise (φ = 0.9 per sample), white noise + a random walk that wanders 2 σ over the record, and
  all three at once; for ``seeds`` seeds each, how often the 95 % Wald intervals of a, b, a − b,
  Dc and k′ and (for the first ``profile_seeds``) the profile ones of a, b and Dc hold the
  truth. Target: 90–99 of 100 (the central 95 % of Binomial(100, 0.95)).
* **Cost** (targets): a three-parameter fit (a, b, Dc; k′ given) of a 10⁴-sample single step
  in ≤ 1 s, the profiles of all three in ≤ 10 s — warm, the minimum of three runs.
* **The inertia check**: single 10× steps from v1 = 1 µm/s and 100 µm/s, the slider of 100 or
  1000 kg on 10 kN (k = k′·Fn), made by the project's inertial slider (the independent model is
  quasi-static) with the same noise; fitted quasi-statically, then refitted with the mass
  (``--mass``): the shift of each parameter in the quasi-static fit's standard errors, and each
  fit's errors against the truth.
* **Real records** (``tests/data/lab-velocity-steps``, Giacomel et al. 2024's published demo
  records, five steps): each through ``rsfbench lab fit --law aging,slip`` at its defaults in a
  fresh process (timed: target ≤ 5 s a record), and the chosen law refitted by the independent
  reference (:mod:`benchmarks.lab.reference_fit`) on the same window, switch times and
  trend; a figure of each record with its fit and residuals.
"""

from __future__ import annotations

import json
import math
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from benchmarks.records.files import write_figure, write_output, write_table
from benchmarks.records.provenance import checkout
from benchmarks.records.report import jsonable, markdown_table
from benchmarks.studies.study import Study

__all__ = ["STUDY", "lab_fit_study", "TRUTH", "RECORDS"]

TRUTH = {"a": 0.006, "b": 0.009, "dc": 10e-6, "k": 3e3}
VELOCITIES, SWITCHES = (1e-6, 1e-5, 1e-6, 3e-6), (20.0, 50.0, 100.0)
NOISE, DISPLACEMENT_NOISE, DRIFT = 6e-4, 0.05e-6, 50.0
#: the accuracy targets of the fit: relative error of a, b and of Dc
TARGETS = {"a": 0.02, "b": 0.02, "dc": 0.05}
DATA = "tests/data/lab-velocity-steps"
#: the real records: (label, file, column specs)
RECORDS = (("basalt 3 → 10 µm/s (b819)", "velstep4_BRAVA_expb819_basalt.txt"),
           ("basalt 100 → 300 µm/s (b819)", "velstep7_BRAVA_expb819_basalt.txt"),
           ("sepiolite 0.2 → 2 µm/s (exp013, 1)", "velstep1_TR2_exp013_sepiolite.txt"),
           ("sepiolite 2 → 0.2 µm/s (exp013, 2)", "velstep2_TR2_exp013_sepiolite.txt"),
           ("sepiolite 0.2 → 2 µm/s (exp013, 3)", "velstep3_TR2_exp013_sepiolite.txt"))
#: the laws each real record is fitted with (the command's --law)
LAWS = "aging,slip"
REAL_COLUMNS = ["time=Time(s):s", "friction=Friction", "load_point=Displ(microns):um"]
COLUMNS = ["time=time_s", "load_point=load_point_um:um", "friction=friction"]


#: the noise kinds of the coverage check: the arguments of
#: :func:`benchmarks.lab.independent_model.synthetic_record` beyond the white noise's σ (the
#: AR(1) part's stationary σ is the white one's; the walk's steps wander 2 σ over 10⁴ samples)
NOISE_KINDS = {"white": {}, "AR(1)": {"noise": 0.0, "correlated": NOISE, "phi": 0.9},
               "white + walk": {"walk": 2 * NOISE / 100},
               "white + AR(1) + walk": {"correlated": NOISE, "phi": 0.9, "walk": 2 * NOISE / 100}}
#: the parameters whose intervals are checked, and those with a profile
COVERED, PROFILED = ("a", "b", "a_minus_b", "dc", "k"), ("a", "b", "dc")


_CLEAN = {}


def _synthetic(seed: int, t=None, velocities=VELOCITIES, switches=SWITCHES, kind="white"):
    """A synthetic record; its noise-free μ is computed once per time base and history."""
    from benchmarks.lab.independent_model import reference_friction, synthetic_record
    from benchmarks.lab.step_data import lab_record_from
    t = np.linspace(0.0, 150.0, 10_000) if t is None else t
    key = (len(t), float(t[0]), float(t[-1]), tuple(velocities), tuple(switches))
    if key not in _CLEAN:
        _CLEAN[key] = reference_friction(t, velocities, switches, **TRUTH, mu0=0.6)
    args = dict(TRUTH, noise=NOISE, displacement_noise=DISPLACEMENT_NOISE, drift=DRIFT,
                seed=seed, clean=_CLEAN[key])
    df = synthetic_record(t, velocities, switches, **{**args, **NOISE_KINDS[kind]})
    return lab_record_from(df, COLUMNS, source=f"synthetic seed {seed}, {kind} noise")


def _coverage(seeds: int, profile_seeds: int, say) -> pd.DataFrame:
    """One row per (noise kind, seed): the fit, its errors, and whether each interval holds
    the truth."""
    from benchmarks.lab.fit import LabFitWarning, fit_lab
    from benchmarks.lab.profile_intervals import profile_lab
    from benchmarks.lab.model import LabModel
    truths = dict(TRUTH, a_minus_b=TRUTH["a"] - TRUTH["b"])
    rows = []
    for kind in NOISE_KINDS:
        for seed in range(seeds):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", LabFitWarning)
                fit = fit_lab(LabModel(_synthetic(seed, kind=kind), "aging"))
            row = {"noise": kind, "seed": seed, "success": fit.success, "wall_s": fit.wall_s,
                   "solves": fit.solves, "sigma": fit.sigma, "rho": fit.rho,
                   "inflation": fit.inflation, "drift_sigma": fit.drift_sigma}
            for name in COVERED:
                low, high = fit.interval(name)
                row[f"{name}"] = fit.values[name]
                row[f"{name}_error"] = fit.values[name] / truths[name] - 1.0
                row[f"{name}_wald"] = bool(low <= truths[name] <= high)
            if seed < profile_seeds:
                for name in PROFILED:
                    low, high = profile_lab(fit, name).interval
                    row[f"{name}_profile"] = bool(low <= truths[name] <= high)
            rows.append(row)
            if (seed + 1) % 25 == 0:
                say(f"coverage, {kind} noise: {seed + 1}/{seeds} seeds")
    return pd.DataFrame(rows)


def _cost() -> dict:
    """The targets' timings: warm, the minimum of three runs."""
    from benchmarks.lab.fit import fit_lab
    from benchmarks.lab.profile_intervals import profile_lab
    from benchmarks.lab.model import LabModel
    record = _synthetic(0, t=np.linspace(0.0, 60.0, 10_000), velocities=(1e-6, 1e-5),
                        switches=(20.0,))
    model = LabModel(record, "aging")
    fit_lab(model, fixed={"k": TRUTH["k"]})                       # warm-up (compiling)
    fits, profiles = [], []
    for _ in range(3):
        start = time.perf_counter()
        fit = fit_lab(model, fixed={"k": TRUTH["k"]})
        fits.append((time.perf_counter() - start, fit.solves))
        start = time.perf_counter()
        solves = sum(profile_lab(fit, n).solves for n in ("a", "b", "dc"))
        profiles.append((time.perf_counter() - start, solves))
    four = min(fit_lab(model).wall_s for _ in range(3))
    (fit_s, fit_solves), (prof_s, prof_solves) = min(fits), min(profiles)
    return {"samples": len(record.t), "fit_s": fit_s, "fit_solves": fit_solves,
            "fit_met": bool(fit_s <= 1.0), "profiles_s": prof_s, "profile_solves": prof_solves,
            "profiles_met": bool(prof_s <= 10.0), "fit_with_stiffness_s": four}


#: the inertia check's cases: (v1 in m/s, mass in kg); the normal force is 10 kN
INERTIA_CASES = ((1e-6, 100.0), (1e-4, 100.0), (1e-4, 1000.0))
NORMAL_FORCE = 1e4


def _inertia() -> list[dict]:
    from benchmarks.lab.checks import inertia_check
    from benchmarks.lab.fit import LabFitWarning, fit_lab
    from benchmarks.lab.model import LabModel
    from benchmarks.lab.step_data import lab_record_from
    rows = []
    for v1, mass in INERTIA_CASES:
        t_step = 60 * TRUTH["dc"] / v1          # 60 Dc of steady sliding, then 40 Dc at 10 v1
        t = np.linspace(0.0, t_step + 40 * TRUTH["dc"] / (10 * v1), 10_000)
        x = np.where(t < t_step, v1 * t, v1 * t_step + 10 * v1 * (t - t_step))
        df = pd.DataFrame({"time_s": t, "load_point_um": x * 1e6, "friction": 0.6 + 0 * t})
        blank = lab_record_from(df, COLUMNS)
        g, sol = LabModel(blank, "aging", detrend="none", mass=mass,
                          normal_force=NORMAL_FORCE).response(**TRUTH)
        rng = np.random.default_rng(0)
        df["friction"] = 0.6 + g + NOISE * rng.standard_normal(len(t))
        record = lab_record_from(df, COLUMNS, source=f"inertial v1 = {v1:g}, m = {mass:g}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LabFitWarning)
            quasi = fit_lab(LabModel(record, "aging", detrend="none"))
            inertial, shifts = inertia_check(quasi, mass, NORMAL_FORCE)
        rows.append({"v1_m_s": v1, "mass_kg": mass, "period_over_dc_time": 2 * np.pi * np.sqrt(
                         mass / (TRUTH["k"] * NORMAL_FORCE)) / (TRUTH["dc"] / (10 * v1)),
                     "shift_se": dict(zip(shifts.parameter, shifts.shift_se)),
                     "quasi_static_error": {n: quasi.values[n] / TRUTH[n] - 1 for n in TRUTH},
                     "inertial_error": {n: inertial.values[n] / TRUTH[n] - 1 for n in TRUTH},
                     "matters": bool((shifts.shift_se.abs() > 1).any())})
    return rows


def _cli_fit(path: Path, root: Path) -> tuple[dict, pd.DataFrame, float]:
    """``rsfbench lab fit`` on ``path`` as a user runs it (both laws, defaults otherwise, a
    fresh process): its JSON, its residuals' table and its wall time (s)."""
    import os
    import subprocess
    import sys
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "benchmarks.cli", "lab", "fit", str(path),
               *(a for c in REAL_COLUMNS for a in ("--column", c)), "--law", LAWS,
               "--json", "--no-progress", "--out", tmp]
        env = dict(os.environ, PYTHONPATH=str(root))
        started = time.perf_counter()
        run = subprocess.run(cmd, capture_output=True, text=True, cwd=root, env=env)
        wall = time.perf_counter() - started
        try:
            doc = json.loads(run.stdout)
        except json.JSONDecodeError:
            doc = {}
        if run.returncode not in (0, 1) or "parameters" not in doc:
            raise RuntimeError(f"rsfbench lab fit {path.name} exited {run.returncode}: "
                               f"{doc.get('error') or run.stderr[-500:]}")
        residuals = pd.read_csv(Path(tmp) / "lab_fit_residuals.csv")
    return doc, residuals, wall


def _compare(doc: dict, ref) -> list[dict]:
    """The project's value and 95 % interval (profile where it has one, else Wald) beside the
    reference's, and whether each holds the other's value."""
    rows = []
    for p in doc["parameters"]:
        name = p["parameter"]
        if name not in ("a", "b", "a_minus_b", "dc", "k"):
            continue
        closed = p.get("profile_low_closed") is True and p.get("profile_high_closed") is True
        low, high = ((p["profile_low95"], p["profile_high95"]) if closed else
                     (p["wald_low95"], p["wald_high95"]))
        r_low, r_high = ref.interval(name)
        value, ours = ref.values[name], p["value"]
        # a null (JSON's NaN or infinity) is no interval: no agreement can be said
        known = all(v is not None and math.isfinite(v) for v in (low, high, r_low, r_high,
                                                                   value, ours))
        rows.append({"parameter": name, "value": ours, "low95": low, "high95": high,
                     "interval": "profile" if closed else "Wald", "reference": value,
                     "reference_low95": r_low, "reference_high95": r_high,
                     "relative_difference": value / ours - 1.0 if known and ours else math.nan,
                     "agree": bool(known and low <= value <= high and r_low <= ours <= r_high)})
    return rows


def _held(record, doc, velocities, switches):
    """``(μ, detrend, columns)`` for the reference fit: the record's μ and trend, or with
    ``--detrend steady`` μ less the command's held trend (its slopes from lab_fit.json times
    the pieces' travel) and the travel columns of the pieces whose slopes it fitted."""
    if doc["detrend"] != "steady":
        return record.mu, doc["detrend"], None
    from benchmarks.lab.steady_trend import travel_columns
    columns = travel_columns(record.t, velocities, switches)
    trend = doc["trend"]
    slopes = np.array([0.0 if s is None else s for s in trend["held_slopes_per_m"]])
    fitted = [i for i in trend["fitted_pieces"] if velocities[i] > 0]
    return record.mu - columns @ slopes, "none", columns[:, fitted]


def _real(root: Path, out: Path, say) -> list[dict]:
    """Each real record through ``rsfbench lab fit`` at its defaults with both laws, and the
    independent reference fit (:mod:`benchmarks.lab.reference_fit`) of the chosen law on
    the same window, switch times and trend."""
    from benchmarks.lab.reference_fit import fit_reference
    from benchmarks.lab.fit import starting_values
    from benchmarks.lab.step_data import read_lab_record
    from benchmarks.lab.switches import with_switches
    results, figures = [], []
    for label, name in RECORDS:
        path = root / DATA / name
        doc, residuals, wall = _cli_fit(path, root)
        say(f"real: {name}: rsfbench lab fit {wall:.1f} s, law {doc['law']}")
        record = read_lab_record(path, REAL_COLUMNS)
        history = doc["history"]
        switches = [s - record.t_offset for s in history["switch_times_s"]]
        record = with_switches(record, switches)
        start = {k: v for k, v in starting_values(record).items() if k != "monotone"}
        mu, trend, columns = _held(record, doc, history["velocities_m_s"], switches)
        ref = fit_reference(record.t, mu, history["velocities_m_s"], switches, doc["law"],
                            trend, start, trend_columns=columns)
        say(f"real: {name}: reference fit {ref.wall_s:.0f} s, {ref.runs} runs")
        check = doc.get("solver_check") or {}
        results.append({
            "record": label, "file": name, "law": doc["law"], "detrend": doc["detrend"],
            "wall_s": wall, "fit_wall_s": doc["wall_s"], "samples": doc["samples"],
            "velocities_m_s": history["velocities_m_s"],
            "switch_times_s": history["switch_times_s"],
            "switches": (doc.get("switches") or {}).get("table"),
            "laws": doc["laws"]["table"] if doc.get("laws") else None,
            "parameters": doc["parameters"], "noise": doc["noise"], "notes": doc["notes"],
            "success": doc["success"], "at_bound": doc["at_bound"],
            "solver_check": ("not run" if not check.get("checked", False) else
                             "passed" if check.get("passed") else "failed"),
            "reference": {"values": ref.values, "se": ref.se, "sigma": ref.sigma,
                          "rho": ref.rho, "runs": ref.runs, "wall_s": ref.wall_s,
                          "success": ref.success, "message": ref.message},
            "comparison": _compare(doc, ref)})
        figures.append((label, doc["law"], residuals))
    _plot(figures, out / "lab_fit.png")
    return results


def _plot(figures, path: Path) -> None:
    """Each real record and its chosen fit against the load point's travel, residuals below."""
    fig = Figure(figsize=(3.4 * len(figures), 5.2))
    axes = fig.subplots(2, len(figures), gridspec_kw={"height_ratios": [3, 1]}, squeeze=False)
    for col, (label, law, table) in enumerate(figures):
        x = (table.load_point_m - table.load_point_m.iloc[0]) * 1e6
        axes[0, col].plot(x, table.mu, lw=0.4, color="0.6", label="record")
        axes[0, col].plot(x, table.mu_model, lw=1.0, color="C3", label=f"fit, {law} law")
        axes[0, col].set_title(label, fontsize=8)
        axes[0, col].legend(fontsize=7)
        axes[1, col].plot(x, table.residual, lw=0.4)
        axes[1, col].axhline(0, color="k", lw=0.5)
        axes[1, col].set_xlabel("load-point travel (µm)", fontsize=8)
    axes[0, 0].set_ylabel("μ")
    axes[1, 0].set_ylabel("residual")
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def lab_fit_study(out: Path, seeds: int = 200, profile_seeds: int = 100,
                  progress: bool = False) -> dict:
    """Run the study of the module docstring; write ``out/lab_fit.{csv,json,md,png}``."""
    from benchmarks.inversion.calibration import binomial_check
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    say = (lambda text: print(f"  {text}", flush=True)) if progress else (lambda text: None)
    started = time.perf_counter()
    root = checkout() or Path.cwd()
    cost = _cost()
    say(f"cost: a fit {cost['fit_s']:.2f} s, three profiles {cost['profiles_s']:.2f} s")
    table = _coverage(seeds, min(profile_seeds, seeds), say)
    write_table(table, out / "lab_fit.csv")
    coverage = []
    for noise, rows in table.groupby("noise", sort=False):
        for name in COVERED:
            for kind in ("wald", "profile"):
                column = f"{name}_{kind}"
                if column in rows and rows[column].notna().any():
                    held = rows[column].dropna().astype(bool)
                    check = binomial_check(int(held.sum()), len(held))
                    coverage.append({"noise": noise, "parameter": name, "interval": kind,
                                     "hits": int(held.sum()), **check})
    white = table[table.noise == "white"]
    errors = {name: {"median_abs": float(white[f"{name}_error"].abs().median()),
                     "max_abs": float(white[f"{name}_error"].abs().max()),
                     "target": TARGETS.get(name),
                     "met": bool(white[f"{name}_error"].abs().max() <= TARGETS[name])
                     if name in TARGETS else None} for name in TRUTH}
    info = {"truth": TRUTH, "velocities_m_s": VELOCITIES, "switch_times_s": SWITCHES,
            "noise": NOISE, "displacement_noise_m": DISPLACEMENT_NOISE, "drift_per_m": DRIFT,
            "seeds": seeds, "profile_seeds": min(profile_seeds, seeds), "errors": errors,
            "coverage": coverage, "cost": cost, "inertia": _inertia(),
            "real": _real(root, out, say),
            "wall_s": time.perf_counter() - started}
    write_output(out / "lab_fit.json", json.dumps(jsonable(info), indent=2))
    write_output(out / "lab_fit.md", _markdown(info))
    return info


def _coverage_rows(coverage: list[dict]) -> list[dict]:
    """One row per (noise, parameter): the Wald and profile intervals' hits."""
    rows = {}
    for c in coverage:
        row = rows.setdefault((c["noise"], c["parameter"]), {
            "noise": c["noise"], "parameter": c["parameter"].replace("a_minus_b", "a − b"),
            "binomial 95 % range": f"{c['binomial_low']}–{c['binomial_high']}"})
        row[c["interval"]] = (f"{c['hits']}/{c['n']}" if c["consistent"] else
                              f"**{c['hits']}/{c['n']}**")
    return [{"noise": r["noise"], "parameter": r["parameter"], "Wald": r.get("wald", ""),
             "profile": r.get("profile", ""), "binomial 95 % range": r["binomial 95 % range"]}
            for r in rows.values()]


def _error_rows(errors: dict) -> list[dict]:
    return [{"parameter": k, "median |error|": f"{v['median_abs']:.2%}",
             "largest |error|": f"{v['max_abs']:.2%}",
             "target": f"{v['target']:.0%}" if v["target"] else "",
             "met": ("yes" if v["met"] else "**no**") if v["met"] is not None else ""}
            for k, v in errors.items()]


#: the real records' wall-time target per record, s (both laws, profiles included)
REAL_TARGET_S = 5.0


def _real_row(r: dict) -> dict:
    """One real record's row: the chosen law, its values and 95 % intervals, what the fit
    says, its wall time and the reference's agreement."""
    p = {row["parameter"]: row for row in r["parameters"]}

    def shown(n):
        scale = {"dc": 1e6, "k": 1e-6}.get(n, 1.0)
        row = p[n]
        closed = row.get("profile_low_closed") is True and row.get("profile_high_closed") is True
        lo, hi = ((row["profile_low95"], row["profile_high95"]) if closed else
                  (row["wald_low95"], row["wald_high95"]))
        return f"{row['value'] * scale:.4g} ({lo * scale:.3g}–{hi * scale:.3g})"

    says = []
    if not r["success"]:
        says.append("did not converge")
    if r["at_bound"]:
        says.append("at a bound: " + ", ".join(r["at_bound"]))
    for key, text in (("trade", "Dc trades with the trend"), ("does not fit", "law does not fit"),
                      ("longer than any", "Dc longer than any lab's"),
                      ("cannot resolve", "Dc below the sampling"),
                      ("not seen to its end", "step short in Dc"),
                      ("does not bound", "a profile is open")):
        if any(key in n for n in r["notes"]):
            says.append(text)
    deltas = [abs(c["relative_difference"]) for c in r["comparison"]]
    delta = math.nan if any(math.isnan(d) for d in deltas) else max(deltas)
    agree = sum(c["agree"] for c in r["comparison"])
    return {"record": r["record"], "law": r["law"], "trend": r["detrend"],
            "a": shown("a"), "b": shown("b"), "Dc (µm)": shown("dc"),
            "k′ (per µm)": shown("k"),
            "wall (s)": f"{r['wall_s']:.1f}" + ("" if r["wall_s"] <= REAL_TARGET_S else " **>5**"),
            "solver check": r["solver_check"], "the fit says": "; ".join(says),
            "reference: largest |Δ|": f"{delta:.1e}",
            "agree": f"{agree}/{len(r['comparison'])}"}


def _inertia_rows(inertia: list[dict]) -> list[dict]:
    return [{
        "v1 (µm/s)": f"{r['v1_m_s'] * 1e6:g}", "mass (kg)": f"{r['mass_kg']:g}",
        "period / (Dc/v2)": f"{r['period_over_dc_time']:.2g}",
        "shift (se): a, b, Dc, k′": ", ".join(f"{r['shift_se'][n]:+.2g}" for n in TRUTH),
        "quasi-static error: a, b, Dc": ", ".join(f"{r['quasi_static_error'][n]:+.1%}"
                                                 for n in ("a", "b", "dc")),
        "inertial error: a, b, Dc": ", ".join(f"{r['inertial_error'][n]:+.1%}"
                                             for n in ("a", "b", "dc")),
        "the check says": "the inertia matters" if r["matters"] else "quasi-static stands"}
        for r in inertia]


def _markdown(info: dict) -> str:
    cov_rows = _coverage_rows(info["coverage"])
    err_rows = _error_rows(info["errors"])
    real_rows = [_real_row(r) for r in info["real"]]
    inertia_rows = _inertia_rows(info["inertia"])
    c = info["cost"]
    return (
        "# Fitting velocity steps\n\n"
        f"Synthetic records from an independent model (scipy's Radau on the published "
        f"equations, `benchmarks/lab/independent_model.py`): aging law a = {TRUTH['a']}, "
        f"b = {TRUTH['b']}, Dc = {TRUTH['dc'] * 1e6:g} µm, k′ = {TRUTH['k'] * 1e-6:g} per µm; "
        "the load point at 1 → 10 → 1 → 3 µm/s (switches at 20, 50, 100 s), 10⁴ samples over "
        f"150 s; noise σ = {NOISE:g} in μ (0.1 %), {DISPLACEMENT_NOISE * 1e6:g} µm on the "
        f"displacement, a drift of {DRIFT * 1e-6:g} per µm. {info['seeds']} seeds; the fit "
        "finds the history in the displacement and fits a, b, Dc, k′ and a level, the trend "
        "at its default (each piece's slope read where the slider is steady and held, or "
        "fitted where that is less precise). The errors below are the white-noise "
        "records'.\n\n"
        + markdown_table(pd.DataFrame(err_rows)) +
        "\n## Coverage under real noise\n\n"
        "The same records with four kinds of noise: white (σ above); AR(1) of the same σ and "
        "φ = 0.9 per sample; white + a random walk whose steps wander 2 σ over the record; "
        "and all three at once. The fit reads the noise from its residuals' variogram as "
        "white + AR(1) + a random walk (`benchmarks/lab/noise.py`). Each cell: how many of "
        f"{info['seeds']} seeds' 95 % intervals hold the truth (Wald; profile for the first "
        f"{info['profile_seeds']}); in bold where outside the central 95 % of the binomial "
        "(the target).\n\n"
        + markdown_table(pd.DataFrame(cov_rows)) +
        "\n## Cost\n\n"
        f"A three-parameter fit (k′ given) of a single step of {c['samples']:,} samples: "
        f"{c['fit_s']:.2f} s ({c['fit_solves']} solves) — target ≤ 1 s "
        f"**{'met' if c['fit_met'] else 'missed'}**; the profiles of a, b and Dc: "
        f"{c['profiles_s']:.2f} s ({c['profile_solves']} solves) — target ≤ 10 s "
        f"**{'met' if c['profiles_met'] else 'missed'}**; with k′ fitted too: "
        f"{c['fit_with_stiffness_s']:.2f} s. Warm, the minimum of three runs.\n\n"
        "## The inertia check\n\n"
        f"A 10× step on a slider of the given mass on {NORMAL_FORCE:g} N (k = k′·Fn), made by the "
        "project's inertial slider with the same noise, fitted quasi-statically and then with "
        "the mass (`rsfbench lab fit --mass KG --normal-force N`). The period is the slider's "
        "2π√(m/k) over the time the load point takes to travel one Dc after the step.\n\n"
        + markdown_table(pd.DataFrame(inertia_rows)) +
        "\nWhere the period nears the time to slip one Dc, the quasi-static fit is biased far "
        "beyond its error bars, the check says so, and the inertial fit recovers the truth.\n\n"
        "## Five real records\n\n"
        "The demo records published with Giacomel et al. (2024), *steadystate*, Geosphere, "
        "doi:10.1130/GES02739.1 (`tests/data/lab-velocity-steps`, MIT licence; three of them "
        "from the branch's history, as its README says), each through `rsfbench lab fit "
        f"RECORD --law {LAWS}` at its defaults (the switch refined on the friction, the "
        "trend read where the slider is steady and held, profiles, the solver check, the "
        "figure) in a fresh process, as a user runs it. Each cell: the chosen law's value and its 95 % interval (profile where both ends "
        "close, else Wald). Then the independent reference fit "
        "(`benchmarks/lab/reference_fit.py`: scipy's least_squares on scipy's Radau, no "
        "code of the project's model) of the same law on the same window, switch times and "
        "trend: its largest relative difference from the project's a, b, a − b, Dc, k′, and in "
        "how many of those five each fit's interval holds the other's value. Wall-time target: "
        f"≤ {REAL_TARGET_S:g} s a record on 2 cores.\n\n"
        + markdown_table(pd.DataFrame(real_rows)) +
        "\nEvery note in full, both laws' tables and the switch rows: `lab_fit.json`. The "
        "figure: each record, its chosen fit and its residuals.\n\n"
        f"Wall time of the study: {info['wall_s'] / 60:.1f} min. Command: `rsfbench study "
        "lab-fit`.\n")


def run(out: Path, seeds: int, profile_seeds: int) -> None:
    lab_fit_study(out, seeds=seeds, profile_seeds=profile_seeds, progress=True)
    print((out / "lab_fit.md").read_text())


def report(out: Path) -> str:
    return (out / "lab_fit.md").read_text().split("\n", 2)[2] + "\n![fits](lab_fit.png)\n"


STUDY = Study("lab-fit", "Fitting (a, b, Dc) to velocity steps: recovery, coverage under real "
              "noise, cost, five real records against an independent fit (`lab_fit.*`)", 208,
              run, report=report, timed=True,
              settings={"seeds": 100, "profile_seeds": 100},
              limits={"seeds": (10, 10_000), "profile_seeds": (0, 10_000)},
              writes=("lab_fit.csv", "lab_fit.json", "lab_fit.md", "lab_fit.png"), minutes=40,
              data=tuple(f"{DATA}/{name}" for _, name in RECORDS))
