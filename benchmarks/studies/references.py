"""The reference solutions of the study problems: two independent solvers that must agree
(:mod:`benchmarks.devtools.reference`), and how closely they do."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from benchmarks.devtools.reference import agreement_table, reference
from benchmarks.devtools.work_precision import study_problems
from benchmarks.records.files import write_table
from benchmarks.records.report import markdown_table
from benchmarks.studies.study import Study

__all__ = ["STUDY"]


def run(out: Path) -> None:
    refs = [(p, reference(p, progress=False)) for p in study_problems("full")]
    write_table(agreement_table(refs), out / "references.csv")


def report(out: Path) -> str:
    agreement = pd.read_csv(out / "references.csv")
    table = markdown_table(
        agreement.groupby(["problem"], sort=False).agg(
            solvers=("name", " & ".join), tol=("tol", "first"),
            recurrence_s=("recurrence_s", "first"), event=("event_index", "first"),
            max_disagreement=("max_disagreement", "first")).reset_index()
        .assign(max_disagreement=lambda d: d.max_disagreement.map("{:.2g}".format),
                recurrence_s=lambda d: d.recurrence_s.map("{:.10f}".format)))
    return ("Each study problem is solved by two independent solvers at rtol = atol = 1e−12; "
            "their limit-cycle\nmetrics on the last complete event must agree to 1e−7 before "
            "either is used. Largest relative\ndisagreement per problem:\n\n" + table)


STUDY = Study("references", "Reference solutions (`references.csv`)", 40, run, report=report,
              writes=("references.csv",), minutes=0.4)
