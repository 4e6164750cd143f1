"""The README's tutorial runs as written: every `sh` block's commands (but the `make` lines,
which are what runs this) and every `python` block, in order, in a fresh directory where
`docs/` and `tests/data/` are the repository's. The fast test checks that each command parses
and each Python block compiles; the slow one runs them all (44 s with the kernels compiled,
about 5 minutes on a first run, which compiles the batch kernels of the inversion)."""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
_FENCE = re.compile(r"^```(sh|python)\n(.*?)^```", re.S | re.M)


def blocks() -> list[tuple[str, str]]:
    return [(m.group(1), m.group(2)) for m in _FENCE.finditer(README.read_text(encoding="utf-8"))]


def commands(text: str) -> list[list[str]]:
    """The commands of an `sh` block: continuation lines joined, comments dropped."""
    joined = text.replace("\\\n", " ")
    return [shlex.split(line, comments=True) for line in joined.splitlines()
            if line.strip() and not line.lstrip().startswith("#")]


def tutorial() -> list[tuple[str, object]]:
    steps = []
    for kind, text in blocks():
        if kind == "python":
            steps.append(("python", text))
            continue
        for argv in commands(text):
            if argv[0] == "make":
                continue
            assert argv[0] == "rsfbench", f"a README command that is not rsfbench: {argv}"
            steps.append(("rsfbench", argv[1:]))
    return steps


def test_the_readme_has_a_tutorial_and_stays_short():
    kinds = [k for k, _ in tutorial()]
    assert kinds.count("rsfbench") >= 5 and "python" in kinds
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 200


#: the files the tutorial's commands write and later ones read
WRITTEN_FIRST = ("run.csv", "obs/observations.json")


def test_every_readme_command_parses_and_every_python_block_compiles(tmp_path, monkeypatch):
    # the parser checks that a file to read exists: those an earlier step writes stand in empty
    work = _workdir(tmp_path)
    for name in WRITTEN_FIRST:
        (work / name).parent.mkdir(exist_ok=True)
        (work / name).touch()
    monkeypatch.chdir(work)
    parser = build_parser()
    for kind, step in tutorial():
        if kind == "python":
            compile(step, "README.md", "exec")
        else:
            parser.parse_args(step)            # an unknown flag or a bad value exits


def _workdir(tmp_path: Path) -> Path:
    (tmp_path / "docs").symlink_to(ROOT / "docs")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "data").symlink_to(ROOT / "tests" / "data")
    return tmp_path


@pytest.mark.slow
@pytest.mark.needs("pyarrow")
def test_the_readme_tutorial_runs_as_written(tmp_path):
    work = _workdir(tmp_path)
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
    for kind, step in tutorial():
        if kind == "python":
            run = subprocess.run([sys.executable, "-c", step], cwd=work, env=env,
                                 capture_output=True, text=True)
        else:
            run = subprocess.run([sys.executable, "-m", "benchmarks.cli", *step], cwd=work,
                                 env=env, capture_output=True, text=True)
        assert run.returncode == 0, f"{kind} {step}: {run.stderr[-2000:]}"
    for written in ("run.csv", "run.png", "obs/observations.json", "inv/inversion.json",
                    "fit/lab_fit.json", "effect/solver_effect.csv"):
        assert (work / written).stat().st_size > 0, written
