"""The Rodas5P kernel's twin in C (``benchmarks/native/rodas5p.c``): the yardstick of the
compiled engine's speed.

The C program does the engine's arithmetic in the same order (the slip law with mass, Rodas5P's
attempt and 3×3 LU, Hairer's initial step, the RODAS controller, the root functions after each
step and the event scan's bisection on the dense output) on one segment of constant loading, so
that, built with gcc ``-O3 -ffp-contract=off`` (no fused multiply-adds: numba's kernels use
none), it takes the same steps, rejections and roots and ends in the same state to the bit
(tests/test_c_twin.py). Its time per step attempt against the kernel's, in one run, is how far
the numba code is from C (``rsfbench study engine-speed``). Not ported: the arrest of a deep
lock, load switches and two-speed loading, the step budget, save points other than the end.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from problems.formulations import N_Q, SLIP_LAW, form_vector, to_ode_state
from problems.loading import ln_load_rate

__all__ = ["SOURCE", "FLAGS", "compiler", "build", "write_input", "run_twin"]

SOURCE = Path(__file__).resolve().parents[1] / "native" / "rodas5p.c"
FLAGS = ("-O3", "-ffp-contract=off")


def compiler() -> str | None:
    """The C compiler the twin is built with (``gcc``), or None if there is none."""
    return shutil.which("gcc")


def build(directory) -> Path:
    """Build the twin into ``directory``; its path. RuntimeError (with gcc's message) if the
    build fails or there is no gcc."""
    cc = compiler()
    if cc is None:
        raise RuntimeError("the C twin needs gcc (apt-get install gcc)")
    binary = Path(directory) / "rodas5p"
    done = subprocess.run([cc, *FLAGS, str(SOURCE), "-lm", "-o", str(binary)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"gcc failed on {SOURCE.name}: {done.stderr.strip()}")
    return binary


def write_input(path, problem, tol: float) -> Path:
    """The twin's input for ``problem`` (slip law with mass, constant loading) at rtol = atol =
    ``tol``: q[8], z0[3], τ_end, rtol, atol, ln(10 E_slow), ln E_slow, ln E, h(0)."""
    nd = problem.nondimensional()
    if nd.law_code != SLIP_LAW or problem.quasi_static or nd.two_speed \
            or len(problem.loading.history.switch_times):
        raise ValueError(f"the C twin solves the slip law with mass under constant loading, "
                         f"not {problem.name}")
    q = form_vector(nd, nd.e_slow)
    values = [*q[:N_Q], *to_ode_state(nd.law_code, nd.beta, nd.x0), nd.tau_end, tol, tol,
              math.log(10.0 * nd.e_slow), math.log(nd.e_slow), ln_load_rate(nd.e_slow),
              nd.x0[0]]
    path = Path(path)
    path.write_text("# q[8] z0[3] tau_end rtol atol ln(10 E_slow) ln(E_slow) ln(E) h(0)\n"
                    + " ".join(repr(float(v)) for v in values) + "\n")
    return path


def run_twin(binary, input_path, repeats: int = 10) -> dict:
    """Run the twin ``repeats`` times: its counters, final state (the ODE form's z) and the
    minimum wall per step attempt (µs)."""
    out = subprocess.run([str(binary), str(input_path), str(int(repeats))], capture_output=True,
                         text=True)
    text = out.stdout
    counts = re.search(r"status (-?\d+) steps (\d+) rejected (\d+) nfev (\d+) njev (\d+) "
                       r"roots \[(\d+), (\d+), (\d+), (\d+)\] events (\d+)", text)
    z_end = re.search(r"z_end (\S+) (\S+) (\S+)", text)
    per = re.search(r"per attempt: min ([\d.]+) us", text)
    if not (counts and z_end and per):
        raise RuntimeError(f"the C twin's output was not understood: {text!r} {out.stderr!r}")
    c = [int(x) for x in counts.groups()]
    return {"status": c[0], "steps": c[1], "rejected": c[2], "nfev": c[3], "njev": c[4],
            "roots": c[5:9], "events": c[9],
            "z_end": np.array([float(x) for x in z_end.groups()]),
            "us_per_attempt": float(per.group(1))}
