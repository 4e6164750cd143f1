"""Where a measurement comes from: CPU, Python and package versions, git commit, date.

Every study table carries these as columns, so a CSV read back with pandas years later still says
on what it was measured.
"""

from __future__ import annotations

import datetime
import functools
import importlib.metadata
import os
import platform
import subprocess
from pathlib import Path

__all__ = ["provenance", "cpu_model", "git_commit", "checkout", "version_line"]

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


def checkout() -> Path | None:
    """The project's checkout the harness runs from, or None for an installed package."""
    root = Path(__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() and (root / ".git").exists() else None


@functools.cache
def git_commit() -> str:
    """The commit of the checkout the harness runs from, ``+dirty`` if it has local changes
    outside ``results/`` (a run rewriting the results it records is not a change of what ran);
    ``"unknown"`` for an installed package.

    Returns
    -------
    str
    """
    root = checkout()
    if root is None:
        return "unknown"
    try:
        rev = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root, text=True,
                             capture_output=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
                                ":!results"], cwd=root,
                               text=True, capture_output=True, check=True).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _version(package: str) -> str:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "missing"


def version_line() -> str:
    """``rsfbench --version``: the package's version, the commit of a checkout, Python's.

    Returns
    -------
    str
    """
    commit = git_commit()
    where = f", commit {commit}" if commit != "unknown" else ""
    return f"rsfbench {_version('rsfbench')}{where} (Python {platform.python_version()})"


def provenance() -> dict[str, str]:
    """Columns describing the machine and software of a measurement."""
    return {"cpu": cpu_model(), "n_cpus": os.cpu_count(), "python": platform.python_version(),
            **{f"v_{p}": _version(p) for p in _PACKAGES},
            "git_commit": git_commit(),
            "date": datetime.date.today().isoformat()}
