"""A library never switches matplotlib's backend: a notebook user who imports a module of ours
keeps the backend they chose. Figures are drawn on a ``matplotlib.figure.Figure``, which saves
with no backend at all."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("problems", "integrators", "benchmarks")
#: imports every module (a ``__main__`` runs a command) under a backend nobody would choose
#: by default, then prints the backend
_IMPORT_ALL = f"""
import importlib, pkgutil, matplotlib
matplotlib.use("svg")
for name in {PACKAGES!r}:
    for info in pkgutil.walk_packages(importlib.import_module(name).__path__, name + "."):
        if not info.name.endswith("__main__"):
            importlib.import_module(info.name)
print(matplotlib.get_backend())
"""


def test_importing_every_module_keeps_the_backend():
    done = subprocess.run([sys.executable, "-c", _IMPORT_ALL], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "svg"


def test_no_module_selects_a_backend():
    selecting = [str(path.relative_to(ROOT)) for package in PACKAGES
                 for path in sorted((ROOT / package).rglob("*.py"))
                 if "matplotlib.use(" in path.read_text(encoding="utf-8")]
    assert selecting == []
