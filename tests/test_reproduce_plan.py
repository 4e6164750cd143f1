"""``make reproduce``: the layering of ``benchmarks/`` (no import circles, nothing below the
command line imports it) and the plan's reuse of steps whose inputs did not change, on tiny fake
steps in a temporary directory."""

import json
import sys
import textwrap
from pathlib import Path

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

def _study(name, call, writes, **kw):
    return f"""
from benchmarks.studies.study import Study


def run(out{", n=1" if "settings" in kw else ""}):
    {call}


STUDY = Study({name!r}, {name + " it"!r}, {len(name)}, run, writes=({writes!r},),
              minutes=0.1, {", ".join(f"{k}={v!r}" for k, v in kw.items())})
"""


#: three fake studies, one module each: make writes a.txt (through a library module), shout
#: reads it and writes b.txt, clock is timed
STUDIES = {
    "fakeplan/studies/make.py": _study("make", "from fakeplan.lib import value\n    "
                                       "(out / 'a.txt').write_text(value() * n)", "a.txt",
                                       settings={"n": 1}),
    "fakeplan/studies/shout.py": _study("shout", "(out / 'b.txt').write_text((out / 'a.txt')"
                                        ".read_text().upper())", "b.txt", reads=("a.txt",)),
    "fakeplan/studies/clock.py": _study("clocks", "(out / 'c.txt').write_text('fast')", "c.txt",
                                        timed=True),
}


@pytest.fixture
def fake(tmp_path, monkeypatch):
    """A project ``fakeplan`` (three studies, a library module, an unrelated one) and an empty
    results directory."""
    root = tmp_path / "project"
    _write(root, {"fakeplan/__init__.py": "", "fakeplan/studies/__init__.py": "",
                  "fakeplan/lib.py": "def value():\n    return 'v'\n",
                  "fakeplan/other.py": "x = 1\n", **STUDIES})
    monkeypatch.syspath_prepend(str(root))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    for name in [m for m in sys.modules if m.split(".")[0] == "fakeplan"]:
        monkeypatch.delitem(sys.modules, name)
    out = tmp_path / "results"
    out.mkdir()

    class Fake:
        pass

    f = Fake()
    f.root, f.out = root, out
    f.steps = list(RP.studies.__wrapped__("fakeplan.studies"))

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
    assert fake.run() == {"make": "ran", "shout": "ran", "clocks": "ran"}
    assert (fake.out / "b.txt").read_text() == "V"
    assert fake.run() == {"make": "reused", "shout": "reused", "clocks": "reused"}
    assert "make: reused (inputs unchanged)" in capsys.readouterr().out


def test_the_manifest_is_json_pandas_reads(fake):
    fake.run()
    table = pd.read_json(fake.out / "manifest.json")
    assert list(table.step) == ["make", "shout", "clocks"]
    assert table.set_index("step").loc["make"].plan == "quick"
    row = table.set_index("step").loc["make"]
    assert set(row.outputs) == {"a.txt"} and len(row.inputs_hash) == 64
    assert set(row.inputs) == {"code", "versions", "settings", "machine", "reads"}
    assert "fakeplan/lib.py" in row.inputs["code"] and row.inputs["settings"] == {"n": 1}
    assert table.set_index("step").loc["shout"].inputs["reads"] == {
        "a.txt": M.file_hash(fake.out / "a.txt")}


def test_a_step_reruns_when_code_it_imports_changes(fake, capsys):
    fake.run()
    (fake.root / "fakeplan/other.py").write_text("x = 2\n")       # imported by no study
    assert set(fake.run().values()) == {"reused"}
    # a study's own module counts whole: its helpers too
    (fake.root / "fakeplan/studies/clock.py").write_text(
        STUDIES["fakeplan/studies/clock.py"] + "\n\ndef helper():\n    return 1\n")
    assert fake.run() == {"make": "reused", "shout": "reused", "clocks": "ran"}
    # documentation is not code: a docstring, a comment, the layout
    (fake.root / "fakeplan/lib.py").write_text(
        'def value():\n    """The value."""\n\n    return  \'v\'  # same\n')
    assert set(fake.run().values()) == {"reused"}
    (fake.root / "fakeplan/lib.py").write_text("def value():\n    return 'v' + ''\n")
    # make reruns; it writes the same a.txt, so shout, which reads it, is reused
    assert fake.run() == {"make": "ran", "shout": "reused", "clocks": "reused"}
    assert "inputs changed: code (fakeplan/lib.py)" in capsys.readouterr().out
    (fake.root / "fakeplan/lib.py").write_text("def value():\n    return 'w'\n")
    del sys.modules["fakeplan.lib"]            # a new process would import it afresh
    assert fake.run() == {"make": "ran", "shout": "ran", "clocks": "reused"}
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
    inversion = RP.study_inputs(RP.study_named("inversion"), M.ROOT / "results")
    windows = RP.study_inputs(RP.study_named("windows"), M.ROOT / "results")
    assert "emcee" in inversion["versions"] and "corner" in inversion["versions"]
    assert "emcee" not in windows["versions"] and "numpy" in windows["versions"]


def test_a_step_reruns_when_its_settings_change(fake):
    fake.run()
    import dataclasses
    steps = [dataclasses.replace(fake.steps[0], settings={"n": 2})] + fake.steps[1:]
    assert fake.run(steps=steps) == {"make": "ran", "shout": "ran", "clocks": "reused"}
    assert (fake.out / "b.txt").read_text() == "VV"


def test_only_a_timed_step_reruns_on_another_machine(fake, monkeypatch):
    fake.run()
    monkeypatch.setattr(M, "machine", lambda: {"cpu": "another", "n_cpus": 64})
    assert fake.run() == {"make": "reused", "shout": "reused", "clocks": "ran"}


def test_a_step_reruns_when_its_output_was_deleted_or_modified(fake, capsys):
    fake.run()
    (fake.out / "b.txt").unlink()
    assert fake.run() == {"make": "reused", "shout": "ran", "clocks": "reused"}
    assert "outputs missing: b.txt" in capsys.readouterr().out
    (fake.out / "a.txt").write_text("edited by hand")
    # make rewrites a.txt as it was, so shout's input is what it last read
    assert fake.run() == {"make": "ran", "shout": "reused", "clocks": "reused"}
    assert "outputs changed since: a.txt" in capsys.readouterr().out
    assert (fake.out / "a.txt").read_text() == "v"


def test_run_keep_and_dry_run(fake, capsys):
    fake.run()
    assert fake.run({"make": "run"}) == {"make": "ran"}              # rsfbench study NAME / --force
    (fake.root / "fakeplan/lib.py").write_text("def value():\n    return 'x'\n")
    assert fake.run("keep") == {"make": "stale", "shout": "reused", "clocks": "reused"}
    assert "make: kept, a step of the full plan (inputs changed" in capsys.readouterr().out
    before = (fake.out / "manifest.json").read_text()
    assert fake.run(dry_run=True) == {"make": "would run", "shout": "reused", "clocks": "reused"}
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
    """The quick plan keeps the full steps, --full runs them, `rsfbench study NAME` reruns one step, --from
    starts later; misuse is one clear error."""
    import dataclasses
    steps = (fake.steps[0], dataclasses.replace(fake.steps[1], plan="full"), fake.steps[2])
    monkeypatch.setattr(RP, "studies", lambda: steps)
    monkeypatch.setattr(RP, "report_markdown", lambda plan, out: "report\n")
    real = RP.run_steps
    monkeypatch.setattr(RP, "run_steps", lambda *a, **kw: real(
        *a, root=fake.root, packages=("fakeplan",), whole=(), **kw))

    def plan(**kw):
        return {r["step"]: r["status"] for r in RP.reproduce(fake.out, **kw)}

    assert plan() == {"make": "ran", "shout": "stale", "clocks": "ran"}
    assert not (fake.out / "b.txt").exists()
    assert plan(full=True) == {"make": "reused", "shout": "ran", "clocks": "reused"}
    assert plan() == {"make": "reused", "shout": "reused", "clocks": "reused"}
    assert plan(only="clocks") == {"clocks": "ran"}
    assert plan(start="shout", full=True) == {"shout": "reused", "clocks": "reused"}
    assert plan(force=True) == {"make": "ran", "shout": "reused", "clocks": "ran"}
    assert (fake.out / "REPORT.md").read_text() == "report\n"
    with pytest.raises(ValueError, match="unknown study 'x'"):
        plan(only="x")
    with pytest.raises(ValueError, match="no setting m; its settings: n"):
        plan(only="make", settings={"m": 2})
    for bad in ("two", 2.5, float("nan")):
        with pytest.raises(ValueError, match="setting n must be a whole number"):
            plan(only="make", settings={"n": bad})
    assert plan(only="make", settings={"n": 3}) == {"make": "ran"}
    assert (fake.out / "a.txt").read_text() == "vvv"
    with pytest.raises(ValueError, match="study 'shout' is in the full plan only"):
        plan(start="shout")


# --- the real steps ------------------------------------------------------------------------

def test_every_study_declares_inputs_that_resolve(tmp_path):
    import inspect
    plan = RP.studies()
    assert len(plan) == 37
    for study in plan:
        assert list(inspect.signature(study.run).parameters)[1:] == list(study.settings), \
            study.name
        inputs = RP.study_inputs(study, tmp_path)
        assert (inputs["machine"] is not None) == study.timed
        assert any(k.startswith("integrators/") for k in inputs["code"]), study.name
        assert any(k.endswith(f"::{study.run.__name__}") for k in inputs["code"])
        assert inspect.getsourcefile(study.run).endswith(
            f"{study.run.__module__.replace('.', '/')}.py")
    probe = RP.study_inputs(RP.study_named("probe"), tmp_path)
    assert {"benchmarks/cli/main.py", "problems/presets.py"} <= set(probe["code"])
    assert {"tests/probe/cases.py", "tests/probe/families/inversion.py"} <= set(probe["reads"])
    code = RP.study_inputs(RP.study_named("windows"), tmp_path)["code"]
    assert {"benchmarks/studies/windows.py", "benchmarks/physics/summary.py",
            "integrators/own/etd.py"} <= set(code)
    assert "benchmarks/pipeline/reproduce.py" not in code and "benchmarks/cli/main.py" not in code
    assert {s.name for s in plan if s.full} == {
        "speedup", "work-precision", "target-full", "binding-overhead", "ensemble-scaling",
        "solver-effect", "family", "mass-limit", "nied-catalogue", "settled-coverage",
        "nuisance-settled", "external", "solver-effect-external"}


def test_each_committed_result_file_belongs_to_one_study():
    """Every file of results/ that a study wrote matches the patterns of exactly one study."""
    records = M.read_manifest(M.ROOT / "results")
    plan = RP.studies()
    for name, record in records.items():
        for path in record["outputs"]:
            owners = [s.name for s in plan if s.declares(path)]
            assert owners == [name], (path, owners)


def test_a_plan_that_reads_what_no_earlier_study_writes_is_refused(fake):
    import dataclasses
    make, shout, clocks = fake.steps
    with pytest.raises(ValueError, match="shout reads a.txt, which no earlier study writes"):
        RP.check_plan([shout, make])
    with pytest.raises(ValueError, match="share a name"):
        RP.check_plan([make, dataclasses.replace(make, order=99)])
    with pytest.raises(ValueError, match="make and copy both declare a.txt"):
        RP.check_plan([make, dataclasses.replace(make, name="copy", order=99,
                                                 writes=("*.txt",))])


def test_a_module_declares_one_study_or_several(tmp_path, monkeypatch):
    """``STUDY`` or a ``STUDIES`` tuple (a module owning the work of several studies): the plan
    has them all, in their declared order whatever their module; a module with both is
    refused."""
    two = _study("second", "pass", "two.txt").replace("STUDY = Study(", "TWO = Study(")
    _write(tmp_path, {"fakemany/__init__.py": "", "fakemany/studies/__init__.py": "",
                      "fakemany/studies/one.py": _study("one", "pass", "one.txt"),
                      "fakemany/studies/pair.py": _study("three", "pass", "three.txt") + two
                      + "\nSTUDIES = (STUDY, TWO)\ndel STUDY\n"})
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    try:
        assert [s.name for s in RP.studies.__wrapped__("fakemany.studies")] == [
            "one", "three", "second"]           # orders 3, 5, 6
        both = tmp_path / "fakemany/studies/pair.py"
        both.write_text(both.read_text().replace("del STUDY\n", ""))
        del sys.modules["fakemany.studies.pair"]
        with pytest.raises(ValueError, match="pair declares both STUDY and STUDIES"):
            RP.studies.__wrapped__("fakemany.studies")
    finally:
        for name in [m for m in sys.modules if m.split(".")[0] == "fakemany"]:
            del sys.modules[name]


def test_a_study_that_writes_what_it_does_not_declare_fails(fake):
    import dataclasses
    make = fake.steps[0]
    stray = dataclasses.replace(make, writes=("z.txt",))
    with pytest.raises(RuntimeError, match="declares z.txt but wrote no such file"):
        fake.run(steps=[stray])
    both = dataclasses.replace(make, writes=("a.txt", "z.txt"))
    with pytest.raises(RuntimeError, match="declares z.txt"):
        fake.run(steps=[both])

    fake.run({"make": "run"})                       # a.txt is there from this run
    lazy = dataclasses.replace(make, run=lambda out, n=1: None)
    with pytest.raises(RuntimeError, match="declares a.txt but wrote no such file .* this run"):
        fake.run({"make": "run"}, steps=[lazy, *fake.steps[1:]])

    def extra(out, n=1):
        make.run(out, n)
        (out / "undeclared.txt").write_text("x")
    with pytest.raises(RuntimeError, match="wrote undeclared.txt .* which no study declares"):
        fake.run(steps=[dataclasses.replace(make, run=extra)])


def test_the_report_has_a_section_per_study_with_its_commit_and_staleness(fake):
    import dataclasses
    fake.run()
    code = {"root": fake.root, "packages": ("fakeplan",), "whole": ()}
    text = RP.report_markdown(fake.steps, fake.out, **code)
    assert "## make it" not in text                     # the fake studies give no section
    steps = [dataclasses.replace(s, report=lambda out, s=s: f"body of {s.name}\n")
             for s in fake.steps]
    text = RP.report_markdown(steps, fake.out, **code)
    assert "## make it\n\n*From the run at commit" in text and "body of make" in text
    (fake.root / "fakeplan/lib.py").write_text("def value():\n    return 'w'\n")
    del sys.modules["fakeplan.lib"]
    text = RP.report_markdown(steps, fake.out, **code)
    assert "**Stale**: inputs changed: code (fakeplan/lib.py)" in text


def test_the_command_line_refuses_misuse_in_one_line(capsys):
    from benchmarks.cli.main import main
    assert main(["study", "speedup", "--set", "scipy_budget=0", "--out", "/tmp/nowhere"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "scipy_budget = 0" in err and "Traceback" not in err
    assert not Path("/tmp/nowhere").exists()
    assert main(["reproduce", "--from", "target-full"]) == 2
    assert "in the full plan only" in capsys.readouterr().err


def test_a_dry_run_says_what_would_run_and_writes_nothing(tmp_path, capsys):
    from benchmarks.cli.main import main
    out = tmp_path / "results"
    assert main(["reproduce", "--dry-run", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "windows: would run (not in the manifest; ~9 s)" in text
    assert "studies would run (~" in text and "probe: would run" in text
    assert "speedup: kept, a step of the full plan (not in the manifest" in text
    # the quick plan alone cannot make wp_quick.csv, which the full plan's work-precision writes
    assert ("target: would fail (reads wp_quick.csv, which is not there and no earlier study of "
            "this run writes)") in text and "would fail, a file they read missing: target" in text
    assert main(["reproduce", "--dry-run", "--full", "--out", str(out)]) == 0
    assert "would fail" not in capsys.readouterr().out
    assert not out.exists()


def test_a_step_refuses_to_run_without_the_file_it_reads(fake):
    with pytest.raises(FileNotFoundError, match="step shout reads .*a.txt, which is not there"):
        fake.run(steps=fake.steps[1:2])
    assert not (fake.out / "manifest.json").exists()


def test_two_runs_at_once_keep_each_others_records(fake):
    """Two ``rsfbench study NAME`` runs of different steps at once: each reads the manifest again
    before it writes a record, so neither drops the other's (here the second finishes during the first's
    step; before, the first wrote the records it had read at its start)."""
    import dataclasses
    make = fake.steps[0]

    def make_while_clock_runs(out, n):
        fake.run({"clocks": "run"})
        make.run(out, n)

    steps = [dataclasses.replace(make, run=make_while_clock_runs), *fake.steps[1:]]
    assert fake.run({"make": "run"}, steps=steps) == {"make": "ran"}
    assert set(M.read_manifest(fake.out)) == {"make", "clocks"}


def test_a_package_the_step_no_longer_imports_is_named_as_such():
    """A version that is on one side only is a package the step's code did not import then or
    does not now: said so, not as a version "none"."""
    line = M.what_changed({"versions": {"dask": "2024.8.0"}}, {"versions": {}})
    assert line == "versions (dask 2024.8.0 → not imported)"
