"""Where a measurement comes from: CPU, Python and package versions, git commit, date.

Every study table carries these as columns, so a CSV read back with pandas years later still says
on what it was measured.
"""

from __future__ import annotations

import datetime
import functools
import importlib.metadata
import platform
import subprocess
from pathlib import Path

__all__ = ["provenance", "cpu_model", "git_commit"]

_PACKAGES = ("numpy", "scipy", "numba", "scikits-odes", "assimulo-testing", "scikit-sundae",
             "numbalsoda")


@functools.cache
def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


@functools.cache
def git_commit() -> str:
    """The commit of the checkout the harness runs from, ``+dirty`` if it has local changes."""
    root = Path(__file__).resolve().parents[1]
    try:
        rev = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root, text=True,
                             capture_output=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               text=True, capture_output=True, check=True).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _version(package: str) -> str:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "missing"


def provenance() -> dict[str, str]:
    """Columns describing the machine and software of a measurement."""
    import os
    return {"cpu": cpu_model(), "n_cpus": os.cpu_count(), "python": platform.python_version(),
            **{f"v_{p}": _version(p) for p in _PACKAGES},
            "git_commit": git_commit(),
            "date": datetime.date.today().isoformat()}
