"""Probe cases: classifying runs at and near the edges of stability (kind ``classification``).

Four families, each complete by construction:

* the ladder around the critical stiffness: k = kcr (1 ± 10⁻ⁿ), n = 0…12, and k = kcr exactly,
  under the slip and the aging law (the paper example, constant loading). Each rung's class
  must agree with the sign of the growth rate σ of steady sliding (Routh–Hurwitz, not the
  roots); a run without events that is "too short to classify" must promise a length, and
  where that length is cheap the rerun there must be classified; at k = kcr to within what σ
  can resolve, the neutral oscillation is classified at once;
* masses and stiffnesses toward the float limits (and a = b, b = 0, the quasi-static slider
  at its kcr): no traceback, and a class the linear stability allows;
* a load switch at every distance from t_end (0, 1 ulp, 1e−15 … 1e−6 s, and at t = 0+),
  for every backend of the registry, at two run lengths: every run must reach t_end and be
  classified; a switch to the same speed changes nothing, so that run must end where the run
  without a switch ends (a step to twice the speed is checked for reaching its end);
* degenerate inputs: no event, one event, events at one instant, a run of one step, with σ = 0,
  −0 or unknown: never a cycle, always a reason;
* an ensemble whose points sit on neutral stability: every chunk is stored, each point with
  its class and reason.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np

from probe.harness import Case, Observed, Wrong, cli, cli_outcome, one_json  # noqa: F401

__all__ = ["cases"]

KIND = "classification"
#: the rungs' run length (s) and the longest rerun a fast case makes to check a promise
T_END = 5.0
PROMISE_CAP = 400.0
#: distances of a load switch from t_end (s); "ulp" is the double just below t_end, "0+"
#: the switch at the smallest positive double (the whole run at the second speed)
SWITCH_DISTANCES = ("ulp", 1e-15, 1e-14, 1e-13, 1e-12, 1e-11, 1e-10, 1e-9, 1e-8, 1e-7, 1e-6,
                    "0+")
_PROMISE = re.compile(r"run to t_end ≥ ([0-9.e+]+) s")


def _rodas():
    from integrators import Rodas5P
    return Rodas5P(rtol=1e-8, atol=1e-8)


def _hurwitz_stable(problem) -> bool:
    """Is steady sliding linearly stable by Routh–Hurwitz (all coefficients positive and
    a2 a1 > a3 a0), compared in logarithms so that no product overflows: the sign of σ
    without the roots' rounding (np.roots loses Re s beside a huge Im s)."""
    from problems.stability import characteristic_polynomial
    with np.errstate(all="ignore"):
        a3, a2, a1, a0 = (float(c) for c in characteristic_polynomial(problem))
    if not all(c > 0 for c in (a2, a1, a0)) or a3 < 0:
        return False
    if a3 == 0.0:                              # quasi-static: a quadratic, positive coefficients
        return True
    return math.log(a2) + math.log(a1) > math.log(a3) + math.log(a0)


def _check_class(problem, sol, lc) -> str:
    """Raise :class:`Wrong` if the class of a run that reached its end contradicts the linear
    stability of steady sliding or breaks the promise rule; returns a short account."""
    from benchmarks.physics.metrics import CYCLES, end_state
    from problems.stability import growth_rate
    what, n = lc.classification, len(sol.events)
    if what in CYCLES:
        if not np.isfinite(lc.recurrence_s) or lc.recurrence_s <= 0:
            raise Wrong(f"{what} with a recurrence interval {lc.recurrence_s}")
        return what
    if not lc.reason or not np.isnan(lc.recurrence_s):
        raise Wrong(f"{what}: no reason, or metrics ({lc.recurrence_s}) on a run without a cycle")
    stable = _hurwitz_stable(problem)
    end = end_state(sol)
    if what == "stable sliding" and not (stable and end.near_steady):
        raise Wrong(f"stable sliding where Routh–Hurwitz says stable={stable} and the end is "
                    f"{end.describe()}")
    if what == "oscillation about vL" and n == 0:
        try:
            g = growth_rate(problem)
        except ValueError:
            g = math.nan
        if not ("small limit cycle" in lc.reason and not stable
                or "neutral stability" in lc.reason and abs(g) * end.longest_run < 50):
            raise Wrong(f"an oscillation without events where σ = {g:g} (stable: {stable}): "
                        f"{lc.reason}")
    if what == "too short to classify" and n == 0 and "run to t_end ≥" not in lc.reason \
            and "unknown linear stability" not in lc.reason and _on_band(end):
        raise Wrong(f"'too short' on an oscillation about vL without a promised length: "
                    f"{lc.reason}")
    return what


def _on_band(end) -> bool:
    from integrators.core import cycles
    return bool(cycles.on_oscillation(end.log_v, end.state_offset, end.force_offset))


def _promise_kept(problem, lc, algorithm, cap: float) -> str:
    """If ``lc`` promises a length ≤ ``cap`` s, rerun there: it must be classified."""
    from benchmarks.physics.metrics import summarize
    from integrators import solve
    m = _PROMISE.search(lc.reason)
    if not m:
        return ""
    t_promised = float(m.group(1)) * (1 + 1e-6)
    if t_promised > cap:
        return f"; promise {t_promised:.3g} s not rerun (cap {cap:g} s)"
    longer = dataclasses.replace(problem, t_end=t_promised)
    sol = solve(longer, algorithm, max_points=2001, wall_budget=60)
    again = summarize(sol)
    if again.classification in ("too short to classify", "failed"):
        raise Wrong(f"promised classified by t_end = {t_promised:.4g} s, got "
                    f"{again.classification}: {again.reason}")
    _check_class(longer, sol, again)
    return f"; at the promised {t_promised:.4g} s: {again.classification}"


# --- the ladder around kcr -----------------------------------------------------------------

def _rung(law: str, factor: float, cap: float = PROMISE_CAP):
    def run(tmp):
        from benchmarks.physics.metrics import summarize
        from integrators import solve
        from problems import critical_stiffness, paper_example
        p = paper_example(law=law, t_end=T_END)
        problem = dataclasses.replace(p, stiffness=critical_stiffness(p) * factor)
        algorithm = _rodas()
        sol = solve(problem, algorithm, max_points=2001, wall_budget=60)
        lc = summarize(sol)
        if lc.classification == "failed":
            raise Wrong(f"Rodas5P at 1e-8 failed: {lc.reason}")
        what = _check_class(problem, sol, lc)
        if abs(factor - 1.0) <= 1e-12 and what != "oscillation about vL":
            raise Wrong(f"k = kcr (1 {factor - 1:+.0e}): {what}, not the neutral oscillation: "
                        f"{lc.reason}")
        return Observed("ok", f"{what}{_promise_kept(problem, lc, algorithm, cap)}")
    return run


def _ladder_cases() -> list[Case]:
    out = []
    for law in ("slip", "aging"):
        out.append(Case(KIND, f"{law} law, k = kcr exactly", _rung(law, 1.0), "ok"))
        for n in range(13):
            for sign in (-1, 1):
                factor = 1.0 + sign * 10.0 ** -n
                label = f"{law} law, k = kcr (1 {'-' if sign < 0 else '+'} 1e-{n})"
                if factor == 0.0:          # k = 0: refused, naming the stiffness
                    out.append(Case(KIND, label, _rung(law, factor), "refused",
                                    names="stiffness"))
                else:
                    out.append(Case(KIND, label, _rung(law, factor), "ok", timeout=180))
        # the promises of the slower rungs kept (a rerun of a few thousand seconds)
        for n, sign in ((3, -1), (4, 1)):
            factor = 1.0 + sign * 10.0 ** -n
            out.append(Case(KIND, f"{law} law, k = kcr (1 {'-' if sign < 0 else '+'} 1e-{n}): "
                            "the promised length kept", _rung(law, factor, cap=5000.0), "ok",
                            slow=True, timeout=600))
    return out


# --- masses and stiffnesses toward the float limits ----------------------------------------

def _extreme(label: str, make, expect_classes):
    """A variant of the paper example run 0.5 s: no traceback, a class allowed by linear
    stability; a run the integrator cannot do is ``failed`` with NaN metrics (``retcode``)."""
    def run(tmp):
        from benchmarks.physics.metrics import summarize
        from integrators import solve
        problem = make()
        sol = solve(problem, _rodas(), max_points=2001, wall_budget=30)
        lc = summarize(sol)
        if lc.classification == "failed":
            if sol.reached_end or not np.isnan(lc.recurrence_s) or not lc.reason:
                raise Wrong(f"failed, yet reached its end or has metrics: {lc}")
            return Observed("retcode", lc.reason)
        what = _check_class(problem, sol, lc)
        if what not in expect_classes:
            raise Wrong(f"{what}, expected one of {expect_classes}: {lc.reason}")
        return Observed("ok", f"{what}: {lc.reason}")
    return run


def _extreme_cases() -> list[Case]:
    from problems import critical_stiffness, paper_example
    tiny, huge = 5e-324, 1.7e308

    def base(law="slip"):
        return paper_example(law=law, t_end=0.5)

    stable = ("stable sliding", "too short to classify")
    unknown = ("stable sliding", "too short to classify", "oscillation about vL")
    specs = {   # label: (make, expected outcome, classes a successful run may have)
        "mass = 5e-324 (smallest double)": (lambda: dataclasses.replace(base(), mass=tiny),
                                            "retcode", ()),
        "mass = 1e-300": (lambda: dataclasses.replace(base(), mass=1e-300), "retcode", ()),
        "mass = 1e30 (k far below its kcr)": (lambda: dataclasses.replace(base(), mass=1e30),
                                              "ok", ("too short to classify",
                                                     "oscillation about vL")),
        "mass = 1e300": (lambda: dataclasses.replace(base(), mass=1e300), "ok",
                         ("too short to classify", "oscillation about vL")),
        "mass = 1.7e308 (largest double)": (lambda: dataclasses.replace(base(), mass=huge),
                                            "ok", ("too short to classify",
                                                   "oscillation about vL")),
        "stiffness = 1e30": (lambda: dataclasses.replace(base(), stiffness=1e30), "ok", stable),
        "stiffness = 1e300": (lambda: dataclasses.replace(base(), stiffness=1e300), "ok",
                              stable),
        "stiffness = 1.7e308 (largest double)": (
            lambda: dataclasses.replace(base(), stiffness=huge), "ok", stable),
        "stiffness = 1e-30": (lambda: dataclasses.replace(base(), stiffness=1e-30), "ok",
                              ("too short to classify",)),
        "stiffness = 5e-324 (smallest double)": (
            lambda: dataclasses.replace(base(), stiffness=tiny), "retcode", ()),
        "a = b (κ infinite)": (lambda: base().with_law(b=base().law.a), "ok", stable),
        "b = 0 (aging law)": (lambda: base("aging").with_law(b=0.0), "ok", stable),
        "b = 0 (slip law)": (lambda: base("slip").with_law(b=0.0), "ok", stable),
    }
    for law in ("slip", "aging"):
        def quasi_static_kcr(law=law):
            q = dataclasses.replace(base(law), mass=0.0)
            return dataclasses.replace(q, stiffness=critical_stiffness(q))
        specs[f"quasi-static at its kcr ({law} law)"] = (quasi_static_kcr, "ok", unknown)
    return [Case(KIND, label, _extreme(label, make, classes), expect, timeout=120)
            for label, (make, expect, classes) in specs.items()]


# --- a load switch at every distance from t_end, every backend -----------------------------

def _switch_problem(t_switch: float | None, t_end: float = 0.05, step: float = 1.0):
    """The paper example to ``t_end`` with a switch of the load speed by the factor ``step`` at
    ``t_switch`` (None: no switch). With ``step`` 1 the physics is the same as without the
    switch, only the restart differs."""
    from problems import LoadHistory, paper_example
    p = paper_example(t_end=t_end)
    if t_switch is None:
        return p
    vl = p.loading.v_slow
    return dataclasses.replace(p, loading=LoadHistory((vl, vl * step), (t_switch,),
                                                      reference_velocity=vl))


def _switch_time(distance, t_end: float) -> float:
    if distance == "ulp":
        return math.nextafter(t_end, 0.0)
    if distance == "0+":
        return 5e-324
    return t_end - distance


def _algorithm(name: str):
    from integrators import REGISTRY, make_algorithm
    cls = REGISTRY[name]
    return make_algorithm(name, rtol=1e-6, atol=1e-9) if cls.adaptive else make_algorithm(name)


def _switch_ladder(name: str, t_end: float):
    def run(tmp):
        from benchmarks.physics.metrics import summarize
        from integrators import solve
        algorithm = _algorithm(name)
        ref = solve(_switch_problem(None, t_end), algorithm, wall_budget=20)
        if not ref.reached_end:
            raise Wrong(f"the run without a switch did not reach its end: {ref.message}")
        v_ref = float(ref.v[-1])
        bad = []
        for d in SWITCH_DISTANCES:
            for step in (1.0, 2.0):        # the same speed, and a step up to twice it
                problem = _switch_problem(_switch_time(d, t_end), t_end, step)
                sol = solve(problem, algorithm, wall_budget=20)
                lc = summarize(sol)
                if lc.classification == "failed" or not sol.reached_end:
                    bad.append(f"{d} (x{step:g}): {lc.classification} ({lc.reason[:80]})")
                elif step == 1.0 and not abs(float(sol.v[-1]) / v_ref - 1.0) < 1e-3:
                    bad.append(f"{d}: ends at v = {sol.v[-1]:.6g}, without the switch "
                               f"{v_ref:.6g}")
        if bad:
            raise Wrong(f"{len(bad)} of {len(SWITCH_DISTANCES)} distances: " + "; ".join(bad))
        return Observed("ok", f"{len(SWITCH_DISTANCES)} distances, ends at v = {v_ref:.6g}")
    return run


def _switch_at_t_end(tmp):
    problem = _switch_problem(0.05)           # a switch at t_end itself: refused
    raise Wrong(f"a switch at t_end = {problem.t_end} s was accepted")


def _switch_cases() -> list[Case]:
    from integrators import REGISTRY
    out = [Case(KIND, "a load switch at t_end exactly is refused", _switch_at_t_end, "refused",
                names="t_end")]
    for name, cls in REGISTRY.items():
        # the own methods (one compiled engine) and one library through the shared segment
        # driver run in the fast probe; every other backend, ~5-15 s for its 13 solves, in
        # make test-slow
        # the drivers treat a switch within 1e-12 τ_end of the end as the end: two run
        # lengths put the ladder's distances on both sides of that (0.05 s: 5e-14 s; 2 s:
        # 2e-12 s); explicit methods take minutes for 2 s of this stiff problem
        fast = "own" in cls.tags or name == "sundials-CVODE-BDF"
        for t_end in (0.05, 2.0) if cls.stiff else (0.05,):
            out.append(Case(KIND, f"{name}: a switch 1 ulp, 1e-15…1e-6 s before t_end = "
                            f"{t_end:g} s, or at 0+", _switch_ladder(name, t_end), "ok",
                            slow=not fast, timeout=600))
    return out


# --- an ensemble on neutral stability is stored ---------------------------------------------

def _neutral_ensemble(algorithm_name: str):
    def run(tmp):
        from benchmarks.ensemble import ensemble
        from problems import critical_stiffness, paper_example
        p = paper_example(t_end=2.0)
        kcr = critical_stiffness(p)
        k = np.array([kcr, kcr * (1 + 1e-12), kcr * (1 - 1e-12), 1e300])
        store = tmp / "chunks"
        kw = dict(store=store, chunk_size=2, workers=1, progress=False, wall_budget=30)
        table = ensemble(p, _algorithm(algorithm_name), {"stiffness": k}, **kw)
        files = sorted(store.glob("*.parquet"))
        if len(files) != 2:
            raise Wrong(f"{len(files)} chunk files stored for 2 chunks")
        for row in table.itertuples():
            if row.classification != "failed" and not row.message:
                raise Wrong(f"k = {row.stiffness:g}: {row.classification} without a reason")
        neutral = table.classification.iloc[:3].tolist()
        if neutral != ["oscillation about vL"] * 3:
            raise Wrong(f"k = kcr (1, 1 ± 1e-12): {neutral}: {table.message.iloc[0]}")
        again = ensemble(p, _algorithm(algorithm_name), {"stiffness": k}, **kw)
        if again.attrs.get("n_resumed") != 4:
            raise Wrong(f"a rerun resumed {again.attrs.get('n_resumed')} of 4 points")
        return Observed("ok", "; ".join(f"{c}" for c in table.classification))
    return run


def _ensemble_cases() -> list[Case]:
    return [Case(KIND, f"an ensemble on neutral stability is stored ({name})",
                 _neutral_ensemble(name), "ok", timeout=300)
            for name in ("Rodas5P", "sundials-CVODE-BDF")]


# --- degenerate inputs to the classification ------------------------------------------------

def _events(starts, duration=0.01):
    import pandas as pd
    t = np.asarray(starts, dtype=float)
    slip = np.arange(len(t)) * 1e-4
    return pd.DataFrame({"t_start": t, "t_end": t + duration, "fs_max_before": 6.1e5,
                         "fs_min": 6.0e5, "v_peak": 0.02, "t_peak": t + duration / 2,
                         "slip_start": slip, "slip_end": slip + 1e-4})


def _degenerate(starts, growth, longest=5e10):
    """:func:`benchmarks.physics.metrics.limit_cycle` of events starting at ``starts`` and an end 0.2 A
    from steady sliding with growth rate ``growth``: never a cycle, always a reason."""
    def run(tmp):
        from benchmarks.physics.metrics import CYCLES, EndState, limit_cycle
        end = EndState(log_v=0.2, state_offset=0.2, force_offset=0.2, growth_rate=growth,
                       longest_run=longest)
        lc = limit_cycle(_events(starts), 1e6, 10.0, v_slow=1e-4, end=end)
        if lc.classification in CYCLES or not lc.reason or not np.isnan(lc.recurrence_s):
            raise Wrong(f"{lc.classification} ({lc.recurrence_s}) from {len(starts)} events: "
                        f"{lc.reason}")
        return Observed("retcode", f"{lc.classification}: {lc.reason}")
    return run


def _one_step(tmp):
    """A run as short as one step (1 ns): classified, not raised."""
    from benchmarks.physics.metrics import summarize
    from integrators import solve
    from problems import paper_example
    sol = solve(paper_example(t_end=1e-9), _rodas())
    lc = summarize(sol)
    if lc.classification != "too short to classify" or "no event in 1e-09 s" not in lc.reason:
        raise Wrong(f"{lc.classification}: {lc.reason}")
    return Observed("retcode", lc.reason)


def _degenerate_cases() -> list[Case]:
    out = [Case(KIND, "a run of one step (t_end = 1 ns)", _one_step, "retcode")]
    for label, starts in (("no event", []), ("one event", [1.0]),
                          ("eight events at one instant", [1.0] * 8),
                          ("two events", [1.0, 2.0])):
        for g_label, g in (("σ = 0", 0.0), ("σ unknown (NaN)", math.nan), ("σ = -0.0", -0.0)):
            out.append(Case(KIND, f"{label}, {g_label}", _degenerate(starts, g), "retcode"))
    return out


def cases() -> list[Case]:
    return (_ladder_cases() + _extreme_cases() + _degenerate_cases() + _switch_cases()
            + _ensemble_cases())
