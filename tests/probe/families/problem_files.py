"""Probe cases: a user's own apparatus in a file (kind ``problem-files``), through every command
that takes ``--problem FILE`` (simulate, sweep, slip-weakening, invert, lab step, lab shs).

Valid files — every loading kind (constant, two speeds, a history with holds, steps up and down,
an overshoot), every law, mass 0, damping, an explicit initial state, in TOML and in JSON — must
read back as the problem they were written from, with the loading switches it has, and each
command must either succeed with a sane answer (checked against the Python API, or against the
history: one step response per velocity step, one healing row per hold) or refuse the file in
one line saying why (``lab step`` on a history without a step). Bad files — each key missing,
unknown, of the wrong type, out of range, non-finite; bad TOML or JSON, empty, a directory, a
FIFO, binary, a repeated JSON key — must be refused by every command in one line naming the key
or the file, before any work.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
from pathlib import Path

from probe.harness import Case, Observed, Wrong, cli, cli_outcome, one_json

__all__ = ["cases", "toml_text"]

KIND = "problem-files"
_TOL = ("--integrator", "Rodas5P", "--rtol", "1e-6", "--atol", "1e-6")


# --- writing a problem as a file ----------------------------------------------------------------

def _toml_value(x) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, str):
        return json.dumps(x)
    if isinstance(x, float):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf") if math.isinf(x) else repr(x)
    if isinstance(x, list):
        return "[" + ", ".join(_toml_value(v) for v in x) + "]"
    return str(x)


def toml_text(data: dict) -> str:
    """``data`` (a problem file's dict: scalars, then tables of scalars) as TOML."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for k, v in data.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{kk} = {_toml_value(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


def _write(tmp: Path, data, suffix: str = ".toml", name: str = "apparatus") -> Path:
    path = tmp / f"{name}{suffix}"
    if isinstance(data, bytes):
        path.write_bytes(data)
    elif isinstance(data, str):
        path.write_text(data)
    else:
        path.write_text(toml_text(data) if suffix == ".toml" else json.dumps(data))
    return path


# --- valid files -------------------------------------------------------------------------------

def _valid_problems() -> dict:
    """name: (a builder of the problem, its number of loading switches). Short runs: each
    command finishes in about a second once compiled."""
    from problems import (
        InitialState,
        LoadHistory,
        paper_example,
        slide_hold_slide_test,
        variant,
        velocity_step_test,
        window,
    )
    from problems.presets import fault_radiation_damping

    def steps_nagata():
        p = velocity_step_test("nagata", c=1.5, mass=3.0, t_step=5.0, t_end=20.0)
        return dataclasses.replace(p, loading=LoadHistory((1e-6, 1e-5, 1e-6), (5.0, 10.0)),
                                   name="steps up and down")

    def overshoot():
        return dataclasses.replace(window("W4", "slip", t_end=3.0), loading=LoadHistory(
            (0.7356e-3, 0.8e-3), (1.5,), overshoot_velocity=3.3027e-3, overshoot_duration=0.046),
            name="W4 with a faster second piece")

    def explicit_start():
        p = window("W4", "aging", t_end=3.0)
        ini = p.initial_state
        return dataclasses.replace(p, initial=InitialState(v=ini.v * 2, theta=ini.theta,
                                                           fs=ini.fs), name="W4 kicked")

    return {
        "constant/slip": (lambda: paper_example("slip", t_end=1.0), 0),
        "two-speed/slip": (lambda: window("W4", "slip", t_end=3.0), 0),
        "two-speed/aging": (lambda: window("W3", "aging", t_end=2.0), 0),
        "step up/aging/mass 0": (lambda: velocity_step_test("aging", t_step=5.0, t_end=15.0), 1),
        "step down/slip/mass 0": (lambda: velocity_step_test("slip", v1=1e-5, v2=1e-6,
                                                             t_step=5.0, t_end=15.0), 1),
        "steps up and down/nagata/mass": (steps_nagata, 2),
        "holds/aging/mass 0": (lambda: slide_hold_slide_test(
            "aging", holds=(1.0, 3.0), slide=40.0, first_slide=5.0), 4),
        "holds/nagata/mass 0, damped": (lambda: slide_hold_slide_test(
            "nagata", holds=(2.0,), slide=40.0, first_slide=5.0, c=1.5,
            radiation_damping=2.0), 2),
        "overshoot history/slip": (overshoot, 1),
        "explicit initial state/aging": (explicit_start, 0),
        "damped with mass/aging": (lambda: variant(window("W4", "aging", t_end=3.0),
                                                   radiation_damping=fault_radiation_damping()), 0),
    }


#: the valid problems whose short run reaches a limit cycle (W4's 0.44 s cycle repeats within
#: 3 s): slip-weakening samples them; the others it must refuse, naming their classification
#: (too short, not converged, stable sliding: checked by each case against the API)
_CYCLES = {"two-speed/slip"}


def _lab_rows(problem, test: str) -> int:
    """The rows ``lab step`` (steps between two sliding speeds) or ``lab shs`` (holds followed
    by sliding) must report, from the history alone; 0 means the command must refuse."""
    hist = problem.loading.history
    if hist.two_speed:
        pairs = []
    else:
        pairs = list(zip(hist.velocities, hist.velocities[1:]))
    if test == "step":
        return sum(1 for a, b in pairs if a > 0 and b > 0 and a != b)
    return sum(1 for a, b in pairs if a == 0 and b > 0)


def _read_back(path: Path, problem, switches: int):
    """The file must read back as ``problem``, with ``switches`` loading switches."""
    from problems import load_problem
    got = load_problem(path)
    if got != problem:
        raise Wrong(f"{path.name} reads back as another problem: {got} != {problem}")
    if len(got.loading.history.switch_times) != switches:
        raise Wrong(f"{path.name}: {len(got.loading.history.switch_times)} loading switches, "
                    f"expected {switches}")
    return got


def _valid_simulate(make, switches, suffix):
    def run(tmp):
        from integrators import Rodas5P, solve
        from problems.files import problem_dict
        problem = make()
        path = _write(tmp, problem_dict(problem), suffix)
        _read_back(path, problem, switches)
        got = cli("simulate", "--problem", path, *_TOL, "--json")
        out = cli_outcome(got, json_mode=True)
        doc = one_json(got.out)
        if out.outcome != "ok":
            return out
        api = solve(problem, Rodas5P(rtol=1e-6, atol=1e-6))
        if doc["retcode"] != "Success" or not api.success:
            raise Wrong(f"exit 0 but retcode {doc['retcode']} (API: {api.retcode.value})")
        if doc["t_end"] != problem.t_end or doc["n_events"] != len(api.events):
            raise Wrong(f"the command ran t_end = {doc['t_end']}, {doc['n_events']} events; the "
                        f"API {problem.t_end}, {len(api.events)}")
        return Observed("ok", f"{switches} switches, {doc['n_events']} events")
    return run


def _valid_sweep(make, switches):
    def run(tmp):
        from problems.files import problem_dict
        problem = make()
        path = _write(tmp, problem_dict(problem))
        _read_back(path, problem, switches)
        b, lc = problem.law.b, problem.law.lc
        got = cli("sweep", "--problem", path, "--b", f"{b!r}:{b!r}:0.0001", "--lc",
                  f"{lc!r}:{lc!r}:1", "--obs-recurrence", "1", "--obs-drop", "0.04",
                  "--workers", "1", "--no-plot", "--no-progress", "--out", tmp / "s",
                  *_TOL, "--json")
        out = cli_outcome(got, json_mode=True)
        if out.outcome != "ok":
            return out
        doc = one_json(got.out)
        if doc["n_points"] != 1 or doc["n_failed"] != 0:
            raise Wrong(f"a one-point sweep of a valid file: {doc['n_points']} points, "
                        f"{doc['n_failed']} failed ({doc['classification']})")
        return Observed("ok", f"{doc['classification']}")
    return run


def _valid_slip_weakening(make, switches):
    def run(tmp):
        from problems.files import problem_dict
        problem = make()
        path = _write(tmp, problem_dict(problem))
        got = cli("slip-weakening", "--problem", path, "--events", "2", "--out",
                  tmp / "c.csv", *_TOL, "--json")
        out = cli_outcome(got, json_mode=True)
        # the API's classification of the same run must agree with the command's answer
        from benchmarks.physics.metrics import CYCLES, summarize
        from integrators import Rodas5P, solve
        cycle = summarize(solve(problem, Rodas5P(rtol=1e-6, atol=1e-6)))
        if out.outcome == "ok":
            doc = one_json(got.out)
            if doc["events"] != 2 or not (tmp / "c.csv").stat().st_size:
                raise Wrong(f"asked for 2 events' curves, got {doc['events']}")
            if cycle.classification not in CYCLES:
                raise Wrong(f"curves from a run the API classifies {cycle.classification}")
        elif out.outcome == "refused" and cycle.classification not in out.detail:
            raise Wrong(f"refused without naming the run's classification "
                        f"({cycle.classification}): {out.detail}")
        return out
    return run


def _valid_lab(make, switches, test):
    def run(tmp):
        from problems.files import problem_dict
        problem = make()
        path = _write(tmp, problem_dict(problem))
        got = cli("lab", test, "--problem", path, "--json", "--no-progress")
        out = cli_outcome(got, json_mode=True)
        if out.outcome == "ok":
            doc = one_json(got.out)
            rows = len(doc["steps_response" if test == "step" else "healing"])
            if rows != _lab_rows(problem, test) or len(doc["switch_times_s"]) != switches:
                raise Wrong(f"lab {test}: {rows} rows for {_lab_rows(problem, test)} "
                            f"{'steps' if test == 'step' else 'holds'}, "
                            f"{len(doc['switch_times_s'])} switches for {switches}")
        return out
    return run


def _valid_invert(make, switches):
    def run(tmp):
        from problems.files import problem_dict
        problem = make()
        path = _write(tmp, problem_dict(problem))
        b, lc = problem.law.b, problem.law.lc
        got = cli("invert", "--problem", path, "--obs-recurrence", "0.44", "--obs-drop", "0.06",
                  "--b-range", f"{b * 0.95!r},{b * 1.05!r}", "--lc-range",
                  f"{lc / 2!r},{lc * 2!r}", "--steps", "0", "--profile-points", "3",
                  "--workers", "1", "--no-progress", "--out", tmp / "i", *_TOL, "--json")
        out = cli_outcome(got, json_mode=True)
        if out.outcome == "ok":
            one_json(got.out)
        return out
    return run


def _valid_cases() -> list[Case]:
    out = []
    for i, (name, (make, switches)) in enumerate(_valid_problems().items()):
        problem = make()
        for suffix in (".toml", ".json"):
            out.append(Case(KIND, f"simulate {name} ({suffix[1:]})",
                            _valid_simulate(make, switches, suffix), "ok", timeout=300))
        out.append(Case(KIND, f"sweep {name}", _valid_sweep(make, switches), "ok", timeout=300))
        stick = name in _CYCLES
        out.append(Case(KIND, f"slip-weakening {name}", _valid_slip_weakening(make, switches),
                        "ok" if stick else "refused", timeout=300,
                        names="" if stick else "no slip-weakening curves"))
        for test in ("step", "shs"):
            rows = _lab_rows(problem, test)
            must = ("overshoot" if problem.loading.two_speed
                    else "velocity step" if test == "step" else "hold")
            out.append(Case(KIND, f"lab {test} {name}", _valid_lab(make, switches, test),
                            "ok" if rows else "refused", timeout=300,
                            names="" if rows else must))
    make, switches = _valid_problems()["two-speed/slip"]
    out.append(Case(KIND, "invert two-speed/slip", _valid_invert(make, switches), "ok",
                    slow=True, timeout=1800))
    return out


# --- bad files ---------------------------------------------------------------------------------

def _base() -> dict:
    from problems import window
    from problems.files import problem_dict
    return problem_dict(window("W2", "slip", t_end=2.0))


def _history_base() -> dict:
    from problems import velocity_step_test
    from problems.files import problem_dict
    return problem_dict(velocity_step_test("aging", t_step=5.0, t_end=15.0))


def _without(data: dict, table: str | None, key: str) -> dict:
    data = json.loads(json.dumps(data))
    (data[table] if table else data).pop(key)
    return data


def _with(data: dict, table: str | None, key: str, value) -> dict:
    data = json.loads(json.dumps(data))
    (data[table] if table else data)[key] = value
    return data


def _bad_contents() -> dict:
    """name: (what the file holds — a dict, a text or bytes — , its suffix, what the refusal
    must name)."""
    base, hist = _base(), _history_base()
    bad = {}
    for key in ("mass", "stiffness", "normal_force", "t_end", "law", "loading"):
        bad[f"missing {key}"] = (_without(base, None, key), ".toml", key)
    for key in ("name", "a", "b", "lc"):
        bad[f"missing [law] {key}"] = (_without(base, "law", key), ".toml", key)
    for key in ("vls", "vlf", "df"):
        bad[f"missing [loading] {key}"] = (_without(base, "loading", key), ".toml", key)
    bad["unknown key masse"] = (_with(base, None, "masse", 1100.0), ".toml", "masse")
    bad["unknown [law] key Lc"] = (_with(base, "law", "Lc", 3e-7), ".toml", "Lc")
    bad["unknown [loading] key vl_s"] = (_with(base, "loading", "vl_s", 1e-4), ".toml", "vl_s")
    bad["unknown [initial] key slowdwn"] = (_with(base, "initial", "slowdwn", 1.1), ".toml",
                                           "slowdwn")
    bad["[law] c for the slip law"] = (_with(base, "law", "c", 2.0), ".toml", "'c'")
    bad["[loading] of no known form"] = (_with(base, None, "loading", {"velocity": 1e-4}),
                                         ".toml", "[loading]")
    bad["[initial] v without theta, fs"] = (_with(base, None, "initial", {"v": 1e-4}), ".toml",
                                            "theta")
    bad["overshoot_velocity without its duration"] = (_without(
        _with(hist, "loading", "overshoot_velocity", 1e-3), "loading", "overshoot_duration"),
        ".toml", "overshoot_duration")
    # wrong types
    bad["mass a string"] = (_with(base, None, "mass", "1100"), ".toml", "mass")
    bad["stiffness a bool"] = (_with(base, None, "stiffness", True), ".toml", "stiffness")
    bad["law a string"] = (_with(base, None, "law", "slip"), ".toml", "[law]")
    bad["loading a list"] = (_with(base, None, "loading", [1e-4]), ".toml", "[loading]")
    bad["[law] a a list"] = (_with(base, "law", "a", [0.008]), ".toml", "a in [law]")
    bad["[law] name a number"] = (_with(base, "law", "name", 3), ".toml", "name")
    bad["[law] name unknown"] = (_with(base, "law", "name", "ruina"), ".toml", "ruina")
    bad["name a number"] = (_with(base, None, "name", 7), ".toml", "name")
    bad["velocities a number"] = (_with(hist, "loading", "velocities", 1e-6), ".toml",
                                  "velocities")
    bad["velocities with a string"] = (_with(hist, "loading", "velocities", [1e-6, "1e-5"]),
                                       ".toml", "velocities[1]")
    # out of range, impossible, non-finite
    for key, value, must in (("mass", -1.0, "mass"), ("stiffness", 0.0, "stiffness"),
                             ("normal_force", -5.0, "normal_force"), ("t_end", -40.0, "t_end"),
                             ("mu0", 60.0, "mu0"), ("mu0", -0.1, "mu0"),
                             ("radiation_damping", -1.0, "radiation_damping"),
                             ("t_end", math.nan, "t_end"), ("t_end", math.inf, "t_end")):
        bad[f"{key} = {value}"] = (_with(base, None, key, value), ".toml", must)
    for key, value in (("a", 8.0), ("b", 1.5), ("lc", 0.0), ("v0", -1e-5), ("a", math.nan)):
        bad[f"[law] {key} = {value}"] = (_with(base, "law", key, value), ".toml", key)
    for key, value in (("vls", 0.0), ("df", -0.1), ("vlf", math.inf)):
        bad[f"[loading] {key} = {value}"] = (_with(base, "loading", key, value), ".toml", key)
    bad["switch_times decreasing"] = (_with(hist, None, "loading", {
        "velocities": [1e-6, 1e-5, 1e-6], "switch_times": [8.0, 5.0]}), ".toml", "switch_times")
    bad["a switch after t_end"] = (_with(hist, None, "t_end", 4.0), ".toml", "t_end")
    bad["only holds"] = (_with(hist, "loading", "velocities", [0.0, 0.0]), ".toml",
                         "velocities")
    bad["slowdown = 0"] = (_with(base, "initial", "slowdown", 0.0), ".toml", "slowdown")
    bad["initial v = 0"] = (_with(base, None, "initial", {"v": 0.0, "theta": 1.0,
                                                          "fs": 6e5}), ".toml", "slip rate v")
    bad["aging theta < 0"] = (_with(hist, None, "initial", {"v": 1e-6, "theta": -1.0,
                                                            "fs": 6e3}), ".toml", "theta")
    bad["mass 0, unbalanced fs"] = (_with(hist, None, "initial", {"v": 1e-6, "theta": 10.0,
                                                                  "fs": 5e3}), ".toml", "fs")
    bad["slip law b = 0 with theta"] = (_with(_with(base, "law", "b", 0.0), None, "initial",
                                              {"v": 1e-4, "theta": 1.0, "fs": 6e5}), ".toml",
                                        "theta")
    # JSON-only values and syntax
    text = json.dumps(base)
    bad["JSON NaN"] = (text.replace('"t_end": 2.0', '"t_end": NaN'), ".json", "t_end")
    bad["JSON Infinity"] = (text.replace('"mass": 1100.0', '"mass": Infinity'), ".json", "mass")
    bad["JSON integer of 400 digits"] = (text.replace('"mass": 1100.0', '"mass": 1' + "0" * 400),
                                         ".json", "mass")
    bad["JSON key twice"] = (text.replace('"mass": 1100.0', '"mass": 1100.0, "mass": 1.0'),
                             ".json", "mass")
    bad["JSON array"] = (json.dumps([base]), ".json", "table")
    bad["JSON number"] = ("3", ".json", "table")
    bad["JSON nested 100000 deep"] = ("[" * 100_000 + "]" * 100_000, ".json", "JSON")
    bad["JSON syntax"] = (text[:-1], ".json", "JSON")
    bad["TOML syntax"] = (toml_text(base).replace("[law]", "[law"), ".toml", "TOML")
    bad["TOML in a .json"] = (toml_text(base), ".json", "JSON")
    bad["empty TOML"] = ("", ".toml", "mass")
    bad["empty JSON"] = ("", ".json", "JSON")
    bad["binary"] = (bytes(range(256)) * 4, ".toml", "TOML")
    bad["UTF-16"] = (toml_text(base).encode("utf-16"), ".toml", "TOML")
    bad["suffix .yaml"] = (toml_text(base), ".yaml", ".toml or .json")
    return bad


def _commands(path: Path, tmp: Path) -> dict:
    """Every command that takes --problem, with the other arguments it needs."""
    return {
        "simulate": ("simulate", "--problem", path, *_TOL),
        "sweep": ("sweep", "--problem", path, "--b", "0.0094:0.0094:0.0001", "--lc",
                  "3e-7:3e-7:1", "--obs-recurrence", "1", "--obs-drop", "0.04", "--workers",
                  "1", "--no-plot", "--out", tmp / "s", *_TOL),
        "slip-weakening": ("slip-weakening", "--problem", path, "--out", tmp / "c.csv", *_TOL),
        "invert": ("invert", "--problem", path, "--obs-recurrence", "1", "--obs-drop", "0.04",
                   "--b-range", "0.008,0.012", "--lc-range", "1e-7,1e-6", "--steps", "0",
                   "--out", tmp / "i", *_TOL),
        "lab step": ("lab", "step", "--problem", path),
        "lab shs": ("lab", "shs", "--problem", path),
    }


def _bad_cli(content, suffix, command, json_mode):
    def run(tmp):
        path = _write(tmp, content, suffix)
        argv = _commands(path, tmp)[command] + (("--json",) if json_mode else ())
        got = cli_outcome(cli(*argv), json_mode)
        for out in ("s", "i"):
            if (tmp / out / "chunks").exists() and any((tmp / out / "chunks").iterdir()):
                raise Wrong("points were run before the refusal")
        return got
    return run


def _bad_api(content, suffix):
    def run(tmp):
        from problems import load_problem
        load_problem(_write(tmp, content, suffix))
        raise Wrong("a bad file was read as a problem")
    return run


def _bad_cases() -> list[Case]:
    out = []
    for name, (content, suffix, must) in _bad_contents().items():
        out.append(Case(KIND, f"load_problem: {name}", _bad_api(content, suffix), "refused",
                        names=must))
        for i, command in enumerate(_commands(Path("x"), Path("."))):
            # every other command also with --json: exactly one JSON document holding the error
            json_mode = (i + len(name)) % 2 == 0
            out.append(Case(KIND, f"{command}: {name}" + (" --json" if json_mode else ""),
                            _bad_cli(content, suffix, command, json_mode), "refused",
                            names=must, timeout=120))
    return out


# --- paths that are not a readable problem file -------------------------------------------------

def _path_cases() -> list[Case]:
    def directory(tmp):
        (tmp / "dir.toml").mkdir()
        return tmp / "dir.toml"

    def fifo(tmp):
        os.mkfifo(tmp / "pipe.toml")
        return tmp / "pipe.toml"

    def missing(tmp):
        return tmp / "missing.toml"

    def dangling(tmp):
        (tmp / "link.toml").symlink_to(tmp / "nowhere.toml")
        return tmp / "link.toml"

    def unreadable(tmp):
        path = _write(tmp, _base(), name="locked")
        path.chmod(0)
        return path

    makers = {"a directory": directory, "a FIFO": fifo, "missing": missing,
              "a dangling symlink": dangling}
    if os.geteuid() != 0:          # root reads a file of mode 000: the case could not fail
        makers["unreadable (mode 000)"] = unreadable
    out = []
    for label, make in makers.items():
        def api(tmp, make=make):
            from problems import load_problem
            load_problem(make(tmp))
            raise Wrong("a path that is no problem file was read")

        out.append(Case(KIND, f"load_problem: {label}", api, "refused", timeout=20,
                        names=".toml"))
        for command in _commands(Path("x"), Path(".")):
            def run(tmp, make=make, command=command):
                return cli_outcome(cli(*_commands(make(tmp), tmp)[command]))
            out.append(Case(KIND, f"{command}: {label}", run, "refused", timeout=20,
                            names=".toml"))
    return out


# --- files in a doubtful unit: read, run, and warned once ----------------------------------------

def _unit_cases() -> list[Case]:
    base = _base()
    slips = {      # name: (file, the parameter the warning must name)
        "normal_force in MPa (1.33)": (_with(base, None, "normal_force", 1.33), "normal_force"),
        "[loading] vls in µm/s (75)": (_with(base, "loading", "vls", 75.0), "vls"),
        "[law] lc in µm (0.3)": (_with(base, "law", "lc", 0.3), "lc"),
        "mass in g (1.1e6)": (_with(base, None, "mass", 1.1e6), "mass"),
        "[law] a in percent (0.8)": (_with(base, "law", "a", 0.8), "a"),
    }
    commands = {   # the run itself may be hard (a tiny Fn is a stiff problem): a budget bounds it
        "simulate": ("simulate", "--problem", "{file}", "--t-end", "0.05", "--wall-budget", "2",
                     *_TOL),
        "sweep": ("sweep", "--problem", "{file}", "--b", "0.0094:0.0094:0.0001", "--lc",
                  "3e-7:3e-7:1", "--t-end", "0.05", "--wall-budget", "2", "--obs-recurrence",
                  "1", "--obs-drop", "0.04", "--workers", "1", "--no-plot", "--no-progress",
                  "--no-solver-check", "--out", "{tmp}/s", *_TOL),   # the unit's warning only
    }
    out = []
    for (name, (content, must)), command in itertools.product(slips.items(), commands):
        def run(tmp, content=content, must=must, args=commands[command]):
            path = _write(tmp, content)
            got = cli(*[str(a).replace("{file}", str(path)).replace("{tmp}", str(tmp))
                        for a in args], "--json")
            outcome = cli_outcome(got, json_mode=True)
            one_json(got.out)
            warned = [x for x in got.err.splitlines() if "warning:" in x]
            if len(warned) != 1 or f"{must} = " not in warned[0]:
                raise Wrong(f"expected one warning line naming {must}, got {warned}")
            if outcome.outcome == "traceback":
                return outcome
            return Observed("warned", warned[0])
        out.append(Case(KIND, f"{command} warns once: {name}", run, "warned", timeout=300))
    return out


def _preset_only_cases() -> list[Case]:
    """Commands whose --problem(s) names a preset, not a file: a file there is refused, not
    read as a preset of another name."""
    def run(tmp, args):
        path = _write(tmp, _base())
        return cli_outcome(cli(*[str(a).replace("{file}", str(path)).replace("{tmp}", str(tmp))
                                 for a in args]))
    commands = {"convergence --problem FILE": ("convergence", "--problem", "{file}", "--out",
                                               "{tmp}/cv"),
                "work-precision --problems FILE": ("work-precision", "--problems", "{file}",
                                                   "--out", "{tmp}/wp")}
    return [Case(KIND, f"{name} (a preset is meant)", lambda tmp, a=args: run(tmp, a), "refused",
                 names="must be one of") for name, args in commands.items()]


def cases() -> list[Case]:
    return (_valid_cases() + _bad_cases() + _path_cases() + _unit_cases()
            + _preset_only_cases())
