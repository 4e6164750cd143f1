"""Compile every kernel once, into numba's on-disk cache: ``python -m integrators.warm``
(``python -m integrators.warm 1/2`` and ``2/2`` in two processes side by side: each half).

numba compiles a method's kernels for each friction law and for the slider with and without mass
the first time they run, and keeps them in its cache beside the sources (``__pycache__``). A
fresh checkout has none: its first runs pay the compiling (tens of seconds per method and law).
``make setup`` runs this module once after installing, so that neither the tests nor a user's
first run pay it; every integrator of the registry runs a short piece (:func:`short_piece`) of
the slider with mass, without it and with radiation damping, under each law, and each own
method's fixed-step entry runs two steps. What a kernel computes is never looked at here: the
tests do that.
"""

from __future__ import annotations

import dataclasses
import sys
import time
import warnings

__all__ = ["problems_to_warm", "warm"]


def problems_to_warm() -> list:
    """One short problem per (law, formulation) the kernels are specialised for."""
    from problems import LAWS, preset, velocity_step_test
    from problems.presets import fault_radiation_damping
    out = []
    for law in LAWS:
        inertial = preset("W2", law=law, t_end=2.0)
        out += [inertial, dataclasses.replace(inertial, mass=0.0),
                dataclasses.replace(inertial, radiation_damping=fault_radiation_damping()),
                velocity_step_test(law, t_end=20.0)]
    return out


def warm(names=None, progress: bool = True) -> dict[str, float]:
    """Run every integrator of ``names`` (default: the registry) on :func:`problems_to_warm`;
    return the seconds each took (its compiling, mostly)."""
    from tqdm.auto import tqdm

    from integrators import REGISTRY
    from integrators.core.registry import ProblemNotSupported
    from integrators.core.solve import compile_ahead
    names = sorted(REGISTRY, key=str.lower) if names is None else list(names)
    problems = problems_to_warm()
    took = {}
    with tqdm(total=len(names) * len(problems), desc="compiling kernels", unit="run",
              disable=not progress) as bar:
        for name in names:
            cls = REGISTRY[name]
            started = time.perf_counter()
            for problem in problems:
                algorithm = cls(rtol=1e-6, atol=1e-6) if cls.adaptive else cls()
                try:
                    algorithm.check_problem(problem)
                except ProblemNotSupported:
                    bar.update()
                    continue
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    compile_ahead(problem, algorithm, wall_budget=1.0)
                bar.update()
            if getattr(cls, "sensitive", False):      # its kernel with sensitivities
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    compile_ahead(problems[0], cls(rtol=1e-6, atol=1e-6), wall_budget=1.0,
                                  sensitivity=("b",))
            _warm_fixed_steps(cls)
            took[name] = time.perf_counter() - started
    return took


def _warm_fixed_steps(cls) -> None:
    """Compile an own method's fixed-step entry (the order studies' and tests'), which no solve
    runs: two steps from the paper example's start (its types are the same for every law)."""
    if not hasattr(cls, "fixed_steps"):
        return
    from problems import paper_example
    from problems.formulations import to_ode_state
    nd = paper_example(t_end=1.0).nondimensional()
    cls(rtol=1e-6, atol=1e-6).fixed_steps(nd, to_ode_state(nd.law_code, nd.beta, nd.x0), 1e-3, 2)


def part(text: str, names: list[str]) -> list[str]:
    """The names of part ``"I/N"`` of ``names``: every N-th from the I-th, so that processes
    warming the parts side by side share the costly own methods."""
    i, _, n = text.partition("/")
    if not (i.isdigit() and n.isdigit() and 1 <= int(i) <= int(n)):
        raise SystemExit(f"part = {text!r}: give I/N with 1 <= I <= N, such as 1/2")
    return names[int(i) - 1::int(n)]


if __name__ == "__main__":
    from integrators import REGISTRY
    every = sorted(REGISTRY, key=str.lower)
    took = warm(part(sys.argv[1], every) if len(sys.argv) > 1 else every,
                progress=sys.stderr.isatty())
    print(f"compiled the kernels of {len(took)} integrators in {sum(took.values()):.0f} s "
          f"(slowest: {max(took, key=took.get)}, {max(took.values()):.0f} s)")
