"""docs/adding-a-law.md is the whole list: a toy law added through exactly the files it names
runs through solve, the batch kernel, the laboratory model (one state and two) and the CLI.

The toy is the aging law restated under its own name and code 3, with its own block of compiled
functions: every route must give the aging law's numbers, and a dispatcher line or a file the
guide forgot shows as NaN (a failed run), an unknown name or a refused ``--law``. It runs on a
copy of the packages in a temporary directory with its own numba cache (the change alters
compiled code that cached kernels of the checkout have inlined), in a subprocess.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "adding-a-law.md"

FRICTION = '''

class ToyLaw(AgingLaw):
    """The aging law under another name and code (tests/test_adding_a_law.py)."""

    name: ClassVar[str] = "toy"
    code: ClassVar[int] = 3


LAWS["toy"] = ToyLaw
'''

BLOCK = '''
# The toy law: the aging law's formulas, written again (tests/test_adding_a_law.py).
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _toy_rate(q, u, s, w):
    return np.exp(-s) - w


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _toy_partials(q, u, s, w):
    return -w, -np.exp(-s)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _toy_second(q, u, s, w):
    return -w, 0.0, np.exp(-s), 0.0, 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _toy_targets(q, h, lnw, w, psi):
    beta = q[Q_BETA]
    return (q[Q_C] * h + beta * w / psi - beta * w * w) / q[Q_D], 1.0 / w, w


'''

#: one line per dispatcher (before its ``return np.nan``), as the guide's step 2 says
DISPATCH = {"state_rate": "    if law == 3:\n        return _toy_rate(q, u, s, w)\n",
            "state_rate_partials": "    if law == 3:\n        return _toy_partials(q, u, s, w)\n",
            "state_rate_second_partials":
                "    if law == 3:\n        return _toy_second(q, u, s, w)\n",
            "ln_slip_rate": "    if law == 3:\n        return _log_state_ln_w(beta, eta, psi)\n",
            "etd_targets": "    if law == 3:\n        return _toy_targets(q, h, lnw, w, psi)\n"}


def _add_to_formulations(text: str) -> str:
    codes = 'LAW_CODES = {SLIP_LAW: "slip", AGING_LAW: "aging", NAGATA_LAW: "nagata"}\n'
    logs = "LOG_STATE_LAWS = frozenset({AGING_LAW, NAGATA_LAW})\n"
    marker = "# The dispatchers:"
    for anchor in (codes, logs, marker):
        assert anchor in text, f"problems/formulations.py no longer has {anchor!r}: update the test"
    text = text.replace(codes, codes + 'LAW_CODES[3] = "toy"\n')
    text = text.replace(logs, "LOG_STATE_LAWS = frozenset({AGING_LAW, NAGATA_LAW, 3})\n")
    text = text.replace(marker, BLOCK.lstrip("\n") + marker)
    for name, line in DISPATCH.items():
        start = text.index(f"\ndef {name}(")
        end = text.index("    return np.nan", start)
        text = text[:end] + line + text[end:]
    return text


def _add_to_friction(text: str) -> str:
    anchor = "\n\ndef law_from_name("
    assert anchor in text, "problems/friction.py no longer has law_from_name: update the test"
    return text.replace(anchor, FRICTION + anchor, 1)


EDITS = {"problems/friction.py": _add_to_friction,
         "problems/formulations.py": _add_to_formulations}

SCRIPT = textwrap.dedent('''
    import json, subprocess, sys
    import numpy as np
    import pandas as pd
    from benchmarks.ensemble import batch_rows, grid, point_problems
    from benchmarks.lab.model import LabModel
    from benchmarks.lab.step_data import lab_record_from
    from benchmarks.lab.independent_model import synthetic_record
    from integrators import Rodas5P, solve
    from problems import LAWS, preset

    assert "toy" in LAWS
    alg = Rodas5P(rtol=1e-8, atol=1e-8)
    out = {}
    runs = {law: solve(preset("W2", law=law, t_end=20.0), alg) for law in ("toy", "aging")}
    assert runs["toy"].success, runs["toy"].message
    out["solve"] = float(np.max(np.abs(runs["toy"].v / runs["aging"].v - 1.0)))
    rows = {}
    for law in ("toy", "aging"):
        base = preset("W2", law=law, t_end=20.0)
        points = grid(b=[0.0095, 0.0100], lc=[2e-6, 3e-6])
        names, values = list(points), np.column_stack(list(points.values()))
        rows[law] = batch_rows(point_problems(base, names, values), alg, names, values,
                               parallel=False)
    out["batch_rows"] = len(rows["toy"])
    cols = [c for c in rows["toy"].select_dtypes("number").columns
            if not any(w in c for w in ("second", "wall", "clock"))]
    out["batch_columns"] = cols
    out["batch"] = float(np.nanmax(np.abs(rows["toy"][cols].to_numpy(float)
                                          - rows["aging"][cols].to_numpy(float))))
    t = np.linspace(0.0, 60.0, 2000)
    df = synthetic_record(t, (1e-6, 1e-5), (20.0,), a=0.006, b=0.009, dc=10e-6, k=3e3, law="aging",
                          noise=0.0)
    rec = lab_record_from(df, ["time=time_s", "load_point=load_point_um:um", "friction=friction"])
    for states, extra in ((1, {}), (2, dict(b2=0.002, dc2=50e-6))):
        g = {law: LabModel(rec, law, detrend="none", states=states).response(
                a=0.006, b=0.009, dc=10e-6, k=3e3, **extra)[0] for law in ("toy", "aging")}
        assert np.isfinite(g["toy"]).all()
        out[f"lab{states}"] = float(np.max(np.abs(g["toy"] - g["aging"])))
    print(json.dumps(out))
''')


def _guide_files() -> set[str]:
    """The files the guide's list names (its section "The files")."""
    text = GUIDE.read_text()
    section = text.split("## The files", 1)[1].split("\n## ", 1)[0]
    return set(re.findall(r"`(problems/\w+\.py)`", section))


def test_the_guide_names_the_files_the_toy_law_touches():
    named = _guide_files()
    assert set(EDITS) <= named and len(named) <= 4, (sorted(EDITS), sorted(named))


@pytest.mark.slow
def test_a_toy_law_added_through_the_guides_files_runs_everywhere(tmp_path):
    """Through exactly the guide's files: solve (Rodas5P), the batch kernel, the lab model with
    one and two states and ``rsfbench simulate --law toy`` give the aging law's numbers (the same
    arithmetic in another block: equal to round-off; 0 when this test was written)."""
    copy = tmp_path / "src"
    skip = shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc", "*.pyc")
    for room in ("problems", "integrators", "benchmarks"):
        shutil.copytree(ROOT / room, copy / room, ignore=skip)
    shutil.copy2(ROOT / "rsfbench_cli.py", copy / "rsfbench_cli.py")
    for path, edit in EDITS.items():
        (copy / path).write_text(edit((copy / path).read_text()))
    env = dict(os.environ, PYTHONPATH=str(copy), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=1500)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["solve"] < 1e-12 and out["batch_rows"] == 4 and out["batch"] < 1e-12, out
    assert out["lab1"] < 1e-12 and out["lab2"] < 1e-12, out
    for law in ("toy", "aging"):
        cli = subprocess.run([sys.executable, str(copy / "rsfbench_cli.py"), "simulate",
                              "--preset", "W2", "--law", law, "--t-end", "20",
                              "--integrator", "Rodas5P", "--rtol", "1e-8", "--atol", "1e-8",
                              "--json"], cwd=tmp_path, env=env, capture_output=True, text=True,
                             timeout=600)
        assert cli.returncode == 0, cli.stderr[-2000:]
        out[law] = json.loads(cli.stdout)
    assert _same_numbers(out["toy"], out["aging"]), (out["toy"], out["aging"])


def _same_numbers(a, b) -> bool:
    """Every number of two JSON documents equal, except those naming the law or timing a run."""
    if isinstance(a, dict):
        return all(_same_numbers(a[k], b.get(k)) for k in a
                   if not re.search(r"law|name|seconds|wall|time_s|provenance|version|commit", k))
    if isinstance(a, list):
        return len(a) == len(b) and all(map(_same_numbers, a, b))
    if isinstance(a, float):
        return isinstance(b, float) and abs(a - b) <= 1e-12 * max(abs(a), abs(b), 1e-300)
    return True
