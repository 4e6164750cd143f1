"""A real catalogue end to end: the 56 stick–slip events of NIED's 4-m biaxial apparatus
(experiment fb03-087; ``tests/data/nied-4m-stick-slip``, MIT) through ``observe --catalogue``
and ``invert``, then the inversion again with each constant the catalogue does not state varied
over a plausible range, one at a time.

The catalogue states the fault (4 m × 0.1 m) and the normal stress (about 2 MPa), not the
stiffness, the load-point speed or the moving mass; nor the friction law's a. The stiffness
and the load-point speed are estimated from it
(:mod:`benchmarks.lab.catalogue_constants`: k the median of the events' drop/slip, vL the
loading rate between events over k/Fn); each is varied over its estimate ± 2 standard errors,
and beyond that:

* k up by the bias bound of the level "after" each event being read 170 ms after its onset
  (the drop misses the reloading over that time, so k is low by up to that fraction);
* vL at the median of the intervals' loading rates instead of the record's (the other way of
  averaging; on this catalogue 2.9 of its standard errors higher).

The mass cannot be estimated from a catalogue: a metagabbro block (2980 kg/m³, the paper's
density for the same rock) on the 4 m × 0.1 m fault, 0.1 to 1 m high, weighs 119 to 1192 kg;
the base takes their geometric mean (377 kg) and the variations the two ends. The law's a is
the paper's for the same rock (0.008, Table 4), varied over 0.006–0.010. The prior box follows
a: b from a (below it steady sliding is velocity-strengthening: no stick–slip) to a + 0.002
(there the friction drop is ≥ 2× the observed one at every Lc of the box), Lc from 10 nm to
the decade above the critical slip distance (b − a)·Fn/k at b = a + 0.002 (above it steady
sliding is stable). The slip law, the means alone (a catalogue has no curves), σ the events'
scatter (the file's default), the grid posterior at its defaults, the integrator the commands
recommend for 1e−3 in ΔT. Each inversion's fit, profile intervals and posterior (or why there
is none) is a row of ``nied_catalogue.csv``; the estimates are ``nied_catalogue_constants.csv``.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from benchmarks.devtools.recommendation import recommended
from benchmarks.inversion.invert import invert
from benchmarks.inversion.misfit import Misfit
from benchmarks.inversion.observations import read_observations
from benchmarks.lab.catalogue import observe_catalogue
from benchmarks.lab.catalogue_constants import box_lc
from benchmarks.records.files import write_figure, write_output, write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study, markdown_file
from problems import load_problem, variant

__all__ = ["STUDY", "nied_inversions", "variations", "CATALOGUE", "COLUMNS", "MASS_RANGE",
           "A_RANGE"]

ROOT = Path(__file__).resolve().parents[2]
#: the catalogue, in the project (its README says what the source states)
CATALOGUE = "tests/data/nied-4m-stick-slip/Macroscopic_stats_FB03_087.csv"
#: its columns, as ``observe --catalogue`` maps them
COLUMNS = ("onset=event_starttime[s]",
           "shear_stress_before=macroshearstress_beforeevent[MPa]:MPa",
           "shear_stress_after=macroshearstress_afterevent[MPa]:MPa",
           "slip=slip_mean[mm]:mm")
#: what the source states: the fault's area (m²), the normal stress (Pa), when "after" is read
AREA, NORMAL_STRESS, AFTER_DELAY = 0.4, 2e6, 0.17
#: kg/m³, the paper's density of the same rock (Sect. 2.2.1)
DENSITY = 2980.0
#: the moving mass (kg): a metagabbro block on the 4 m × 0.1 m fault, 0.1 to 1 m high (assumed)
MASS_RANGE = (DENSITY * AREA * 0.1, DENSITY * AREA * 1.0)
#: the friction law's a: the paper's (Table 4) ± 0.002
A_RANGE = (0.006, 0.010)
#: the prior box in b: from a to a + this
B_SPAN = 0.002
#: the commands' default accuracy in ΔT (``--accuracy``): the integrator they recommend for it
ACCURACY = 1e-3


def variations(constants: dict, a: float) -> list[dict]:
    """The inversions of the study, base first: one constant off its base value per row.

    Parameters
    ----------
    constants : dict
        :meth:`~benchmarks.lab.catalogue_constants.CatalogueConstants.as_dict` of the
        catalogue.
    a : float
        The law's a at the base.

    Returns
    -------
    list of dict
        ``varied`` (the constant, or ``none``), ``label``, and the four values ``stiffness``
        (N/m), ``vl`` (m/s), ``mass`` (kg), ``a``.
    """
    k, vl = constants["stiffness"], constants["vl"]
    base = {"stiffness": k["value"], "vl": vl["value"], "mass": math.sqrt(math.prod(MASS_RANGE)),
            "a": a}
    bias = constants["after_bias"]["stiffness_low_by_at_most"]
    rows = [("none", "base (the estimates; mass the range's geometric mean)", {})]
    for key, e in (("stiffness", k), ("vl", vl)):
        rows += [(key, f"{key} − 2 se", {key: e["value"] - 2 * e["se"]}),
                 (key, f"{key} + 2 se", {key: e["value"] + 2 * e["se"]})]
        if key == "stiffness":
            rows.append((key, "stiffness + the 170 ms bias bound",
                         {key: e["value"] * (1 + bias)}))
    rows += [("vl", "vl from the median interval's rate", {"vl": constants["vl_median_interval"]}),
             ("mass", "mass, a 0.1 m high block", {"mass": MASS_RANGE[0]}),
             ("mass", "mass, a 1 m high block", {"mass": MASS_RANGE[1]}),
             ("a", "a low", {"a": A_RANGE[0]}), ("a", "a high", {"a": A_RANGE[1]})]
    return [{"varied": v, "label": label, **base, **change} for v, label, change in rows]


def nied_inversions(progress: bool = False) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """The catalogue through ``observe --catalogue``, then one inversion per row of
    :func:`variations`.

    Parameters
    ----------
    progress : bool
        Print a line per inversion.

    Returns
    -------
    inversions : pandas.DataFrame
        One row per inversion (the constants, then :func:`_summary`'s columns).
    constants : pandas.DataFrame
        The estimates: one row per constant, with its standard error, how and assumption.
    observed : dict
        The observations' means and σ, and the integrator.
    """
    with tempfile.TemporaryDirectory() as tmp:
        doc = observe_catalogue(ROOT / CATALOGUE, list(COLUMNS), Path(tmp) / "obs", area=AREA,
                                normal_stress=NORMAL_STRESS, after_delay=AFTER_DELAY,
                                mass=math.sqrt(math.prod(MASS_RANGE)))
        obs = read_observations(doc["files"]["observations"], curve_noise="none")
        problem = load_problem(doc["files"]["apparatus"])
    algorithm, why = recommended(ACCURACY)
    rows = []
    for v in variations(doc["constants"], problem.law.a):
        p = variant(problem, stiffness=v["stiffness"], vl=v["vl"], mass=v["mass"], a=v["a"])
        b_range = (v["a"], v["a"] + B_SPAN)
        lc_hi, lc_lo = box_lc(B_SPAN, p.normal_force, p.stiffness)
        start = time.perf_counter()
        inv = invert(Misfit(p, obs, algorithm), b_range, (lc_lo, lc_hi))
        rows.append({**v, "b_lo": b_range[0], "b_hi": b_range[1], "lc_lo_m": lc_lo,
                     "lc_hi_m": lc_hi, **_summary(inv), "wall_s": time.perf_counter() - start})
        if progress:
            r = rows[-1]
            print(f"{v['label']}: b = {r['b_fit']:.6g}, Lc = {r['lc_fit_m']:.3g} m "
                  f"({r['wall_s']:.0f} s)", flush=True)
    observed = {"recurrence_s": obs.recurrence_s, "sigma_recurrence_s": obs.sigma_recurrence_s,
                "friction_drop": obs.friction_drop, "sigma_friction_drop":
                obs.sigma_friction_drop, "n_events": doc["n_events"],
                "n_events_used": doc["n_events_used"], "integrator": why}
    return pd.DataFrame(rows), _constants_table(doc, problem.law.a), observed


def _summary(inv) -> dict:
    """An inversion's fit, profile intervals and posterior as one row (NaN where absent)."""
    f, pb, pl = inv.fit, inv.profiles["b"], inv.profiles["log10_lc"]
    row = {"b_fit": f.b, "lc_fit_m": f.lc, "misfit_fit": f.misfit, "sigma_b_fit": f.sigma_b,
           "sigma_log10_lc_fit": f.sigma_log10_lc,
           "b_profile_low": pb.low, "b_profile_high": pb.high,
           "b_profile_open": _open(pb), "log10_lc_profile_low": pl.low,
           "log10_lc_profile_high": pl.high, "log10_lc_profile_open": _open(pl),
           "profile_warnings": " | ".join([*pb.warnings, *pl.warnings])}
    post = inv.posterior
    if post is None:
        return {**row, "posterior": "none", "no_posterior": inv.no_posterior,
                **{k: math.nan for k in ("b_post_mean", "b_post_low", "b_post_high",
                                         "log10_lc_post_mean", "log10_lc_post_low",
                                         "log10_lc_post_high")},
                "fit_in_posterior": False, "solves": inv.misfit.failures["solves"]}
    ib, il = _interval(post, "b"), _interval(post, "log10_lc")
    x = (f.b, math.log10(f.lc)) if f.lc > 0 else (math.nan, math.nan)
    return {**row, "posterior": inv.method, "no_posterior": "",
            "b_post_mean": post.mean["b"], "b_post_low": ib[0], "b_post_high": ib[1],
            "log10_lc_post_mean": post.mean["log10_lc"], "log10_lc_post_low": il[0],
            "log10_lc_post_high": il[1],
            "fit_in_posterior": bool(ib[0] <= x[0] <= ib[1] and il[0] <= x[1] <= il[1]),
            "solves": inv.misfit.failures["solves"]}


def _open(p) -> str:
    """Which ends of a profile's interval are the box's (not resolved by the data)."""
    return "+".join(e for e, o in (("low", p.open_low), ("high", p.open_high)) if o) or "no"


def _interval(post, name: str) -> tuple[float, float]:
    """The 95 % interval of a grid posterior, or of a sample's quantiles."""
    if hasattr(post, "interval"):
        return tuple(post.interval[name])
    q = post.samples[name].quantile([0.025, 0.975])
    return float(q.iloc[0]), float(q.iloc[1])


def _constants_table(doc: dict, a_base: float) -> pd.DataFrame:
    """The estimates of the catalogue (and the mass and a, not in it) as rows."""
    c, a = doc["constants"], doc["apparatus"]
    rows = [{"constant": name, "value": c[key]["value"], "se": c[key]["se"],
             "unit": c[key]["unit"], "how": c[key]["how"], "assumption": c[key]["assumption"]}
            for name, key in (("k/Fn", "stiffness_per_fn"), ("k", "stiffness"),
                              ("k per unit area", "stiffness_per_area"), ("vL", "vl"),
                              ("loading rate", "loading_rate"))]
    rows += [{"constant": "k, regression through the origin", "value":
              c["stiffness_regression"] * a["normal_force"], "se": math.nan, "unit": "N/m",
              "how": "measured", "assumption": "least squares of the drops on the slips: a check"},
             {"constant": "vL, median interval", "value": c["vl_median_interval"],
              "se": math.nan, "unit": "m/s", "how": "measured",
              "assumption": "the median of the intervals' loading rates over k/Fn: a check"},
             {"constant": "mass", "value": a["mass"], "se": math.nan, "unit": "kg",
              "how": "assumed", "assumption": f"{c['mass']}; a metagabbro block "
              f"({DENSITY:g} kg/m³) on the 4 m × 0.1 m fault, 0.1–1 m high: "
              f"{MASS_RANGE[0]:.0f}–{MASS_RANGE[1]:.0f} kg, their geometric mean"},
             {"constant": "a", "value": a_base, "se": math.nan, "unit": "", "how": "assumed",
              "assumption": "the paper's for the same rock (Table 4); not in the catalogue"}]
    return pd.DataFrame(rows)


#: the constants as the table and the figure show them: column, label, scale, unit
SHOWN = (("stiffness", "k", 1e-8, "10⁸ N/m"), ("vl", "vL", 1e6, "µm/s"), ("mass", "m", 1.0, "kg"),
         ("a", "a", 1.0, ""))


def nied_markdown(inversions: pd.DataFrame, constants: pd.DataFrame, observed: dict) -> str:
    """The report: the observations, the estimates, one row per inversion, how (b, Lc) move
    with each constant and what the record leaves open — every number read from the tables.

    Parameters
    ----------
    inversions, constants : pandas.DataFrame
        ``nied_catalogue.csv`` and ``nied_catalogue_constants.csv``.
    observed : dict
        The observations' means and σ (:func:`nied_inversions`).

    Returns
    -------
    str
        Markdown.
    """
    o = observed
    lines = [f"The catalogue: {o['n_events']} events, {o['n_events_used']} in the means (the "
             f"start-up left out): ΔT = {o['recurrence_s']:.4g} s, σ {o['sigma_recurrence_s']:.3g}"
             f" s; Δμ = {o['friction_drop']:.4g}, σ {o['sigma_friction_drop']:.3g} (σ: the "
             f"events' scatter). Integrator: {o['integrator']}.", "",
             "The constants (± 1 standard error; the mass and a are not in the catalogue):", "",
             markdown_table(constants.assign(
                 value=constants.value.map(lambda x: f"{x:.4g}"),
                 se=constants.se.map(lambda x: "–" if not np.isfinite(x) else f"{x:.2g}"))
                 [["constant", "value", "se", "unit", "how", "assumption"]]), "",
             "Each inversion (profile intervals: Δ misfit ≤ 3.84; posterior: the grid's 95 % "
             "region, or why there is none):", "", markdown_table(_rows(inversions)), ""]
    lines += ["How (b, Lc) move with each constant (profile intervals; b − a, since a varied "
              "moves b with it):", ""]
    lines += _moves(inversions) + ["", "What the record leaves open:", ""]
    lines += _open_questions(inversions)
    lines += ["", f"{len(inversions)} inversions, {inversions.wall_s.sum() / 60:.1f} min in all "
              f"({inversions.solves.sum():,} forward solves)."]
    return "\n".join(lines) + "\n"


def _rows(inv: pd.DataFrame) -> pd.DataFrame:
    """The inversions' table as shown."""
    def interval(lo, hi, fmt):
        return "–" if not np.isfinite(lo) else f"{lo:{fmt}} – {hi:{fmt}}"
    out = pd.DataFrame({"inversion": inv.label})
    for key, label, scale, unit in SHOWN:
        out[f"{label} ({unit})" if unit else label] = (inv[key] * scale).map(lambda x: f"{x:.4g}")
    out["b fit"] = inv.b_fit.map(lambda x: f"{x:.6g}")
    out["b − a"] = (inv.b_fit - inv.a).map(lambda x: f"{x:.3g}")
    out["b 95 % (profile)"] = [interval(lo, hi, ".6g") for lo, hi in
                               zip(inv.b_profile_low, inv.b_profile_high)]
    out["Lc fit (µm)"] = (inv.lc_fit_m * 1e6).map(lambda x: f"{x:.3g}")
    out["log10 Lc 95 % (profile)"] = [
        interval(lo, hi, ".3f") + ("" if o == "no" else f" (open: {o})") for lo, hi, o in
        zip(inv.log10_lc_profile_low, inv.log10_lc_profile_high, inv.log10_lc_profile_open)]
    out["posterior b; log10 Lc (95 %)"] = [
        f"none: {why[:60]}…" if kind == "none" else
        f"{interval(bl, bh, '.6g')}; {interval(ll, lh, '.3f')}"
        for kind, why, bl, bh, ll, lh in zip(inv.posterior, inv.no_posterior, inv.b_post_low,
                                             inv.b_post_high, inv.log10_lc_post_low,
                                             inv.log10_lc_post_high)]
    out["misfit"] = inv.misfit_fit.map(lambda x: f"{x:.2g}")
    out["s"] = inv.wall_s.map(lambda x: f"{x:.0f}")
    return out


def _moves(inv: pd.DataFrame) -> list[str]:
    """A line per constant, from its lowest value to its highest: the fit's b − a, the 95 %
    profile interval of b − a, and the upper end of Lc's, beside the base's."""
    def excess(r):
        return f"{r.b_profile_low - r.a:.3g} – {r.b_profile_high - r.a:.3g}"
    base = inv.iloc[0]
    lines = []
    for key, label, scale, unit in SHOWN:
        g = pd.concat([inv.iloc[[0]], inv[inv.varied == key]]).sort_values(key)
        lo, hi = g.iloc[0], g.iloc[-1]
        lines.append(
            f"* {label} from {lo[key] * scale:.4g} to {hi[key] * scale:.4g}"
            f"{' ' + unit if unit else ''}: the fit's b − a {lo.b_fit - lo.a:.3g} → "
            f"{hi.b_fit - hi.a:.3g} (b {lo.b_fit:.6g} → {hi.b_fit:.6g}); b − a's 95 % interval "
            f"{excess(lo)} → {excess(hi)} (base {excess(base)}); the upper end of Lc's 95 % "
            f"interval {10 ** lo.log10_lc_profile_high * 1e6:.3g} → "
            f"{10 ** hi.log10_lc_profile_high * 1e6:.3g} µm (base "
            f"{10 ** base.log10_lc_profile_high * 1e6:.3g} µm).")
    return lines


def _open_questions(inv: pd.DataFrame) -> list[str]:
    """What the inversions leave open, counted from the table."""
    n = len(inv)
    open_low = int(inv.log10_lc_profile_open.str.contains("low").sum())
    at_edge = int((np.isclose(inv.lc_fit_m, inv.lc_lo_m, rtol=0.05, atol=0.0)).sum())
    post = inv[inv.posterior != "none"]
    lines = [f"* The profile of log10 Lc is open at the low end of the box (10 nm) in "
             f"{open_low} of {n} inversions: no Lc below its upper limit is excluded. The "
             f"least-squares Lc lies at that edge in {at_edge} of {n} (its Gauss–Newton σ of "
             f"log10 Lc, median: {inv.sigma_log10_lc_fit.median():.2g} decades — no "
             "information).",
             f"* A grid posterior was reported in {len(post)} of {n} inversions; its 95 % "
             f"region contains the least-squares fit in {int(post.fit_in_posterior.sum())} of "
             "them" + (": where the fit is at the box's edge, the posterior's central interval "
                       "(2.5 % to 97.5 %) cannot reach it, however much of its mass piles up "
                       "there" if at_edge else "")
             + ("." if len(post) == n else "; where none was reported: " + "; ".join(
                 sorted(set(inv.no_posterior[inv.posterior == "none"]))) + ".")]
    return lines


def plot_nied(inv: pd.DataFrame, path: Path) -> None:
    """(b − a, Lc) against each constant: the least-squares fit with its profile interval, and
    the posterior's 95 % region beside it; the base's interval shaded. b − a, not b: a varied
    moves b with it, and b − a is what the cycle feels.

    Parameters
    ----------
    inv : pandas.DataFrame
        ``nied_catalogue.csv``.
    path : pathlib.Path
        The figure written.
    """
    fig = Figure(figsize=(13, 6))
    axes = fig.subplots(2, len(SHOWN), sharey="row")
    base = inv.iloc[0]
    for j, (key, label, scale, unit) in enumerate(SHOWN):
        g = pd.concat([inv.iloc[[0]], inv[inv.varied == key]])
        x = g[key].to_numpy() * scale
        for i, (fit, lo, hi, plo, phi) in enumerate((
                (g.b_fit - g.a, g.b_profile_low - g.a, g.b_profile_high - g.a,
                 g.b_post_low - g.a, g.b_post_high - g.a),
                (np.log10(g.lc_fit_m), g.log10_lc_profile_low, g.log10_lc_profile_high,
                 g.log10_lc_post_low, g.log10_lc_post_high))):
            ax = axes[i, j]
            ax.axhspan(lo.iloc[0], hi.iloc[0], color="0.85", label="base: profile 95 %")
            ax.errorbar(x, fit, yerr=[fit - lo, hi - fit], fmt="o", color="C0", capsize=3,
                        label="fit, profile 95 %")
            dx = 0.012 * (np.ptp(x) or abs(x[0]))
            mid = (plo + phi) / 2
            ax.errorbar(x + dx, mid, yerr=[mid - plo, phi - mid], fmt="none", color="C1",
                        capsize=3, label="posterior 95 %")
            ax.set_xlabel(f"{label} ({unit})" if unit else label)
        axes[0, j].axvline(base[key] * scale, color="0.5", lw=0.8, ls=":")
        axes[1, j].axvline(base[key] * scale, color="0.5", lw=0.8, ls=":")
    axes[0, 0].set_ylabel("b − a")
    axes[1, 0].set_ylabel("log10 Lc (m)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("NIED 4-m catalogue fb03-087: (b, Lc) as each assumed constant varies "
                 "(dotted: the base)", fontsize=10)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def run(out: Path) -> None:
    inversions, constants, observed = nied_inversions(progress=True)
    write_table(inversions, out / "nied_catalogue.csv")
    write_table(constants, out / "nied_catalogue_constants.csv")
    text = nied_markdown(inversions, constants, observed)
    write_output(out / "nied_catalogue.md", text)
    plot_nied(inversions, out / "nied_catalogue.png")
    print(text)


def report(out: Path) -> str:
    return (markdown_file("nied_catalogue.md")(out)
            + "\n![(b, Lc) against each constant](nied_catalogue.png)\n")


STUDY = Study("nied-catalogue", "A real catalogue end to end: NIED's 4-m apparatus "
              "(`nied_catalogue.*`)", 215, run, report=report, plan="full",
              data=(CATALOGUE,), minutes=8,
              writes=("nied_catalogue.csv", "nied_catalogue_constants.csv", "nied_catalogue.md",
                      "nied_catalogue.png"))
