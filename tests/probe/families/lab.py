"""Probe cases: lab — laboratory measures (:mod:`benchmarks.lab.measures`, ``rsfbench lab``).

Families, each complete by construction:

* every numeric flag of ``rsfbench lab`` × every kind of bad value, and the flags of the other
  test, the flags a problem file states, combinations that measure nothing: refused in one line
  naming the flag (with ``--json``, one JSON document);
* every step ratio of :data:`benchmarks.lab.measures.STEP_REFERENCE` through the command line at its
  defaults, at two ``--after`` (save grids ten times apart): the peak and its time as the tight
  reference, and the same on both;
* the same through the API at 50 and 200,000 saved points;
* problem files whose loading switches, holds, steps down, never settles, cannot be measured;
* what the measures must refuse through the API (not a Solution, a failed or truncated run, an
  overshoot, a peak after the end).
"""

from __future__ import annotations

import json
import math
import warnings

from probe.harness import Case, Observed, Wrong, cli, cli_outcome, one_json

__all__ = ["cases"]

KIND = "lab"
LC, V1 = 1e-5, 1e-6         # the laboratory apparatus's Dc (m), the default --v1 (m/s)

#: (test, flag, what it is: p positive / n non-negative)
FLAGS = (("step", "--v1", "p"), ("step", "--v2", "p"), ("step", "--t-step", "p"),
         ("step", "--after", "p"), ("shs", "--holds", "p"), ("shs", "--v", "p"),
         ("shs", "--slide", "p"), ("shs", "--first-slide", "p"), ("step", "--mass", "n"),
         ("step", "--radiation-damping", "n"), ("step", "--stiffness", "p"),
         ("step", "--c", "n"), ("step", "--rtol", "p"), ("step", "--atol", "p"))
#: (label, text, applies to p / n)
BAD = (("negative", "-1", "pn"), ("zero", "0", "p"), ("nan", "nan", "pn"), ("inf", "inf", "pn"),
       ("text", "1e-6m", "pn"))


def _refusal(*args, names: str, json_mode: bool = False):
    def run(tmp):
        argv = [str(a).replace("{tmp}", str(tmp)) for a in args]
        return cli_outcome(cli("lab", *argv, "--no-progress", *(("--json",) if json_mode
                                                                  else ())), json_mode)
    return run


def _flag_cases() -> list[Case]:
    out = []
    for test, flag, kind in FLAGS:
        for label, text, applies in BAD:
            if kind in applies:
                out.append(Case(KIND, f"lab {test} {flag} {label}",
                                _refusal(test, flag, text, names=flag), "refused", names=flag))
    more = {     # name: (arguments, what the refusal names)
        "step --holds (an option of shs)": (("step", "--holds", "5"), "--holds"),
        "shs --after (an option of step)": (("shs", "--after", "5"), "--after"),
        "step --c without --law nagata": (("step", "--c", "1"), "--c"),
        "step --c -1 --law nagata": (("step", "--law", "nagata", "--c", "-1"), "--c"),
        "step --v2 equal to --v1": (("step", "--v1", "2e-6", "--v2", "2e-6"), "--v2"),
        "step --law friction": (("step", "--law", "friction"), "--law"),
        "step --integrator Foo": (("step", "--integrator", "Foo"), "Foo"),
        "step --integrator Rodas5P without --rtol": (("step", "--integrator", "Rodas5P"),
                                                     "rtol"),
        "step --rtol 2": (("step", "--rtol", "2"), "rtol"),
        "step --integrator ETD2 without mass": (("step", "--integrator", "ETD2"), "mass"),
        "step --t-step 1e13 (beyond double precision)": (("step", "--t-step", "1e13"),
                                                          "--t-step"),
        "step --after 0.5 (before the peak)": (("step", "--after", "0.5"), "--after"),
        "step --v2 1e-7 --after 1e-3 (before the trough)": (
            ("step", "--v2", "1e-7", "--after", "1e-3"), "--after"),
        "shs --slide 2 (before the reload's peak)": (("shs", "--holds", "1", "--slide", "2"),
                                                      "--slide"),
        "step --out onto a file": (("step", "--out", "{tmp}/f"), "--out"),
        "lab (no test)": ((), "{step,shs,fit}"),
        "lab drop": (("drop",), "drop"),
    }
    for name, (args, names) in more.items():
        for json_mode in (False, True):
            out.append(Case(KIND, name + (" --json" if json_mode else ""),
                            _with_file("f", _refusal(*args, names=names, json_mode=json_mode)),
                            "refused", names=names))
    return out


def _with_file(name: str, run):
    """``run`` with a plain file ``name`` in its directory (what ``--out {tmp}/f`` meets)."""
    def wrapped(tmp):
        (tmp / name).write_text("not a directory")
        return run(tmp)
    return wrapped


# --- the measures against the tight reference, on two save grids -------------------------------
def _after(ratio: float, factor: float) -> float:
    return factor * LC / (V1 * min(ratio, 1.0))


def _step_cli(law: str, mass: float, ratio: float):
    def run(tmp):
        from benchmarks.lab.measures import SETTLED, STEP_REFERENCE
        from problems.presets import LAB
        t_ref, jump_ref = STEP_REFERENCE[(law, mass, ratio)]
        a, b = LAB["a"], LAB["b"]
        rows = []
        for factor in (60.0, 600.0):
            done = cli("lab", "step", "--law", law, "--mass", str(mass), "--v2",
                       str(V1 * ratio), "--after", str(_after(ratio, factor)), "--json",
                       "--no-progress")
            got = cli_outcome(done, json_mode=True)
            if got.outcome != "ok":
                return got
            rows.append(one_json(done.out)["steps_response"][0])
        for row, factor in zip(rows, (60, 600)):
            _near(row["t_extreme_s"] - 10.0, t_ref, 1e-6, f"peak time (--after {factor} Dc)")
            _near(row["mu_extreme"] - row["mu_before"], jump_ref, 1e-6,
                  f"peak excursion (--after {factor} Dc)")
            if not row["settled"] or row["delta_mu_ss"] is None:
                raise Wrong(f"60 Dc after the step is not settled: {row}")
            # settled: both ends within SETTLED × a |ln(v2/v1)| of steady sliding
            _near(row["delta_mu_ss"], row["expected_delta_mu_ss"],
                  2 * SETTLED * a / abs(a - b), "the steady change")
        _near(rows[0]["mu_extreme"], rows[1]["mu_extreme"], 1e-9, "the peak on the two grids")
        return Observed("ok", f"excursion {rows[0]['mu_extreme'] - rows[0]['mu_before']:+.9g}")
    return run


def _near(got, want, rel, what):
    if got is None or not abs(got - want) <= rel * abs(want):
        raise Wrong(f"{what}: {got!r}, the reference {want!r} (relative tolerance {rel:g})")


def _step_api(ratio: float):
    def run(tmp):
        from benchmarks.lab.measures import STEP_REFERENCE, step_response
        from integrators import Rodas5P, solve
        from problems import velocity_step_test
        t_ref, jump_ref = STEP_REFERENCE[("aging", 0.0, ratio)]
        p = velocity_step_test(v2=V1 * ratio, t_end=10.0 + _after(ratio, 60.0))
        for n in (50, 200_000):
            row = step_response(solve(p, Rodas5P(rtol=1e-8, atol=1e-8), max_points=n)).iloc[0]
            _near(row.t_extreme_s - 10.0, t_ref, 1e-6, f"peak time ({n} saved points)")
            _near(row.mu_extreme - row.mu_before, jump_ref, 1e-6, f"excursion ({n} points)")
        return Observed("ok")
    return run


def _reference_cases() -> list[Case]:
    from benchmarks.lab.measures import STEP_REFERENCE
    out = [Case(KIND, f"lab step --law {law} --mass {mass:g} --v2 {V1 * r:g}: the reference on "
                "two grids", _step_cli(law, mass, r), "ok", timeout=60)
           for law, mass, r in STEP_REFERENCE]
    out += [Case(KIND, f"step_response v2/v1 = {r:g} at 50 and 200,000 points", _step_api(r),
                 "ok", timeout=60) for r in (1e6, 1e5, 1e-3)]
    return out


# --- problem files ------------------------------------------------------------------------------
def _history(velocities, switches, t_end, initial=None, **loading):
    import dataclasses

    from problems import BalancedStart, LoadHistory, velocity_step_test
    base = velocity_step_test()
    return dataclasses.replace(base, loading=LoadHistory(tuple(velocities), tuple(switches),
                                                         **loading),
                               t_end=t_end, name="history",
                               initial=initial or BalancedStart(1.0))


def _write(tmp, problem, name="p.json"):
    from problems.files import problem_dict
    path = tmp / name
    path.write_text(json.dumps(problem_dict(problem)))
    return path


def _file_refusal(build, test: str, names: str, what: str = ""):
    def run(tmp):
        path = build(tmp)
        return cli_outcome(cli("lab", test, "--problem", str(path), "--no-progress"))
    return Case(KIND, f"lab {test} --problem: {what or names}", run, "refused", names=names)


def _file_history_measures(tmp):
    """Up, hold, reload, down: the command's measures equal a run at 1e−10 on another grid."""
    from benchmarks.lab.measures import healing, step_response
    from integrators import make_algorithm, solve
    p = _history((1e-6, 1e-5, 0.0, 1e-5, 1e-6), (10.0, 210.0, 230.0, 430.0), 1030.0)
    path = _write(tmp, p)
    runs = {t: cli("lab", t, "--problem", str(path), "--json", "--no-progress")
            for t in ("step", "shs")}
    for done in runs.values():
        got = cli_outcome(done, json_mode=True)
        if got.outcome != "ok":
            return got
    steps = one_json(runs["step"].out)["steps_response"]
    heal = one_json(runs["shs"].out)["healing"]
    tight = solve(p, make_algorithm("sundials-CVODE-BDF", 1e-10, 1e-10), max_points=777)
    want_steps, want_heal = step_response(tight), healing(tight)
    if [r["v_after"] for r in steps] != [1e-5, 1e-6] or len(heal) != 1:
        raise Wrong(f"rows: steps {[r['v_after'] for r in steps]}, holds {len(heal)}")
    for got, want in zip(steps, want_steps.to_dict(orient="records")):
        _near(got["mu_extreme"] - want["mu_before"], want["mu_extreme"] - want["mu_before"],
              1e-6, "a step's excursion")
    _near(heal[0]["delta_mu_peak"], float(want_heal.delta_mu_peak.iloc[0]), 1e-6,
          "the healing")
    return Observed("ok")


def _file_unsettled(tmp):
    """Issue 29: a first piece that never settled (a healed start, 0.5 Dc before the step)."""
    from problems import BalancedStart
    p = _history((1e-6, 1e-5), (5.0,), 65.0, initial=BalancedStart(3.0))
    done = cli("lab", "step", "--problem", str(_write(tmp, p)), "--json", "--no-progress")
    got = cli_outcome(done, json_mode=True)
    if got.outcome != "ok":
        return got
    row = one_json(done.out)["steps_response"][0]
    if row["delta_mu_ss"] is not None or row["settled"] or row["settled_before"]:
        raise Wrong(f"an unsettled baseline reported as steady: {row}")
    warned = [x for x in done.err.splitlines() if "warning:" in x and "not settled" in x]
    if not warned:
        raise Wrong(f"no warning names the unsettled piece: {done.err!r}")
    return Observed("warned", warned[0])


def _file_cases() -> list[Case]:
    def bad(**kw):
        return lambda tmp: _write(tmp, _history(**kw))
    out = [
        Case(KIND, "lab step/shs --problem: up, hold, reload, down as a tight run",
             _file_history_measures, "ok", timeout=60),
        Case(KIND, "lab step --problem: a first piece that never settled", _file_unsettled,
             "warned", timeout=60),
        _file_refusal(bad(velocities=(1e-6, 0.0, 1e-6), switches=(10.0, 20.0), t_end=200.0),
                      "step", "no velocity step"),
        _file_refusal(bad(velocities=(1e-6, 1e-5), switches=(10.0,), t_end=40.0), "shs",
                      "no hold followed by sliding"),
        _file_refusal(bad(velocities=(1e-6, 1e-6), switches=(10.0,), t_end=40.0), "step",
                      "no velocity step", "a switch to the same speed"),
        _file_refusal(bad(velocities=(1e-6, 1e-5, 1e-6), switches=(10.0, 40.0), t_end=80.0,
                          overshoot_velocity=1e-4, overshoot_duration=1.0), "step", "overshoot"),
        _file_refusal(bad(velocities=(1e-6, 1e-5), switches=(10.0,), t_end=10.2), "step",
                      "not reached inside the piece"),
        _file_refusal(lambda tmp: tmp / "missing.toml", "step", "missing.toml"),
        _file_refusal(lambda tmp: tmp, "step", "is not a file"),
        _file_refusal(lambda tmp: (tmp / "p.toml").write_text("mass = [") and tmp / "p.toml",
                      "step", "p.toml"),
    ]
    for flag, value in (("--mass", "1"), ("--after", "3"), ("--law", "slip")):
        def run(tmp, flag=flag, value=value):
            path = _write(tmp, _history((1e-6, 1e-5), (10.0,), 40.0))
            return cli_outcome(cli("lab", "step", "--problem", str(path), flag, value,
                                   "--no-progress"))
        out.append(Case(KIND, f"lab step --problem FILE {flag} {value}", run, "refused",
                        names=flag))
    return out


# --- the API --------------------------------------------------------------------------------------
def _api(make):
    def run(tmp):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            make()
        raise Wrong("measured without complaint")
    return run


def _api_cases() -> list[Case]:
    from benchmarks.lab.measures import healing, step_response
    from problems import window

    def solved(problem, **kw):
        from integrators import Rodas5P, solve
        return solve(problem, Rodas5P(rtol=1e-8, atol=1e-8, **kw))

    def vs(**kw):
        from problems import velocity_step_test
        return velocity_step_test(**kw)

    def retcode_run(tmp):
        from problems import velocity_step_test
        sol = solved(velocity_step_test("slip", t_end=20.0))
        if sol.success:
            raise Wrong("the slip law's tenfold step without mass did not run away")
        try:
            step_response(sol)
        except ValueError as exc:
            if "did not reach its end" not in str(exc):
                raise
            return Observed("retcode", str(exc))
        raise Wrong("a run that ran away was measured")

    out = [
        Case(KIND, "step_response('run.csv')", _api(lambda: step_response("run.csv")),
             names="solution"),
        Case(KIND, "healing(None)", _api(lambda: healing(None)), names="solution"),
        Case(KIND, "step_response of a run stopped by max_steps",
             _api(lambda: step_response(solved(vs(), max_steps=5))), names="did not reach"),
        Case(KIND, "healing of a run stopped by max_steps",
             _api(lambda: healing(solved(vs(), max_steps=5))), names="did not reach"),
        Case(KIND, "step_response of a two-speed (overshoot) run",
             _api(lambda: step_response(solved(window("W2", t_end=0.2)))), names="overshoot"),
        Case(KIND, "step_response with the peak after the end",
             _api(lambda: step_response(solved(vs(t_end=10.5)))), names="not reached"),
        Case(KIND, "step_response of a run that ran away (slip law, no mass)", retcode_run,
             "retcode"),
    ]

    def settled_after(tmp):
        from benchmarks.lab.measures import UnsettledWarning
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            row = step_response(solved(vs(v2=1e-7, t_end=40.0))).iloc[0]
        hits = [w for w in seen if issubclass(w.category, UnsettledWarning)]
        if not hits or row.settled_after or not math.isnan(row.delta_mu_ss):
            raise Wrong(f"0.3 Dc after a step down read as steady: {row.to_dict()}")
        return Observed("warned", str(hits[0].message))

    def constant_loading(tmp):
        from problems import paper_example
        sol = solved(paper_example("aging", t_end=0.05))
        if len(step_response(sol)) or len(healing(sol)):
            raise Wrong("a constant loading has a step or a hold")
        return Observed("ok")

    out += [Case(KIND, "step_response 30 s after a step down to 0.1 µm/s", settled_after,
                 "warned"),
            Case(KIND, "measures of a constant loading: empty tables", constant_loading, "ok")]
    return out


def _marone_case() -> Case:
    def run(tmp):
        done = cli("lab", "shs", "--holds", "100", "--first-slide", "10", "--slide", "100",
                   "--json", "--no-progress")
        got = cli_outcome(done, json_mode=True)
        if got.outcome != "ok":
            return got
        row = one_json(done.out)["healing"][0]
        # the vertex of Marone's rows (tests/test_problem_family.py), good to ~1e-9
        if not abs(row["mu_peak"] - 0.6204361366) <= 2e-8:
            raise Wrong(f"the peak after Marone's 100 s hold: {row['mu_peak']!r}, his 0.6204361366")
        return Observed("ok")
    return Case(KIND, "lab shs --holds 100: Marone's peak", run, "ok", timeout=60)


# --- lab fit: a record in, refused in one line when it cannot be fitted -------------------------
BASALT = (__import__("pathlib").Path(__file__).resolve().parents[2] / "data"
          / "lab-velocity-steps" / "velstep4_BRAVA_expb819_basalt.txt")
FIT_COLUMNS = ("--column", "time=Time(s):s", "--column", "friction=Friction", "--column",
               "load_point=Displ(microns):um")


def _fit_record(tmp, rows: str):
    path = tmp / "rec.csv"
    path.write_text("t,x,mu\n" + rows)
    return path


def _fit_cases() -> list[Case]:
    def on_basalt(*extra, json_mode=False, columns=FIT_COLUMNS):
        def run(tmp):
            return cli_outcome(cli("lab", "fit", str(BASALT), *columns, *extra,
                                   "--no-profiles", "--no-solver-check",
                                   *(("--json",) if json_mode else ())), json_mode)
        return run

    def on_rows(rows, *columns):
        def run(tmp):
            path = _fit_record(tmp, rows)
            return cli_outcome(cli("lab", "fit", str(path), *columns, "--no-profiles",
                                   "--no-solver-check"))
        return run

    ramp = "".join(f"{i * 0.1},{i * 0.1},0.6\n" for i in range(400))
    back = "".join(f"{i * 0.1},{(i if i < 200 else 400 - i) * 0.1},0.6\n" for i in range(400))
    nan = ramp.replace("0.6\n", "\n", 1)
    plain = ("--column", "time=t", "--column", "friction=mu", "--column", "load_point=x:um")
    refusals = {
        "no velocity step": (on_rows(ramp, *plain), "no velocity step"),
        "a load point that moves back": (on_rows(back, *plain), "moves back"),
        "a missing friction value": (on_rows(nan, *plain), "'mu'"),
        "--weights of the wrong count": (on_basalt("--weights", "1", "1", "1"), "--weights"),
        "--weights negative": (on_basalt("--weights", "1", "-1"), "--weights"),
        "--window with no step": (on_basalt("--window", "11700", "11720"), "no velocity step"),
        "--window outside the record": (on_basalt("--window", "0", "10"), "window"),
        "--stiffness 0": (on_basalt("--stiffness", "0"), "--stiffness"),
        "--c without nagata": (on_basalt("--c", "2"), "--c"),
        "--states 2 with --mass": (on_basalt("--states", "2", "--mass", "1",
                                             "--normal-force", "1e4"), "--states"),
        "--walkers without --posterior": (on_basalt("--walkers", "10"), "--walkers"),
        "--integrator ETD2": (on_basalt("--integrator", "ETD2"), "ETD2"),
        "displacement read as m": (on_basalt(columns=FIT_COLUMNS[:4] + (
            "--column", "load_point=Displ(microns)")), "unit"),
        "--json with no step": (on_basalt("--window", "11700", "11720", json_mode=True),
                                "no velocity step"),
    }
    return [Case(KIND, f"lab fit: {name}", run, "refused", names=names)
            for name, (run, names) in refusals.items()]


def cases() -> list[Case]:
    return (_flag_cases() + _reference_cases() + _file_cases() + _api_cases()
            + [_marone_case()] + _fit_cases())
