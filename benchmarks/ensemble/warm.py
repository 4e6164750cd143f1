"""Compile the own methods' batch kernels once, into numba's on-disk cache:
``python -m benchmarks.ensemble.warm`` (``make setup`` runs it after
``python -m integrators.warm``, which compiles the single solves).

An ensemble of an own method runs one compiled batch per chunk (:mod:`integrators.own.batch`):
serially in a process of a pool, or over numba's threads. Each is compiled for every method and
friction law on first use; this runs a two-point ensemble of each both ways (and, for a method
with sensitivities, one with them).
"""

from __future__ import annotations

import sys
import time
import warnings

from tqdm.auto import tqdm

from benchmarks.ensemble.run import batched, ensemble
from integrators import REGISTRY
from integrators.warm import problems_to_warm

__all__ = ["warm"]


def warm(progress: bool = True) -> dict[str, float]:
    """Two-point ensembles of every batched own method, under each law, serially and on two
    threads; return the seconds each method took (its compiling, mostly)."""
    names = [n for n in sorted(REGISTRY, key=str.lower)
             if REGISTRY[n].adaptive and batched(REGISTRY[n](rtol=1e-6, atol=1e-6))]
    problems = [p for p in problems_to_warm() if p.t_end <= 2.0]
    took = {}
    with tqdm(total=len(names) * len(problems) * 2, desc="compiling batch kernels", unit="run",
              disable=not progress) as bar:
        for name in names:
            started = time.perf_counter()
            algorithm = REGISTRY[name](rtol=1e-4, atol=1e-4)
            for problem in problems:
                b = problem.law.b
                for backend, workers in (("processes", 1), ("threads", 2)):
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        ensemble(problem, algorithm, {"b": [b, 1.01 * b]}, workers=workers,
                                 backend=backend, progress=False, wall_budget=2.0)
                    bar.update()
            if getattr(algorithm, "sensitive", False):   # its batches with sensitivities
                problem = problems[0]
                for backend, workers in (("processes", 1), ("threads", 2)):
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        ensemble(problem, algorithm, {"b": [problem.law.b] * 2},
                                 workers=workers, backend=backend, progress=False,
                                 wall_budget=2.0, sensitivity=("b",))
            took[name] = time.perf_counter() - started
    return took


if __name__ == "__main__":
    took = warm(progress=sys.stderr.isatty())
    print(f"compiled the batch kernels of {', '.join(took)} in {sum(took.values()):.0f} s")
