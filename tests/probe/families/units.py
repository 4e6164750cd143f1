"""Probe cases: dimensional inputs in an implausible unit (kind ``units``).

Every entry of :data:`problems._validate.PLAUSIBLE` is probed at its edges through the object
that holds it (a law, a loading, an initial state, the slider, the observations): just inside
each bound no warning, just outside a :class:`~problems._validate.UnitWarning` that names the
parameter, its value and its unit, and at the bound of the impossible a refusal. So a range
added to the table is probed without a new case. Beside the edges: the derived checks (an
initial θ read as a slip rate, Fs against Fn, σ against its mean), the apparatuses of the
literature that must never warn, a sweep and an ensemble that warn once (not once a point), and
the command line, where a warning is one ``warning:`` line on the standard error and an
impossible value a one-line refusal.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

from probe.harness import Case, Observed, Wrong, cli, cli_outcome, one_json

__all__ = ["cases"]

KIND = "units"
_EPS = 1e-9          # "just outside": a relative step no unit slip is as small as


def _unit_warnings(make):
    """Run ``make()``; its UnitWarnings' messages (every one: the filter is "always"), a
    RegularCycleWarning's too (a σ far below its mean, said as a regular cycle)."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        make()
    return [str(w.message) for w in seen
            if type(w.message).__name__ in ("UnitWarning", "RegularCycleWarning")]


def _expect(make, name: str, unit: str, expect: str):
    """A case's run: ``expect`` "warned" (one UnitWarning naming ``name =`` and ``unit``, and
    no other about it) or "ok" (none naming ``name``)."""
    def run(tmp):
        seen = _unit_warnings(make)
        mine = [m for m in seen if m.startswith(f"{name} = ")]
        if expect == "ok":
            if mine:
                raise Wrong(f"a plausible value warned: {mine[0]}")
            return Observed("ok")
        if len(mine) != 1:
            raise Wrong(f"expected one UnitWarning naming {name!r}, got {seen}")
        if unit and f" {unit}" not in mine[0]:
            raise Wrong(f"the warning does not name the unit {unit!r}: {mine[0]}")
        return Observed("warned", mine[0])
    return run


# --- every plausible range, at its edges ----------------------------------------------------------

def _holders() -> dict:
    """PLAUSIBLE key: [(the object that holds it, the name it is reported under, a builder of
    the object from a value)]: every law for a law's field, every slider field, every loading."""
    from benchmarks.inversion.observations import Observations
    from problems import (
        AgingLaw,
        ConstantLoading,
        InitialState,
        LoadHistory,
        NagataLaw,
        SlipLaw,
        TwoSpeedLoading,
        paper_example,
        velocity_step_test,
    )
    from problems.presets import fault_radiation_damping
    law = dict(a=0.008, b=0.0092, lc=5e-7, v0=1e-5)
    two = dict(vls=1e-4, vlf=1e-3, df=0.04)
    hist = dict(velocities=(1e-4, 2e-4), switch_times=(1.0,), overshoot_velocity=1e-3,
                overshoot_duration=0.04, reference_velocity=2e-4)
    paper = paper_example(t_end=1.0)
    # t_end of a long run on the laboratory apparatus (Lc = 10 µm): within TAU_END_MAX
    lab = dataclasses.replace(velocity_step_test("aging"), loading=ConstantLoading(1e-6))
    obs = dict(recurrence_s=3.1, sigma_recurrence_s=0.31, friction_drop=0.046,
               sigma_friction_drop=0.0046)

    def observations(field, v):
        # a σ is given its mean's value (σ/mean = 1, plausible), a mean a σ of 10 % of it
        pair = {"recurrence_s": "sigma_recurrence_s", "friction_drop": "sigma_friction_drop"}
        mean = {s: m for m, s in pair.items()}
        kw = dict(obs, **{field: v})
        if field in pair:
            kw[pair[field]] = 0.1 * v
        else:
            kw[mean[field]] = max(v, 1e-5) if field == "sigma_friction_drop" else v
        return Observations(**kw)

    out = {k: [(c.__name__, k, lambda v, c=c, k=k: c(**{**law, k: v}))
               for c in (SlipLaw, AgingLaw, NagataLaw)] for k in ("a", "b", "lc", "v0")}
    out["vl"] = [("ConstantLoading", "vl", lambda v: ConstantLoading(v))]
    for k in two:
        out[k] = [("TwoSpeedLoading", k, lambda v, k=k: TwoSpeedLoading(**{**two, k: v}))]
    out["velocity"] = [("LoadHistory", "velocities[1]",
                        lambda v: LoadHistory(**{**hist, "velocities": (1e-4, v)}))]
    out["time"] = [("LoadHistory", "switch_times[0]",
                    lambda v: LoadHistory(**{**hist, "switch_times": (v,)}))]
    for k in ("overshoot_velocity", "overshoot_duration", "reference_velocity"):
        out[k] = [("LoadHistory", k, lambda v, k=k: LoadHistory(**{**hist, k: v}))]
    out["slip_rate"] = [("InitialState", "initial v",
                         lambda v: InitialState(v=v, theta=1.0, fs=6e5))]
    for k in ("mass", "stiffness", "normal_force", "radiation_damping", "mu0"):
        out[k] = [("SpringSlider", k, lambda v, k=k: dataclasses.replace(paper, **{k: v}))]
    out["t_end"] = [("SpringSlider", "t_end", lambda v: dataclasses.replace(lab, t_end=v))]
    for k in ("recurrence_s", "friction_drop", "sigma_recurrence_s", "sigma_friction_drop"):
        out[k] = [("Observations", k, lambda v, k=k: observations(k, v))]
    out["density"] = [("fault_radiation_damping", "density", fault_radiation_damping)]
    return out


#: fields that take 0 as an allowed limit (b = 0, no mass, no damping, no overshoot, a hold)
_ZERO_ALLOWED = {"b", "mass", "radiation_damping", "df", "overshoot_duration", "velocity"}


def _edge_cases() -> list[Case]:
    from problems._validate import PLAUSIBLE
    holders = _holders()
    missing = sorted(set(PLAUSIBLE) - set(holders))
    if missing:                      # a range added without a holder here: probe it too
        raise RuntimeError(f"no probe holder for the plausible range of {missing}")
    out = []
    for key, p in PLAUSIBLE.items():
        edges = [(p.low, "ok", "at the lower bound"), (p.low * (1 - _EPS), "warned", "just below"),
                 (p.high * (1 - _EPS), "ok", "just under the upper bound"),
                 (p.high, "warned", "at the upper bound")]
        if key in _ZERO_ALLOWED and p.zero_ok:
            edges.append((0.0, "ok", "zero (an allowed limit)"))
        if math.isfinite(p.impossible):
            edges += [(p.impossible * (1 - _EPS), "warned", "just under the impossible"),
                      (p.impossible, "refused", "at the impossible")]
        for owner, name, build in holders[key]:
            for value, expect, label in edges:
                if owner == "NagataLaw" and value == 0.0:
                    continue                 # its stress term needs b > 0 (refused, not a unit)
                title = f"{owner}.{name} = {value:.10g} ({label})"
                if expect == "refused":
                    out.append(Case(KIND, title, lambda tmp, b=build, v=value: b(v), "refused",
                                    names=name))
                else:
                    out.append(Case(KIND, title, _expect(lambda b=build, v=value: b(v), name,
                                                         p.unit, expect), expect))
    return out


# --- the checks that are not one field against a range ----------------------------------------------

def _derived_cases() -> list[Case]:
    from benchmarks.inversion.observations import Observations
    from problems import InitialState, window

    def start(law, **kw):
        p = window("W2", law, t_end=1.0)
        ini = p.initial_state
        return lambda: dataclasses.replace(p, initial=InitialState(
            **{**dict(v=ini.v, theta=ini.theta, fs=ini.fs), **kw}))

    def obs(**kw):
        return lambda: Observations(**{**dict(recurrence_s=3.1, sigma_recurrence_s=0.31,
                                              friction_drop=0.046, sigma_friction_drop=0.0046),
                                       **kw})
    doubtful = {     # name: (builder, the parameter named, its unit, expected)
        "aging theta = 1e-12 s (steady at 0.3 km/s)": (start("aging", theta=1e-12),
                                                      "initial theta", "s", "warned"),
        "aging theta = 1e30 s (older than the universe)": (start("aging", theta=1e30),
                                                          "initial theta", "s", "warned"),
        "aging theta = 1e5 s (a day's hold)": (start("aging", theta=1e5), "initial theta", "s",
                                               "ok"),
        "slip theta = -1e6 N (steady far above 10 m/s)": (start("slip", theta=-1e6),
                                                          "initial theta", "N", "warned"),
        "fs = 0.6 N (a friction coefficient for a force)": (start("slip", fs=0.6),
                                                            "initial fs", "N", "warned"),
        "fs = 6e7 N (60 times Fn)": (start("slip", fs=6e7), "initial fs", "N", "warned"),
        "fs = 0 (an unloaded spring)": (start("slip", fs=0.0), "initial fs", "N", "ok"),
        "sigma_recurrence_s = 310 (ms for s)": (obs(sigma_recurrence_s=310.0),
                                                "sigma_recurrence_s", "", "warned"),
        "sigma_friction_drop = 0.46 (percent of 0.046)": (obs(sigma_friction_drop=0.46),
                                                          "sigma_friction_drop", "", "warned"),
        "sigma_friction_drop = 1e-5 (below 0.1 % of its mean: a regular cycle, said so)": (
            obs(sigma_friction_drop=1e-5), "sigma_friction_drop", "", "warned"),
        "sigma_friction_drop = 1e-7 (below 0.1 % of its mean and implausible: said once)": (
            obs(sigma_friction_drop=1e-7), "sigma_friction_drop", "", "warned"),
    }
    out = [Case(KIND, name, _expect_derived(make, who, unit, expect), expect)
           for name, (make, who, unit, expect) in doubtful.items()]
    impossible = {
        "mu0 = 1e300": (lambda: dataclasses.replace(window("W2"), mu0=1e300), "mu0"),
        "mu0 = 60 (percent)": (lambda: dataclasses.replace(window("W2"), mu0=60.0), "mu0"),
        "mu0 = -0.1": (lambda: dataclasses.replace(window("W2"), mu0=-0.1), "mu0"),
        "friction_drop = 84 (percent of the friction)": (obs(friction_drop=84.0,
                                                            sigma_friction_drop=8.4),
                                                        "friction_drop"),
        "window b = 9.2 (percent)": (lambda: window("W2", b=9.2), "b"),
    }
    out += [Case(KIND, f"refused: {name}", lambda tmp, f=f: f(), "refused", names=n)
            for name, (f, n) in impossible.items()]
    return out


def _expect_derived(make, name, unit, expect):
    def run(tmp):
        seen = [m for m in _unit_warnings(make) if m.startswith(f"{name} = ")]
        if expect == "ok":
            if seen:
                raise Wrong(f"a plausible start warned: {seen[0]}")
            return Observed("ok")
        if len(seen) != 1 or (unit and unit not in seen[0]):
            raise Wrong(f"expected one UnitWarning naming {name!r} in {unit!r}, got {seen}")
        return Observed("warned", seen[0])
    return run


# --- real apparatuses never warn ---------------------------------------------------------------------

def _apparatus_cases() -> list[Case]:
    from benchmarks.inversion.observations import observations
    from problems import (
        BalancedStart,
        ConstantLoading,
        SpringSlider,
        law_from_name,
        load_problem,
        paper_example,
        slide_hold_slide_test,
        velocity_step_test,
        window,
    )
    from problems.presets import fault_radiation_damping
    apparatus = Path(__file__).resolve().parents[3] / "docs" / "examples" / "apparatus.toml"

    def slider(fn, k, m, vl, lc, t_end, a=0.01, b=0.015, v0=None, law="aging"):
        return lambda: SpringSlider(
            mass=m, stiffness=k, normal_force=fn, law=law_from_name(law, a=a, b=b, lc=lc,
                                                                    v0=v0 or vl),
            loading=ConstantLoading(vl), initial=BalancedStart(),
            t_end=t_end)
    real = {
        "paper example, both laws": lambda: [paper_example(law) for law in ("slip", "aging")],
        "W1–W4, every law": lambda: [window(w, law) for w in ("W1", "W2", "W3", "W4")
                                     for law in ("slip", "aging", "nagata")],
        "W1–W4 observations": lambda: [observations(w) for w in ("W1", "W2", "W3", "W4")],
        "the paper's fault, radiation-damped": lambda: dataclasses.replace(
            window("W2"), radiation_damping=fault_radiation_damping()),
        "Marone's apparatus (rsfmodel): step and slide-hold-slide": lambda: [
            velocity_step_test(law) for law in ("slip", "aging", "nagata")] + [
            slide_hold_slide_test(law) for law in ("slip", "aging", "nagata")],
        "docs/examples/apparatus.toml": lambda: load_problem(apparatus),
        # double-direct shear (BRAVA, Penn State): 2 × 5 cm × 5 cm at 20 MPa, 10 µm/s
        "double-direct shear, 1e5 N at 10 µm/s": slider(1e5, 5e8, 0.0, 1e-5, 1e-5, 100.0),
        # high-velocity rotary shear (SHIVA): 20 MPa on 1.5e-3 m², 6.5 m/s
        "rotary shear, 3e4 N at 6.5 m/s": slider(3e4, 1e9, 10.0, 6.5, 1e-3, 10.0, a=0.005,
                                                 b=0.01, v0=1.0),
        # low-stress gouge: 0.1 MPa on 1 cm², a gram-scale slider on a soft spring
        "low-stress gouge, 10 N, 1 g": slider(10.0, 1e3, 1e-3, 1e-6, 1e-6, 100.0),
        # a natural fault patch: 10 MPa on 10 m², at a plate rate, for 30 years
        "fault patch at 3 cm/yr for 30 years": slider(9.9e7, 1e10, 1e4, 1e-9, 5e-3, 9.5e8,
                                                      v0=1e-9),
    }
    return [Case(KIND, f"never warns: {name}", _no_warning(make), "ok")
            for name, make in real.items()]


def _no_warning(make):
    def run(tmp):
        seen = _unit_warnings(make)
        if seen:
            raise Wrong(f"a real apparatus warned: {seen[0]}")
        return Observed("ok")
    return run


# --- warned once, not once a point ------------------------------------------------------------------

def _sweep_once(tmp):
    from benchmarks.inversion.observations import Observations
    from benchmarks.inversion.sweep import sweep
    from integrators import ETD2
    from problems import window

    def run():
        problem = dataclasses.replace(window("W2", t_end=0.05), normal_force=5.0)
        obs = Observations(3.1, 0.31, 8.4, 0.84)
        sweep(problem, [0.0093, 0.0094], [0.3], ETD2(), obs, tmp / "s", workers=1,
              progress=False)
    seen = _unit_warnings(run)
    names = sorted(m.split(" = ")[0] for m in seen)
    if names != ["friction_drop", "lc", "normal_force"]:
        raise Wrong(f"a sweep of 2 points with three doubtful values warned {len(seen)} times: "
                    f"{names}")
    return Observed("warned", "; ".join(seen))


def _ensemble_once(tmp):
    from benchmarks.ensemble import ensemble, grid
    from integrators import ETD2
    from problems import window

    def run():
        ensemble(window("W2", t_end=0.05), ETD2(), grid(normal_force=[2.0, 3.0, 4.0, 5.0, 6.0]),
                 store=tmp / "e", workers=1, progress=False)
    seen = _unit_warnings(run)
    if not 1 <= len(seen) <= 2 or not all(m.startswith("normal_force = ") for m in seen):
        raise Wrong(f"an axis of 5 implausible normal forces warned {len(seen)} times: {seen}")
    return Observed("warned", seen[0])


# --- the command line: one warning line, one refusal line -------------------------------------------

_SIM = ("simulate", "--preset", "W2", "--t-end", "0.05", "--wall-budget", "5",
        "--integrator", "Rodas5P", "--rtol", "1e-6", "--atol", "1e-6")
_SWEEP = ("sweep", "--preset", "W2", "--b", "0.0094:0.0094:0.0001", "--lc", "3e-7:3e-7:1",
          "--t-end", "1", "--workers", "1", "--no-plot", "--no-progress", "--no-solver-check",
          "--out", "{tmp}/s")                 # the units' warnings alone, not the check's

_LAB = ("lab", "step", "--t-step", "1", "--after", "2", "--no-progress")


def _cli_warns(args, name):
    def run(tmp):
        got = cli(*[str(a).replace("{tmp}", str(tmp)) for a in args], "--json")
        outcome = cli_outcome(got, json_mode=True)
        one_json(got.out)
        lines = [x for x in got.err.splitlines() if "warning:" in x and "UnitWarning" not in x]
        mine = [x for x in lines if x.startswith(f"rsfbench: warning: {name} = ")]
        if len(mine) != 1:
            raise Wrong(f"expected one 'rsfbench: warning:' line naming {name}, got {lines}")
        if outcome.outcome == "traceback":
            return outcome
        return Observed("warned", mine[0])
    return run


def _cli_cases() -> list[Case]:
    warned = {
        "simulate --lc 0.3 (µm for m)": (_SIM + ("--lc", "0.3"), "lc"),
        "simulate --b 0.92 (percent)": (_SIM + ("--b", "0.92"), "b"),
        "sweep --obs-drop 8.4 (percent)": (_SWEEP + ("--obs-drop", "8.4"), "friction_drop"),
        "sweep --sigma-drop 0.46 (percent of the mean)": (_SWEEP + ("--sigma-drop", "0.46"),
                                                          "sigma_friction_drop"),
        "sweep --sigma-recurrence 310 (ms for s)": (_SWEEP + ("--sigma-recurrence", "310"),
                                                    "sigma_recurrence_s"),
        "sweep --obs-recurrence 1e11": (_SWEEP + ("--obs-recurrence", "1e11"), "recurrence_s"),
        "lab step --v2 10 (µm/s for m/s)": (_LAB + ("--v2", "10"), "velocities[1]"),
        "lab step --mass 1e6 (g for kg)": (_LAB + ("--mass", "1e6"), "mass"),
        "lab step --stiffness 10 (a stiffness per µm)": (_LAB + ("--stiffness", "10"),
                                                         "stiffness"),
    }
    out = [Case(KIND, f"command line warns once: {name}", _cli_warns(args, who), "warned",
                timeout=300) for name, (args, who) in warned.items()]
    refused = {
        "simulate --b 1.5": (_SIM + ("--b", "1.5"), "b = 1.5"),
        "sweep --obs-drop 84": (_SWEEP + ("--obs-drop", "84"), "friction_drop"),
        "sweep --obs-drop 10": (_SWEEP + ("--obs-drop", "10"), "friction_drop"),
    }
    for name, (args, must) in refused.items():
        def run(tmp, args=args):
            got = cli_outcome(cli(*[str(a).replace("{tmp}", str(tmp)) for a in args], "--json"),
                              json_mode=True)
            if (tmp / "s" / "chunks").exists() and any((tmp / "s" / "chunks").iterdir()):
                raise Wrong("points were run before the refusal")
            return got
        out.append(Case(KIND, f"command line refuses: {name}", run, "refused", names=must))
    return out


def cases() -> list[Case]:
    return (_edge_cases() + _derived_cases() + _apparatus_cases()
            + [Case(KIND, "a sweep warns once, not once a point", _sweep_once, "warned",
                    timeout=300),
               Case(KIND, "an ensemble axis warns at most twice (its ends)", _ensemble_once,
                    "warned", timeout=300)]
            + _cli_cases())
