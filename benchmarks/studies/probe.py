"""The reliability probe, slow cases included: the harness used as a new user and a hostile one
would use it (:mod:`benchmarks.probe`)."""

from __future__ import annotations

from pathlib import Path

from benchmarks.studies.study import Study

__all__ = ["STUDY"]


def run(out: Path) -> None:
    from benchmarks.probe import run_probe, write_probe
    from benchmarks.probe_cases import cases
    print(write_probe(run_probe(cases()), out))


def report(out: Path) -> str:
    return ("Every case of `benchmarks/probe_cases.py`, by kind and outcome (`rsfbench study "
            "probe`):\n\n" + (out / "reliability.md").read_text())


STUDY = Study("probe", "Reliability: the probe (`reliability.*`)", 260, run, report=report,
              data=("results/wp_quick.csv", "docs/examples/apparatus.toml"),
              modules=("benchmarks.cli",),
              writes=("reliability.csv", "reliability.md"), minutes=19)
