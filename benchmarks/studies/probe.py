"""The reliability probe, slow cases included: the harness used as a new user and a hostile one
would use it. The probe is a test suite (``tests/probe``); this study runs it with pytest and
keeps its table of kinds and outcomes. It needs a checkout (the tests are not installed)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

from benchmarks.studies.study import Study

__all__ = ["STUDY"]

ROOT = Path(__file__).resolve().parents[2]
SUITE = ROOT / "tests" / "probe"


def run(out: Path) -> None:
    if not SUITE.is_dir():
        raise ValueError(f"the probe is the test suite {SUITE}, which only a checkout has")
    if importlib.util.find_spec("pytest") is None:
        raise ValueError("the probe runs the test suite with pytest, which is not installed: "
                         "pip install --group test . (or make test)")
    for name in ("reliability.csv", "reliability.md"):     # the run's own, never an earlier one
        (out / name).unlink(missing_ok=True)
    done = subprocess.run([sys.executable, "-m", "pytest", str(SUITE), "-q", "-p",
                           "no:cacheprovider", "-m", "slow or not slow",
                           f"--probe-report={Path(out).resolve()}"], cwd=ROOT)
    if done.returncode not in (0, 1) or not (out / "reliability.csv").is_file():
        raise RuntimeError(f"the probe's pytest run stopped (exit status {done.returncode})")


def report(out: Path) -> str:
    return ("Every case of `tests/probe`, by kind and outcome (`rsfbench study probe`):\n\n"
            + (out / "reliability.md").read_text())


STUDY = Study("probe", "Reliability: the probe (`reliability.*`)", 260, run, report=report,
              data=("results/wp_quick.csv", "docs/examples/apparatus.toml",
                    *sorted(p.relative_to(ROOT).as_posix() for p in SUITE.rglob("*.py"))),
              modules=("benchmarks.cli",),
              writes=("reliability.csv", "reliability.md"), minutes=19)
