"""Every command and code block of the README and of the docs pages runs as written.

A page's fenced blocks are of four kinds:

* ``sh``: each line (continuations joined, comments dropped) is an ``rsfbench`` command; a
  ``make`` line is skipped, since make is what runs this;
* ``python``: run, all of a page's blocks in one process in order, as in a notebook;
* ``text`` (output shown), ``toml`` and ``json`` (a file shown; each must parse);
* a MyST directive (``{toctree}``, ``{literalinclude}``, ...), which Sphinx checks.

A fence of another language, or of none, fails. The fast tests check that every command parses
with the real CLI parser (files an earlier step writes stand in empty) and that every Python
block compiles; the slow one runs each page's blocks in order in a fresh directory where
``docs/``, ``tests/data/`` and ``results/`` are the repository's, and checks that nothing in
the repository changed.
"""

import json
import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from benchmarks.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
_FENCE = re.compile(r"^(?P<fence>`{3,})(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=fence)[ \t]*$",
                    re.S | re.M)
RUN = ("sh", "python")
SHOWN = {"text": None, "toml": tomllib.loads, "json": json.loads}
#: the longest a page's blocks may take, in s, with the kernels compiled (the tutorial's budget
#: is 10 minutes of machine time; the README's `invert` on the means alone takes 29 s on a quiet
#: 2-core machine, its zoomed grid bent along the valley, and took 160 s of the page's 230 s
#: when it fell back to emcee: the budget keeps room for a page run beside another); the test
#: stops a page at 3 × its budget
BUDGET_S = {"tutorial.md": 600.0, "README.md": 300.0}
DEFAULT_BUDGET_S = 120.0


def blocks(page: Path) -> list[tuple[str, str]]:
    """The page's fenced blocks as (language, body); a directive's language is ``{name}``."""
    text = page.read_text(encoding="utf-8")
    return [(m.group("info").strip().split(" ")[0], m.group("body"))
            for m in _FENCE.finditer(text)]


#: a command's comment that lets it exit 1 as well as 0 (a verdict, such as the self-check's)
MAY_EXIT_1 = "# may exit 1"


def commands_and_exits(text: str) -> list[tuple[list[str], bool]]:
    """Each command of an `sh` block (continuation lines joined, comments dropped) and whether
    it may exit 1 (its comment says :data:`MAY_EXIT_1`)."""
    joined = text.replace("\\\n", " ")
    return [(shlex.split(line, comments=True), MAY_EXIT_1 in line)
            for line in joined.splitlines()
            if line.strip() and not line.lstrip().startswith("#")]


def steps(page: Path) -> list[tuple[str, object]]:
    """What the page asks a reader to run, in order: ("python", code) or ("rsfbench", argv)
    (``"rsfbench, exit 0 or 1"`` for a command whose comment says :data:`MAY_EXIT_1`)."""
    out = []
    for kind, text in blocks(page):
        if kind == "python":
            out.append(("python", text))
        elif kind == "sh":
            for argv, may_fail in commands_and_exits(text):
                if argv[0] != "make":
                    assert argv[0] == "rsfbench", f"{page.name}: a command not of rsfbench: {argv}"
                    out.append(("rsfbench, exit 0 or 1" if may_fail else "rsfbench", argv[1:]))
    return out


def _name(page: Path) -> str:
    return page.name if page == README else f"docs/{page.name}"


RUNNABLE = [p for p in PAGES if steps(p)]


@pytest.mark.parametrize("page", PAGES, ids=_name)
def test_every_block_is_of_a_kind_that_is_run_or_checked(page):
    for kind, text in blocks(page):
        assert kind in RUN or kind in SHOWN or kind.startswith("{"), \
            f"{_name(page)}: a ```{kind or '(no language)'} block: label it sh, python, text, " \
            f"toml or json"
        if SHOWN.get(kind):
            SHOWN[kind](text)
        if kind == "text":                 # output, not a command dressed as one
            assert not re.search(r"^\$? ?rsfbench ", text, re.M), f"{_name(page)}: {text[:80]}"


def test_the_readme_has_a_tutorial_and_stays_short():
    kinds = [k for k, _ in steps(README)]
    assert kinds.count("rsfbench") >= 5 and "python" in kinds
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 200


def test_the_tutorial_follows_an_apparatus_from_recording_to_integrator():
    said = {argv[0] for kind, argv in steps(ROOT / "docs" / "tutorial.md") if kind == "rsfbench"}
    assert {"simulate", "observe", "invert", "solver-effect", "lab"} <= said


_FILE = re.compile(r"^[\w.-][\w./-]*\.(csv|json|toml|parquet|txt|png)$")


@pytest.mark.parametrize("page", RUNNABLE, ids=_name)
def test_every_command_parses_and_every_python_block_compiles(page, tmp_path, monkeypatch):
    work = _workdir(tmp_path)
    monkeypatch.chdir(work)
    parser = build_parser()
    for kind, step in steps(page):
        if kind == "python":
            compile(step, _name(page), "exec")
            continue
        # the parser checks that a file to read exists: one an earlier step writes stands in
        for token in step:
            if _FILE.match(token) and not (work / token).exists():
                (work / token).parent.mkdir(parents=True, exist_ok=True)
                (work / token).touch()
        parser.parse_args(step)            # an unknown flag or a bad value exits


def _workdir(tmp_path: Path) -> Path:
    for shared in ("docs", "results"):
        (tmp_path / shared).symlink_to(ROOT / shared)
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "data").symlink_to(ROOT / "tests" / "data")
    return tmp_path


#: runs a page's steps in one process: Python blocks share one namespace; a command runs as
#: ``python -m benchmarks.cli`` and must exit 0 (or 1, where its comment says ``# may exit 1``)
_DRIVER = """
import json, subprocess, sys, time
ns = {"__name__": "__main__"}
for i, (kind, step) in enumerate(json.load(open(sys.argv[1]))):
    print(f"--- step {i}: {kind} {step if kind != 'python' else ''}", flush=True)
    start = time.perf_counter()
    if kind == "python":
        exec(compile(step, f"{sys.argv[2]} python block", "exec"), ns)
    else:
        run = subprocess.run([sys.executable, "-m", "benchmarks.cli", *step])
        if run.returncode and not (run.returncode == 1 and kind.endswith("or 1")):
            sys.exit(f"step {i} (rsfbench {' '.join(step)}) exited {run.returncode}")
    print(f"--- step {i} took {time.perf_counter() - start:.1f} s", flush=True)
"""


def _repository_state() -> str:
    return subprocess.run(["git", "status", "--porcelain", "--", "docs", "results", "tests/data"],
                          cwd=ROOT, capture_output=True, text=True, check=True).stdout


@pytest.mark.slow
@pytest.mark.needs("pyarrow")
@pytest.mark.parametrize("page", RUNNABLE, ids=_name)
def test_the_page_runs_as_written(page, tmp_path):
    work = _workdir(tmp_path)
    (tmp_path / "steps.json").write_text(json.dumps(steps(page)))
    (tmp_path / "driver.py").write_text(_DRIVER)
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
    before = _repository_state()
    run = subprocess.run([sys.executable, str(tmp_path / "driver.py"), str(tmp_path / "steps.json"),
                          _name(page)], cwd=work, env=env, capture_output=True, text=True,
                         timeout=3 * BUDGET_S.get(page.name, DEFAULT_BUDGET_S))
    assert run.returncode == 0, f"{_name(page)}:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    assert _repository_state() == before, f"{_name(page)} wrote into the repository"
    # a reader runs the page from the repository's root: git must ignore what it writes there
    written = sorted(p.name + "/" * p.is_dir() for p in work.iterdir()
                     if p.name not in ("docs", "results", "tests", "steps.json", "driver.py"))
    ignored = subprocess.run(["git", "check-ignore", "--no-index", *written], cwd=ROOT,
                             capture_output=True, text=True).stdout.split()
    assert set(written) <= set(ignored), \
        f"{_name(page)} writes {sorted(set(written) - set(ignored))}: add them to .gitignore"
    took = sum(float(s) for s in re.findall(r"took ([\d.]+) s", run.stdout))
    print(f"{_name(page)}: {took:.0f} s")
    if page == README:
        for written in ("run.csv", "run.png", "obs/observations.json", "inv/inversion.json",
                        "fit/lab_fit.json", "effect/solver_effect.csv"):
            assert (work / written).stat().st_size > 0, written
