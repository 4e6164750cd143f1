"""``make reproduce``: the layering of ``benchmarks/`` (no import circles, nothing below the
command line imports it) and the plan's reuse of steps whose inputs did not change, on tiny fake
steps in a temporary directory."""

import importlib
import json
import sys
import textwrap

import pandas as pd
import pytest

from benchmarks.pipeline import manifest as M
from benchmarks.pipeline import reproduce as RP

# --- layering ------------------------------------------------------------------------------


def test_benchmarks_has_no_import_cycle():
    graph = M.import_graph(M.ROOT, ("benchmarks",))
    assert "benchmarks.cli" in graph and "benchmarks.pipeline.reproduce" in graph
    assert M.find_cycles(graph) == []


def test_only_the_command_line_imports_the_command_line():
    graph = M.import_graph(M.ROOT, ("benchmarks",))
    wrong = {m: sorted(d for d in deps if d.startswith("benchmarks.cli"))
             for m, deps in graph.items() if not m.startswith("benchmarks.cli")}
    assert {m: d for m, d in wrong.items() if d} == {}


def _write(root, files):
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))


def test_the_import_graph_counts_imports_inside_functions_and_relative_ones(tmp_path):
    _write(tmp_path, {"pkg/__init__.py": "from . import a\n",
                      "pkg/a.py": "from pkg import b\n",
                      "pkg/b.py": "def f():\n    from .c import x\n",
                      "pkg/c.py": "import json\nx = 1\n",
                      "pkg/d.py": "def g():\n    import pkg.a\n"})
    graph = M.import_graph(tmp_path, ("pkg",))
    assert graph == {"pkg": {"pkg.a"}, "pkg.a": {"pkg.b"}, "pkg.b": {"pkg.c"}, "pkg.c": set(),
                     "pkg.d": {"pkg.a"}}
    assert M.find_cycles(graph) == []
    (tmp_path / "pkg/c.py").write_text("def h():\n    from pkg.a import b\n")
    assert M.find_cycles(M.import_graph(tmp_path, ("pkg",))) == [["pkg.a", "pkg.b", "pkg.c"]]


# --- reuse, on fake steps ------------------------------------------------------------------

STEPS_PY = """
from pathlib import Path


def make(out, n=1):
    from fakeplan.lib import value
    (out / "a.txt").write_text(value() * n)


def shout(out):
    (out / "b.txt").write_text((out / "a.txt").read_text().upper())


def clock(out):
    (out / "c.txt").write_text("fast")
"""


@pytest.fixture
def fake(tmp_path, monkeypatch):
    """A project ``fakeplan`` (three steps, a library module, an unrelated one) and an empty
    results directory."""
    root = tmp_path / "project"
    _write(root, {"fakeplan/__init__.py": "",
                  "fakeplan/lib.py": "def value():\n    return 'v'\n",
                  "fakeplan/other.py": "x = 1\n",
                  "fakeplan/steps.py": STEPS_PY})
    monkeypatch.syspath_prepend(str(root))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    for name in [m for m in sys.modules if m.split(".")[0] == "fakeplan"]:
        monkeypatch.delitem(sys.modules, name)
    steps = importlib.import_module("fakeplan.steps")
    out = tmp_path / "results"
    out.mkdir()

    class Fake:
        pass

    f = Fake()
    f.root, f.out, f.module = root, out, steps
    f.steps = [RP.Step("make", "make a", steps.make, settings={"n": 1}),
               RP.Step("shout", "shout a", steps.shout, reads=("a.txt",)),
               RP.Step("clock", "time it", steps.clock, timed=True)]

    def run(modes="check", steps=None, **kw):
        steps = steps or f.steps
        modes = modes if isinstance(modes, dict) else {s.name: modes for s in steps}
        rows = RP.run_steps(steps, out, modes, root=root, packages=("fakeplan",), whole=(), **kw)
        return {r["step"]: r["status"] for r in rows}

    f.run = run
    yield f
    for name in [m for m in sys.modules if m.split(".")[0] == "fakeplan"]:
        del sys.modules[name]


def test_a_step_runs_once_then_is_reused(fake, capsys):
    assert fake.run() == {"make": "ran", "shout": "ran", "clock": "ran"}
    assert (fake.out / "b.txt").read_text() == "V"
    assert fake.run() == {"make": "reused", "shout": "reused", "clock": "reused"}
    assert "make: reused (inputs unchanged)" in capsys.readouterr().out


def test_the_manifest_is_json_pandas_reads(fake):
    fake.run()
    table = pd.read_json(fake.out / "manifest.json")
    assert list(table.step) == ["make", "shout", "clock"]
    row = table.set_index("step").loc["make"]
    assert set(row.outputs) == {"a.txt"} and len(row.inputs_hash) == 64
    assert set(row.inputs) == {"code", "versions", "settings", "machine", "reads"}
    assert "fakeplan/lib.py" in row.inputs["code"] and row.inputs["settings"] == {"n": 1}
    assert table.set_index("step").loc["shout"].inputs["reads"] == {
        "a.txt": M.file_hash(fake.out / "a.txt")}


def test_a_step_reruns_when_code_it_imports_changes(fake, capsys):
    fake.run()
    (fake.root / "fakeplan/other.py").write_text("x = 2\n")       # imported by no step
    assert set(fake.run().values()) == {"reused"}
    # documentation is not code: a docstring, a comment, the layout
    (fake.root / "fakeplan/lib.py").write_text(
        'def value():\n    """The value."""\n\n    return  \'v\'  # same\n')
    assert set(fake.run().values()) == {"reused"}
    (fake.root / "fakeplan/lib.py").write_text("def value():\n    return 'v' + ''\n")
    # make reruns; it writes the same a.txt, so shout, which reads it, is reused
    assert fake.run() == {"make": "ran", "shout": "reused", "clock": "reused"}
    assert "inputs changed: code (fakeplan/lib.py)" in capsys.readouterr().out
    (fake.root / "fakeplan/lib.py").write_text("def value():\n    return 'w'\n")
    del sys.modules["fakeplan.lib"]            # a new process would import it afresh
    assert fake.run() == {"make": "ran", "shout": "ran", "clock": "reused"}
    assert (fake.out / "b.txt").read_text() == "W"


def test_a_step_reruns_when_a_version_changes(fake, monkeypatch, capsys):
    fake.run()
    real = M.versions
    monkeypatch.setattr(M, "versions", lambda root, sources=None: {**real(root, sources),
                                                                     "python": "0.0"})
    assert set(fake.run().values()) == {"ran"}
    assert "inputs changed: versions (python" in capsys.readouterr().out
    assert set(fake.run().values()) == {"reused"}


def test_an_optional_pin_counts_only_for_the_code_that_imports_it(tmp_path):
    _write(tmp_path, {"pyproject.toml": """
        [project]
        name = "proj"
        dependencies = ["numpy>=2"]
        [project.optional-dependencies]
        extra = ["emcee>=3.1", "no-such-dist-xyz==1.0"]
        all = ["proj[extra]"]
        """})
    plain = M.versions(tmp_path, ["import numpy\n"])
    assert set(plain) == {"python", "numpy"}
    sampling = M.versions(tmp_path, ["def f():\n    from emcee import EnsembleSampler\n"])
    assert set(sampling) == {"python", "numpy", "emcee"}
    assert set(M.versions(tmp_path, ["import no_such_dist_xyz\n"])) == {
        "python", "numpy", "no-such-dist-xyz"}
    assert M.versions(tmp_path, ["import no_such_dist_xyz\n"])["no-such-dist-xyz"] == "missing"
    assert set(M.versions(tmp_path)) == {"python", "numpy", "emcee", "no-such-dist-xyz"}


def test_a_step_gets_an_optional_pin_it_imports_through_other_modules():
    """The inversion step imports emcee four modules down, inside a function; the windows step
    never does."""
    steps = {s.name: s for s in RP.STEPS}
    inversion = M.step_inputs(steps["inversion"].run, {}, M.ROOT / "results")
    windows = M.step_inputs(steps["windows"].run, {}, M.ROOT / "results")
    assert "emcee" in inversion["versions"] and "corner" in inversion["versions"]
    assert "emcee" not in windows["versions"] and "numpy" in windows["versions"]


def test_a_step_reruns_when_its_settings_change(fake):
    fake.run()
    steps = [RP.Step("make", "make a", fake.module.make, settings={"n": 2})] + fake.steps[1:]
    assert fake.run(steps=steps) == {"make": "ran", "shout": "ran", "clock": "reused"}
    assert (fake.out / "b.txt").read_text() == "VV"


def test_only_a_timed_step_reruns_on_another_machine(fake, monkeypatch):
    fake.run()
    monkeypatch.setattr(M, "machine", lambda: {"cpu": "another", "n_cpus": 64})
    assert fake.run() == {"make": "reused", "shout": "reused", "clock": "ran"}


def test_a_step_reruns_when_its_output_was_deleted_or_modified(fake, capsys):
    fake.run()
    (fake.out / "b.txt").unlink()
    assert fake.run() == {"make": "reused", "shout": "ran", "clock": "reused"}
    assert "outputs missing: b.txt" in capsys.readouterr().out
    (fake.out / "a.txt").write_text("edited by hand")
    # make rewrites a.txt as it was, so shout's input is what it last read
    assert fake.run() == {"make": "ran", "shout": "reused", "clock": "reused"}
    assert "outputs changed since: a.txt" in capsys.readouterr().out
    assert (fake.out / "a.txt").read_text() == "v"


def test_run_keep_and_dry_run(fake, capsys):
    fake.run()
    assert fake.run({"make": "run"}) == {"make": "ran"}              # --only / --force
    (fake.root / "fakeplan/lib.py").write_text("def value():\n    return 'x'\n")
    assert fake.run("keep") == {"make": "stale", "shout": "reused", "clock": "reused"}
    assert "make: kept, a step of the full plan (inputs changed" in capsys.readouterr().out
    before = (fake.out / "manifest.json").read_text()
    assert fake.run(dry_run=True) == {"make": "would run", "shout": "reused", "clock": "reused"}
    assert (fake.out / "a.txt").read_text() == "v"
    assert (fake.out / "manifest.json").read_text() == before


def test_a_bad_manifest_means_every_step_reruns(fake, capsys):
    fake.run()
    (fake.out / "manifest.json").write_text('{"not": "a list"}')
    assert set(fake.run().values()) == {"ran"}
    said = capsys.readouterr().out
    assert "is not an array of step records" in said
    assert said.count("every step reruns") == 1          # said once, not before every step
    assert len(json.loads((fake.out / "manifest.json").read_text())) == 3


def test_the_plans(fake, monkeypatch):
    """The quick plan keeps the full steps, --full runs them, --only reruns one step, --from
    starts later; misuse is one clear error."""
    steps = (fake.steps[0], RP.Step("shout", "shout a", fake.module.shout, full=True,
                                    reads=("a.txt",)), fake.steps[2])
    monkeypatch.setattr(RP, "STEPS", steps)
    monkeypatch.setattr(RP, "STEP_NAMES", tuple(s.name for s in steps))
    monkeypatch.setattr(RP, "_collect", lambda out: {})
    monkeypatch.setattr(RP, "_report_markdown", lambda r: "report\n")

    def plan(**kw):
        return {r["step"]: r["status"] for r in RP.reproduce(fake.out, **kw)}

    assert plan() == {"make": "ran", "shout": "stale", "clock": "ran"}
    assert not (fake.out / "b.txt").exists()
    assert plan(full=True) == {"make": "reused", "shout": "ran", "clock": "reused"}
    assert plan() == {"make": "reused", "shout": "reused", "clock": "reused"}
    assert plan(only="clock") == {"clock": "ran"}
    assert plan(start="shout", full=True) == {"shout": "reused", "clock": "reused"}
    assert plan(force=True) == {"make": "ran", "shout": "reused", "clock": "ran"}
    assert (fake.out / "REPORT.md").read_text() == "report\n"
    with pytest.raises(ValueError, match="only='x'"):
        plan(only="x")
    with pytest.raises(ValueError, match="step 'shout' is in the full plan only"):
        plan(start="shout")
    with pytest.raises(ValueError, match="scipy budget"):
        plan(scipy_budget=5.0)


# --- the real steps ------------------------------------------------------------------------

def test_every_step_declares_inputs_that_resolve(tmp_path):
    import inspect
    for step in RP.STEPS:
        assert list(inspect.signature(step.run).parameters)[1:] == list(step.settings), step.name
        inputs = RP._inputs(step, tmp_path)
        assert (inputs["machine"] is not None) == step.timed
        assert any(k.startswith("integrators/") for k in inputs["code"]), step.name
        assert any(k.endswith(f"::{step.run.__name__}") for k in inputs["code"])
    code = RP._inputs(RP.STEPS[RP.STEP_NAMES.index("probe")], tmp_path)["code"]
    assert {"benchmarks/cli/main.py", "benchmarks/probe_cases.py", "problems/presets.py"} <= set(code)
    code = RP._inputs(RP.STEPS[RP.STEP_NAMES.index("windows")], tmp_path)["code"]
    assert {"benchmarks/studies/windows.py", "benchmarks/physics/summary.py", "integrators/own/etd.py"} <= set(code)
    assert "benchmarks/pipeline/reproduce.py" not in code and "benchmarks/cli/main.py" not in code
    assert {"speedup", "work-precision", "target-full", "binding-overhead",
            "ensemble-scaling", "solver-effect", "family", "mass-limit"} == set(RP.FULL_STEPS)


def test_the_command_line_refuses_misuse_in_one_line(capsys):
    from benchmarks.cli.main import main
    assert main(["reproduce", "--scipy-budget", "5", "--out", "/tmp"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--full" in err and "Traceback" not in err
    assert main(["reproduce", "--from", "target-full"]) == 2
    assert "in the full plan only" in capsys.readouterr().err


def test_a_dry_run_says_what_would_run_and_writes_nothing(tmp_path, capsys):
    from benchmarks.cli.main import main
    out = tmp_path / "results"
    assert main(["reproduce", "--dry-run", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "windows: would run (not in the manifest; ~9 s)" in text
    assert "steps would run (~" in text
    assert "speedup: kept, a step of the full plan (not in the manifest" in text
    assert not out.exists()


def test_a_step_refuses_to_run_without_the_file_it_reads(fake):
    with pytest.raises(FileNotFoundError, match="step shout reads .*a.txt, which is not there"):
        fake.run(steps=fake.steps[1:2])
    assert not (fake.out / "manifest.json").exists()


def test_two_runs_at_once_keep_each_others_records(fake):
    """Two ``--only`` runs of different steps at once: each reads the manifest again before it
    writes a record, so neither drops the other's (here the second finishes during the first's
    step; before, the first wrote the records it had read at its start)."""
    module = fake.module

    def make_while_clock_runs(out, n):
        fake.run({"clock": "run"})
        module.make(out, n)

    steps = [RP.Step("make", "make a", make_while_clock_runs, settings={"n": 1})]
    assert fake.run({"make": "run"}, steps=steps) == {"make": "ran"}
    assert set(M.read_manifest(fake.out)) == {"make", "clock"}


def test_a_file_claimed_by_two_runs_at_once_goes_to_the_one_that_wrote_it(tmp_path):
    """Two `--only` runs at once each see the other's files appear; the file's time decides.
    Here speedup (12:00–12:15) ran beside target-full (12:01–12:34), as on 2026-11-23, when
    target-full's record claimed speedup's three files."""
    import datetime
    import os

    def at(hhmmss):
        return datetime.datetime.fromisoformat(f"2026-11-23T{hhmmss}")

    def record(step, finished, outputs):
        return {"step": step, "finished": at(finished).isoformat(), "outputs": dict.fromkeys(
            outputs, "h")}

    for name, written in (("speedup.md", "12:14:59"), ("wp_full.csv", "12:34:00"),
                          ("later.md", "13:00:00")):
        (tmp_path / name).write_text("x")
        os.utime(tmp_path / name, (at(written).timestamp(),) * 2)
    records = {"speedup": record("speedup", "12:15:00", ["speedup.md"]),
               "target-full": record("target-full", "12:34:34",
                                     ["speedup.md", "wp_full.csv", "later.md"]),
               "work-precision": record("work-precision", "12:40:50",
                                        ["wp_full.csv", "later.md"])}
    M.assign_outputs(records, tmp_path)
    assert list(records["speedup"]["outputs"]) == ["speedup.md"]
    assert list(records["target-full"]["outputs"]) == ["wp_full.csv", "later.md"]
    # written after both claimants finished: it changed since, both keep it and are stale
    assert list(records["work-precision"]["outputs"]) == ["later.md"]
    # a record whose time cannot be read (edited by hand) keeps its claims, and nothing raises
    records["speedup"]["finished"] = "yesterday"
    records["target-full"]["outputs"]["speedup.md"] = "h"
    M.assign_outputs(records, tmp_path)
    assert "speedup.md" in records["target-full"]["outputs"]
